"""How the shipped benchmark specs were chosen: a validation study on the TRAINING data only.

    python benchmarks/benchmark_selection.py                       # every benchmark, its whole grid
    python benchmarks/benchmark_selection.py emps --quick          # the first few candidates only
    python benchmarks/benchmark_selection.py silverbox --out sel.jsonl   # append results (resumes)

For each benchmark we hold data for, every candidate configuration is fitted on part of the
benchmark's training data and scored on the held-out rest, under the benchmark's own protocol
(the held-out part is a run of its own, initialized from the protocol's window, or scored on every
sample from the input alone where the protocol says so). The test outputs are never read: the
only use of a test set is its *input* (and, where the protocol allows one, its initialization
window), to reject a candidate whose free run leaves a band of half the training output range
around that range, the robustness rule of the ``auto`` issue (a run held at an output clipping
bound beyond the training range counts as leaving: the clip hides a diverging model; clipping at
the training range itself, a saturating sensor, passes). The survivors form a committee: a
candidate whose run on the test inputs lies farther from the committee's pointwise median run than
twice the median such distance is dropped (where candidates that validate alike disagree on an
input beyond the training range, the outliers extrapolate; inputs only, again). Among the rest, the
choice is the candidate with the fewest terms whose validation RMSE lies within 1 % of the lowest
(differences below that are noise of the validation split); specs/benchmarks/*.yaml ship it.

Validation layouts: ``holdout`` scores the last 20 % of each training recording (Silverbox,
EMPS, Bouc-Wen, where the data are long); ``folds K`` (Cascaded Tanks, 1024 training samples)
scores each of K consecutive blocks in turn, trained on the rest, and averages the RMSE (a single
20 % block, 155 scored samples after the window, cannot rank candidates reliably).

Figures print in the benchmark's units; fit seconds are wall time on this machine (under load
when others run). Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from dynmodel import engine, registry
from dynmodel.data.dataset import Dataset, Recording
from dynmodel.errors import DynmodelError
from dynmodel.spec import validate_spec

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
BAND = 0.5  # a free run on a test input must stay within the training output range +- BAND x its width
TIE = 1.01  # validation RMSEs within 1 % of the lowest count as equal; the fewest terms wins
COMMITTEE = 2.0  # a candidate's distance to the committee's median run: at most this x the median distance
PROTOCOL = 3  # version of the validation protocol and checks (cached results of another version are redone)


def _narx(u: int, y: int, degree: int = 3, u_from: int = 0, **params) -> dict[str, Any]:
    lags = {"u": [{"from": u_from, "to": u}], "y": [{"from": 1, "to": y}]}
    return {"family": "narx", "params": {"lags": lags, "degree": degree, **params}}


def _grid_silverbox() -> list[dict[str, Any]]:
    out = [_narx(k, k) for k in (4, 5, 6, 7, 8)]
    out += [_narx(6, 6, max_terms=m, patience=None) for m in (60, 80, 100, 130)]
    out += [_narx(8, 8, max_terms=m, patience=None) for m in (100, 130)]
    return [{"model": m} for m in out]


def _grid_tanks() -> list[dict[str, Any]]:
    out = []
    for degree in (2, 3):
        for u, y in [(2, 2), (4, 3), (4, 4), (6, 3), (8, 4)]:
            for terms in (10, 15, 20, 30):
                for bounds in (None, 0.0):
                    extra = {} if bounds is None else {"bounds": bounds}
                    out.append(_narx(u, y, degree, max_terms=terms, patience=None, **extra))
    # second stage: the first stage's best lay on its edge (the longest input lags, bounds 0)
    for degree in (2, 3):
        for u in (8, 10, 12, 16):
            for y in (2, 3, 4, 6):
                for terms in (6, 8, 10, 12, 15):
                    cand = _narx(u, y, degree, max_terms=terms, patience=None, bounds=0.0)
                    if cand not in out:
                        out.append(cand)
    return [{"model": m} for m in out]


def _grid_emps() -> list[dict[str, Any]]:
    out = []
    for u_from, u, y in [(1, 2, 3), (1, 2, 2), (0, 2, 3), (1, 3, 3), (1, 4, 4), (1, 2, 4)]:
        for terms in (10, 15, 20, 30):
            for bounds in (None, 0.1):
                extra = {} if bounds is None else {"bounds": bounds}
                out.append(_narx(u, y, 3, u_from=u_from, max_terms=terms, patience=None, **extra))
    # second stage: around the best candidates that stay bounded on the test input
    for u_from, u, y in [(1, 2, 3), (1, 2, 2), (0, 2, 3), (0, 2, 2), (1, 2, 4)]:
        for terms in (12, 13, 14, 16, 17, 18):
            out.append(_narx(u, y, 3, u_from=u_from, max_terms=terms, patience=None))
    out += [_narx(2, 3, 3, u_from=1, patience=p) for p in (1, 3)]  # FOS stopped on the validation error
    out += [_narx(2, 3, 2, u_from=1, max_terms=t, patience=None) for t in (6, 8, 10, 15)]  # degree 2
    return [{"model": m} for m in out]


def _grid_bouc_wen() -> list[dict[str, Any]]:
    out = []
    for k in (4, 6, 8):
        for terms in (40, 60, 80, 100):
            out.append(_narx(k, k, 3, max_terms=terms, patience=None, initial="zeros"))
    # second stage: between and beyond the first stage's best (6 lags, more terms)
    for k in (5, 6, 7):
        for terms in (50, 60, 70, 80, 100, 120):
            cand = _narx(k, k, 3, max_terms=terms, patience=None, initial="zeros")
            if cand not in out:
                out.append(cand)
    return [{"model": m} for m in out]


#: benchmark -> (folder under the shared data, validation layout, candidate grid)
STUDIES: dict[str, tuple[str, tuple[str, int], Any]] = {
    "silverbox": ("silverbox", ("holdout", 0), _grid_silverbox),
    "cascaded-tanks": ("cascaded_tanks", ("folds", 5), _grid_tanks),
    "emps": ("emps", ("holdout", 0), _grid_emps),
    "bouc-wen": ("bouc_wen", ("holdout", 0), _grid_bouc_wen),
}


def folds(train: list[Recording], layout: tuple[str, int]) -> list[tuple[list[Recording], list[Recording]]]:
    """(training recordings, validation recordings) per fold."""
    kind, k = layout
    if kind == "holdout":
        cut = [int(round(0.8 * r.n)) for r in train]
        return [
            (
                [Recording(r.name, r.u[:c], r.y[:c]) for r, c in zip(train, cut)],
                [Recording(f"{r.name}[{c}:]", r.u[c:], r.y[c:]) for r, c in zip(train, cut)],
            )
        ]
    out = []
    for i in range(k):
        fit, val = [], []
        for r in train:
            a, b = (i * r.n) // k, ((i + 1) * r.n) // k
            fit += [Recording(f"{r.name}[{s}:{e}]", r.u[s:e], r.y[s:e]) for s, e in ((0, a), (b, r.n)) if e - s > 50]
            val.append(Recording(f"{r.name}[{a}:{b}]", r.u[a:b], r.y[a:b]))
        out.append((fit, val))
    return out


def fold_dataset(bench_data, fit: list[Recording], val: list[Recording]) -> Dataset:
    """The fold as a dataset under the benchmark's protocol: the validation recordings are runs of their
    own (the protocol's window, or every sample scored), or, for a protocol without one (Bouc-Wen's
    steady-state multisine), holdout validation continues the free run of its training recording."""
    if bench_data.window is None and not bench_data.score_all and len(fit) == len(val):
        recs = [Recording(f.name, np.concatenate([f.u, v.u]), np.concatenate([f.y, v.y])) for f, v in zip(fit, val)]
        ranges = {
            "train": [(i, 0, f.n) for i, f in enumerate(fit)],
            "validation": [(i, f.n, f.n + v.n) for i, (f, v) in enumerate(zip(fit, val))],
        }
        windows, every = {}, set()
    else:
        recs = fit + val
        ranges = {
            "train": [(i, 0, r.n) for i, r in enumerate(fit)],
            "validation": [(len(fit) + i, 0, r.n) for i, r in enumerate(val)],
        }
        windows = {} if bench_data.score_all else {"validation": bench_data.window}
        every = {"validation"} if bench_data.score_all else set()
    return Dataset(
        recs,
        ranges,
        0,
        list(bench_data.input_names),
        list(bench_data.output_names),
        bench_data.sampling_time,
        windows=windows,
        score_all=every,
        units=dict(bench_data.units),
    )


def test_input_runs(model, bench_data) -> list[np.ndarray]:
    """The candidate's free runs on every test INPUT (from the protocol's measured window where there is
    one, from rest otherwise), in the data's units, over the samples the protocol scores."""
    runs = []
    for t in bench_data.tests:
        for r in t.recordings:
            warm = model.warmup
            y = model.run(r.u, r.y[:warm] if warm else None).y
            runs.append(y[max(t.lead_in, 0 if t.score_all else t.window) :])
    return runs


def test_input_check(model, runs: list[np.ndarray], bench_data, train_y: np.ndarray) -> str:
    """'ok', or where a free run on a test INPUT leaves the band around the training output range
    (the test outputs are not read beyond the protocol's initialization window). Output clipping
    (narx ``bounds``) counts as leaving when it holds the run at a bound beyond the training range:
    such a model diverges and the clip hides it. Clipping at the training range itself (``bounds: 0``,
    a saturating sensor) is the model's own behaviour and passes."""
    lo, hi = train_y.min(axis=0), train_y.max(axis=0)
    width = hi - lo
    fam = model.family
    clip_lo, clip_hi = np.full_like(lo, -np.inf), np.full_like(hi, np.inf)
    if getattr(fam, "clip_lo_", None) is not None:
        pre = model.preprocessor
        clip_lo = np.where(np.isfinite(fam.clip_lo_), pre.physical_outputs(fam.clip_lo_[None, :])[0], -np.inf)
        clip_hi = np.where(np.isfinite(fam.clip_hi_), pre.physical_outputs(fam.clip_hi_[None, :])[0], np.inf)
    tol = 1e-9 * width
    held_lo = clip_lo < lo - tol  # a clip bound beyond the training range: reaching it means diverging
    held_hi = clip_hi > hi + tol
    names = [t.name or "test" for t in bench_data.tests for _ in t.recordings]
    for name, y in zip(names, runs):
        bad = ~np.isfinite(y).all(axis=1) | ((y < lo - BAND * width) | (y > hi + BAND * width)).any(axis=1)
        bad |= ((y <= clip_lo + tol) & held_lo).any(axis=1) | ((y >= clip_hi - tol) & held_hi).any(axis=1)
        if bad.any():
            return f"leaves the band on the {name} input at sample {int(np.argmax(bad))}"
    return "ok"


def evaluate_candidate(
    name: str, root: Path, layout, candidate: dict[str, Any]
) -> tuple[dict[str, Any], list[np.ndarray] | None]:
    """The candidate's validation figures, and its test-input runs in the reporting units (averaged over folds)."""
    bench_data = registry.benchmark(name).load(root)
    raw = {
        "name": f"{name}-selection",
        "data": {"benchmark": name, "root": str(root), **candidate.get("data", {})},
        "model": candidate["model"],
        "cost": candidate.get("cost", "mse_inf"),
        "evaluation": {"metrics": ["rmse"], "one_step": False},
    }
    spec = validate_spec(raw, f"<{name} selection>")
    scores, seconds, checks, terms, fold_runs = [], 0.0, [], [], []
    for fit, val in folds(bench_data.train, layout):
        ds = fold_dataset(bench_data, fit, val)
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                model, _ = engine.fit_dataset(spec, ds)
        except DynmodelError as exc:
            return {"error": exc.line()}, None
        seconds += time.perf_counter() - t0
        m = model.metrics["validation"]
        scores.append(m.get("rmse") if m.get("rmse") is not None else float("inf"))
        terms.append(int(np.size(getattr(model.family, "weights_", []))))
        runs = test_input_runs(model, bench_data)
        checks.append(test_input_check(model, runs, bench_data, ds.concat_outputs("train")))
        fold_runs.append(runs)
    scale, units = next(iter(bench_data.units.values()), (1.0, ""))
    bad = next((c for c in checks if c != "ok"), "ok")
    mean_runs = [scale * np.mean([runs[i] for runs in fold_runs], axis=0) for i in range(len(fold_runs[0]))]
    return {
        "validation_rmse": float(np.mean(scores)),
        "folds": [float(s) for s in scores],
        "units": units,
        "test_inputs": bad,
        "check": "clip-aware",
        "protocol": PROTOCOL,
        "fit_seconds": round(seconds, 1),
        "terms": max(terms),
    }, mean_runs


def consistent(rows: list[dict[str, Any]], runs: list[list[np.ndarray]], name: str) -> list[dict[str, Any]]:
    """The candidates whose test-input runs agree with the committee: the RMS distance of a candidate's run
    from the pointwise median of all candidates' runs, averaged over the test inputs, at most COMMITTEE x the
    median of those distances. Inputs only: where candidates that validate alike disagree on a test input
    (it leaves the training range), the outliers are extrapolating, whatever their validation error."""
    medians = [np.median([c[i] for c in runs], axis=0) for i in range(len(runs[0]))]
    dist = np.array([np.mean([np.sqrt(np.mean((r[i] - m) ** 2)) for i, m in enumerate(medians)]) for r in runs])
    limit = COMMITTEE * float(np.median(dist))
    kept = [row for row, d in zip(rows, dist) if d <= limit]
    for row, d in zip(rows, dist):
        row["committee_distance"] = float(d)
    print(
        f"{name}: {len(kept)} of {len(rows)} candidates agree with the committee on the test inputs "
        f"(distance to the median run <= {limit:.3g} {rows[0]['units']})"
    )
    return kept


def _key(candidate: dict[str, Any]) -> str:
    return json.dumps(candidate, sort_keys=True)


def study(name: str, data_root: Path, quick: bool, out: Path | None) -> dict[str, Any] | None:
    folder, layout, grid = STUDIES[name]
    root = data_root / folder
    if not root.is_dir():
        print(f"{name}: no data in {root}, skipped")
        return None
    done: dict[str, dict[str, Any]] = {}
    if out is not None and out.exists():
        for line in out.read_text().splitlines():
            row = json.loads(line)
            if row.get("benchmark") == name:
                done[_key(row["candidate"])] = row
    candidates = grid()[: 4 if quick else None]
    print(f"\n{name}: {len(candidates)} candidates, validation layout {layout[0]} {layout[1] or ''}".rstrip())
    rows, runs = [], {}
    store = None if out is None else out.with_suffix(".runs")
    for cand in candidates:
        key = _key(cand)
        row = done.get(key)
        cached = None if store is None else store / f"{hashlib.sha1(key.encode()).hexdigest()}.npz"
        if row is not None and row.get("protocol") == PROTOCOL and "error" not in row:
            if cached is not None and cached.exists():
                with np.load(cached) as z:
                    runs[key] = [z[k] for k in sorted(z.files, key=lambda k: int(k[3:]))]
            else:
                row = None  # redo: no stored runs
        if row is None or row.get("protocol") != PROTOCOL:
            figures, cand_runs = evaluate_candidate(name, root, layout, cand)
            row = {"benchmark": name, "candidate": cand, **figures}
            if cand_runs is not None:
                runs[key] = cand_runs
                if cached is not None:
                    cached.parent.mkdir(parents=True, exist_ok=True)
                    np.savez(cached, **{f"run{i}": r for i, r in enumerate(cand_runs)})
            if out is not None:
                with out.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")
        rows.append(row)
        shown = json.dumps(cand["model"]["params"], separators=(",", ":"))
        if "error" in row:
            print(f"  error  {shown}: {row['error']}")
        else:
            print(
                f"  {row['validation_rmse']:10.4g} {row['units']:<4} {row['terms']:4d} terms {row['fit_seconds']:7.1f} s  "
                f"test inputs {row['test_inputs']:<8} {shown}",
                flush=True,
            )
    ok = [r for r in rows if "error" not in r and r["test_inputs"] == "ok" and np.isfinite(r["validation_rmse"])]
    if not ok:
        print(f"{name}: no candidate passed")
        return None
    ok = consistent(ok, [runs[_key(r["candidate"])] for r in ok], name)
    lowest = min(r["validation_rmse"] for r in ok)
    close = [r for r in ok if r["validation_rmse"] <= TIE * lowest]
    best = min(close, key=lambda r: (r["terms"], r["validation_rmse"]))
    print(
        f"{name}: chosen {json.dumps(best['candidate'])} (validation RMSE {best['validation_rmse']:.4g} "
        f"{best['units']}, {best['terms']} terms; the lowest was {lowest:.4g})"
    )
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("benchmarks", nargs="*", default=list(STUDIES), help=f"any of {', '.join(STUDIES)}")
    ap.add_argument("--data", type=Path, default=DATA, help="folder holding one sub-folder per benchmark")
    ap.add_argument("--quick", action="store_true", help="only the first 4 candidates of each grid")
    ap.add_argument("--out", type=Path, help="JSON-lines file of results (appended; finished candidates are reused)")
    args = ap.parse_args()
    for name in args.benchmarks:
        study(name, args.data, args.quick, args.out)


if __name__ == "__main__":
    main()
