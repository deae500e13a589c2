"""family: auto on small recordings it was not tuned for, next to every family's default.

    python benchmarks/auto_small_data.py                      # every case (about 20 min on 2 cores)
    python benchmarks/auto_small_data.py --only kdn-3bar tanks --json small.json
    python benchmarks/auto_small_data.py --separate-test      # the last fifth as a test file of its own
    python benchmarks/auto_small_data.py --samples 500        # each recording cut to its first 500 samples

What a new user does with one recording of 1500 to 5000 samples: a spec naming the file, the input
and output columns and nothing else (the default split: 60 % train, 20 % validation, 20 % test, in time
order), then ``dynmodel fit``. The cases are slices of the real recordings in ../shared/data that
neither the search nor the family defaults were tuned on: seals and bore shapes of the pneumatic seal
data other than the NAPN seal (force from position and pressure, resampled to 50 Hz), a 3000-sample
stretch of the Silverbox multisine, the first 4000 samples of the Bouc-Wen multisine validation
recording, the Cascaded Tanks estimation recording alone, and 6000 samples of EMPS.

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of each family's default
(narx, esn, the external esn, annealed-rnn, and the example ``arx`` family when it is installed), the
ratio of auto to the best default ON THE TEST (an oracle a user does not have), the model auto chose and
the wall time. A ratio near or below 1 means auto gets, without tuning, what the best family default
would have given had the user known which one to pick. Asserts nothing.

``--separate-test``: what a user with a second file does. The recording's last fifth is a test recording of
its own (``data.test: {segments: ...}``: its free run starts afresh, from its own first samples) and the
first four fifths are split 75 / 25 into training and validation.

``--samples N``: each recording cut to its first N samples (of its stretch), the smallest recordings the issue
names (500): 300 training, 100 validation and 100 test samples with the default split.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dynmodel.errors import DynmodelError

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
SEALS = DATA / "pneumatic_seal_friction" / "friction"


#: how a pneumatic seal file is read: force from piston position and chamber pressure (PROVENANCE.md there)
SEAL_COLUMNS: dict[str, Any] = {
    "header": False,
    "columns": ["t_ms", "laser_v", "pressure_v", "force_v", "position", "pressure", "force"],
    "time_column": "t_ms",
    "time_unit": 0.001,
    "input": ["position", "pressure"],
    "output": ["force"],
}


def _seal(name: str) -> dict[str, Any]:
    return {"path": str(SEALS / f"{name}.csv"), **SEAL_COLUMNS, "resample": 0.02}


CASES: dict[str, dict[str, Any]] = {
    "kdn-3bar": _seal("KDN_3bar"),
    "pk-5bar": _seal("PK_5bar"),
    "xring257-7bar": _seal("X-ring257_7bar"),
    "kidney-2bar": _seal("Kidney_2bar"),
    "nap310-1bar": _seal("NAP310_1bar"),
    "silverbox-3000": {
        "path": str(DATA / "silverbox" / "SNLS80mV.csv"),
        "input": ["V1"],
        "output": ["V2"],
        "segments": [[60000, 63000]],
    },
    "bouc-wen-4000": {
        "path": {
            "input": str(DATA / "bouc_wen" / "uval_multisine.mat"),
            "output": str(DATA / "bouc_wen" / "yval_multisine.mat"),
        },
        "input": ["uval_multisine"],
        "output": ["yval_multisine"],
        "segments": [[0, 4000]],
    },
    "tanks": {"path": str(DATA / "cascaded_tanks" / "dataBenchmark.csv"), "input": ["uEst"], "output": ["yEst"]},
    "emps-6000": {
        "path": str(DATA / "emps" / "DATA_EMPS.mat"),
        "input": ["vir"],
        "output": ["qm"],
        "segments": [[0, 6000]],
    },
}
DEFAULTS: dict[str, dict[str, Any]] = {
    "narx": {"family": "narx"},
    "esn": {"family": "esn"},
    "esn-ext": {"family": "esn", "params": {"mode": "external"}},
    "rnn": {"family": "annealed-rnn"},
    "arx": {"family": "arx"},
}


def fit_timed(raw: dict[str, Any], workers: int | None) -> tuple[Any, float]:
    """The model of spec ``raw`` (paths absolute or relative to the repository) and its wall time, warnings
    silenced, with ``workers`` parallel fits for a search."""
    from dynmodel import engine
    from dynmodel.data import load_dataset
    from dynmodel.search import search_options
    from dynmodel.spec import validate_spec

    spec = validate_spec(raw, raw["name"], ROOT)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = load_dataset(spec)
        with search_options(workers=workers):
            model, _ = engine.fit_dataset(spec, ds)
    return model, time.perf_counter() - t0


def separate_test(case: dict[str, Any]) -> dict[str, Any]:
    """``case`` with its last fifth as a separate test recording, the rest split 75 / 25 (train / validation)."""
    from dynmodel.data import load_dataset
    from dynmodel.spec import validate_spec

    whole = {**case, "split": {"train": 1.0}}
    spec = validate_spec({"name": "n", "data": whole, "model": {"family": "narx"}}, "n", ROOT)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        n = load_dataset(spec).n_scored("train")
    a, b = case["segments"][0] if case.get("segments") else (0, n)
    cut = a + int(0.8 * (b - a))
    return {
        **case,
        "segments": [[a, cut]],
        "split": {"train": 0.75, "validation": 0.25},
        "test": {"segments": [[cut, b]]},
    }


def first_samples(case: dict[str, Any], n: int) -> dict[str, Any]:
    """``case`` cut to the first ``n`` samples of its stretch (after any resampling)."""
    a = case["segments"][0][0] if case.get("segments") else 0
    return {**case, "segments": [[a, a + n]]}


def _installed() -> set[str]:
    from dynmodel.registry import families

    return set(families())


def _record_auto(row: dict[str, Any], model: Any, seconds: float) -> None:
    search = model.search or {}
    row.update(
        auto=(model.metrics.get("test") or {}).get("nmse"),
        auto_validation=(model.metrics.get("validation") or {}).get("nmse"),
        seconds=seconds,
        chosen=search.get("winner_summary") or model.family.name,
        family=model.family.name,
        notes=search.get("notes", []),
    )


def run_case(name: str, args) -> dict[str, Any]:
    case = first_samples(CASES[name], args.samples) if getattr(args, "samples", None) else CASES[name]
    data = separate_test(case) if args.separate_test else case
    base = {"name": name, "data": data, "seed": 0, "evaluation": {"metrics": ["nmse", "rmse"]}}
    model_section: dict[str, Any] = {"family": "auto"}
    if args.budget is not None:
        model_section["params"] = {"budget": args.budget}
    row: dict[str, Any] = {"case": name, "defaults": {}}
    try:
        model, seconds = fit_timed({**base, "model": model_section}, args.workers)
    except DynmodelError as err:  # a search that ends without a model is a figure too
        row.update(auto=f"error: {err.what}", seconds=0.0, chosen=f"no model: {err.what}", notes=[])
        model = None
    if model is not None:
        _record_auto(row, model, seconds)
    if not args.no_defaults:
        installed = _installed()
        for dname, section in DEFAULTS.items():
            if section["family"] not in installed:
                continue
            try:
                dm, _ = fit_timed({**base, "model": section}, 1)
                row["defaults"][dname] = (dm.metrics.get("test") or {}).get("nmse")
            except Exception as exc:  # noqa: BLE001 - a failing default is a figure too
                row["defaults"][dname] = f"error: {exc}"
    return row


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, str):
        return "error"
    return f"{v:.3g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", help=f"cases: {', '.join(CASES)}")
    ap.add_argument("--budget", type=float, help="search budget in seconds (default: auto's own, 300)")
    ap.add_argument("--workers", type=int, help="parallel fits of the search (default: one per core)")
    ap.add_argument("--no-defaults", action="store_true", help="run auto only")
    ap.add_argument(
        "--separate-test", action="store_true", help="the last fifth of each recording as a test file of its own"
    )
    ap.add_argument("--samples", type=int, help="cut each recording to its first N samples (e.g. 500)")
    ap.add_argument("--json", type=Path, help="write every figure as JSON")
    args = ap.parse_args()
    if not DATA.is_dir():
        raise SystemExit(f"no data folder at {DATA}")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    results = []
    for name in args.only or list(CASES):
        if name not in CASES:
            raise SystemExit(f"unknown case '{name}' (cases: {', '.join(CASES)})")
        print(f"... {name}", flush=True)
        results.append(run_case(name, args))
        r = results[-1]
        print(f"    auto {_fmt(r['auto'])} % in {r['seconds']:.0f} s: {r['chosen']}", flush=True)
        if args.json:
            args.json.write_text(json.dumps(results, indent=1, default=str))
    layout = (
        "the last fifth a separate test recording, the rest 75/25"
        if args.separate_test
        else "default split 60/20/20 of one recording"
    )
    if args.samples:
        layout += f", its first {args.samples} samples"
    print_table(results, list(DEFAULTS), f"test NMSE % ({layout})")


def fit_files(
    name: str,
    folder: Path,
    args,
    split: dict[str, float],
    defaults: list[str],
    data: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``family: auto`` (with the command line's budget and families) and each installed default of ``defaults``
    fitted on ``folder/<name>-train.csv`` (columns u, y; ``split``) and tested on ``folder/<name>-test.csv``, or
    on the spec's data section ``data`` when given: one row of figures for :func:`print_table`."""
    from dynmodel.registry import families

    data = data or {
        "path": str(folder / f"{name}-train.csv"),
        "input": ["u"],
        "output": ["y"],
        "split": split,
        "test": {"path": str(folder / f"{name}-test.csv")},
    }
    base = {"name": name, "data": data, "seed": 0}
    params: dict[str, Any] = {}
    if args.budget is not None:
        params["budget"] = args.budget
    if getattr(args, "families", None):
        params["families"] = args.families
    model, seconds = fit_timed({**base, "model": {"family": "auto", "params": params}}, args.workers)
    row: dict[str, Any] = {
        "case": name,
        "auto": model.metrics["test"]["nmse"],
        "auto_validation": model.metrics.get("validation", {}).get("nmse"),
        "seconds": seconds,
        "chosen": (model.search or {}).get("winner_summary") or model.family.name,
        "mode": (model.search or {}).get("mode"),
        "notes": (model.search or {}).get("notes", []),
        "defaults": {},
    }
    if getattr(args, "records", None) is not None:  # every candidate's figures, as `fit --json` writes them
        record = {"metrics": model.metrics, "search": model.search}
        file = name.replace("/", "_")  # a seal's case names its pressures: NAPN-1/3/7-5
        (args.records / f"{file}.json").write_text(json.dumps(record, indent=1, default=str))
    installed = set(families())
    for family in defaults:
        if family in installed and not args.no_defaults:
            try:
                fitted, _ = fit_timed({**base, "model": {"family": family}}, 1)
            except DynmodelError as err:  # e.g. a default that chooses on a validation split the spec has not
                row["defaults"][family] = f"error: {err.what}"
                continue
            row["defaults"][family] = fitted.metrics["test"]["nmse"]
    return row


def fit_series(
    name: str,
    folder: Path,
    args,
    train: dict[str, np.ndarray],
    test: dict[str, np.ndarray],
    defaults: list[str],
    split: dict[str, float] | None = None,
) -> dict[str, Any]:
    """:func:`fit_files` on ``train`` and ``test`` (column name -> values: u, y) written to ``folder`` as
    ``<name>-train.csv`` and ``<name>-test.csv``; ``split`` of the training file (default 80 / 20)."""
    for part, series in (("train", train), ("test", test)):
        np.savetxt(
            folder / f"{name}-{part}.csv",
            np.column_stack(list(series.values())),
            delimiter=",",
            header=",".join(series),
            comments="",
        )
    return fit_files(name, folder, args, split or {"train": 0.8, "validation": 0.2}, defaults)


def run_generated(
    doc: str,
    cases: list[str],
    run_one,
    defaults: list[str],
    title: str,
    families: bool = True,
    options: Callable[[argparse.ArgumentParser], Any] | None = None,
) -> None:
    """The command line of the generated-case scripts (auto_noisy.py, auto_periodic.py): every case of
    ``cases`` written to a temporary folder and run by ``run_one(name, folder, args)``, the figures kept as
    JSON after each case and printed as one table. ``options`` adds a script's own arguments."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", choices=list(cases), help="cases (default: all)")
    ap.add_argument("--budget", type=float, help="search budget in seconds (default: auto's own, 300)")
    ap.add_argument("--workers", type=int, help="parallel fits of the search (default: one per core)")
    if families:
        ap.add_argument("--families", nargs="*", help="families auto searches (default: every installed one)")
    ap.add_argument("--no-defaults", action="store_true", help="run auto only")
    ap.add_argument("--json", type=Path, help="write every figure as JSON")
    ap.add_argument(
        "--records", type=Path, help="folder for each case's search record (<case>.json, a / in its name as _) of auto"
    )
    if options is not None:
        options(ap)
    args = ap.parse_args()
    if args.records is not None:
        args.records.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or list(cases):
            print(f"... {name}", flush=True)
            results.append(run_one(name, Path(tmp), args))
            if args.json:
                args.json.write_text(json.dumps(results, indent=1, default=str))
    print_table(results, list(defaults), title)


def print_table(results: list[dict[str, Any]], defaults: list[str], title: str) -> None:
    """Auto's test NMSE next to each default's, the ratio to the best default on the test (an oracle a
    user does not have), the wall time and the model chosen, one row per case."""
    names = [d for d in defaults if any(d in r["defaults"] for r in results)]
    width = max([16] + [len(r["case"]) for r in results])
    print(f"\n{title}; x best = auto / best default on the test")
    head = f"{'case':<{width}} {'auto':>7} " + " ".join(f"{d:>8}" for d in names) + f" {'x best':>7} {'s':>5}  chosen"
    print(head)
    print("-" * len(head))
    for r in results:
        nums = [v for v in r["defaults"].values() if isinstance(v, (int, float))]
        ratio = r["auto"] / min(nums) if nums and r["auto"] is not None and min(nums) > 0 else None
        print(
            f"{r['case']:<{width}} {_fmt(r['auto']):>7} "
            + " ".join(f"{_fmt(r['defaults'].get(d)):>8}" for d in names)
            + f" {_fmt(ratio):>7} {r['seconds']:>5.0f}  {r['chosen'][:70]}"
        )


if __name__ == "__main__":
    main()
