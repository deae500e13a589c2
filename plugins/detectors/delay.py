"""missing-delay: the residual is correlated with an input at a lag beyond the model's memory.

Both the input and the residual are prewhitened by the input's AR filter (order by AIC), so the
cross-correlation r(k) = corr(e_t, u_{t-k}) of independent series has standard deviation s
(Bartlett's formula, about 1/sqrt(n_k) with n_k pairs at lag k). Lags from the model's memory M + 1
(the largest lag at which an input impulse still moves the model's output by 1 %) up to the search
horizon are scanned; the largest |r(k)| / s is significant when it beats the Sidak bound for that
many lags at level alpha (per lag, the 99 % bound is 2.576 s). Score: the share of the residual's
mean square that the raw input at lags k-2 .. k+2 explains beyond the input at the lags the model
already sees (and beyond a drift: two slow functions of time).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.correlation import ar_coefficients, ar_filter, bartlett_sd, crosscorr, sidak_z
from dynmodel.diagnose.dependence import lagged, partial_share
from dynmodel.diagnose.detector import Detector, Extension, Finding

from ._extend import NARX, with_inputs

Z99 = float(stats.norm.isf(0.005))
MIN_LAGS = 10


class MissingDelay(Detector):
    cause = "missing-delay"
    description = "residual correlated with an input at a lag beyond the model's memory (thesis 6.3.2)"
    priority = 4

    def detect(self, ctx: Context) -> Finding | None:
        memory = ctx.memory
        max_lag = ctx.max_lag
        if max_lag - memory < MIN_LAGS:
            return None  # the model remembers (nearly) the whole search horizon
        best = None
        for j in range(len(ctx.input_names)):
            u_segs = ctx.inputs(j)
            phi = ar_coefficients(u_segs)
            uw = ar_filter(u_segs, phi)
            for k in range(len(ctx.output_names)):
                ew = ar_filter(ctx.residuals(k), phi)
                r = crosscorr(ew, uw, max_lag)
                sd = bartlett_sd(ew, uw, max_lag)
                lags = np.arange(memory + 1, max_lag + 1)
                z = np.abs(np.nan_to_num(r[lags])) / sd[lags]
                i = int(np.argmax(z))
                cand = (float(z[i]), j, k, int(lags[i]), r, sd, len(phi), len(lags))
                if best is None or cand[0] > best[0]:
                    best = cand
        zmax, j, k, lag, r, sd, order, m = best
        p_lag = 2 * stats.norm.sf(zmax)
        p = float(-np.expm1(m * np.log1p(-min(p_lag, 1 - 1e-16)))) if p_lag > 0 else 0.0
        zcrit = sidak_z(ctx.settings.alpha, m)
        window = [max(0, lag - 2) + i for i in range(5)]
        short = sorted(set(np.linspace(0, memory, num=min(memory + 1, 12)).round().astype(int).tolist()))
        # rows whose lagged inputs lie inside their segment (no padding), the trend of the residual in the base
        keep = np.concatenate([np.arange(s.n) >= window[-1] for s in ctx.segments])
        base = np.hstack([np.vstack(lagged(ctx.inputs(j), short)), ctx.trend_features()])[keep]
        feats = np.vstack(lagged(ctx.inputs(j), window))[keep]
        e = np.concatenate(ctx.residuals(k))[keep]
        share = partial_share(e, base, feats) if e.size > 20 else 0.0
        significant = bool(zmax > zcrit) and ctx.judge(p, share, k)
        st = ctx.sampling_time
        name = ctx.input_names[j]
        evidence = {
            "statistic": "prewhitened cross-correlation of residual and input, Sidak bound over the searched lags",
            "input": name,
            "output": ctx.output_names[k],
            "lag_samples": lag,
            "lag_seconds": lag * st,
            "correlation": float(r[lag]),
            "z": zmax,
            "bound_99_per_lag": Z99 * float(sd[lag]),
            "bound_family": zcrit * float(sd[lag]),
            "p_value": p,
            "alpha": ctx.settings.alpha,
            "lags_searched": [int(memory + 1), int(ctx.max_lag)],
            "model_memory_samples": int(memory),
            "prewhitening_ar_order": order,
            "explained_share": share,
        }
        summary = (
            f"{ctx.output_names[k]} residual correlates with {name} {lag} samples ({lag * st:.4g} s) back: "
            f"r = {r[lag]:.3f} against a bound of {zcrit * sd[lag]:.3f} (model memory {memory} samples); the input "
            f"there explains {100 * share:.1f} % of the residual"
        )
        if ctx.family == NARX:
            d = max(1, lag - 1)
            ext = Extension(
                f"delay line at {d} samples ({d * st:.4g} s) with lags 0-2: {name} at {d}..{d + 2} samples "
                "back (thesis 6.3.2)",
                with_inputs(ctx, delay_lines=[d], lags=[0, 1, 2]),
            )
        else:
            ext = Extension(
                f"delay line at {lag} samples ({lag * st:.4g} s) (thesis 6.3.2)", with_inputs(ctx, delay_lines=[lag])
            )
        return self.finding(ctx, share, significant, summary, evidence, [ext])
