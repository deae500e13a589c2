"""The benchmark leaderboard: our shipped benchmark specs, SysIdentPy on the same split, the published best.

    python benchmarks/leaderboard.py                    # fit every spec of specs/benchmarks, print the table
    python benchmarks/leaderboard.py --no-peer          # without SysIdentPy
    python benchmarks/leaderboard.py --readme           # also rewrite the table in README.md (between its markers)
    python benchmarks/leaderboard.py --data DIR         # the benchmarks' files under DIR/<benchmark folder>
    python benchmarks/leaderboard.py --readme --keep narx peer   # refit the auto specs only, keep the rest

Every spec of ``specs/benchmarks`` is fitted with ``dynmodel.fit`` exactly as ``dynmodel fit SPEC`` would
(the benchmark source reproduces the splits, windows and units of nonlinear-benchmarks 1.0.1; the
configuration was chosen on validation, see benchmarks/benchmark_selection.py) and scored on every
test set. ``<benchmark>-auto.yaml`` specs (``model: {family: auto}``, the auto issue) get a column of
their own once they exist.

The peer: SysIdentPy's FROLS polynomial NARX with the same lags, degree and number of terms as our
spec's fitted model, least-squares weights (its default one-step estimation), fitted on the same
training samples and simulated free-running on the same test inputs from the same measured start,
scored on the same samples. It is optional (``pip install sysidentpy``); without it, or where it fails
(memory, time, a diverging simulation), its cell says so.

The table is written to docs/leaderboard.md; ``--readme`` replaces the lines between
``<!-- leaderboard:begin -->`` and ``<!-- leaderboard:end -->`` in README.md. Fit times are wall time
on the machine that ran it. ``--keep`` takes the named columns (``narx``, ``auto``, ``peer``) and their
specs' notes as they stand in the last table written (docs/leaderboard.md) instead of fitting them again: the
auto specs' search takes minutes per benchmark, and a machine without SysIdentPy keeps its measured column.
Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.errors import DynmodelError
from dynmodel.spec import load_spec

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs" / "benchmarks"
BEGIN, END = "<!-- leaderboard:begin -->", "<!-- leaderboard:end -->"


@dataclass
class Published:
    value: str
    source: str


@dataclass
class Benchmark:
    name: str  # the benchmark source's name
    title: str
    folder: str  # under the shared data folder
    tests: dict[str, str]  # metrics key -> label
    published: dict[str, Published]
    rows: dict[str, dict[str, str]] = field(default_factory=dict)  # variant -> metrics key -> cell


CHAMPNEYS = "Champneys et al. 2024, arXiv 2405.10779"
BENCHMARKS = [
    Benchmark(
        "silverbox",
        "Silverbox (mV)",
        "silverbox",
        {
            "test:multisine": "multisine",
            "test:arrow-full": "arrow full",
            "test:arrow-no-extrapolation": "arrow no-extrap.",
        },
        {
            "test:multisine": Published("0.301", f"GP-NARX baseline, {CHAMPNEYS}"),
            "test:arrow-full": Published("0.26", "PNLSS, Paduart et al. 2010 (from the literature, not verified here)"),
            "test:arrow-no-extrapolation": Published("0.259", f"GP-NARX baseline, {CHAMPNEYS}"),
        },
    ),
    Benchmark(
        "cascaded-tanks",
        "Cascaded Tanks (V)",
        "cascaded_tanks",
        {"test": "test (50-sample window)"},
        {"test": Published("0.306", "CT-SUBNET, Beintema et al. 2023 (grey-box 0.191, Rogers et al.)")},
    ),
    Benchmark(
        "bouc-wen",
        "Bouc-Wen (m)",
        "bouc_wen",
        {"test:multisine": "multisine", "test:sinesweep": "sine-sweep"},
        {
            "test:multisine": Published("1.87e-5", "PNLSS for hysteresis, Esfahani et al. 2017/18"),
            "test:sinesweep": Published("–", "no verified published figure"),
        },
    ),
    Benchmark(
        "emps",
        "EMPS (mm)",
        "emps",
        {"test": "test (20-sample window)"},
        {"test": Published("2.64", "dynoNet, Forgione & Piga 2021")},
    ),
]
VARIANTS = ("narx", "auto")  # specs/benchmarks/<benchmark>-<variant>.yaml


def _fmt(value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "diverged"
    return f"{value:#.3g}" if value >= 1e-3 else f"{value:.2e}".replace("e-0", "e-")


def run_spec(path: Path, data: Path | None) -> tuple[dict[str, float | None], float, object, object, object]:
    spec = load_spec(path)
    if data is not None:
        spec.data.root = str(data / Path(spec.data.root).name)
    ds = load_dataset(spec)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model, _ = engine.fit_dataset(spec, ds)
    seconds = time.perf_counter() - t0
    return {k: m.get("rmse") for k, m in model.metrics.items()}, seconds, spec, ds, model


def peer(spec, ds, model) -> dict[str, float | None] | str:
    """SysIdentPy FROLS with our model's lags, degree and term count, on the same samples."""
    try:
        from sysidentpy.basis_function import Polynomial
        from sysidentpy.model_structure_selection import FROLS
        from sysidentpy.parameter_estimation import LeastSquares
    except Exception:  # noqa: BLE001 - the peer is optional
        return "not installed"
    fam = model.family
    if spec.model.family != "narx" or len(ds.input_names) != 1 or len(ds.output_names) != 1:
        return "n/a"
    lags = fam.params.lag_table()
    u_lags, y_lags = lags[ds.input_names[0]], lags[ds.output_names[0]]
    # SysIdentPy's input lags start at 1: it receives the input advanced by one sample, x_t = u_{t+1}
    xlag, ylag = [lag + 1 for lag in u_lags], list(y_lags)
    n_terms = int(len(fam.weights_))
    frols = FROLS(
        order_selection=False,
        n_terms=n_terms,
        xlag=xlag if len(xlag) > 1 else xlag[0],
        ylag=ylag if len(ylag) > 1 else ylag[0],
        estimator=LeastSquares(),
        basis_function=Polynomial(degree=fam.params.degree),
        model_type="NARMAX",
    )
    train = [(ds.recordings[r].u[a:b], ds.recordings[r].y[a:b]) for r, a, b in ds.ranges["train"]]
    u = np.concatenate([_advanced(x) for x, _ in train])
    y = np.concatenate([t for _, t in train])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            frols.fit(X=u, y=y)
    except Exception as exc:  # noqa: BLE001 - report, do not crash the table
        return f"failed ({type(exc).__name__})"
    scale = {n: s for n, (s, _) in ds.units.items()}.get(ds.output_names[0], 1.0)
    out: dict[str, float | None] = {}
    for key in ds.test_splits():
        sq, count = 0.0, 0
        for r, a, b in ds.scored(key, model.warmup):
            rec = ds.recordings[r]
            start = np.zeros((frols.max_lag, 1)) if key in ds.score_all else rec.y[: frols.max_lag]
            try:
                with warnings.catch_warnings(), np.errstate(all="ignore"):
                    warnings.simplefilter("ignore")
                    yhat = frols.predict(X=_advanced(rec.u), y=start)
            except Exception:  # noqa: BLE001
                yhat = np.full_like(rec.y, np.nan)
            err = (yhat[a:b, 0] - rec.y[a:b, 0]) * scale
            sq += float(np.sum(err**2))
            count += b - a
        out[key] = float(np.sqrt(sq / count)) if np.isfinite(sq) else None
    return out


def _advanced(u: np.ndarray) -> np.ndarray:
    return np.concatenate([u[1:], u[-1:]])


#: --keep's column names -> the table's headers
HEADERS = {"narx": "dynmodel narx spec", "auto": "dynmodel auto", "peer": "SysIdentPy FROLS, same split"}


def kept_cells(path: Path, columns: list[str]) -> tuple[dict[tuple[str, str, str], str], dict[str, str]]:
    """From the last table written to ``path``: {(column, benchmark title, test label): cell} for ``columns``, and
    {spec file: its note} (the line after the table, one note per spec, ``; `` between them)."""
    if not path.exists():
        raise SystemExit(f"--keep: {path} does not exist; run without --keep first")
    lines = path.read_text().splitlines()
    rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines if line.startswith("| ")]
    if not rows:
        raise SystemExit(f"--keep: {path} holds no table")
    head, body = rows[0], rows[1:]
    cells: dict[tuple[str, str, str], str] = {}
    for column in columns:
        if HEADERS[column] not in head:
            raise SystemExit(f"--keep {column}: the table in {path} has no column {HEADERS[column]!r}")
        j = head.index(HEADERS[column])
        cells.update({(column, row[0], row[1]): row[j] for row in body if len(row) == len(head)})
    notes: dict[str, str] = {}
    for line in lines:
        if line.startswith("`specs/"):
            for note in line.split("; "):
                notes[note.split("`")[1]] = note
    return cells, notes


def table(benchmarks: list[Benchmark], with_peer: bool) -> str:
    head = ["benchmark", "test set", "dynmodel narx spec", "dynmodel auto"]
    head += ["SysIdentPy FROLS, same split"] if with_peer else []
    head += ["published best black-box", "source of the published figure"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for b in benchmarks:
        for key, label in b.tests.items():
            cells = [b.title, label]
            for variant in VARIANTS:
                cells.append(b.rows.get(variant, {}).get(key, "–"))
            if with_peer:
                cells.append(b.rows.get("peer", {}).get(key, "–"))
            cells += [b.published[key].value, b.published[key].source]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, help="folder holding one sub-folder per benchmark (default: the specs' roots)")
    ap.add_argument("--no-peer", action="store_true", help="do not run SysIdentPy")
    ap.add_argument("--readme", action="store_true", help="rewrite the leaderboard table in README.md")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "leaderboard.md", help="Markdown file to write")
    ap.add_argument(
        "--keep",
        nargs="+",
        choices=sorted(HEADERS),
        default=[],
        help="take these columns from the last table written (--out) instead of fitting them again",
    )
    args = ap.parse_args()
    kept, kept_notes = kept_cells(args.out, args.keep) if args.keep else ({}, {})
    with_peer = not args.no_peer or "peer" in args.keep
    notes = []
    for b in BENCHMARKS:
        for column in args.keep:
            b.rows[column] = {
                k: kept[(column, b.title, label)] for k, label in b.tests.items() if (column, b.title, label) in kept
            }
        for variant in VARIANTS:
            path = SPECS / f"{b.name}-{variant}.yaml"
            if not path.exists():
                continue
            if variant in args.keep:
                note = kept_notes.get(str(path.relative_to(ROOT)))
                notes += [note] if note else []
                continue
            try:
                rmse, seconds, spec, ds, model = run_spec(path, args.data)
            except DynmodelError as exc:
                print(f"{path.name}: {exc.line()}")
                continue
            b.rows[variant] = {k: f"**{_fmt(rmse.get(k))}**" for k in b.tests}
            terms = f", {len(model.family.weights_)} terms" if hasattr(model.family, "weights_") else ""
            notes.append(f"`{path.relative_to(ROOT)}`: fit and scoring {seconds:.2g} s{terms}")
            print(
                f"{path.name}: fit and scoring {seconds:.2g} s; "
                + ", ".join(f"{k} {_fmt(rmse.get(k))}" for k in b.tests),
                flush=True,
            )
            if variant == "narx" and not args.no_peer and "peer" not in args.keep:
                t0 = time.perf_counter()
                got = peer(spec, ds, model)
                if isinstance(got, str):
                    b.rows["peer"] = {k: got for k in b.tests}
                else:
                    b.rows["peer"] = {k: _fmt(got.get(k)) for k in b.tests}
                print(f"  SysIdentPy ({time.perf_counter() - t0:.0f} s): {b.rows['peer']}", flush=True)
    text = table(BENCHMARKS, with_peer)
    body = (
        "Test RMSE of the free run, in each benchmark's units, with the protocol of nonlinear-benchmarks 1.0.1 "
        "(Bouc-Wen: its benchmark document, every sample scored from the input alone); configurations chosen on "
        "validation within the training data (`benchmarks/benchmark_selection.py`), never on a test set. "
        "Regenerate with `python benchmarks/leaderboard.py --readme` (times: wall time of that run).\n\n"
        + text
        + "\n\n"
        + "; ".join(notes)
        + "\n"
    )
    print("\n" + text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("# Benchmark leaderboard\n\n" + body)
    print(f"\nwritten to {args.out}")
    if args.readme:
        readme = ROOT / "README.md"
        src = readme.read_text()
        if BEGIN not in src or END not in src:
            raise SystemExit(f"README.md has no {BEGIN} ... {END} markers")
        head, rest = src.split(BEGIN, 1)
        _, tail = rest.split(END, 1)
        readme.write_text(head + BEGIN + "\n" + body + END + tail)
        print("README.md updated")


if __name__ == "__main__":
    main()
