"""Speed of the `lorenz-net` hot loop: RK4 integration of M driven Lorenz elements (eq. 4.52).

Compares dynmodel's compiled integration (numba, one element at a time over the whole series, as
the annealing evaluator does) with the same RK4 written in plain numpy, vectorised over the M
elements and looping over samples and substeps in Python. Both integrate the same 32-element
parallel network on the rossler-cross input; the states agree to rounding. Also prints the cost of
one annealing step of each strategy (integration of the touched elements + least-squares readout).
Prints figures; asserts nothing.

    python benchmarks/lorenz_speed.py [--size 32] [--n 10000] [--substeps 4]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from timing import best_of

from dynmodel.anneal import Schedule, anneal
from dynmodel.data import Preprocessor, load_dataset, training_data
from dynmodel.spec import validate_spec
from dynmodel_plugins.lorenz_net.elements import simulate_network
from dynmodel_plugins.lorenz_net.params import LorenzNetParams
from dynmodel_plugins.lorenz_net.search import Evaluator, initial_state, make_moves


def numpy_parallel(params: np.ndarray, B: np.ndarray, U: np.ndarray, dt: float, substeps: int) -> np.ndarray:
    """States (n, M, 3) of a parallel network (C = 0) by RK4 in plain numpy, drive held per interval."""
    s, r, b, a = params.T
    h = dt / substeps
    x = np.zeros((params.shape[0], 3))

    def rhs(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                a * s * (v - x[:, 0]),
                a * (r * x[:, 0] - x[:, 1] - x[:, 0] * x[:, 2]),
                a * (x[:, 0] * x[:, 1] - b * x[:, 2]),
            ],
            axis=1,
        )

    out = np.empty((U.shape[0], params.shape[0], 3))
    for t in range(U.shape[0]):
        v = B @ U[t]
        for _ in range(substeps):
            k1 = rhs(x, v)
            k2 = rhs(x + 0.5 * h * k1, v)
            k3 = rhs(x + 0.5 * h * k2, v)
            k4 = rhs(x + h * k3, v)
            x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out[t] = x
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--substeps", type=int, default=4)
    args = ap.parse_args()
    spec = validate_spec(
        {
            "data": {
                "generator": "rossler-cross",
                "n": args.n,
                "seed": 1,
                "split": {"train": 0.7, "validation": 0.3},
                "scaling": "none",
            },
            "model": {"family": "lorenz-net", "params": {"size": args.size, "substeps": args.substeps}},
        }
    )
    ds = load_dataset(spec)
    td = training_data(ds, Preprocessor.fit(ds, [], "none"))
    U = np.ascontiguousarray(td.series[0].u)
    dt = 0.1
    p = LorenzNetParams(size=args.size, substeps=args.substeps, strategy="parallel")
    state = initial_state(p, 1, np.random.default_rng(0))
    simulate_network(state.params, state.C, state.B, U[:10], dt, p.substeps)  # compile outside the timing

    fast = best_of(lambda: simulate_network(state.params, state.C, state.B, U, dt, p.substeps))
    slow = best_of(lambda: numpy_parallel(state.params, state.B, U, dt, p.substeps), repeats=1)
    X, _ = simulate_network(state.params, state.C, state.B, U, dt, p.substeps)
    Xn = numpy_parallel(state.params, state.B, U[:2000], dt, p.substeps)
    diff = float(np.max(np.abs(X[:2000] - Xn)))
    steps = args.n * args.size * args.substeps
    print(
        f"RK4 over {args.size} Lorenz elements, {args.n} samples, {args.substeps} substeps "
        f"({steps / 1e6:.2f} M element-steps):"
    )
    print(f"  dynmodel (numba)     {fast * 1e3:8.1f} ms   {1e9 * fast / steps:6.1f} ns per element-step")
    print(f"  plain numpy          {slow * 1e3:8.1f} ms   {1e9 * slow / steps:6.1f} ns per element-step")
    print(f"  speed-up             {slow / fast:8.1f}x   (largest state difference over 2000 samples: {diff:.1e})")

    for strategy in ("parallel", "feed-forward"):
        q = LorenzNetParams(size=args.size, substeps=args.substeps, strategy=strategy, steps=100)
        rng = np.random.default_rng(1)
        ev = Evaluator(td, q, dt)
        s0 = initial_state(q, 1, rng)
        start = ev.score(s0)
        t0 = time.perf_counter()
        anneal(s0, start, ev.score, make_moves(q), Schedule(q.steps, q.t0, q.t_end), rng)
        sec = time.perf_counter() - t0
        print(
            f"  annealing, {strategy:12s} {1e3 * sec / q.steps:6.1f} ms per step "
            f"({ev.element_integrations / ev.evaluations:.1f} elements integrated per step on average; "
            f"400 steps: {4 * sec:.1f} s)"
        )


if __name__ == "__main__":
    main()
