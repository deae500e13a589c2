"""family: auto on systems whose output rightly leaves its training range (the linear-system band, docs/auto.md).

    python benchmarks/auto_beyond_range.py                 # five cases, about 1 min on 2 cores
    python benchmarks/auto_beyond_range.py --only cart --budget 40

Each case is one generated recording, a spec naming the file and its columns and nothing else (the default split:
60 % train, 20 % validation, 20 % test, in time order), `family: auto` with a 40 s budget in one process. The
cases are linear (or about linear) systems whose test output goes beyond the training output range: a plant driven
at three times its training amplitude, a thermal process heated to twice its training power, a cart whose
position drifts from a force inside its own range, a heat exchanger whose inlet runs 8 K hotter, and a lightly
damped 1 Hz resonance sampled at 1 kHz. Printed per case: the test NMSE (%) of auto, of a linear ARX reference
(least squares, output lags 1..10, input lags 0..10 and a constant, on the training split, free run from the first
10 measured outputs) and of the training mean, the model auto chose and the wall time. Asserts nothing.

Before the linear-system band the search rejected every model that follows such an output and kept a saturating
network or an output-error model: 2.07, 229, 587, 834 and 87.5 % test NMSE.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.search import search_options
from dynmodel.spec import validate_spec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from beyond_range import CASES  # noqa: E402 - the generated systems, shared with the tests


def _nmse(y: np.ndarray, yhat: np.ndarray) -> float:
    return float(np.mean(100.0 * np.mean((y - yhat) ** 2, axis=0) / np.var(y, axis=0)))


def references(u: np.ndarray, y: np.ndarray, lags: int = 10) -> tuple[float, float]:
    """(linear ARX free-run, training mean) test NMSE on the default split."""
    n = len(y)
    a, b = int(round(0.6 * n)), int(round(0.8 * n))
    um, us = u[:a].mean(0), np.where(u[:a].std(0) > 0, u[:a].std(0), 1.0)
    ym, ys = y[:a].mean(0), y[:a].std(0)
    us_, ys_ = (u - um) / us, (y - ym) / ys

    def row(yy: np.ndarray, k: int) -> np.ndarray:
        return np.concatenate([[1.0], yy[k - lags : k][::-1].ravel(), us_[k - lags : k + 1][::-1].ravel()])

    rows = np.arange(lags, a)
    theta, *_ = np.linalg.lstsq(np.array([row(ys_, k) for k in rows]), ys_[rows], rcond=None)
    sim = np.zeros_like(ys_)
    sim[:lags] = ys_[:lags]
    for k in range(lags, n):
        sim[k] = row(sim, k) @ theta
    return _nmse(y[b:], sim[b:] * ys + ym), _nmse(y[b:], np.broadcast_to(y[:a].mean(0), y[b:].shape))


def run(name: str, budget: float, folder: Path) -> dict[str, object]:
    columns, inputs = CASES[name]()
    outputs = [c for c in columns if c not in inputs]
    header = ",".join(columns)
    np.savetxt(
        folder / f"{name}.csv", np.column_stack(list(columns.values())), delimiter=",", header=header, comments=""
    )
    raw = {
        "name": name,
        "data": {"path": f"{name}.csv", "input": inputs, "output": outputs},
        "model": {"family": "auto", "params": {"budget": budget}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<benchmark>", folder)
    t0 = time.perf_counter()
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec))
    wall = time.perf_counter() - t0
    u = np.column_stack([columns[c] for c in inputs])
    y = np.column_stack([columns[c] for c in outputs])
    arx, mean = references(u, y)
    linear = any("about linear" in note for note in model.search["notes"])
    return {
        "auto": model.metrics["test"]["nmse"],
        "arx": arx,
        "mean": mean,
        "chosen": model.search["winner_summary"],
        "seconds": wall,
        "linear": linear,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", choices=list(CASES), help="cases to run (default: all)")
    parser.add_argument("--budget", type=float, default=40.0, help="search budget in seconds (default 40)")
    args = parser.parse_args()
    print(f"{'case':16} {'auto':>10} {'ARX':>10} {'mean':>8} {'s':>5}  about linear  chosen")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or list(CASES):
            r = run(name, args.budget, Path(tmp))
            print(
                f"{name:16} {r['auto']:10.4g} {r['arx']:10.4g} {r['mean']:8.4g} {r['seconds']:5.0f}  "
                f"{'yes' if r['linear'] else 'no':12}  {r['chosen']}"
            )


if __name__ == "__main__":
    main()
