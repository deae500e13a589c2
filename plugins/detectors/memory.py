"""insufficient-memory: the residual depends on input history older than the model's memory.

Test features: exponential moving averages of the input, m_t = (1 - 1/tau) m_{t-1} + u_t / tau, with
tau = 2, 4, 8, ... times the model's memory M (M at least 2 samples; tau at most a twentieth of the
longest segment, at most 8 values); base features: the input at up to 12 lags spread over 0 .. M
(what the model already sees) and two slow functions of time (a drift is not input history).
History slower than about a twentieth of the record looks like a trend and is, honestly, hard to
tell from one. Statistic: the out-of-sample incremental R^2 (fit on train, judged on validation)
with its batch-means p-value (:mod:`dynmodel.diagnose.dependence`). Score: that share of the
residual mean square. The evidence names the time constant that explains most on its own beyond the
short lags (a fine logarithmic grid over the same range).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.dependence import holdout_share, lagged, partial_share
from dynmodel.diagnose.detector import Detector, Finding

from ._extend import delay_lines

MAX_AVERAGES = 8


def moving_averages(u_segs: list[np.ndarray], taus: list[float]) -> np.ndarray:
    cols = []
    for u in u_segs:
        u = np.asarray(u, dtype=np.float64)
        seg = []
        for tau in taus:
            a = 1.0 / tau
            # start in the steady state of the first stretch's mean (a single noisy first sample would leave a
            # transient as slow as the average itself)
            zi = signal.lfilter_zi([a], [1.0, -(1.0 - a)]) * u[: max(1, int(2 * tau))].mean()
            seg.append(signal.lfilter([a], [1.0, -(1.0 - a)], u, zi=zi)[0])
        cols.append(np.column_stack(seg))
    return np.vstack(cols)


class InsufficientMemory(Detector):
    cause = "insufficient-memory"
    description = "residual depends on input history older than the model's memory"
    priority = 8
    applies = "records longer than 40 x the model's memory"

    def detect(self, ctx: Context) -> Finding | None:
        memory = ctx.memory
        m = max(memory, 2)
        longest = max(s.n for s in ctx.segments)
        taus = [float(2**i * m) for i in range(1, MAX_AVERAGES + 1) if 2**i * m <= longest / 20]
        if not taus:
            return None
        short = sorted(set(np.linspace(0, memory, num=min(memory + 1, 12)).round().astype(int).tolist()))
        best = None
        check = ctx.check_rows()
        for j in range(len(ctx.input_names)):
            u_segs = ctx.inputs(j)
            base = np.hstack([np.vstack(lagged(u_segs, short)), ctx.trend_features()])
            F = moving_averages(u_segs, taus)
            for k in range(len(ctx.output_names)):
                e = np.concatenate(ctx.residuals(k))
                dep = holdout_share(e, base, F, check)
                if best is None or dep.share > best[0].share:
                    best = (dep, j, k, base, F, e)
        dep, j, k, base, F, e = best
        grid = np.geomspace(taus[0], taus[-1], num=max(2, 6 * len(taus)))
        lags_only = base[:, :-2]  # without the trend terms, which would soak up the slowest averages
        singles = [partial_share(e, lags_only, moving_averages(ctx.inputs(j), [float(t)])) for t in grid]
        tau = float(grid[int(np.argmax(singles))])
        name = ctx.input_names[j]
        st = ctx.sampling_time
        significant = ctx.judge(dep.p_value, dep.share, k)
        evidence = {
            "statistic": "partial R^2 of exponential moving averages of the input beyond the lags within the model's "
            "memory, out of sample (fit on train, judged on validation)",
            "input": name,
            "output": ctx.output_names[k],
            **dep.to_json(),
            "alpha": ctx.settings.alpha,
            "model_memory_samples": int(memory),
            "time_constants_samples": taus,
            "best_time_constant_samples": tau,
            "best_time_constant_seconds": tau * st,
        }
        summary = (
            f"{ctx.output_names[k]} residual depends on {name} averaged over about {tau:.0f} samples "
            f"({tau * st:.4g} s), beyond the model's memory of {memory} samples: {100 * dep.share:.1f} % of "
            f"its mean square (p = {dep.p_value:.2g})"
        )
        t = int(round(tau))
        delays = sorted({max(1, t), max(2, 2 * t)})
        generic = delay_lines(
            ctx,
            delays,
            f"delay lines at {delays} samples ({', '.join(f'{d * st:.4g}' for d in delays)} s): external memory of "
            "the input (thesis 6.3.2)",
        )
        extensions = ctx.extensions(self.cause, evidence)
        return self.finding(ctx, dep.share, significant, summary, evidence, extensions[:1] + generic + extensions[1:])
