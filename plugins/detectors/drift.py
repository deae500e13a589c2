"""sensor-drift: a slow trend in the residual that the input does not explain (thesis 6.2.2).

The residual and the input are averaged over K = 60 blocks (L = n / 60 samples each), t being the
time since the recording's start. Null model for the block means: one constant per recording plus
the block means of every input, of its square and of the free run (everything the input explains at
low frequency). Alternatives add a drift term: t, 1 - exp(-t / tau), or both, tau on a grid from
1/16 to 2 times the span. Serial correlation left between blocks is removed by a Cochrane-Orcutt
transform (AR(1) coefficient of the alternative's block residuals); the drift terms are then tested
with an F-test, the smallest p-value Bonferroni-corrected for the number of alternatives. Score: the
variance of the fitted drift over the samples, as a share of the residual mean square.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from dynmodel.data.derived import time_function
from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Detector, Extension, Finding

from ._extend import inputs_patch

BLOCKS = 60
MIN_BLOCKS = 12
TAU_FRACTIONS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0)


def _ols(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    scale = np.maximum(np.abs(X).max(axis=0), 1e-300)
    coef, *_ = np.linalg.lstsq(X / scale, y, rcond=None)
    coef = coef / scale
    return coef, y - X @ coef


def _rank(X: np.ndarray) -> int:
    scale = np.maximum(np.abs(X).max(axis=0), 1e-300)
    return int(np.linalg.matrix_rank(X / scale, tol=1e-9 * np.sqrt(X.shape[0])))


def _ar1(resid: np.ndarray, seg: np.ndarray) -> float:
    same = seg[1:] == seg[:-1]
    a, b = resid[1:][same], resid[:-1][same]
    if a.size < 3 or b @ b <= 0:
        return 0.0
    return float(np.clip((a @ b) / (b @ b), 0.0, 0.95))


def _quasi_difference(M: np.ndarray, seg: np.ndarray, rho: float) -> np.ndarray:
    """Cochrane-Orcutt: rows minus rho times the previous row of the same segment (first rows dropped)."""
    same = np.flatnonzero(seg[1:] == seg[:-1]) + 1
    return M[same] - rho * M[same - 1]


def _f_test(e: np.ndarray, X0: np.ndarray, D: np.ndarray, seg: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """(F, p, rho, drift coefficients) for adding columns D to X0, with AR(1)-corrected blocks."""
    X1 = np.hstack([X0, D])
    coef, resid = _ols(X1, e)
    rho = _ar1(resid, seg)
    e_t, X0_t, X1_t = (_quasi_difference(a, seg, rho) for a in (e, X0, X1))
    _, r0 = _ols(X0_t, e_t)
    _, r1 = _ols(X1_t, e_t)
    q = _rank(X1_t) - _rank(X0_t)
    df2 = len(e_t) - _rank(X1_t)
    rss0, rss1 = float(r0 @ r0), float(r1 @ r1)
    if q <= 0 or df2 <= 0 or rss1 <= 0:
        return 0.0, 1.0, rho, coef[X0.shape[1] :]
    F = ((rss0 - rss1) / q) / (rss1 / df2)
    return F, float(stats.f.sf(F, q, df2)), rho, coef[X0.shape[1] :]


def _terms(tau: float | None, linear: bool) -> list:
    out: list = ["linear"] if linear else []
    if tau is not None:
        out.append({"saturating": float(f"{tau:.3g}")})
    return out


class SensorDrift(Detector):
    cause = "sensor-drift"
    description = "slow trend in the residual that the input does not explain (thesis 6.2.2)"
    priority = 3
    applies = "at least 12 blocks of data"

    def detect(self, ctx: Context) -> Finding | None:
        best: Finding | None = None
        for k in range(len(ctx.output_names)):
            f = self._output(ctx, k)
            if f is not None and (best is None or (f.significant, f.score) > (best.significant, best.score)):
                best = f
        return best

    def _output(self, ctx: Context, k: int) -> Finding | None:
        segs = ctx.segments
        n = ctx.n
        L = int(max(n // BLOCKS, 2))
        rows, seg_id, rec_id, times = [], [], [], []
        for i, s in enumerate(segs):
            m = s.n // L
            if m == 0:
                continue
            cut = m * L
            t = (np.arange(s.start, s.start + cut) * ctx.sampling_time).reshape(m, L)
            u = s.u[:cut].reshape(m, L, -1)
            z = [s.e[:cut, k].reshape(m, L).mean(axis=1), t.mean(axis=1)]
            z += [u[:, :, j].mean(axis=1) for j in range(u.shape[2])]
            z += [(u[:, :, j] ** 2).mean(axis=1) for j in range(u.shape[2])]
            z += [s.yhat[:cut, k].reshape(m, L).mean(axis=1)]
            rows.append(np.column_stack(z))
            seg_id += [i] * m
            rec_id += [s.recording] * m
            times.append(t)
        if not rows or sum(len(r) for r in rows) < MIN_BLOCKS:
            return None
        Z = np.vstack(rows)
        seg_id, rec_id = np.array(seg_id), np.array(rec_id)
        eb, tb, feats = Z[:, 0], Z[:, 1], Z[:, 2:]
        recs = sorted(set(rec_id.tolist()))
        consts = np.column_stack([(rec_id == r).astype(float) for r in recs])
        X0 = np.hstack([consts, feats])
        K = len(eb)
        span = float(max(s.stop for s in segs) * ctx.sampling_time)
        alternatives: list[tuple[float | None, bool]] = [(None, True)]
        for frac in TAU_FRACTIONS:
            alternatives += [(frac * span, False), (frac * span, True)]
        results = []
        for tau, linear in alternatives:
            terms = _terms(tau, linear)
            D = np.column_stack([time_function(fn, tb) for fn in terms])
            F, p, rho, coef = _f_test(eb, X0, D, seg_id)
            results.append((p, -F, tau, linear, terms, F, rho, coef))
        results.sort(key=lambda r: (r[0], r[1]))
        p, _, tau, linear, terms, F, rho, coef = results[0]
        p_adj = min(1.0, p * len(alternatives))
        # the fitted drift over every sample, centred per recording, against the residual's energy
        drift_parts, e_parts = [], []
        for s in segs:
            t = np.arange(s.start, s.stop) * ctx.sampling_time
            dr = sum(c * time_function(fn, t) for c, fn in zip(coef, terms))
            drift_parts.append(dr)
            e_parts.append(s.e[:, k])
        drift, e = np.concatenate(drift_parts), np.concatenate(e_parts)
        rec_all = np.concatenate([[s.recording] * s.n for s in segs])
        for r in recs:
            mask = rec_all == r
            drift[mask] -= drift[mask].mean()
        ec = e - e.mean()
        share = float(min(1.0, (drift @ drift) / max(ec @ ec, np.finfo(float).tiny)))
        _, r_null = _ols(consts, eb)
        _, r_in = _ols(X0, eb)
        input_share = float(1 - (r_in @ r_in) / max(r_null @ r_null, np.finfo(float).tiny))
        significant = ctx.judge(p_adj, share, k)
        t0 = float(min(s.start for s in segs) * ctx.sampling_time)
        t_end = float(max(s.stop for s in segs) * ctx.sampling_time)
        change = float(
            sum(
                c * (time_function(fn, np.array([t_end])) - time_function(fn, np.array([t0])))[0]
                for c, fn in zip(coef, terms)
            )
        )
        evidence = {
            "statistic": "F-test of drift terms on block means beyond the input (AR(1)-corrected, Bonferroni over "
            f"{len(alternatives)} drift shapes)",
            "output": ctx.output_names[k],
            "F": F,
            "p_value": p_adj,
            "alpha": ctx.settings.alpha,
            "terms": terms,
            "tau_seconds": tau,
            "coefficients": [float(c) for c in coef],
            "drift_change": change,
            "drift_share": share,
            "input_explained_share": input_share,
            "blocks": K,
            "block_length": L,
            "block_ar1": rho,
            "window": [t0, t_end],
        }
        shape = " + ".join("c t" if fn == "linear" else f"c (1 - exp(-t / {fn['saturating']:g} s))" for fn in terms)
        summary = (
            f"{ctx.output_names[k]}: a drift {shape} changes the residual by {change:.4g} over "
            f"[{t0:.4g}, {t_end:.4g}] s, {100 * share:.1f} % of its mean square (F = {F:.3g}, p = {p_adj:.2g}); "
            f"the input explains {100 * max(input_share, 0):.0f} % of the slow residual"
        )
        derived = [{"time": fn} for fn in terms]
        extensions = [
            Extension(
                f"a drift term in the output model: time inputs {', '.join(_name(fn) for fn in terms)}",
                inputs_patch(ctx, derived=derived, history=0),
            ),
            Extension(
                f"detrend the output by {', '.join(_name(fn) for fn in terms)} (fitted on the training data, "
                "added back to predictions)",
                {"data": {"detrend": terms}},
            ),
        ]
        extensions = [x for x in extensions if x.patch]
        return self.finding(
            ctx, share, significant, summary, evidence, ctx.extensions(self.cause, evidence, extensions)
        )


def _name(fn) -> str:
    return "t" if fn == "linear" else f"1 - exp(-t / {fn['saturating']:g} s)"
