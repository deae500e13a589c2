"""ESN speed: free-run microseconds per step and fit seconds, side by side in one run.

Compares, on the same random sparse network (connection probability 2/M, input 0.1, bias 0.8,
sigma(C) = 0.95) and the same narx-system data:

* dynmodel's compiled kernels: internal-mode drive (states stored) and external-mode free run
  (output fed back every step);
* a plain numpy loop doing the same recurrence, ``x = tanh(C @ x + c0 + B u_t)``, with C dense and
  with C as a scipy CSR matrix;
* reservoirpy (``Reservoir(W=C, Win=B, bias=c0).run``) when it is importable.

Fit seconds: ``dynmodel.fit`` of an internal-mode spec (states + readout), and reservoirpy's
``Reservoir >> Ridge`` fit. Prints figures; asserts nothing.

    python benchmarks/esn_speed.py            # M=200/N=10000 and M=1000/N=100000
    python benchmarks/esn_speed.py --quick    # M=200/N=10000 only
"""

from __future__ import annotations

import argparse

import numpy as np
from timing import best_of

from dynmodel import engine, kernels
from dynmodel.spec import validate_spec
from dynmodel_plugins.esn.network import build_network
from dynmodel_plugins.esn.params import EsnParams
from dynmodel_plugins.generators.maps import NarxSystem

try:  # optional peer
    from reservoirpy.nodes import Reservoir, Ridge
except Exception:  # noqa: BLE001
    Reservoir = None


def numpy_loop(C, B, c0, U, steps):
    x = np.zeros(C.shape[0])
    X = np.empty((steps, C.shape[0]))
    for t in range(steps):
        x = np.tanh(C @ x + c0 + B @ U[t])
        X[t] = x
    return X


def case(m: int, n: int) -> None:
    u, y = NarxSystem.generate(NarxSystem.Params(), n, np.random.default_rng(1))
    net = build_network(EsnParams(size=m, mode="external"), 1, 1, np.random.default_rng(0))
    args = net.kernel_args()
    internal_B = np.ascontiguousarray(net.B_in)
    internal_args = (*args[:3], internal_B, *args[4:])
    kernels.drive(*internal_args, u[:10], np.zeros(m))  # compile outside the timing
    t_drive = best_of(lambda: kernels.drive(*internal_args, u, np.zeros(m))) / n * 1e6
    W = 0.01 * np.random.default_rng(2).standard_normal((1, m))
    D, w0, lo, hi = np.zeros((1, 2)), np.zeros(1), np.full(1, -1e12), np.full(1, 1e12)
    fr = lambda: kernels.free_run(
        *args,
        u,
        np.zeros((0, 1)),
        0,
        0.0,
        W,
        D,
        w0,
        np.zeros(1),
        lo,
        hi,  # noqa: E731
        np.zeros(m),
        False,
    )
    fr()
    t_free = best_of(fr) / n * 1e6
    steps = min(n, 20000)
    dense = net.C.toarray()
    t_np_dense = best_of(lambda: numpy_loop(dense, internal_B, net.c0, u, steps), 2) / steps * 1e6
    t_np_csr = best_of(lambda: numpy_loop(net.C, internal_B, net.c0, u, steps), 2) / steps * 1e6
    Xd = kernels.drive(*internal_args, u[:2000], np.zeros(m))
    Xn = numpy_loop(dense, internal_B, net.c0, u, 2000)
    agree = float(np.abs(Xd - Xn).max())

    raw = {
        "data": {
            "generator": "narx-system",
            "n": n,
            "seed": 1,
            "split": {"train": 1.0},
            "transient": 1000,
            "scaling": "none",
        },
        "model": {"family": "esn", "params": {"size": m, "readout": {"solver": "lstsq", "direct": False}}},
    }
    spec = validate_spec(raw)
    engine.fit(validate_spec({**raw, "data": {**raw["data"], "n": 3000}}))  # warm the kernels
    t_fit = best_of(lambda: engine.fit(spec), 1)

    print(f"\nM = {m}, N = {n}")
    print(f"  dynmodel  internal drive   {t_drive:8.3f} us/step")
    print(f"  dynmodel  external free run{t_free:8.3f} us/step")
    print(
        f"  numpy     loop, dense C    {t_np_dense:8.3f} us/step   ({t_np_dense / t_drive:5.1f}x slower than dynmodel)"
    )
    print(f"  numpy     loop, CSR C      {t_np_csr:8.3f} us/step   ({t_np_csr / t_drive:5.1f}x slower)")
    print(f"  (dynmodel and numpy states agree to {agree:.1e})")
    print(f"  dynmodel  fit (states + least-squares readout, {n} samples): {t_fit:6.2f} s")
    if Reservoir is not None:
        res = Reservoir(W=net.C.tocsr(), Win=internal_B, bias=net.c0, lr=1.0)
        res.run(u[:10])
        t_peer = best_of(lambda: (res.reset(), res.run(u)), 2) / n * 1e6

        def peer_fit():
            r = Reservoir(W=net.C.tocsr(), Win=internal_B, bias=net.c0, lr=1.0)
            (r >> Ridge(ridge=1e-8)).fit(u, y, warmup=1000)

        t_peer_fit = best_of(peer_fit, 1)
        print(f"  reservoirpy run            {t_peer:8.3f} us/step   ({t_peer / t_drive:5.1f}x slower than dynmodel)")
        print(f"  reservoirpy fit (Reservoir >> Ridge):                   {t_peer_fit:6.2f} s")
    else:
        print("  reservoirpy: not installed (pip install reservoirpy in a separate environment to compare)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only M=200, N=10000")
    args = ap.parse_args()
    case(200, 10000)
    if not args.quick:
        case(1000, 100000)


if __name__ == "__main__":
    main()
