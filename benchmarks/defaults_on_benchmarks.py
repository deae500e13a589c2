"""What a user who never tunes gets: every family with its defaults on the real benchmarks.

    python benchmarks/defaults_on_benchmarks.py                       # every case, table on stdout
    python benchmarks/defaults_on_benchmarks.py --only silverbox tanks --models narx esn
    python benchmarks/defaults_on_benchmarks.py --json after.json     # also write every figure

Datasets (local files in ../shared/data, see each PROVENANCE.md; never downloaded):

* Silverbox, Cascaded Tanks, EMPS, Bouc-Wen with the protocol of nonlinear-benchmarks 1.0.1: the
  standard training file; the last 20 % of it is the validation split (carved from the training
  data, never from a test); free run of every test file from its first sample, where only the
  first ``window`` measured outputs may be used (Silverbox 50, Tanks 50, EMPS 20, Bouc-Wen none:
  the model starts from the output at rest, 0); test RMSE in the benchmark's units over
  ``y[window:]``. A model that needs more measured outputs than the window (a NARX lag or an
  external network's tune-in longer than the window) is scored anyway but marked ``*``.
* GMS friction (``dynmodel generate gms``, random trajectory): 4000, 12000 and 24000 samples, 80 /
  20 train / validation, each tested on a fresh realization (seed 2) of the same length; and 60 /
  20 / 20 train / validation / test of one 12000-sample recording (the README's first try); test
  NMSE %.
* Pneumatic seal friction (NAPN seal, force from position and pressure): trained on 1, 3, 7 bar
  (75 / 25 % per recording), tested on 5 bar (inside the training pressures) and, trained on 1, 3,
  5 bar, tested on 7 bar (outside); test NMSE %. ``seal-PK``, ``seal-KDN``, ``seal-X-ring257``,
  ``seal-NAP310``, ``seal-O-ring257``: the same for the other seals (kept aside: checked, not tuned on).

Models: ``narx`` and ``esn`` with no parameter and no cost given (the spec's and families'
defaults), and ``esn-external`` (``mode: external`` only). Every choice is made on the training
and validation data; the test outputs are read only to score. Prints figures; asserts nothing.
Run it with ``nice -n 10`` and OPENBLAS_NUM_THREADS=1 on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from auto_seals import seal_data

from dynmodel import engine
from dynmodel.spec import validate_spec

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"

MODELS: dict[str, dict] = {
    "narx": {"family": "narx"},
    "esn": {"family": "esn"},
    "esn-external": {"family": "esn", "params": {"mode": "external"}},
}


@dataclass
class Benchmark:
    """A standard train file and its tests, in the benchmark's protocol."""

    name: str
    unit: str  # unit of the printed RMSE
    factor: float  # file unit -> printed unit
    train: tuple[np.ndarray, np.ndarray]
    tests: dict[str, tuple[np.ndarray, np.ndarray]]
    window: int
    sampling_time: float
    published: dict[str, float] = field(default_factory=dict)
    tuned: dict[str, float] = field(default_factory=dict)


def _mat(path: Path):
    import scipy.io

    return scipy.io.loadmat(path)


def silverbox() -> Benchmark:
    d = _mat(DATA / "silverbox" / "SNLS80mV.mat")
    u, y = d["V1"].ravel(), d["V2"].ravel()
    block_u, block_y = u[40650:127400], y[40650:127400]
    n_train = int(0.75 * len(block_u))
    arrow_u, arrow_y = u[100:40575], y[100:40575]
    return Benchmark(
        "silverbox",
        "mV",
        1e3,
        (block_u[:n_train], block_y[:n_train]),
        {
            "multisine": (block_u[n_train:], block_y[n_train:]),
            "arrow": (arrow_u, arrow_y),
            "arrow-noextrap": (arrow_u[:32000], arrow_y[:32000]),
        },
        50,
        1 / 610.35,
        {"multisine": 0.301, "arrow": 0.26, "arrow-noextrap": 0.259},
        {"multisine": 0.211, "arrow": 0.311, "arrow-noextrap": 0.219},
    )


def tanks() -> Benchmark:
    a = np.genfromtxt(DATA / "cascaded_tanks" / "dataBenchmark.csv", delimiter=",", skip_header=1)
    return Benchmark(
        "tanks", "V", 1.0, (a[:, 0], a[:, 2]), {"test": (a[:, 1], a[:, 3])}, 50, 4.0, {"test": 0.306}, {"test": 0.442}
    )


def emps() -> Benchmark:
    tr, te = _mat(DATA / "emps" / "DATA_EMPS.mat"), _mat(DATA / "emps" / "DATA_EMPS_PULSES.mat")
    return Benchmark(
        "emps",
        "mm",
        1e3,
        (tr["vir"].ravel(), tr["qm"].ravel()),
        {"pulses": (te["vir"].ravel(), te["qm"].ravel())},
        20,
        1e-3,
        {"pulses": 2.64},
        {"pulses": 2.87},
    )


def bouc_wen() -> Benchmark:
    import h5py

    base = DATA / "bouc_wen"
    with h5py.File(base / "forgione_generated_train.h5", "r") as f:
        u, y = f["multisine/u"][:].ravel(), f["multisine/y"][:].ravel()
    tests = {}
    for kind in ("multisine", "sinesweep"):
        tu = _mat(base / f"uval_{kind}.mat")
        ty = _mat(base / f"yval_{kind}.mat")
        tests[kind] = (
            np.asarray([v for k, v in tu.items() if not k.startswith("__")][0], dtype=float).ravel(),
            np.asarray([v for k, v in ty.items() if not k.startswith("__")][0], dtype=float).ravel(),
        )
    return Benchmark(
        "bouc-wen",
        "1e-5 m",
        1e5,
        (u, y),
        tests,
        0,
        1 / 750,
        {"multisine": 1.87},
        {"multisine": 3.00, "sinesweep": 1.59},
    )


BENCHMARKS = {"silverbox": silverbox, "tanks": tanks, "emps": emps, "bouc-wen": bouc_wen}


def _model(name: str) -> dict:
    """The spec's ``model`` (and ``cost``, when a case gives one) of a case."""
    entry = dict(MODELS[name])
    cost = entry.pop("cost", None)
    return {"model": entry, **({"cost": cost} if cost else {})}


def _quiet_fit(raw: dict, base: Path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        model = engine.fit(validate_spec(raw, "<bench>", base))
        elapsed = time.perf_counter() - t0
    return model, elapsed, [str(w.message)[:80] for w in caught]


def _input_free(model) -> bool | None:
    """True when a NARX model kept no input term (None for other families)."""
    fam = model.family
    if getattr(fam, "exponents_", None) is None:
        return None
    src, _, _ = fam.embedding_.arrays()
    return not bool((fam.exponents_[:, src == 0] > 0).any())


def run_benchmark(b: Benchmark, model_name: str, tmp: Path) -> dict:
    u, y = b.train
    np.savez(tmp / f"{b.name}-train.npz", u=u, y=y)
    raw = {
        "name": f"{b.name}-{model_name}",
        "data": {
            "path": f"{b.name}-train.npz",
            "input": ["u"],
            "output": ["y"],
            "sampling_time": b.sampling_time,
            "split": {"train": 0.8, "validation": 0.2},
        },
        **_model(model_name),
        "evaluation": {"metrics": ["nmse"]},
    }
    model, elapsed, notes = _quiet_fit(raw, tmp)
    out: dict = {
        "fit_s": round(elapsed, 2),
        "validation_nmse": model.metrics.get("validation", {}).get("nmse"),
        "warmup": model.warmup,
        "input_free": _input_free(model),
        "notes": notes,
        "tests": {},
    }
    for name, (tu, ty) in b.tests.items():
        warm = model.warmup
        tune = (ty[:warm] if b.window else np.zeros(warm)) if warm else None
        run = model.run(tu, tune)
        yhat = run.y[:, 0]
        score = slice(max(b.window, 0), None)
        err = ty[score] - yhat[score]
        rmse = float(np.sqrt(np.mean(err**2))) * b.factor if np.isfinite(err).all() else None
        out["tests"][name] = {
            "rmse": rmse,
            "diverged_at": run.diverged_at,
            "needs_more_than_window": bool(warm > b.window),
            "max_abs_prediction": float(np.nanmax(np.abs(yhat))) * b.factor,
        }
    return out


def run_generated(kind: str, model_name: str, tmp: Path) -> dict:
    if kind == "gms":
        fresh = {
            "generator": "gms",
            "seed": 1,
            "input": ["position"],
            "output": ["force"],
            "split": {"train": 0.8, "validation": 0.2},
            "test": {"seed": 2},
            "transient": 50,
            "transient_at": "recording",
        }
        tests = {f"n{n}": {**fresh, "n": n} for n in (4000, 12000, 24000)}
        split = {**fresh, "n": 12000, "split": {"train": 0.6, "validation": 0.2, "test": 0.2}}
        split["transient_at"] = "segment"
        del split["test"]
        tests["split12k"] = split
    else:
        name = kind.partition("-")[2] or "NAPN"
        tests = {"5bar": seal_data(name, (1, 3, 7), 5), "7bar": seal_data(name, (1, 3, 5), 7)}
    out: dict = {"tests": {}}
    for test, data in tests.items():
        raw = {
            "name": f"{kind}-{model_name}",
            "data": data,
            **_model(model_name),
            "evaluation": {"metrics": ["nmse", "rmse"]},
        }
        model, elapsed, notes = _quiet_fit(raw, tmp)
        m = model.metrics
        out["tests"][test] = {
            "nmse": m["test"].get("nmse"),
            "validation_nmse": m.get("validation", {}).get("nmse"),
            "diverged_at": (m["test"].get("unstable_from") or {}).get("sample"),
            "fit_s": round(elapsed, 2),
            "input_free": _input_free(model),
            "notes": notes,
        }
    return out


def _fmt(v, digits=4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--only",
        nargs="*",
        default=None,
        help="datasets: silverbox tanks emps bouc-wen gms seal (NAPN), seal-PK, seal-KDN, ... (other seals)",
    )
    ap.add_argument("--models", nargs="*", default=list(MODELS), choices=list(MODELS))
    ap.add_argument("--json", type=Path, default=None, help="write every figure to this file")
    args = ap.parse_args()
    names = args.only or [*BENCHMARKS, "gms", "seal"]
    results: dict = {}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for name in names:
            results[name] = {}
            b = BENCHMARKS[name]() if name in BENCHMARKS else None
            for model_name in args.models:
                try:
                    r = run_benchmark(b, model_name, tmp) if b else run_generated(name, model_name, tmp)
                except Exception as exc:  # a failing default is a result too
                    r = {"error": f"{type(exc).__name__}: {str(exc)[:160]}"}
                results[name][model_name] = r
                _print(name, model_name, r, b)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


def _print(name: str, model_name: str, r: dict, b: Benchmark | None) -> None:
    if "error" in r:
        print(f"{name:10s} {model_name:13s} ERROR {r['error']}", flush=True)
        return
    if b is not None:
        cells = []
        for test, t in r["tests"].items():
            star = "*" if t["needs_more_than_window"] else ""
            val = f"div@{t['diverged_at']}" if t["rmse"] is None else f"{t['rmse']:.4g}{star}"
            ref = b.tuned.get(test)
            cells.append(f"{test} {val}" + (f" (tuned {ref}, best {b.published.get(test, '-')})" if ref else ""))
        flag = " INPUT-FREE" if r["input_free"] else ""
        print(
            f"{name:10s} {model_name:13s} test RMSE [{b.unit}]: {'; '.join(cells)} | val NMSE "
            f"{_fmt(r['validation_nmse'])} % | warmup {r['warmup']} | fit {r['fit_s']} s{flag}",
            flush=True,
        )
    else:
        cells = []
        for test, t in r["tests"].items():
            val = f"div@{t['diverged_at']}" if t["nmse"] is None else f"{t['nmse']:.4g} %"
            flag = " INPUT-FREE" if t["input_free"] else ""
            cells.append(f"{test} {val} (val {_fmt(t['validation_nmse'])} %, {t['fit_s']} s){flag}")
        print(f"{name:10s} {model_name:13s} test NMSE: {'; '.join(cells)}", flush=True)


if __name__ == "__main__":
    main()
