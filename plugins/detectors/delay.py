"""missing-delay: the residual is correlated with an input at a lag beyond the model's memory.

Both the input and the residual are prewhitened by the input's AR filter (order by AIC), so the
cross-correlation r(k) = corr(e_t, u_{t-k}) of independent series has standard deviation s
(Bartlett's formula, about 1/sqrt(n_k) with n_k pairs at lag k). Lags from the model's memory M + 1
(the largest lag at which an input impulse still moves the model's output by 1 %) up to the search
horizon are scanned; the largest |r(k)| / s is significant when it beats the Sidak bound for that
many lags at level alpha (per lag, the 99 % bound is 2.576 s). Score: the share of the residual's
mean square that the raw input at lags k-2 .. k+2 explains beyond the input at the lags the model
already sees (and beyond a drift: two slow functions of time).

A model with output feedback remembers long (its memory counts every sample an input impulse still moves the
output), so a dead time inside that memory went unscanned: a plant that acts 25 samples after its input, modeled
by a NARX default on input lags 0..6 with feedback (memory 124 samples), was named "inadequate-structure" and
extended by more lags to no gain. So the window of 5 lags around an input's dead time read from the data
(:func:`dynmodel.data.delay.dead_times`, on the measured segments) is scanned too, counted in the Sidak bound,
when the model's own impulse response reaches 10 % of its peak at least 3 samples before that dead time (it acts
before the system does); the share is then taken beyond the input at lags below the window.

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

from dynmodel.data.delay import MIN_DELAY, dead_times
from dynmodel.diagnose.context import Context
from dynmodel.diagnose.correlation import ar_coefficients, ar_filter, bartlett_sd, crosscorr, sidak_z
from dynmodel.diagnose.dependence import holdout_share, lagged, partial_share
from dynmodel.diagnose.detector import Detector, Finding
from dynmodel.diagnose.memory import impulse_response

from ._extend import delay_lines

Z99 = float(stats.norm.isf(0.005))
MIN_LAGS = 10
#: the model acts on an input from the first lag where its impulse response reaches this share of its peak
ONSET = 0.1
#: lags scanned on either side of a dead time the model does not reproduce
HALF_WINDOW = 2


def unmatched_dead_times(ctx: Context) -> dict[int, int]:
    """{input index: dead time} for each input whose dead time in the data (:func:`dead_times` on the measured
    segments) the model does not reproduce: its impulse response reaches :data:`ONSET` of its peak at least
    MIN_DELAY samples earlier."""
    found = dead_times([s.u for s in ctx.segments], [s.y for s in ctx.segments], ctx.input_names)
    out: dict[int, int] = {}
    for j, name in enumerate(ctx.input_names):
        d = found.get(name)
        if d is None:
            continue
        response = impulse_response(ctx.fit, j, max(2 * d, 20))
        if response is None or not response.max() > 0:
            continue
        onset = int(np.flatnonzero(response >= ONSET * response.max())[0])
        if onset <= d - MIN_DELAY:
            out[j] = d
    return out


def _scanned(first: int, max_lag: int, dead: int | None) -> np.ndarray:
    """The lags searched: ``first`` .. ``max_lag`` (beyond the memory), and around a dead time the model does not
    reproduce."""
    lags = set(range(first, max_lag + 1))
    if dead is not None:
        lags |= set(range(max(1, dead - HALF_WINDOW), min(dead + HALF_WINDOW, max_lag) + 1))
    return np.array(sorted(lags), dtype=int)


def _fit_parts(ctx: Context, series: list[np.ndarray]) -> list[np.ndarray]:
    """The training (non-check) stretches of per-segment series, each contiguous."""
    out = []
    for s, x in zip(ctx.segments, series):
        fit = ~s.check
        edges = np.flatnonzero(np.diff(np.r_[0, fit.astype(int), 0]))
        out += [x[a:b] for a, b in zip(edges[::2], edges[1::2]) if b - a > 0]
    return out


def _locate(ctx: Context, first: int, max_lag: int, parts, dead: dict[int, int]):
    """(z, input, output, lag, r, sd, AR order, lags searched) of the largest prewhitened cross-correlation
    beyond the memory (or around a dead time of ``dead``), on the stretches ``parts`` makes of the segments;
    None when too short."""
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
            lags = _scanned(first, max_lag, dead.get(j))
            if lags.size == 0:
                continue
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
    applies = (
        "the model's memory must leave at least 10 lags of the search horizon, or the data show a dead time the "
        "model does not reproduce"
    )

    def detect(self, ctx: Context) -> Finding | None:
        memory = ctx.memory
        max_lag = ctx.max_lag
        dead = unmatched_dead_times(ctx)
        # beyond the memory unless the model remembers (nearly) the whole search horizon
        first = memory + 1 if max_lag - memory >= MIN_LAGS else max_lag + 1
        if first > max_lag and not dead:
            return None
        best = _locate(ctx, first, max_lag, lambda x: x, dead)
        if best is None:
            return None
        zmax, j, k, lag, r, sd, order, m = best
        p_lag = 2 * stats.norm.sf(zmax)
        p_sidak = float(-np.expm1(m * np.log1p(-min(p_lag, 1 - 1e-16)))) if p_lag > 0 else 0.0
        zcrit = sidak_z(ctx.settings.alpha / 2, m)

        def design(j: int, k: int, lag: int):
            top = memory if lag >= first else max(lag - HALF_WINDOW - 1, 0)  # the lags the model already sees
            short = sorted(set(np.linspace(0, top, num=min(top + 1, 12)).round().astype(int).tolist()))
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
        fit_best = _locate(ctx, first, max_lag, lambda x: _fit_parts(ctx, x), dead)
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
            "lags_searched": [int(first), int(max_lag)] if first <= max_lag else [],
            "dead_time_windows": {
                ctx.input_names[i]: [max(1, d - HALF_WINDOW), d + HALF_WINDOW] for i, d in dead.items()
            },
            "model_memory_samples": int(memory),
            "prewhitening_ar_order": order,
            "explained_share": share,
        }
        where = (
            f"model memory {memory} samples"
            if lag >= first
            else f"the dead time the data show is {dead.get(j)} samples, and the model acts on {name} earlier"
        )
        summary = (
            f"{ctx.output_names[k]} residual depends on {name} {lag} samples ({lag * st:.4g} s) back ({where}): "
            f"r = {r[lag]:.3f} against a bound of {zcrit * sd[lag]:.3f}; the input there explains "
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
