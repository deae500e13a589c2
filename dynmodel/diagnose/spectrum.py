"""Spectral peaks of a residual: Welch spectrum, a running-median background and a chi-square test.

A Welch estimate P(f) with K half-overlapping Hann segments scatters around the true spectrum S(f)
as S(f) chi2_nu / nu, nu = 2 K / (1 + 2 c^2) with c = 0.167 the overlap correlation of Hann windows
at 50 % (Welch 1967). The background B(f) at bin k is the larger of two one-sided medians, of bins
k-14..k-3 and of bins k+3..k+14 (the main lobe of a peak, +-2 bins, is left out), divided by the
chi2_nu median (median bias): a peak must stand above both of its sides, so a knee or a broad bump
of a smooth spectrum is not taken for one. Under a smooth spectrum P(f) / B(f) is at most an F law:
chi2_nu / nu over the scatter of one side's median, whose degrees of freedom are those of its 12
bins (adjacent Hann bins are correlated, so half of them count) times the efficiency of a median (2
/ pi); taking the larger side makes the test conservative. The largest ratio over m bins is
significant at level alpha when its F tail is below alpha / m (Bonferroni). The peak frequency is
then refined on a spectrum with four times the resolution (longer Welch segments, within 1.5 coarse
bins of the peak) by a parabola through log P at its maximum and the two neighbouring bins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal, stats

HANN_OVERLAP_CORRELATION = 0.167


@dataclass
class Spectrum:
    freq: np.ndarray  # cycles per sample
    power: np.ndarray
    background: np.ndarray
    dof: float
    background_dof: float

    @property
    def testable(self) -> np.ndarray:
        return np.isfinite(self.background)

    def ratio(self) -> np.ndarray:
        """P / B, 0 where the bin is not testable."""
        with np.errstate(invalid="ignore"):
            r = self.power / np.maximum(self.background, np.finfo(float).tiny)
        return np.where(self.testable, r, 0.0)

    def p_values(self) -> np.ndarray:
        return np.where(self.testable, stats.f.sf(self.ratio(), self.dof, self.background_dof), 1.0)


GAP = 2  # bins left out on each side of the tested bin (the Hann main lobe)


def background(power: np.ndarray, width: int) -> np.ndarray:
    """max(median of P[k-GAP-width : k-GAP], median of P[k+GAP+1 : k+GAP+1+width]) per bin; NaN (not
    testable) where either side has fewer than width / 3 bins, i.e. next to 0 and to the Nyquist
    frequency."""
    n = len(power)
    out = np.full(n, np.nan)
    need = max(1, width // 3)
    for k in range(n):
        left = power[max(0, k - GAP - width) : max(0, k - GAP)]
        right = power[min(n, k + GAP + 1) : min(n, k + GAP + 1 + width)]
        if len(left) >= need and len(right) >= need:
            out[k] = max(np.median(left), np.median(right))
    return out


def welch(segments: list[np.ndarray], nperseg: int | None = None, width: int = 12) -> Spectrum | None:
    """Pooled Welch spectrum of the segments long enough for ``nperseg`` (default: a power of two
    near n / 16, between 64 and 2048), with its running-median background."""
    n = sum(len(s) for s in segments)
    if nperseg is None:
        nperseg = int(2 ** np.clip(np.round(np.log2(max(n, 1) / 16)), 6, 11))
    usable = [np.asarray(s, dtype=np.float64) for s in segments if len(s) >= nperseg]
    if not usable:
        return None
    total: np.ndarray | None = None
    freq: np.ndarray | None = None
    count = 0
    for s in usable:
        f, p = signal.welch(
            s - s.mean(),
            fs=1.0,
            window="hann",
            nperseg=nperseg,
            noverlap=nperseg // 2,
            detrend="constant",
            scaling="density",
            average="mean",
        )
        k = 1 + (len(s) - nperseg) // (nperseg // 2)
        total = p * k if total is None else total + p * k
        count += k
        freq = f
    assert total is not None and freq is not None  # usable is not empty
    power = total / count
    dof = 2.0 * count / (1.0 + 2.0 * HANN_OVERLAP_CORRELATION**2)
    back = background(power, width) / (stats.chi2.median(dof) / dof)
    return Spectrum(freq, power, back, dof, dof * width / 2 * (2 / np.pi))


def _parabola(freq: np.ndarray, power: np.ndarray, k: int) -> float:
    if k <= 0 or k >= len(freq) - 1:
        return float(freq[k])
    a, b, c = np.log(np.maximum(power[k - 1 : k + 2], np.finfo(float).tiny))
    den = a - 2 * b + c
    delta = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(freq[k] + np.clip(delta, -0.5, 0.5) * (freq[1] - freq[0]))


def refine_peak(spec: Spectrum, k: int, segments: list[np.ndarray] | None = None) -> float:
    """Peak frequency near bin k: from a 4x finer Welch spectrum of ``segments`` when they are long
    enough, else from a parabola through log P at bins k - 1, k, k + 1 of ``spec``."""
    step = spec.freq[1] - spec.freq[0]
    nperseg = int(round(1.0 / step)) * 4
    if segments:
        usable = [s for s in segments if len(s) >= nperseg]
        if usable:
            fine = welch(usable, nperseg)
            if fine is not None:
                window = np.flatnonzero(np.abs(fine.freq - spec.freq[k]) <= 1.5 * step)
                j = int(window[np.argmax(fine.power[window])])
                return _parabola(fine.freq, fine.power, j)
    return _parabola(spec.freq, spec.power, k)
