"""unmodeled-oscillation: a spectral peak in the residual that is not a line of the input.

Welch spectrum of the residual against a background that must lie below the peak on both sides
(:mod:`dynmodel.diagnose.spectrum`): the largest ratio is significant when its F tail,
Bonferroni-corrected over the tested bins, is below alpha. Bins next to 0 and to the Nyquist
frequency (one-sided background) are not tested, nor bins within two bins of the three strongest
lines of each input (periodogram peaks above 20 times its median) or of their harmonics up to the
10th: a residual at a driving frequency or its harmonics (hysteresis, clipping) is a misfit of the
response to that drive, not an oscillation of its own. The frequency is refined on a four times
finer spectrum (:func:`dynmodel.diagnose.spectrum.refine_peak`). Not named when the model's own free-run
output peaks at the same frequency (its spectrum at least ``OWN_PEAK`` times its background within two
bins): the model produces that oscillation, mistuned (a wrong stiffness, as in a Duffing oscillator fitted
by a polynomial without the cubic term), which is not a missing mode. Score: the power above the
background within +-4 bins of the peak (integrated over frequency), as a share of the residual's
mean square.
"""

from __future__ import annotations

import numpy as np

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Detector, Finding
from dynmodel.diagnose.spectrum import Spectrum, refine_peak, welch

from ._extend import delay_lines

BAND = 4
HARMONICS = 10
LINES = 3
LINE_RATIO = 20.0
OWN_PEAK = 4.0  # the model's own output this many times above its background at the peak: its own mode


def input_lines(ctx: Context) -> list[float]:
    """Frequencies (cycles per sample) of the strongest lines of every input: local maxima of the
    periodogram of its longest segment that exceed 20 times the periodogram's median."""
    lines = []
    for j in range(len(ctx.input_names)):
        u = max(ctx.inputs(j), key=len)
        power = np.abs(np.fft.rfft(u - u.mean())) ** 2
        freq = np.fft.rfftfreq(len(u))
        peak = (power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:]) & (power[1:-1] > LINE_RATIO * np.median(power))
        idx = np.flatnonzero(peak) + 1
        lines += [float(freq[i]) for i in idx[np.argsort(power[idx])[::-1][:LINES]]]
    return lines


def _excluded(spec: Spectrum, lines: list[float]) -> np.ndarray:
    step = spec.freq[1] - spec.freq[0]
    mask = ~spec.testable
    for f in lines:
        for h in range(1, HARMONICS + 1):
            mask |= np.abs(spec.freq - h * f) <= 2 * step + 1e-12
    return mask


def _own_peak(ctx: Context, k: int, spec: Spectrum, i: int) -> float:
    """The largest ratio of the model's free-run output spectrum to its background within 2 bins of bin i
    (same Welch segments as the residual's)."""
    nperseg = int(round(1.0 / (spec.freq[1] - spec.freq[0])))
    own = welch([s.yhat[:, k] for s in ctx.segments], nperseg)
    if own is None or not np.isfinite(np.concatenate([s.yhat[:, k] for s in ctx.segments])).all():
        return 0.0
    lo, hi = max(i - 2, 0), min(i + 3, len(own.freq))
    return float(np.max(own.ratio()[lo:hi]))


class UnmodeledOscillation(Detector):
    cause = "unmodeled-oscillation"
    description = "a spectral peak in the residual (an oscillation the model does not produce)"
    priority = 5
    applies = "records of at least 64 samples"

    def detect(self, ctx: Context) -> Finding | None:
        lines = input_lines(ctx)
        best = None
        for k in range(len(ctx.output_names)):
            e_segs = ctx.residuals(k)
            spec = welch(e_segs)
            if spec is None:
                continue
            excluded = _excluded(spec, lines)
            ratio = np.where(excluded, 0.0, spec.ratio())
            i = int(np.argmax(ratio))
            m = int((~excluded).sum())
            p = float(min(1.0, spec.p_values()[i] * m))
            lo, hi = max(i - BAND, 0), min(i + BAND + 1, len(spec.freq))
            excess = np.nansum(np.maximum(spec.power[lo:hi] - spec.background[lo:hi], 0.0)) * (
                spec.freq[1] - spec.freq[0]
            )
            e = np.concatenate(e_segs)
            share = float(min(1.0, excess / max(float(np.var(e)), np.finfo(float).tiny)))
            cand = (share, p, k, i, spec, m, e_segs)
            if best is None or (p, -share) < (best[1], -best[0]):
                best = cand
        if best is None:
            return None
        share, p, k, i, spec, m, e_segs = best
        f = refine_peak(spec, i, e_segs)
        st = ctx.sampling_time
        period = 1.0 / f if f > 0 else float("inf")
        own = _own_peak(ctx, k, spec, i)
        significant = ctx.judge(
            p,
            share,
            k,
            {
                "not_the_models_own_mode": (
                    own < OWN_PEAK,
                    f"the model's output peaks there too ({own:.3g} x its background): a mistuned mode",
                )
            },
        )
        evidence = {
            "statistic": "Welch spectrum of the residual over its running-median background, chi-square test "
            f"(Bonferroni over {m} bins)",
            "output": ctx.output_names[k],
            "frequency_cycles_per_sample": f,
            "frequency_hz": f / st,
            "period_samples": period,
            "period_seconds": period * st,
            "peak_to_background": float(spec.ratio()[i]),
            "model_output_peak_to_background": own,
            "p_value": p,
            "alpha": ctx.settings.alpha,
            "dof": spec.dof,
            "band_share": share,
            "resolution_cycles_per_sample": float(spec.freq[1] - spec.freq[0]),
            "input_lines_excluded": sorted(set(round(x, 6) for x in lines))[:20],
        }
        summary = (
            f"{ctx.output_names[k]} residual has a spectral peak at {f / st:.4g} Hz (period {period:.3g} "
            f"samples), {spec.ratio()[i]:.3g} x its background (p = {p:.2g}), {100 * share:.1f} % of its power"
        )
        short = sorted({max(1, round(period / 4)), max(1, round(period / 2))}) if np.isfinite(period) else []
        generic = delay_lines(
            ctx,
            short,
            f"short-delay inputs: delay lines at {short} samples (a quarter and half of the {period:.3g}-sample period)",
        )
        extensions = ctx.extensions(self.cause, evidence)
        return self.finding(ctx, share, significant, summary, evidence, extensions[:1] + generic + extensions[1:])
