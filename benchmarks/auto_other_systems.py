"""family: auto on kinds of data the other benchmarks lack: feedback, several inputs, a dead zone, a drifting
sensor, input glitches, stick-slip friction and (``--long``) one million samples.

    python benchmarks/auto_other_systems.py                  # six cases, about 1 min on 2 cores
    python benchmarks/auto_other_systems.py --only deadzone --budget 40
    python benchmarks/auto_other_systems.py --long           # adds 1 000 000 samples, default budget (about 2 min)

Each case is one generated recording and a spec naming the file and its columns and nothing else (the default
split: 60 % train, 20 % validation, 20 % test, in time order), ``family: auto`` with a 40 s budget (the long case:
auto's default) and the built-in families (``--families`` to change). Printed per case: the test NMSE (%) of
auto, of a linear ARX reference and of the training mean (as in ``auto_beyond_range.py``; no ARX for the long
case), the model auto chose and the wall time. Asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.signal import butter, lfilter

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.search import search_options
from dynmodel.spec import validate_spec

sys.path.insert(0, str(Path(__file__).resolve().parent))
from auto_beyond_range import references  # noqa: E402 - the same ARX and mean references

Columns = dict[str, np.ndarray]
BUILT_IN = ["narx", "esn", "annealed-rnn"]


def closed_loop() -> tuple[Columns, list[str]]:
    """A lightly damped second-order plant under PI control tracking random steps: the recorded input is the
    controller's output, which depends on the measured (noisy) output."""
    rng = np.random.default_rng(37)
    n = 6000
    r = np.repeat(rng.uniform(-1, 1, n // 100 + 1), 100)[:n]
    y, u, measured = np.zeros(n), np.zeros(n), np.zeros(n)
    integral = 0.0
    for k in range(2, n):
        y[k] = 1.6 * y[k - 1] - 0.7 * y[k - 2] + 0.05 * u[k - 1]
        measured[k] = y[k] + 0.01 * rng.standard_normal()
        error = r[k] - measured[k]
        integral += 0.05 * error
        u[k] = 1.5 * error + integral
    return {"u": u, "y": measured}, ["u"]


def four_inputs() -> tuple[Columns, list[str]]:
    """Two inputs act through dynamics, one through a static square, one not at all."""
    rng = np.random.default_rng(38)
    n = 6000
    U = rng.standard_normal((n, 4))
    U[:, 1] = lfilter([1], [1, -0.9], U[:, 1]) * 0.3
    y = (
        lfilter([0.2, 0.1], [1, -1.1, 0.3], U[:, 0])
        + lfilter([0.5], [1, -0.8], U[:, 1])
        + 0.3 * U[:, 2] ** 2
        + 0.01 * rng.standard_normal(n)
    )
    return {**{f"u{i}": U[:, i] for i in range(4)}, "y": y}, [f"u{i}" for i in range(4)]


def deadzone() -> tuple[Columns, list[str]]:
    """An actuator dead zone (|u| < 0.4 does nothing) before a second-order plant; held input levels."""
    rng = np.random.default_rng(39)
    n = 5000
    u = np.repeat(rng.uniform(-1.5, 1.5, n // 20 + 1), 20)[:n] + 0.1 * rng.standard_normal(n)
    acting = np.sign(u) * np.maximum(np.abs(u) - 0.4, 0)
    y = lfilter([0.05, 0.04], [1, -1.5, 0.6], acting) + 0.003 * rng.standard_normal(n)
    return {"u": u, "y": y}, ["u"]


def sensor_drift() -> tuple[Columns, list[str]]:
    """A linear plant whose output sensor drifts (a ramp and a slow wander) that no input explains."""
    rng = np.random.default_rng(40)
    n = 6000
    u = rng.standard_normal(n)
    drift = np.linspace(0, 0.8, n) + np.cumsum(rng.standard_normal(n)) * 0.003
    y = lfilter([0.3, 0.2], [1, -1.2, 0.45], u) + drift + 0.01 * rng.standard_normal(n)
    return {"u": u, "y": y}, ["u"]


def input_glitches() -> tuple[Columns, list[str]]:
    """A Hammerstein plant (cubic input) whose recorded input carries 12 spikes of 8 that the plant never saw."""
    rng = np.random.default_rng(41)
    n = 6000
    u = lfilter([1], [1, -0.5], rng.standard_normal(n)) * 0.6
    y = lfilter([0.3, 0.1], [1, -1.0, 0.3], u + 0.3 * u**3) + 0.005 * rng.standard_normal(n)
    recorded = u.copy()
    recorded[rng.choice(n, 12, replace=False)] += rng.choice([-1, 1], 12) * 8.0
    return {"u": recorded, "y": y}, ["u"]


def stick_slip() -> tuple[Columns, list[str]]:
    """Friction force from a belt velocity through a bristle state (LuGre-like: Stribeck, viscous), 1 kHz."""
    rng = np.random.default_rng(42)
    n, dt = 8000, 1e-3
    t = np.arange(n) * dt
    v = (
        0.02 * np.sin(2 * np.pi * 0.7 * t)
        + 0.01 * np.sin(2 * np.pi * 1.9 * t + 1)
        + 0.004 * rng.standard_normal(n).cumsum() / 40
    )
    sigma0, sigma1, sigma2, fc, fs, vs = 1e4, 100.0, 5.0, 1.0, 1.5, 0.005
    z, force = 0.0, np.zeros(n)
    for k in range(n):
        g = (fc + (fs - fc) * np.exp(-((v[k] / vs) ** 2))) / sigma0
        for _ in range(10):
            dz = v[k] - abs(v[k]) / g * z
            z += dz * dt / 10
        force[k] = sigma0 * z + sigma1 * dz + sigma2 * v[k]
    return {"v": v, "F": force + 0.01 * rng.standard_normal(n)}, ["v"]


def one_million() -> tuple[Columns, list[str]]:
    """A Wiener system (a resonant filter, then tanh) logged at 10 kHz for 100 s: 1 000 000 samples."""
    rng = np.random.default_rng(43)
    n = 1_000_000
    b, a = butter(3, 0.02)
    u = lfilter(b, a, rng.standard_normal(n)) * 8
    y = np.tanh(2 * lfilter([0.02, 0.015], [1, -1.8, 0.83], u)) + 0.002 * rng.standard_normal(n)
    return {"u": u, "y": y}, ["u"]


CASES: dict[str, Callable[[], tuple[Columns, list[str]]]] = {
    "closed-loop": closed_loop,
    "four-inputs": four_inputs,
    "deadzone": deadzone,
    "sensor-drift": sensor_drift,
    "input-glitches": input_glitches,
    "stick-slip": stick_slip,
}
LONG = {"one-million": one_million}


def run(name: str, budget: float | None, families: list[str] | None, folder: Path) -> dict[str, object]:
    columns, inputs = {**CASES, **LONG}[name]()
    outputs = [c for c in columns if c not in inputs]
    table = np.column_stack(list(columns.values()))
    np.savetxt(folder / f"{name}.csv", table, delimiter=",", header=",".join(columns), comments="")
    params: dict[str, object] = {} if budget is None else {"budget": budget}
    if families:
        params["families"] = families
    raw = {
        "name": name,
        "data": {"path": f"{name}.csv", "input": inputs, "output": outputs},
        "model": {"family": "auto", "params": params},
        "seed": 0,
    }
    spec = validate_spec(raw, "<benchmark>", folder)
    t0 = time.perf_counter()
    with search_options(workers=None if name in LONG else 1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec))
    wall = time.perf_counter() - t0
    u = np.column_stack([columns[c] for c in inputs])
    y = np.column_stack([columns[c] for c in outputs])
    arx, mean = references(u, y) if name not in LONG else (float("nan"), float("nan"))
    return {
        "auto": model.metrics["test"]["nmse"],
        "arx": arx,
        "mean": mean,
        "seconds": wall,
        "chosen": model.search["winner_summary"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", choices=[*CASES, *LONG], help="cases to run (default: the six)")
    parser.add_argument("--long", action="store_true", help="add the case of one million samples")
    parser.add_argument("--budget", type=float, help="search budget in seconds (default 40; the long case: 300)")
    parser.add_argument("--families", nargs="*", default=BUILT_IN, help="families searched (default: built-in)")
    args = parser.parse_args()
    names = args.only or [*CASES, *(LONG if args.long else [])]
    print(f"{'case':16} {'auto':>10} {'ARX':>10} {'mean':>8} {'s':>5}  chosen")
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            budget = args.budget if args.budget is not None else (None if name in LONG else 40.0)
            r = run(name, budget, args.families, Path(tmp))
            arx, mean = (f"{v:.4g}" if np.isfinite(v) else "-" for v in (r["arx"], r["mean"]))
            print(f"{name:16} {r['auto']:10.4g} {arx:>10} {mean:>8} {r['seconds']:5.0f}  {r['chosen']}", flush=True)


if __name__ == "__main__":
    main()
