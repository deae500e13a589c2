"""output-nonlinearity: the residual is a nonlinear function of the model's own output (a stiffness or
damping that depends on the output level, as in a Duffing oscillator; saturation, overflow).

The free-run output y_hat (a function of the input only, so it carries none of the residual's noise)
is mapped to x in [-1, 1] over its 1-99 % quantile range (clipped beyond). Test features: the
Legendre polynomials P2(x) .. P5(x) at lags L = 0, 1, 2, 4, 8, 16, 32 (a nonlinear force acts through
the system's dynamics, so the residual is a filtered nonlinear function of the output; the spread lags
span that filter; lags up to a twentieth of the longest segment and at most one feature per 20
training rows). Base features: the same lags of y_hat and of every input, linear (a wrong linear
dynamics is not an output nonlinearity, see missing-dynamics), Legendre P2 .. P5 of every input's level
(an input nonlinearity is static-nonlinearity's), the direction and travel-since-reversal features of an
input that moves like a position (hysteresis is direction-dependence's) and two slow functions of time. Statistic: the
out-of-sample incremental R^2 (fit on train, judged on validation) with its batch-means p-value
(:mod:`dynmodel.diagnose.dependence`). Score: that share of the residual mean square. The evidence also
gives the residual as a function of the output level (the lag-0 part of the fitted curve).

Measured outputs are never features: y = y_hat + e contains the residual itself.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.dependence import holdout_share, lagged
from dynmodel.diagnose.detector import Detector, Finding

from .direction import DEADBAND, MAX_REVERSAL_RATE, direction_features
from .nonlinearity import level_features

LAGS = (0, 1, 2, 4, 8, 16, 32)
DEGREES = (2, 3, 4, 5)
ROWS_PER_FEATURE = 20


def _scaled(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return np.clip((x - 0.5 * (lo + hi)) / max(0.5 * (hi - lo), 1e-300), -1.0, 1.0)


def _legendre(x: np.ndarray) -> np.ndarray:
    return np.column_stack([legendre.legval(x, np.eye(6)[d]) for d in DEGREES])


def _direction(u_segs: list[np.ndarray], u: np.ndarray, n: int) -> list[np.ndarray]:
    """direction-dependence's features of an input that moves like a position (hysteresis is not an output
    nonlinearity), else nothing."""
    lo, hi = np.quantile(u, [0.01, 0.99])
    span = float(hi - lo)
    if span <= 0:
        return []
    F, _, count = direction_features(u_segs, DEADBAND * span, span)
    return [F] if count <= MAX_REVERSAL_RATE * n else []


class OutputNonlinearity(Detector):
    cause = "output-nonlinearity"
    description = "residual depends nonlinearly on the model's own output (Duffing-like stiffness, saturation)"
    priority = 7
    applies = "a finite free run and enough training rows per feature"

    def lags(self, ctx: Context) -> list[int]:
        longest = max(s.n for s in ctx.segments)
        fit_rows = int((~ctx.check_rows()).sum())
        n_in = len(ctx.input_names)
        out = []
        for lag in LAGS:
            trial = out + [lag]
            features = len(trial) * (len(DEGREES) + 1 + n_in) + len(DEGREES) * n_in + 3
            if lag > longest / 20 or features * ROWS_PER_FEATURE > fit_rows:
                break
            out = trial
        return out

    def detect(self, ctx: Context) -> Finding | None:
        lags = self.lags(ctx)
        if not lags:
            return None
        check = ctx.check_rows()
        keep = np.concatenate([np.arange(s.n) >= max(lags) for s in ctx.segments])
        inputs = []
        for j in range(len(ctx.input_names)):
            u_segs = ctx.inputs(j)
            u = np.concatenate(u_segs)
            if np.ptp(u) > 0:
                inputs.append(np.vstack(lagged(u_segs, lags)))
                inputs.append(level_features(u)[0])
                inputs += _direction(u_segs, u, ctx.n)
        best = None
        for k in range(len(ctx.output_names)):
            yh_segs = [s.yhat[:, k] for s in ctx.segments]
            yh = np.concatenate(yh_segs)
            if not np.isfinite(yh).all() or np.ptp(yh) <= 0:
                continue
            lo, hi = (float(q) for q in np.quantile(yh, [0.01, 0.99]))
            x_segs = [_scaled(y, lo, hi) for y in yh_segs]
            F = np.hstack([np.vstack(lagged([_legendre(x)[:, d] for x in x_segs], lags)) for d in range(len(DEGREES))])
            base = np.hstack([np.vstack(lagged(yh_segs, lags)), *inputs, ctx.trend_features()])
            e = np.concatenate(ctx.residuals(k))
            dep = holdout_share(e[keep], base[keep], F[keep], check[keep])
            if best is None or dep.share > best[0].share:
                best = (dep, k, lo, hi, yh)
        if best is None:
            return None
        dep, k, lo, hi, yh = best
        # the lag-0 part of the fitted nonlinear function, centred, over the output range
        grid = np.linspace(lo, hi, 9)
        coef0 = dep.coef.reshape(len(DEGREES), len(lags))[:, 0]
        curve = (_legendre(_scaled(grid, lo, hi)) - _legendre(_scaled(yh, lo, hi)).mean(axis=0)) @ coef0
        name = ctx.output_names[k]
        significant = ctx.judge(dep.p_value, dep.share, k)
        evidence = {
            "statistic": "partial R^2 of Legendre polynomials P2..P5 of the model's free-run output at lags "
            f"{lags} beyond the linear lags of output and inputs and the input level, out of sample (fit on train, "
            "judged on validation)",
            "output": name,
            **dep.to_json(),
            "alpha": ctx.settings.alpha,
            "lags": lags,
            "output_range": [lo, hi],
            "curve": {"output": grid.tolist(), "residual": curve.tolist()},
        }
        summary = (
            f"{name} residual is a nonlinear function of the model's own output (lags {lags[0]}..{lags[-1]}): "
            f"{100 * dep.share:.1f} % of its mean square (p = {dep.p_value:.2g}), beyond linear dynamics and the "
            "input level"
        )
        return self.finding(ctx, dep.share, significant, summary, evidence, ctx.extensions(self.cause, evidence))
