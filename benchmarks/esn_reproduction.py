"""Thesis section 5.3.2 with dynmodel: internal vs external approach, and the noisy-training sweep.

    python benchmarks/esn_reproduction.py                 # 20 networks, internal and external
    python benchmarks/esn_reproduction.py --noise         # + noise sweep 0, 0.2, 0.5, 1.0 (mse1 vs mse_inf)
    python benchmarks/esn_reproduction.py --noise --levels 0,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0
    python benchmarks/esn_reproduction.py --peer          # + reservoirpy on the same networks (if installed)

Every figure is the test NMSE (%) of the free run on a separate clean 10000-sample realization,
first 1000 samples not scored. Network seeds are 0 .. nets-1. Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.spec import NoiseSpec, load_spec

SPECS = Path(__file__).resolve().parents[1] / "specs"


def stats(values: np.ndarray) -> str:
    finite = values[np.isfinite(values)]
    diverged = len(values) - len(finite)
    text = (
        f"mean {np.mean(values):9.4g}  median {np.median(values):9.4g}  std {np.std(finite):8.3g}  "
        f"min {np.min(finite):8.3g}  max {np.max(values):8.3g}"
    )
    return text + (f"  ({diverged} diverged)" if diverged else "")


def test_nmse(spec_file: str, seeds, **changes) -> np.ndarray:
    out = []
    for seed in seeds:
        spec = load_spec(SPECS / spec_file)
        spec.seed = seed
        for key, value in changes.items():
            obj, attr = (spec.data, key[5:]) if key.startswith("data_") else (spec, key)
            setattr(obj, attr, value)
        v = engine.fit(spec).metrics["test"]["nmse"]
        out.append(np.inf if v is None else v)
    return np.array(out)


def peer(seeds) -> None:
    try:
        from reservoirpy.nodes import Reservoir, Ridge
    except Exception:  # noqa: BLE001
        print("reservoirpy is not installed; skipping the peer comparison")
        return
    from dynmodel import kernels
    from dynmodel.metrics import nmse
    from dynmodel_plugins.esn.network import build_network

    spec = load_spec(SPECS / "thesis-5.3.2-internal.yaml")
    ds = load_dataset(spec)
    u, y = ds.recordings[0].u, ds.recordings[0].y
    ut, yt = ds.recordings[1].u, ds.recordings[1].y
    ridge, plain = [], []
    for seed in seeds:
        net = build_network(spec.model.params, 1, 1, engine.family_rng(seed))
        res = Reservoir(W=net.C.tocsr(), Win=np.ascontiguousarray(net.B_in), bias=net.c0, lr=1.0)
        model = res >> Ridge(ridge=1e-8)
        model.fit(u, y, warmup=1000)
        res.reset()
        pred = model.run(ut)
        ridge.append(float(nmse(yt[1000:], pred[1000:])[0]))
        X = kernels.drive(
            *net.kernel_args()[:3], np.ascontiguousarray(net.B_in), *net.kernel_args()[4:], u, np.zeros(net.size)
        )
        Xt = kernels.drive(
            *net.kernel_args()[:3], np.ascontiguousarray(net.B_in), *net.kernel_args()[4:], ut, np.zeros(net.size)
        )
        A = np.hstack([X[1000:], np.ones((len(X) - 1000, 1))])
        w, *_ = np.linalg.lstsq(A, y[1000:], rcond=None)
        plain.append(float(nmse(yt[1000:], Xt[1000:] @ w[:-1] + w[-1])[0]))
    print(f"reservoirpy internal, ridge 1e-8 (same networks): {stats(np.array(ridge))}")
    print(f"numpy lstsq internal (same networks):             {stats(np.array(plain))}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nets", type=int, default=20)
    ap.add_argument("--noise", action="store_true", help="run the noisy-training sweep")
    ap.add_argument("--levels", default="0,0.2,0.5,1.0", help="noise levels (fractions of the output std)")
    ap.add_argument("--peer", action="store_true", help="compare with reservoirpy on the same networks")
    args = ap.parse_args()
    seeds = range(args.nets)
    t0 = time.perf_counter()
    print(f"thesis 5.3.2, narx-system, {args.nets} random 200-element networks (test NMSE %):")
    print(f"  internal approach  {stats(test_nmse('thesis-5.3.2-internal.yaml', seeds))}")
    print(f"  external approach  {stats(test_nmse('thesis-5.3.2-external.yaml', seeds))}")
    if args.peer:
        peer(seeds)
    if args.noise:
        print("\nexternal approach, noisy training outputs, clean test (test NMSE %):")
        for level in [float(x) for x in args.levels.split(",")]:
            noise = NoiseSpec(std=level)
            one = test_nmse("thesis-5.3.2-noise.yaml", seeds, cost="mse1", data_noise=noise)
            inf = test_nmse("thesis-5.3.2-noise.yaml", seeds, cost="mse_inf", data_noise=noise)
            print(f"  noise {level:3.1f}  mse1    {stats(one)}")
            print(f"             mse_inf {stats(inf)}   better in {int(np.sum(inf < one))}/{len(one)}")
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
