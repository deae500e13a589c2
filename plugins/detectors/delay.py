"""missing-delay: the residual is correlated with an input at a lag beyond the model's memory.

Both the input and the residual are prewhitened by the input's AR filter (order by AIC), so the
cross-correlation r(k) = corr(e_t, u_{t-k}) of independent series has standard deviation s
(Bartlett's formula, about 1/sqrt(n_k) with n_k pairs at lag k). Lags from the model's memory M + 1
(the largest lag at which an input impulse still moves the model's output by 1 %) up to the search
horizon are scanned; the largest |r(k)| / s is significant when it beats the Sidak bound for that
many lags at level alpha (per lag, the 99 % bound is 2.576 s). Score: the share of the residual's
mean square that the raw input at lags k-2 .. k+2 explains beyond the input at the lags the model
already sees (and beyond a drift: two slow functions of time).

A second, out-of-sample test keeps its power when other misfits dominate the residual (a delayed path
hidden behind the direction dependence of friction): the lag is located on the training rows only (the
same prewhitened cross-correlation), and the input at lags k-2 .. k+2 must then predict the residual of
the validation rows beyond the short lags and the drift terms (:func:`dynmodel.diagnose.dependence.holdout_share`,
its batch-means p-value). The finding's p is the smaller of the two, doubled (Bonferroni); the score is
the share of the test that decides (the out-of-sample share for the second).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.correlation import ar_coefficients, ar_filter, bartlett_sd, crosscorr, sidak_z
from dynmodel.diagnose.dependence import holdout_share, lagged, partial_share
from dynmodel.diagnose.detector import Detector, Finding

from ._extend import delay_lines

Z99 = float(stats.norm.isf(0.005))
MIN_LAGS = 10


def _fit_parts(ctx: Context, series: list[np.ndarray]) -> list[np.ndarray]:
    """The training (non-check) stretches of per-segment series, each contiguous."""
    out = []
    for s, x in zip(ctx.segments, series):
        fit = ~s.check
        edges = np.flatnonzero(np.diff(np.r_[0, fit.astype(int), 0]))
        out += [x[a:b] for a, b in zip(edges[::2], edges[1::2]) if b - a > 0]
    return out


def _locate(ctx: Context, memory: int, max_lag: int, parts):
    """(z, input, output, lag, r, sd, AR order, lags searched) of the largest prewhitened cross-correlation
    beyond the memory, on the stretches ``parts`` makes of the segments; None when too short."""
    best = None
    for j in range(len(ctx.input_names)):
        u_segs = parts(ctx.inputs(j))
        if sum(len(x) for x in u_segs) < 4 * max_lag:
            return None
        phi = ar_coefficients(u_segs)
        uw = ar_filter(u_segs, phi)
        for k in range(len(ctx.output_names)):
            ew = ar_filter(parts(ctx.residuals(k)), phi)
            r = crosscorr(ew, uw, max_lag)
            sd = bartlett_sd(ew, uw, max_lag)
            lags = np.arange(memory + 1, max_lag + 1)
            z = np.abs(np.nan_to_num(r[lags])) / sd[lags]
            i = int(np.argmax(z))
            cand = (float(z[i]), j, k, int(lags[i]), r, sd, len(phi), len(lags))
            if best is None or cand[0] > best[0]:
                best = cand
    return best


class MissingDelay(Detector):
    cause = "missing-delay"
    description = "residual correlated with an input at a lag beyond the model's memory (thesis 6.3.2)"
    priority = 4
    applies = "the model's memory must leave at least 10 lags of the search horizon"

    def detect(self, ctx: Context) -> Finding | None:
        memory = ctx.memory
        max_lag = ctx.max_lag
        if max_lag - memory < MIN_LAGS:
            return None  # the model remembers (nearly) the whole search horizon
        best = _locate(ctx, memory, max_lag, lambda x: x)
        zmax, j, k, lag, r, sd, order, m = best
        p_lag = 2 * stats.norm.sf(zmax)
        p_sidak = float(-np.expm1(m * np.log1p(-min(p_lag, 1 - 1e-16)))) if p_lag > 0 else 0.0
        zcrit = sidak_z(ctx.settings.alpha / 2, m)
        short = sorted(set(np.linspace(0, memory, num=min(memory + 1, 12)).round().astype(int).tolist()))

        def design(j: int, k: int, lag: int):
            window = [max(0, lag - 2) + i for i in range(5)]
            # rows whose lagged inputs lie inside their segment (no padding); the residual's trend in the base
            keep = np.concatenate([np.arange(s.n) >= window[-1] for s in ctx.segments])
            base = np.hstack([np.vstack(lagged(ctx.inputs(j), short)), ctx.trend_features()])[keep]
            feats = np.vstack(lagged(ctx.inputs(j), window))[keep]
            return np.concatenate(ctx.residuals(k))[keep], base, feats, keep

        e, base, feats, keep = design(j, k, lag)
        share = partial_share(e, base, feats) if e.size > 20 else 0.0
        # out of sample: the lag located on the training rows, judged on the validation rows
        check = ctx.check_rows()
        fit_best = _locate(ctx, memory, max_lag, lambda x: _fit_parts(ctx, x))
        holdout = None
        if fit_best is not None:
            _, j2, k2, lag2, *_ = fit_best
            e2, base2, feats2, keep2 = design(j2, k2, lag2)
            holdout = (holdout_share(e2, base2, feats2, check[keep2]), j2, k2, lag2)
        p_out = holdout[0].p_value if holdout is not None else 1.0
        if holdout is not None and p_out < p_sidak:
            dep, j, k, lag = holdout
            decided = "out of sample"
            share = dep.share
            e, base, feats, keep = design(j, k, lag)
        else:
            decided = "cross-correlation"
        p = float(min(1.0, 2 * min(p_sidak, p_out)))
        significant = ctx.judge(p, share, k)
        st = ctx.sampling_time
        name = ctx.input_names[j]
        evidence = {
            "statistic": "prewhitened cross-correlation of residual and input, Sidak bound over the searched lags",
            "input": name,
            "output": ctx.output_names[k],
            "lag_samples": lag,
            "lag_seconds": lag * st,
            "correlation": float(r[lag]) if lag < len(r) else None,
            "z": zmax,
            "bound_99_per_lag": Z99 * float(sd[lag]),
            "bound_family": zcrit * float(sd[lag]),
            "p_value": p,
            "p_cross_correlation": p_sidak,
            "p_out_of_sample": p_out,
            "decided_by": decided,
            "alpha": ctx.settings.alpha,
            "lags_searched": [int(memory + 1), int(ctx.max_lag)],
            "model_memory_samples": int(memory),
            "prewhitening_ar_order": order,
            "explained_share": share,
        }
        summary = (
            f"{ctx.output_names[k]} residual depends on {name} {lag} samples ({lag * st:.4g} s) back (model memory "
            f"{memory} samples): r = {r[lag]:.3f} against a bound of {zcrit * sd[lag]:.3f}; the input there explains "
            f"{100 * share:.1f} % of the residual"
            + (" out of sample" if decided == "out of sample" else "")
            + f" (p = {p:.2g})"
        )
        d = max(1, lag - 1)
        generic = delay_lines(
            ctx,
            [d],
            f"delay line at {d} samples ({d * st:.4g} s) with two more past samples where the model takes a "
            f"history: {name} at {d}..{d + 2} samples back (thesis 6.3.2)",
            history=2,
        )
        generic += delay_lines(ctx, [lag], f"delay line at {lag} samples ({lag * st:.4g} s) (thesis 6.3.2)")
        return self.finding(ctx, share, significant, summary, evidence, ctx.extensions(self.cause, evidence, generic))
