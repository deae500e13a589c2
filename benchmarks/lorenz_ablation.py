"""Ablation of thesis 4.4.2 (networks of 32 driven Lorenz systems, Rossler cross-prediction): every
factor examined, one at a time on the shipped specs and combined, test NMSE mean +- std over seeds.

    python benchmarks/lorenz_ablation.py                      # every row, 5 seeds (hours on 2 cores)
    python benchmarks/lorenz_ablation.py --rows baseline input-scale-2 --seeds 5
    python benchmarks/lorenz_ablation.py --list               # the rows and what they change
    python benchmarks/lorenz_ablation.py --table results.json # print the Markdown table of saved results

Each row runs specs/thesis-4.4.2-parallel.yaml and specs/thesis-4.4.2-feed-forward.yaml with the
row's changes and the family seeds 0 .. seeds-1 (the data stay those of the specs: generator seed 1,
test seed 2, unless the row changes them), and reports the free-running test NMSE (%) on the fresh
10000-sample realization (first 1000 samples not scored), as `dynmodel fit` does. Readout rows refit
only the linear readout of the baseline's annealed networks; the `esn` / `annealed-rnn` rows fit
other families on the same data. Results are appended to --out (JSON) as rows finish. Prints
figures; asserts nothing. Run with OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 on a shared machine.
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from dynmodel import engine, regression
from dynmodel.spec import parse_yaml, validate_spec

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"
STRATEGIES = ("parallel", "feed-forward")


@dataclass
class Row:
    key: str
    factor: str
    change: str
    params: dict[str, Any] = field(default_factory=dict)  # model.params overrides
    data: dict[str, Any] = field(default_factory=dict)  # data overrides (generator params under "params")
    model: dict[str, Any] | None = None  # replaces the whole model section (other families)
    # ridge | fos | lstsq (with ``lags``): refit the baseline readout; euler: random Euler networks
    readout: str | None = None
    lags: tuple[int, ...] = (0,)  # readout refits: the states at these delays (samples)
    fresh_data: bool = False  # generator seeds 100 + seed (train) / 200 + seed (test)
    strategies: tuple[str, ...] = STRATEGIES


ESN_LEAKY = {"size": 400, "relaxation": [0.0, 0.95]}

ROWS = [
    Row("baseline", "none", "the shipped specs (thesis settings: M = 32, 400 annealing steps, RK4 4 x 0.025)"),
    # integration
    Row(
        "substeps-1",
        "integration",
        "one RK4 step of t_i = 0.1 per sample (the thesis's sentence on t_i)",
        {"substeps": 1},
    ),
    Row("substeps-20", "integration", "20 RK4 steps per sample (converged)", {"substeps": 20}),
    Row(
        "euler-0.1-random",
        "integration",
        "explicit Euler with t_i = 0.1, random (not annealed) networks; compare `steps-0`",
        readout="euler",
    ),
    Row(
        "rossler-step-0.1",
        "integration",
        "the Rossler data integrated with RK4 steps of 0.1 as well (thesis: all simulations with t_i = 0.1)",
        data={"params": {"integration_step": 0.1}},
    ),
    # element time constants (memory)
    Row(
        "time-scale-0.05", "time constants", "elements at half speed: 0.05 time units per sample", {"time_scale": 0.05}
    ),
    Row("time-scale-0.2", "time constants", "elements at double speed: 0.2 time units per sample", {"time_scale": 0.2}),
    Row(
        "alpha-0.1-1.2",
        "time constants",
        "alpha ~ U[0.1, 1.2] (elements up to 10x slower)",
        {"alpha_range": (0.1, 1.2)},
    ),
    Row("b-0-1", "time constants", "b ~ U[0, 1] (x3 decays over 1 - 100 time units)", {"b_range": (0.0, 1.0)}),
    # input coupling
    Row("scaling-standard", "input", "standardised input (zero mean, unit variance)", data={"scaling": "standard"}),
    Row("input-scale-1.5", "input", "drive 1.5 u (input_scale: 1.5)", {"input_scale": 1.5}),
    Row("input-scale-2", "input", "drive 2 u (input_scale: 2)", {"input_scale": 2.0}),
    Row("input-scale-3", "input", "drive 3 u (input_scale: 3)", {"input_scale": 3.0}),
    # annealing
    Row("steps-0", "annealing", "no annealing (the random initial networks)", {"steps": 0}),
    Row(
        "t0-0.01",
        "annealing",
        "10x colder: T0 = 0.01, T_end = 1e-5 (acceptance of worse moves)",
        {"t0": 0.01, "t_end": 1e-5},
    ),
    Row("step-0.2", "annealing", "smaller moves: step 0.2", {"step": 0.2}),
    Row("step-1", "annealing", "larger moves: step 1", {"step": 1.0}),
    Row("steps-2000", "annealing", "5x the budget: 2000 steps", {"steps": 2000}),
    Row("restarts-4", "annealing", "best of 4 annealing runs on validation", {"restarts": 4, "workers": 1}),
    # readout (refit on the baseline's annealed networks)
    Row("readout-ridge", "readout", "ridge readout, penalty chosen on validation", readout="ridge"),
    Row("readout-fos", "readout", "FOS readout (A.2.2), terms chosen on validation", readout="fos"),
    Row(
        "readout-delayed",
        "readout",
        "states at t, t-1, t-2, t-3 time units (4 x 97 features), least squares on the annealed networks",
        readout="lstsq",
        lags=(0, 10, 20, 30),
    ),
    Row(
        "readout-delayed-5-to-50",
        "readout",
        "states at t and every 0.5 time units up to t-5 (11 x 97 features), least squares",
        readout="lstsq",
        lags=tuple(range(0, 51, 5)),
    ),
    Row(
        "readout-delayed-10-to-100",
        "readout",
        "states at t and every time unit up to t-10 (11 x 97 features), least squares",
        readout="lstsq",
        lags=tuple(range(0, 101, 10)),
    ),
    Row(
        "readout-delayed-5-to-75",
        "readout",
        "states at t and every 0.5 time units up to t-7.5 (16 x 97 features), least squares",
        readout="lstsq",
        lags=tuple(range(0, 76, 5)),
    ),
    Row(
        "readout-delayed-3-to-60",
        "readout",
        "states at t and every 0.3 time units up to t-6 (21 x 97 features), least squares",
        readout="lstsq",
        lags=tuple(range(0, 61, 3)),
    ),
    Row(
        "readout-delayed-5-to-50-ridge",
        "readout",
        "states at t and every 0.5 time units up to t-5, ridge with the penalty chosen on validation",
        readout="ridge",
        lags=tuple(range(0, 51, 5)),
    ),
    Row(
        "delays-10-20-30",
        "readout",
        "readout_delays [10, 20, 30]: the delayed states in the family, annealed on that readout",
        {"readout_delays": [10, 20, 30]},
    ),
    Row(
        "delays-5-to-50",
        "readout",
        "readout_delays [5, 10, ..., 50] (11 x 97 features)",
        {"readout_delays": list(range(5, 51, 5))},
    ),
    Row(
        "delays-5-to-50-final",
        "readout",
        "readout_delays [5, 10, ..., 50], annealed on the current states (anneal_delays: false)",
        {"readout_delays": list(range(5, 51, 5)), "anneal_delays": False},
    ),
    # capacity and task (evidence, not the thesis protocol)
    Row("size-64", "capacity", "64 elements (feed-forward: 60 extra links)", {"size": 64, "extra_links": 60}),
    Row("size-128", "capacity", "128 elements (feed-forward: 120 extra links)", {"size": 128, "extra_links": 120}),
    Row("horizon-7", "task", "output z2(t + 7) instead of z2(t + 10)", data={"params": {"horizon": 7.0}}),
    Row(
        "fresh-data", "task", "a fresh Rossler realization per run (generator seeds 100 + k / 200 + k)", fresh_data=True
    ),
    # combined
    Row(
        "input-1.5-time-0.2",
        "combined",
        "input_scale 1.5 and 0.2 time units per sample",
        {"input_scale": 1.5, "time_scale": 0.2},
    ),
    Row(
        "input-1.5-steps-2000",
        "combined",
        "input_scale 1.5 and 2000 annealing steps",
        {"input_scale": 1.5, "steps": 2000},
    ),
    Row(
        "input-1.5-time-0.2-steps-2000",
        "combined",
        "input_scale 1.5, 0.2 time units per sample, 2000 annealing steps",
        {"input_scale": 1.5, "time_scale": 0.2, "steps": 2000},
    ),
    Row(
        "input-1.5-delays-10-20-30",
        "combined",
        "input_scale 1.5 and readout_delays [10, 20, 30]",
        {"input_scale": 1.5, "readout_delays": [10, 20, 30]},
    ),
    Row(
        "input-1.5-delays-5-to-50",
        "combined",
        "input_scale 1.5 and readout_delays [5, 10, ..., 50]",
        {"input_scale": 1.5, "readout_delays": list(range(5, 51, 5))},
    ),
    # other families on the same data
    Row(
        "esn-leaky-400",
        "other family",
        "esn, 400 leaky elements (relaxation U[0, 0.95])",
        model={"family": "esn", "params": ESN_LEAKY},
        strategies=("parallel",),
    ),
    Row(
        "esn-leaky-32",
        "other family",
        "esn, 32 leaky elements (relaxation U[0, 0.95])",
        model={"family": "esn", "params": {**ESN_LEAKY, "size": 32}},
        strategies=("parallel",),
    ),
    Row(
        "annealed-rnn-32",
        "other family",
        "annealed-rnn, 32 leaky tanh elements, 400 steps",
        model={"family": "annealed-rnn", "params": {"size": 32, "steps": 400, "relaxation": [0.0, 0.95], "workers": 1}},
        strategies=("parallel",),
    ),
]
BY_KEY = {r.key: r for r in ROWS}


def raw_spec(strategy: str) -> dict[str, Any]:
    path = SPECS / f"thesis-4.4.2-{strategy}.yaml"
    return parse_yaml(path.read_text(), str(path))


def make(row: Row, strategy: str, seed: int):
    raw = copy.deepcopy(raw_spec(strategy))
    raw["seed"] = seed
    if row.model is not None:
        raw["model"] = copy.deepcopy(row.model)
    raw["model"].setdefault("params", {}).update(row.params)
    for k, v in row.data.items():
        if k == "params":
            raw["data"].setdefault("params", {}).update(v)
        else:
            raw["data"][k] = v
    if row.fresh_data:
        raw["data"]["seed"] = 100 + seed
        raw["data"]["test"] = {**raw["data"]["test"], "seed": 200 + seed}
    return validate_spec(raw, f"ablation:{row.key}:{strategy}", SPECS)


_baseline: dict[tuple[str, int], Any] = {}


def baseline_model(strategy: str, seed: int):
    key = (strategy, seed)
    if key not in _baseline:
        _baseline[key] = engine.fit(make(BY_KEY["baseline"], strategy, seed))
    return _baseline[key]


def _lagged(F: np.ndarray, lags: tuple[int, ...]) -> np.ndarray:
    return np.hstack([np.vstack([np.repeat(F[:1], k, axis=0), F[: len(F) - k]]) for k in lags])


def readout_nmse(kind: str, strategy: str, seed: int, lags: tuple[int, ...] = (0,)) -> float:
    """Test NMSE of the baseline's annealed network with another readout over its 3M states."""
    from dynmodel.data import load_dataset

    model = baseline_model(strategy, seed)
    spec = make(BY_KEY["baseline"], strategy, seed)
    ds = load_dataset(spec)
    from dynmodel_plugins.lorenz_net.elements import simulate_network

    fam = model.family
    rec = {s: ds.scored(s) for s in ("train", "validation", "test")}
    states = []
    for r in ds.recordings:
        X, _ = simulate_network(
            fam.element_params_, fam.C_, fam.B_, model.preprocessor.inputs(r.u), fam.dt_, fam.params.substeps
        )
        states.append(X.reshape(X.shape[0], -1))
    if lags != (0,):
        states = [_lagged(F, lags) for F in states]

    def rows(split):
        return np.vstack([states[r][a:b] for r, a, b in rec[split]]), np.vstack(
            [ds.recordings[r].y[a:b] for r, a, b in rec[split]]
        )

    Ft, yt = rows("train")
    Fv, yv = rows("validation")
    Fs, ys = rows("test")
    if kind == "ridge":
        fit = regression.ridge(Ft, yt, "auto", Fv, yv)
    elif kind == "fos":
        fit = regression.fos(Ft, yt, Fv=Fv, Yv=yv, patience=5)
    else:
        fit = regression.lstsq(Ft, yt)
    err = ys - fit.predict(Fs)
    return float(100 * np.mean(np.mean(err**2, axis=0) / np.var(ys, axis=0)))


@njit(cache=True)
def _euler_network(params, C, B, U, dt):
    """States (n, M, 3) of eq. 4.52 / 4.59 by one explicit Euler step of dt per sample (drive u_t)."""
    n, M = U.shape[0], params.shape[0]
    X = np.zeros((n, M, 3))
    x = np.zeros((M, 3))
    for t in range(n):
        for i in range(M):
            v = 0.0
            for k in range(U.shape[1]):
                v += B[i, k] * U[t, k]
            for j in range(i):
                if C[i, j] != 0.0:
                    v += C[i, j] * x[j, 1] / params[j, 1]
            s, r, b, a = params[i, 0], params[i, 1], params[i, 2], params[i, 3]
            x1, x2, x3 = x[i, 0], x[i, 1], x[i, 2]
            x[i, 0] = x1 + dt * a * s * (v - x1)
            x[i, 1] = x2 + dt * a * (r * x1 - x2 - x1 * x3)
            x[i, 2] = x3 + dt * a * (x1 * x2 - b * x3)
            X[t, i] = x[i]
    return X


def euler_nmse(strategy: str, seed: int) -> float:
    """Test NMSE of the random initial network of ``seed`` integrated by explicit Euler (t_i = 0.1);
    elements that diverge are left out of the readout."""
    from dynmodel.data import load_dataset
    from dynmodel_plugins.lorenz_net.params import LorenzNetParams
    from dynmodel_plugins.lorenz_net.search import initial_state

    spec = make(BY_KEY["baseline"], strategy, seed)
    ds = load_dataset(spec)
    p = LorenzNetParams(**spec.model.params.model_dump(mode="python"))
    st = initial_state(p, 1, engine.family_rng(seed).spawn(1)[0])  # the family's first restart
    with np.errstate(all="ignore"):
        states = [_euler_network(st.params, st.C, st.B, np.ascontiguousarray(r.u), 0.1) for r in ds.recordings]
    ok = np.all([np.isfinite(X).all(axis=(0, 2)) & (np.abs(X).max(axis=(0, 2)) < 1e6) for X in states], axis=0)
    states = [X[:, ok, :].reshape(X.shape[0], -1) for X in states]
    rows = {s: ds.scored(s) for s in ("train", "test")}
    Ft = np.vstack([states[r][a:b] for r, a, b in rows["train"]])
    yt = np.vstack([ds.recordings[r].y[a:b] for r, a, b in rows["train"]])
    Fs = np.vstack([states[r][a:b] for r, a, b in rows["test"]])
    ys = np.vstack([ds.recordings[r].y[a:b] for r, a, b in rows["test"]])
    err = ys - regression.lstsq(Ft, yt).predict(Fs)
    return float(100 * np.mean(np.mean(err**2, axis=0) / np.var(ys, axis=0)))


def run_one(row: Row, strategy: str, seed: int) -> float:
    if row.readout == "euler":
        return euler_nmse(strategy, seed)
    if row.readout is not None:
        return readout_nmse(row.readout, strategy, seed, row.lags)
    model = baseline_model(strategy, seed) if row.key == "baseline" else engine.fit(make(row, strategy, seed))
    value = model.metrics["test"]["nmse"]
    return float("inf") if value is None else float(value)


def command(key: str, seeds: int) -> str:
    return f"python benchmarks/lorenz_ablation.py --rows {key} --seeds {seeds}"


def fmt(values: list[float] | None) -> str:
    if not values:
        return ""
    v = np.asarray(values)
    return f"{np.mean(v):.2f} ± {np.std(v):.2f}"


def table(results: dict[str, dict[str, list[float]]], seeds: int) -> str:
    lines = [
        "| factor | row | change | parallel: test NMSE % | feed-forward: test NMSE % | command |",
        "|---|---|---|---|---|---|",
    ]
    for row in ROWS:
        if row.key not in results:
            continue
        res = results[row.key]
        n = max(len(v) for v in res.values())
        ff = "(one network per run)" if row.model is not None else fmt(res.get("feed-forward"))
        lines.append(
            f"| {row.factor} | `{row.key}` | {row.change} | {fmt(res.get('parallel'))} | {ff} | `{command(row.key, n)}` |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", nargs="*", default=None, help="row keys (default: all)")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--strategies", nargs="*", default=list(STRATEGIES))
    ap.add_argument("--out", type=Path, default=None, help="JSON file the results are merged into")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--table", type=Path, default=None, help="print the table of a saved JSON file and exit")
    args = ap.parse_args()
    if args.list:
        for r in ROWS:
            print(f"{r.key:18s} {r.factor:14s} {r.change}")
        return
    if args.table is not None:
        print(table(json.loads(args.table.read_text()), args.seeds))
        return
    keys = args.rows or [r.key for r in ROWS]
    unknown = [k for k in keys if k not in BY_KEY]
    if unknown:
        raise SystemExit(f"unknown row(s) {unknown}; see --list")
    results: dict[str, dict[str, list[float]]] = {}
    if args.out is not None and args.out.is_file():
        results = json.loads(args.out.read_text())
    print("thesis 4.4.2 ablation: test NMSE % (mean ± std over seeds; thesis: parallel 1.9, feed-forward 0.9)")
    for key in keys:
        row = BY_KEY[key]
        for strategy in [s for s in args.strategies if s in row.strategies]:
            t0 = time.perf_counter()
            values = [run_one(row, strategy, seed) for seed in range(args.seeds)]
            results.setdefault(key, {})[strategy] = values
            print(
                f"  {key:18s} {strategy:12s} {fmt(values):>16s}   {np.round(values, 2)}  "
                f"({(time.perf_counter() - t0) / args.seeds:.0f} s per run)",
                flush=True,
            )
            if args.out is not None:
                args.out.write_text(json.dumps(results, indent=1))
    print()
    print(table({k: results[k] for k in keys if k in results}, args.seeds))


if __name__ == "__main__":
    main()
