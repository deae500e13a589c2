"""dynmodel's `narx` family against SysIdentPy's FROLS, side by side in one run.

    python benchmarks/narx_vs_sysidentpy.py               # speed at N = 10000 and 100000, noise sweep 0 .. 1.0
    python benchmarks/narx_vs_sysidentpy.py --quick       # N = 10000, noise levels 0, 0.5, 1.0, one seed
    python benchmarks/narx_vs_sysidentpy.py --no-sweep    # speed only

The peer is optional: install it in the benchmark's own environment (``pip install sysidentpy``;
it is not a dependency of dynmodel); without it only dynmodel's figures are printed.

Same data, same pool: the NARX system of eq. 3.37 (``specs/thesis-3.2.4-narx.yaml``), N samples
of which the first 80 % train, a separate clean 10000-sample test realization; monomials up to
degree 5 of u_t, u_{t-1}, u_{t-2}, y_{t-1}, y_{t-2} plus a constant (252 candidates), 8 terms.
SysIdentPy's input lags start at 1, so it receives the input advanced by one sample
(x_t = u_{t+1}), which makes its lags 1, 2, 3 the same regressors u_t, u_{t-1}, u_{t-2}.
Noise (std = level x the clean output std) is added to the training outputs by dynmodel's data
loader and the *same* noisy arrays go to both libraries.

Figures: fit seconds (dynmodel: ``Narx.fit`` on the loaded data; SysIdentPy: ``FROLS.fit``), the
free-run NMSE (%) on the clean test realization from sample 3 on (both start from the measured
first outputs), and free-run microseconds per step (dynmodel's compiled kernel, SysIdentPy's
``predict``, and a plain numpy loop of the same model). Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from timing import best_of

from dynmodel.data import Preprocessor, load_dataset, training_data
from dynmodel.spec import NoiseSpec, load_spec
from dynmodel_plugins.narx import Narx

try:  # optional peer
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares
except Exception:  # noqa: BLE001
    FROLS = None

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "specs/thesis-3.2.4-narx.yaml"
FREE = ROOT / "specs/thesis-3.2.4-narx-noise.yaml"
SKIP = 3  # scored test samples start here (SysIdentPy's largest lag)


def nmse(y: np.ndarray, yhat: np.ndarray) -> float:
    y, yhat = np.ravel(y)[SKIP:], np.ravel(yhat)[SKIP:]
    return float(100 * np.mean((y - yhat) ** 2) / np.var(y)) if np.all(np.isfinite(yhat)) else np.inf


def load(n: int, level: float, seed: int, spec_path: Path = SPEC):
    spec = load_spec(spec_path)
    spec.data.n, spec.seed = n, seed
    spec.data.noise = NoiseSpec(std=level, splits=["train", "validation"]) if level > 0 else None
    ds = load_dataset(spec)
    td = training_data(ds, Preprocessor.fit(ds, [], "none"))
    return spec, ds, td


def ours(spec, ds, td, cost: str) -> tuple[float, float, Narx]:
    fam = Narx(**spec.model.params.model_dump(mode="python"))
    t0 = time.perf_counter()
    fam.fit(td, cost)
    seconds = time.perf_counter() - t0
    test = ds.recordings[-1]
    return seconds, nmse(test.y, fam.simulate(test.u, test.y[: fam.warmup]).y), fam


def advanced(u: np.ndarray) -> np.ndarray:
    """x_t = u_{t+1} (the last value repeated), so that SysIdentPy's lag k is u_{t+1-k}."""
    u = np.ravel(u)
    return np.concatenate([u[1:], u[-1:]])[:, None]


def peer(ds, n_train: int, estimator=None) -> tuple[float, float, object]:
    model = FROLS(
        order_selection=False,
        n_terms=8,
        ylag=2,
        xlag=3,
        estimator=estimator or LeastSquares(),
        basis_function=Polynomial(degree=5),
        model_type="NARMAX",
    )
    rec = ds.recordings[0]
    t0 = time.perf_counter()
    model.fit(X=advanced(rec.u[:n_train]), y=rec.y[:n_train])
    seconds = time.perf_counter() - t0
    test = ds.recordings[-1]
    return seconds, nmse(test.y, model.predict(X=advanced(test.u), y=test.y[:SKIP])), model


def numpy_free_run(fam: Narx, u: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """The same model as a plain numpy loop: regressors, monomials by np.prod, weights by a dot."""
    src, ch, lag = fam.embedding_.arrays()
    E, w = fam.exponents_, fam.weights_
    y = np.zeros(len(u))
    y[: len(y0)] = y0
    for t in range(len(y0), len(u)):
        x = np.where(src == 0, u[t - lag, 0], y[t - lag])
        y[t] = w @ np.prod(x**E, axis=1)
    return y


def speed(n: int) -> None:
    spec, ds, td = load(n, 0.0, 0)
    n_train = sum(b - a for _, a, b in ds.ranges["train"])
    t_ours = []
    for _ in range(3):
        s, e, fam = ours(spec, ds, td, "mse1")
        t_ours.append(s)
    print(f"\nN = {n} ({n_train} training samples), 8 terms from the 252-monomial pool, clean data")
    print(f"  dynmodel  Narx.fit (FOS + least squares)  {min(t_ours):7.3f} s   test NMSE {e:.4f} %")
    print(f"            terms: {' + '.join(fam.terms_[0])}")
    if FROLS is not None:
        t_peer = []
        for _ in range(2 if n <= 20000 else 1):
            s, e_peer, model = peer(ds, n_train)
            t_peer.append(s)
        print(
            f"  SysIdentPy FROLS.fit (8 terms, LS)        {min(t_peer):7.3f} s   test NMSE {e_peer:.4f} %   "
            f"-> dynmodel fits {min(t_peer) / min(t_ours):.1f}x faster"
        )
    # the Gram matrix of the pool: one compiled pass over the monomial sums against BLAS on the pool
    from dynmodel_plugins.narx import pool as narx_pool
    from dynmodel_plugins.narx.onestep import make_pool

    train = narx_pool.patterns(td, narx_pool.regressor_matrices(td, fam.embedding_), "train", fam.embedding_.max_lag)
    E = make_pool(fam.embedding_.size, fam.params)
    t_mom = best_of(lambda: narx_pool.moment_gram(train.X, train.Y, E))
    t_blas = best_of(lambda: narx_pool.chunked_gram(train.X, train.Y, E))
    print(f"  Gram matrix of the pool: monomial sums {t_mom:.3f} s, chunked pool + BLAS syrk {t_blas:.3f} s")
    # free-run cost per step on a long input
    u = np.random.default_rng(7).standard_normal((100000, 1))
    y0 = np.zeros((fam.warmup, 1))
    fam.simulate(u[:100], y0)
    t_free = best_of(lambda: fam.simulate(u, y0), 5) / len(u) * 1e6
    steps = 20000
    t_np = best_of(lambda: numpy_free_run(fam, u[:steps], y0[:, 0]), 1) / steps * 1e6
    agree = float(np.nanmax(np.abs(numpy_free_run(fam, u[:2000], y0[:, 0]) - fam.simulate(u[:2000], y0).y[:, 0])))
    print(
        f"  free run: dynmodel {t_free:.3f} us/step; plain numpy loop {t_np:.2f} us/step ({t_np / t_free:.0f}x slower, "
        f"agrees to {agree:.1e})",
        end="",
    )
    if FROLS is not None:
        x = advanced(u)
        model.predict(X=x[:100], y=np.zeros((SKIP, 1)))
        t_peer_run = best_of(lambda: model.predict(X=x[:steps], y=np.zeros((SKIP, 1))), 2) / steps * 1e6
        print(f"; SysIdentPy predict {t_peer_run:.2f} us/step ({t_peer_run / t_free:.0f}x slower)")
    else:
        print()


def sweep(levels: list[float], seeds: int) -> None:
    print(f"\nnoise sweep (figure 3.9), N = 10000, same noisy training arrays for both; median over {seeds} seed(s)")
    print("clean-test free-run NMSE % [fit seconds]")
    names = ["dynmodel fos8 mse1", "dynmodel fos8 mse_inf", "dynmodel free_run mse_inf"]
    if FROLS is not None:
        names.append("SysIdentPy FROLS LS")
    print(f"{'noise':>5} " + "".join(f"| {n:^27} " for n in names))
    for level in levels:
        cells: dict[str, list[tuple[float, float]]] = {n: [] for n in names}
        for seed in range(seeds):
            spec, ds, td = load(10000, level, seed)
            n_train = sum(b - a for _, a, b in ds.ranges["train"])
            cells[names[0]].append(ours(spec, ds, td, "mse1")[:2])
            cells[names[1]].append(ours(spec, ds, td, "mse_inf")[:2])
            fspec, fds, ftd = load(10000, level, seed, FREE)
            cells[names[2]].append(ours(fspec, fds, ftd, "mse_inf")[:2])
            if FROLS is not None:
                cells[names[3]].append(peer(ds, n_train)[:2])
        row = []
        for n in names:
            sec, err = np.median([c[0] for c in cells[n]]), np.median([c[1] for c in cells[n]])
            row.append(f"{err:9.4g} % [{sec:6.3f} s]")
        print(f"{level:5.1f} " + "".join(f"| {c:>27} " for c in row), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="N = 10000 only; levels 0, 0.5, 1.0; one seed")
    ap.add_argument("--no-sweep", action="store_true", help="speed only")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--levels", default="0,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0")
    args = ap.parse_args()
    if FROLS is None:
        print("sysidentpy is not installed: dynmodel figures only (pip install sysidentpy in a separate environment)")
    t0 = time.perf_counter()
    _, ds, td = load(2000, 0.0, 0)  # compile / load the kernels outside the timings
    ours(load_spec(SPEC), ds, td, "mse_inf")
    if FROLS is not None:
        peer(ds, 1600)
    for n in [10000] if args.quick else [10000, 100000]:
        speed(n)
    if not args.no_sweep:
        levels = [0.0, 0.5, 1.0] if args.quick else [float(x) for x in args.levels.split(",")]
        sweep(levels, 1 if args.quick else args.seeds)
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
