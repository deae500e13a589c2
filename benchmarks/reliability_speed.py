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

A polynomial NARX model (degree 3, lags up to 5, 100 terms, fitted on a generated Duffing-like
oscillator) is checked whole two ways: as shipped (every replica's monomials by the compiled kernel, weighed
in one product; the tangent map by the compiled model gradient), and with the term-by-term numpy loops the
view used before (one numpy expression per term and time step).

Prints figures (best of ``--repeats`` runs after a warm-up that compiles the kernels); asserts nothing.

    python benchmarks/reliability_speed.py            # M = 200, 1000 (sparse) and 200 (dense), and NARX
    python benchmarks/reliability_speed.py --quick    # M = 200 sparse only
    python benchmarks/reliability_speed.py --narx     # the NARX model only
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


def _terms_one_by_one(self, R: np.ndarray) -> np.ndarray:
    """The NARX view's polynomial before the compiled kernel: one numpy expression per term."""
    acc = np.zeros((R.shape[0], self.n_out))
    with np.errstate(over="ignore", invalid="ignore"):
        for e, k, w in zip(self.exponents, self.term_output, self.weights):
            used = np.flatnonzero(e)
            mon = np.prod(R[:, used] ** e[used], axis=1) if len(used) else np.ones(R.shape[0])
            acc[:, k] += w * mon
    return acc


def _gradient_one_by_one(self, R: np.ndarray) -> np.ndarray:
    """The NARX view's state gradient before the compiled model gradient: a numpy loop over terms and factors."""
    G = np.zeros((R.shape[0], self.n_out, self.state_dim))
    with np.errstate(over="ignore", invalid="ignore"):
        for e, k, w in zip(self.exponents, self.term_output, self.weights):
            for r in np.flatnonzero(e):
                if not self.fed_back[r]:
                    continue
                d = e[r] * R[:, r] ** (e[r] - 1) if e[r] > 1 else np.ones(R.shape[0])
                for q in np.flatnonzero(e):
                    if q != r:
                        d = d * R[:, q] ** e[q]
                G[:, k, self.column[r]] += w * d
    return G


def narx_case(repeats: int) -> None:
    from dynmodel.reliability import check_model
    from dynmodel_plugins.narx import Narx
    from dynmodel_plugins.narx.reliability import NarxSystem

    rng = np.random.default_rng(0)
    u = rng.standard_normal(5000)
    y = np.zeros(5000)
    for t in range(2, 5000):  # a Duffing-like oscillator: a cubic stiffness, lightly damped
        y[t] = 1.6 * y[t - 1] - 0.8 * y[t - 2] - 0.05 * y[t - 1] ** 3 + 0.3 * u[t - 1]
    lags = {"u": list(range(6)), "y": list(range(1, 6))}
    model = Narx(degree=3, lags=lags, max_terms=100, patience=None).fit(u, y).model_
    settings = Settings()
    check_model(model, settings)  # warm-up: compile
    t_ours, report = best_of(lambda: check_model(model, settings), repeats)
    shipped = NarxSystem._outputs, NarxSystem._state_gradient
    NarxSystem._outputs, NarxSystem._state_gradient = _terms_one_by_one, _gradient_one_by_one  # type: ignore[method-assign]
    try:
        t_loop, before = best_of(lambda: check_model(model, settings), 1)
    finally:
        NarxSystem._outputs, NarxSystem._state_gradient = shipped  # type: ignore[method-assign]
    terms = len(model.family.driven_system().weights)
    print(
        f"NARX degree 3, lags up to 5, {terms} terms: verdict {report.verdict.verdict} (term by term: {before.verdict.verdict})"
    )
    print(f"  whole check, compiled monomials and gradient ............ {t_ours:8.2f} s")
    print(
        f"  whole check, term-by-term numpy loops (before) .......... {t_loop:8.2f} s   ({t_loop / t_ours:.1f}x slower)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="M = 200 sparse only")
    ap.add_argument("--narx", action="store_true", help="the NARX model only")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    if not args.narx:
        cases = [(200, False)] if args.quick else [(200, False), (1000, False), (200, True)]
        for m, dense in cases:
            case(m, dense, args.repeats)
    if not args.quick:
        narx_case(args.repeats)


if __name__ == "__main__":
    main()
