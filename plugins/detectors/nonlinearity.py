"""static-nonlinearity: the residual depends nonlinearly on the current level of an input.

The input level is mapped to x in [-1, 1] over its 1-99 % quantile range (clipped beyond); test
features: the Legendre polynomials P2(x) .. P5(x); base features: the input at lags 0 .. min(M, 5),
M the model's memory (a wrong linear gain or wrong linear dynamics is not a static nonlinearity),
and two slow functions of time (nor is a drift). Statistic: the out-of-sample incremental R^2 (fit
on train, judged on validation) with its batch-means p-value (:mod:`dynmodel.diagnose.dependence`).
Score: that share of the residual mean square.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.dependence import holdout_share, lagged
from dynmodel.diagnose.detector import Detector, Finding

DEGREES = (2, 3, 4, 5)


def level_features(u: np.ndarray) -> tuple[np.ndarray, float, float]:
    lo, hi = np.quantile(u, [0.01, 0.99])
    x = np.clip((u - 0.5 * (lo + hi)) / max(0.5 * (hi - lo), 1e-300), -1.0, 1.0)
    return np.column_stack([legendre.legval(x, np.eye(6)[d]) for d in DEGREES]), float(lo), float(hi)


class StaticNonlinearity(Detector):
    cause = "static-nonlinearity"
    description = "residual depends nonlinearly on the current input level"
    priority = 7
    applies = "a varying input"

    def detect(self, ctx: Context) -> Finding | None:
        best = None
        check = ctx.check_rows()
        lags = list(range(0, min(ctx.memory, 5) + 1))
        for j in range(len(ctx.input_names)):
            u_segs = ctx.inputs(j)
            u = np.concatenate(u_segs)
            if np.ptp(u) <= 0:
                continue
            F, lo, hi = level_features(u)
            base = np.hstack([np.vstack(lagged(u_segs, lags)), ctx.trend_features()])
            for k in range(len(ctx.output_names)):
                e = np.concatenate(ctx.residuals(k))
                dep = holdout_share(e, base, F, check)
                if best is None or dep.share > best[0].share:
                    best = (dep, j, k, lo, hi, u, e)
        if best is None:
            return None
        dep, j, k, lo, hi, u, e = best
        name = ctx.input_names[j]
        grid = np.linspace(lo, hi, 9)
        Fg, _, _ = level_features(np.concatenate([grid, u]))
        curve = (Fg[: len(grid)] - Fg[len(grid) :].mean(axis=0)) @ dep.coef
        significant = ctx.judge(dep.p_value, dep.share, k)
        evidence = {
            "statistic": "partial R^2 of Legendre polynomials P2..P5 of the input level beyond its linear lags, "
            "out of sample (fit on train, judged on validation)",
            "input": name,
            "output": ctx.output_names[k],
            **dep.to_json(),
            "alpha": ctx.settings.alpha,
            "base_lags": lags,
            "level_range": [lo, hi],
            "curve": {"level": grid.tolist(), "residual": curve.tolist()},
        }
        summary = (
            f"{ctx.output_names[k]} residual is a nonlinear function of the level of {name}: "
            f"{100 * dep.share:.1f} % of its mean square (p = {dep.p_value:.2g}); the curve spans "
            f"{np.ptp(curve):.4g} over [{lo:.4g}, {hi:.4g}]"
        )
        return self.finding(ctx, dep.share, significant, summary, evidence, ctx.extensions(self.cause, evidence))
