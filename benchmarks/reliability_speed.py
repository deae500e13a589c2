"""Reliability-check speed: seconds for a whole check, and for its replica test against a plain
numpy loop doing the same replica test.

Networks as the `esn` family builds them (connection probability 2/M, input 0.1, bias 0.8,
sigma(C) = 0.95), internal mode, one input in [-2, 2]; plus a dense network (connection
probability 1, spectral radius 0.95) that the check cannot prove reliable. Default settings:
16 replicas x 32 test inputs x 2000 steps, 23 constant inputs x 32 replicas.

The replica test is timed three ways on the same battery of inputs and initial states:

* dynmodel as shipped (compiled batched step; replicas that agree to rounding are merged);
* dynmodel with merging switched off (every replica simulated to the end);
* a plain numpy loop: ``X = tanh(X @ C.T + V @ B.T + c0)`` with C as scipy CSR (sparse) or dense
  array, and the spread of each signal's replicas computed with numpy every step.

Prints figures (best of ``--repeats`` runs after a warm-up that compiles the kernels); asserts nothing.

    python benchmarks/reliability_speed.py            # M = 200, 1000 (sparse) and 200 (dense)
    python benchmarks/reliability_speed.py --quick    # M = 200 sparse only
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp

from dynmodel.reliability import InputDomain, Settings, check, replicas
from dynmodel.reliability.networks import SigmoidNetwork
from dynmodel.reliability.signals import battery
from dynmodel_plugins.esn.network import build_network
from dynmodel_plugins.esn.params import EsnParams


def network(m: int, dense: bool) -> SigmoidNetwork:
    params = (
        EsnParams(size=m, connectivity=1.0, scale={"by": "spectral", "value": 0.95}) if dense else EsnParams(size=m)
    )
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net = build_network(params, 1, 0, np.random.default_rng(0))
    return SigmoidNetwork(
        net.C,
        net.B,
        net.c0,
        net.a,
        net.g,
        InputDomain.from_range(["u"], -2.0, 2.0),
        name=f"esn M={m}{' dense' if dense else ''}",
    )


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def numpy_replica_test(net: SigmoidNetwork, signals, X0: np.ndarray, dense: bool) -> np.ndarray:
    """The same replica test as dynmodel's, in plain numpy: all signals' replicas in one batch."""
    S, (R, M) = len(signals), X0.shape
    V = np.stack([s.u for s in signals])  # (S, n, 1): the identity drive of a network
    C = net.C.toarray() if dense else sp.csr_matrix(net.C)
    X = np.tile(X0, (S, 1))
    n = V.shape[1]
    spread = np.empty((n, S))
    for t in range(n):
        Vt = np.repeat(V[:, t, :], R, axis=0)
        Z = (X @ C.T) if dense else (C @ X.T).T
        X = net.a * X + net.g * np.tanh(Z + Vt @ net.B.T + net.c0)
        Xg = X.reshape(S, R, M)
        spread[t] = np.sqrt(((Xg - Xg[:, :1]) ** 2).sum(axis=2)).max(axis=1)
    return spread


def case(m: int, dense: bool, repeats: int) -> None:
    net = network(m, dense)
    settings = Settings()
    rng = np.random.default_rng(0)
    n = net.default_length
    signals = battery(net, n, rng, [])
    X0 = net.sample_states(np.random.default_rng(1), settings.replicas)
    scale = net.scale()
    tol, apart = settings.tolerance * scale, replicas.APART * scale
    check(net, settings)  # warm-up: compile
    t_check, report = best_of(lambda: check(net, settings), repeats)
    t_ours, _ = best_of(lambda: replicas.run(net, signals, X0, tol, apart, lambda *a: None, scale), repeats)
    saved = replicas.COLLAPSE
    replicas.COLLAPSE = -1.0
    try:
        t_full, _ = best_of(lambda: replicas.run(net, signals, X0, tol, apart, lambda *a: None, scale), repeats)
    finally:
        replicas.COLLAPSE = saved
    t_np, _ = best_of(lambda: numpy_replica_test(net, signals, X0, dense), 1)
    steps = len(signals) * settings.replicas * n
    label = f"M = {m}{' dense (spectral 0.95)' if dense else ''}"
    print(f"{label}: verdict {report.verdict.verdict}; sigma(C) = {report.evidence[0].value:.3g}")
    print(
        f"  whole check (replicas, exponents, constant scan) ....... {t_check:8.2f} s   "
        f"({', '.join(f'{k} {v:.2f}' for k, v in report.timing.items() if k != 'total')})"
    )
    print(f"  replica test, dynmodel as shipped ........................ {t_ours:8.2f} s")
    print(
        f"  replica test, dynmodel without merging ({steps / 1e6:.2f} M replica-steps) {t_full:6.2f} s   "
        f"{1e6 * t_full / steps:.2f} us per replica-step"
    )
    print(
        f"  replica test, plain numpy loop ({'dense' if dense else 'scipy CSR'}) ..................... {t_np:8.2f} s   "
        f"{1e6 * t_np / steps:.2f} us per replica-step ({t_np / t_full:.1f}x slower than without merging, "
        f"{t_np / t_ours:.0f}x than shipped)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="M = 200 sparse only")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    cases = [(200, False)] if args.quick else [(200, False), (1000, False), (200, True)]
    for m, dense in cases:
        case(m, dense, args.repeats)


if __name__ == "__main__":
    main()
