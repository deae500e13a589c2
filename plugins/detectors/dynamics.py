"""missing-dynamics: the residual is a linear function of the recent input history that the model does not
reproduce (too few lags, a too low order; thesis 3.1.1 on the embedding).

Test features: every input and the model's free-run output y_hat at lags 1, 2, 3, 4, 6, 8, 12, 16 (up to a
twentieth of the longest segment, at most one feature per 20 training rows). The lagged free-run output
brings the model's own poles, so the regression can express a rational correction of the input-output
dynamics (an output-error ARX fit on the residual). Base: the inputs and y_hat at lag 0 (a gain error
is not missing dynamics) and two slow functions of time (nor is a drift). Measured outputs are never
features: their residual part would make any coloured noise look like dynamics. Statistic: the
out-of-sample incremental R^2 (fit on train, judged on validation) with its batch-means p-value
(:mod:`dynmodel.diagnose.dependence`): a residual of the right order is, given the input history,
unpredictable beyond its noise floor. Score: that share of the residual mean square. Evidence: the
order, the smallest lag L whose features 1..L reach 90 % of the in-sample share of the full set.
"""

from __future__ import annotations

import numpy as np

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.dependence import holdout_share, lagged, partial_share
from dynmodel.diagnose.detector import Detector, Finding

LAGS = (1, 2, 3, 4, 6, 8, 12, 16)
ROWS_PER_FEATURE = 20
ORDER_LEVEL = 0.9


class MissingDynamics(Detector):
    cause = "missing-dynamics"
    description = "residual predictable from the recent input history: too few lags / too low an order"
    priority = 9
    applies = "a finite free run and enough training rows per feature"

    def lags(self, ctx: Context) -> list[int]:
        longest = max(s.n for s in ctx.segments)
        fit_rows = int((~ctx.check_rows()).sum())
        width = len(ctx.input_names) + 1
        out = []
        for lag in LAGS:
            if lag > longest / 20 or (len(out) + 2) * width * ROWS_PER_FEATURE > fit_rows:
                break
            out.append(lag)
        return out

    def detect(self, ctx: Context) -> Finding | None:
        lags = self.lags(ctx)
        if len(lags) < 2:
            return None
        check = ctx.check_rows()
        keep = np.concatenate([np.arange(s.n) >= max(lags) for s in ctx.segments])
        u_cols = [ctx.inputs(j) for j in range(len(ctx.input_names))]
        best = None
        for k in range(len(ctx.output_names)):
            yh_segs = [s.yhat[:, k] for s in ctx.segments]
            if not np.isfinite(np.concatenate(yh_segs)).all():
                continue
            series = u_cols + [yh_segs]
            base = np.column_stack([np.concatenate(s) for s in series] + [ctx.trend_features()])
            blocks = [np.vstack(lagged(s, lags)) for s in series]
            F = np.hstack(blocks)
            e = np.concatenate(ctx.residuals(k))
            dep = holdout_share(e[keep], base[keep], F[keep], check[keep])
            if best is None or dep.share > best[0].share:
                best = (dep, k, base, blocks, e)
        if best is None:
            return None
        dep, k, base, blocks, e = best
        fit = keep & ~check
        full = partial_share(e[fit], base[fit], np.hstack(blocks)[fit])
        order = lags[-1]
        for i in range(1, len(lags) + 1):
            part = np.hstack([b[:, :i] for b in blocks])
            if full > 0 and partial_share(e[fit], base[fit], part[fit]) >= ORDER_LEVEL * full:
                order = lags[i - 1]
                break
        name = ctx.output_names[k]
        st = ctx.sampling_time
        significant = ctx.judge(dep.p_value, dep.share, k)
        evidence = {
            "statistic": f"partial R^2 of the inputs and the model's free-run output at lags {lags} beyond lag 0, "
            "out of sample (fit on train, judged on validation)",
            "output": name,
            **dep.to_json(),
            "alpha": ctx.settings.alpha,
            "lags": lags,
            "order": int(order),
            "order_seconds": order * st,
            "in_sample_share_by_lags": float(full),
        }
        summary = (
            f"{name} residual is predictable from the inputs and the model's output over the last {order} samples "
            f"({order * st:.4g} s): {100 * dep.share:.1f} % of its mean square out of sample (p = {dep.p_value:.2g})"
        )
        return self.finding(ctx, dep.share, significant, summary, evidence, ctx.extensions(self.cause, evidence))
