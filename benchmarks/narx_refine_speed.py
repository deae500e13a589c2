"""`cost: mse_inf` solver speed: the narx family's Levenberg-Marquardt (plugins/narx/lm.py) against
MINPACK's lmder (scipy's ``least_squares(method="lm")``), the solver it replaced, side by side.

Both are Moré's trust-region Levenberg-Marquardt with the same steps and stopping tests; they differ in
the factorization of the N x p Jacobian at every iteration (lmder: an unblocked, column-pivoted
Householder QR; ours: LAPACK's blocked QR on row blocks of [J r], Q never formed). Each spec is fitted
twice in this process, once per solver (the whole fit: term selection, then the free-run refinement),
and the script prints the seconds spent inside the solver, the Jacobians it took, the seconds per
Jacobian, the whole fit's seconds, and the free-run NMSE of both fits on every split. Prints figures;
asserts nothing.

    python benchmarks/narx_refine_speed.py                   # the Silverbox and Bouc-Wen narx specs
    python benchmarks/narx_refine_speed.py specs/x.yaml ...  # any narx specs with cost mse_inf

The benchmark specs read ../shared/data; without it the script falls back to the thesis's NARX system
(short, so the two solvers take about the same time there).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

import dynmodel
from dynmodel.spec import load_spec
from dynmodel_plugins.narx import estimation
from dynmodel_plugins.narx.lm import levenberg_marquardt

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "specs/benchmarks/silverbox-narx.yaml", ROOT / "specs/benchmarks/bouc-wen-narx.yaml"]
FALLBACK = [ROOT / "specs/thesis-3.2.4-narx.yaml"]


def minpack_lmder(fun, jac, x0, *, max_nfev, ftol, xtol, gtol):
    """The solver before: scipy's wrapper of MINPACK lmder, with the arguments the family passed it."""
    return least_squares(
        fun, x0, jac=jac, method="lm", x_scale="jac", ftol=ftol, xtol=xtol, gtol=gtol, max_nfev=max_nfev
    )


class Timed:
    """Wraps a solver: seconds inside it and Jacobians taken, over every call of one fit."""

    def __init__(self, solver):
        self.solver, self.seconds, self.njev = solver, 0.0, 0

    def __call__(self, fun, jac, x0, **options):
        t0 = time.perf_counter()
        res = self.solver(fun, jac, x0, **options)
        self.seconds += time.perf_counter() - t0
        self.njev += int(res.njev)
        return res


def fit_with(spec, solver) -> tuple[object, Timed, float]:
    timed = Timed(solver)
    saved = estimation.levenberg_marquardt
    estimation.levenberg_marquardt = timed  # refine() calls it by this name
    try:
        t0 = time.perf_counter()
        model = dynmodel.fit(spec)
        return model, timed, time.perf_counter() - t0
    finally:
        estimation.levenberg_marquardt = saved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("specs", nargs="*", type=Path)
    args = ap.parse_args()
    specs = args.specs or [p for p in DEFAULT if (ROOT.parent / "shared/data").is_dir()] or FALLBACK
    print(f"{'spec':<28}{'solver':<9}{'terms':>6}{'solver s':>10}{'Jacobians':>10}{'s/Jac':>8}{'fit s':>8}")
    for path in specs:
        spec = load_spec(path)
        runs = {}
        for name, solver in (("lmder", minpack_lmder), ("blocked", levenberg_marquardt)):
            model, timed, total = fit_with(spec, solver)
            runs[name] = model
            terms = int(np.asarray(model.family.weights_).size)
            per = timed.seconds / max(timed.njev, 1)
            print(f"{path.stem:<28}{name:<9}{terms:>6}{timed.seconds:>10.1f}{timed.njev:>10}{per:>8.2f}{total:>8.1f}")
        for split, m in runs["lmder"].metrics.items():
            other = runs["blocked"].metrics.get(split, {})
            a, b = m.get("nmse", float("nan")), other.get("nmse", float("nan"))
            print(f"{'':<28}{split}: free-run NMSE {a:.6g} % (lmder), {b:.6g} % (blocked)")


if __name__ == "__main__":
    main()
