"""direction-dependence: the residual depends on the direction of motion of an input, or on how far it
moved since the last reversal (hysteresis, Coulomb friction; thesis 6.1-6.3).

For an input that moves like a position (fewer than one reversal per 20 samples; the direction of a
noise-like input means nothing), d_t = +-1 is its direction of motion (reversal once it moved back
by more than 0.5 % of its range) and s_t = |u_t - u_r| / range its travel since the last reversal.
Test features: d, d s, d s^2, d exp(-s / 0.05), d exp(-s / 0.2); base features: the input's level u,
u^2, u^3, u one and two samples back and two slow functions of time (level, rate and drift effects
are not direction effects). Statistic: the out-of-sample incremental R^2 (fit on train, judged on
validation) with its batch-means p-value (:mod:`dynmodel.diagnose.dependence`). Score: that share of
the residual mean square.
"""

from __future__ import annotations

import numpy as np

from dynmodel.data.derived import DEADBAND_FRACTION, POSITION_STROKE, reversals
from dynmodel.diagnose.context import Context
from dynmodel.diagnose.dependence import holdout_share, lagged
from dynmodel.diagnose.detector import Detector, Extension, Finding

from ._extend import inputs_patch

MAX_REVERSAL_RATE = 1.0 / POSITION_STROKE
DEADBAND = DEADBAND_FRACTION


def direction_features(u_segs: list[np.ndarray], deadband: float, span: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(features, direction, reversal count) over the concatenated segments."""
    feats, dirs, count = [], [], 0
    for u in u_segs:
        d, s = reversals(u, deadband)
        count += int(np.sum(d[1:] != d[:-1]))
        x = np.abs(s) / span
        feats.append(np.column_stack([d, d * x, d * x**2, d * np.exp(-x / 0.05), d * np.exp(-x / 0.2)]))
        dirs.append(d)
    return np.vstack(feats), np.concatenate(dirs), count


class DirectionDependence(Detector):
    cause = "direction-dependence"
    description = "residual depends on the direction of motion or on the travel since the last reversal"
    priority = 6
    applies = "an input that moves like a position (< 1 reversal per 20 samples)"

    def detect(self, ctx: Context) -> Finding | None:
        best = None
        check = ctx.check_rows()
        n = ctx.n
        for j in range(len(ctx.input_names)):
            u_segs = ctx.inputs(j)
            u = np.concatenate(u_segs)
            lo, hi = np.quantile(u, [0.01, 0.99])
            span = float(hi - lo)
            if span <= 0:
                continue
            deadband = DEADBAND * span
            F, d, count = direction_features(u_segs, deadband, span)
            if count > MAX_REVERSAL_RATE * n:
                continue
            level = (u - 0.5 * (lo + hi)) / (0.5 * span)
            base = np.column_stack([level, level**2, level**3, np.vstack(lagged(u_segs, [1, 2])), ctx.trend_features()])
            for k in range(len(ctx.output_names)):
                e = np.concatenate(ctx.residuals(k))
                dep = holdout_share(e, base, F, check)
                if best is None or dep.share > best[0].share:
                    best = (dep, j, k, count, deadband, d, e, span)
        if best is None:
            return None
        dep, j, k, count, deadband, d, e, span = best
        name = ctx.input_names[j]
        up, down = e[d > 0], e[d < 0]
        significant = ctx.judge(dep.p_value, dep.share, k)
        evidence = {
            "statistic": "partial R^2 of direction and travel-since-reversal features beyond the input level, "
            "out of sample (fit on train, judged on validation)",
            "input": name,
            "output": ctx.output_names[k],
            **dep.to_json(),
            "alpha": ctx.settings.alpha,
            "deadband": deadband,
            "reversals": count,
            "mean_stroke_samples": ctx.n / max(count, 1),
            "residual_mean_moving_up": float(up.mean()) if up.size else None,
            "residual_mean_moving_down": float(down.mean()) if down.size else None,
        }
        gap = (evidence["residual_mean_moving_up"] or 0.0) - (evidence["residual_mean_moving_down"] or 0.0)
        summary = (
            f"{ctx.output_names[k]} residual depends on the direction of {name} and its travel since the last "
            f"reversal: {100 * dep.share:.1f} % of its mean square (p = {dep.p_value:.2g}); moving up minus "
            f"moving down: {gap:.4g} ({count} reversals)"
        )
        db = float(f"{deadband:.3g}")
        items = [{"direction": name, "deadband": db}, {"since_reversal": name, "deadband": db}]
        patch = inputs_patch(ctx, derived=items, history=0)
        generic = (
            [
                Extension(
                    f"direction features of {name}: its direction of motion and travel since the last reversal as "
                    "inputs",
                    patch,
                )
            ]
            if patch
            else []
        )
        return self.finding(
            ctx, dep.share, significant, summary, evidence, ctx.extensions(self.cause, evidence, generic)
        )
