"""Auto- and cross-correlation of residuals, pooled over segments, with bounds that respect autocorrelation.

Segments are contiguous stretches of one recording; products never pair samples of different
segments. Prewhitening (Box-Jenkins): an AR(p) filter fitted to the input (order by AIC) is applied
to both series, so the filtered input is close to white and the cross-correlation at each lag has
variance about 1/n_k (n_k the number of pairs at lag k); the remaining autocorrelation of both
filtered series enters through Bartlett's formula var(r_ab(k)) = (1/n_k) sum_h r_aa(h) r_bb(h).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg, stats


def _fft_len(n: int) -> int:
    return 1 << int(np.ceil(np.log2(max(2 * n, 2))))


def _centred(segments: list[np.ndarray]) -> list[np.ndarray]:
    mean = np.concatenate(segments).mean() if segments else 0.0
    return [np.asarray(s, dtype=np.float64) - mean for s in segments]


def cross_sums(
    a_segments: list[np.ndarray], b_segments: list[np.ndarray], max_lag: int
) -> tuple[np.ndarray, np.ndarray]:
    """Sums S(k) = sum_t a_t b_{t-k} for k = 0..max_lag within every segment, and the pair counts."""
    sums = np.zeros(max_lag + 1)
    counts = np.zeros(max_lag + 1)
    for a, b in zip(a_segments, b_segments):
        n = len(a)
        if n == 0:
            continue
        m = _fft_len(n)
        full = np.fft.irfft(np.fft.rfft(a, m) * np.conj(np.fft.rfft(b, m)), m)
        k = min(max_lag, n - 1)
        sums[: k + 1] += full[: k + 1]
        counts[: k + 1] += n - np.arange(k + 1)
    return sums, counts


def crosscorr(a_segments: list[np.ndarray], b_segments: list[np.ndarray], max_lag: int) -> np.ndarray:
    """r_ab(k) = corr(a_t, b_{t-k}), k = 0..max_lag (pooled; NaN where no pair exists)."""
    a_c, b_c = _centred(a_segments), _centred(b_segments)
    sa = np.sqrt(sum(float(x @ x) for x in a_c) / max(sum(len(x) for x in a_c), 1))
    sb = np.sqrt(sum(float(x @ x) for x in b_c) / max(sum(len(x) for x in b_c), 1))
    sums, counts = cross_sums(a_c, b_c, max_lag)
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts / max(sa * sb, np.finfo(float).tiny)


def autocorr(segments: list[np.ndarray], max_lag: int) -> np.ndarray:
    """r(k), k = 0..max_lag, pooled over segments."""
    return crosscorr(segments, segments, max_lag)


def integrated_time(segments: list[np.ndarray], max_lag: int = 2000) -> float:
    """Integrated autocorrelation time tau = 1 + 2 sum_k r(k), summed until r first drops below zero."""
    n = sum(len(s) for s in segments)
    r = autocorr(segments, min(max_lag, max(n // 4, 1)))
    r = np.nan_to_num(r[1:])
    stop = np.flatnonzero(r <= 0)
    r = r[: stop[0]] if stop.size else r
    return float(1.0 + 2.0 * r.sum())


def ar_coefficients(segments: list[np.ndarray], max_order: int = 30) -> np.ndarray:
    """AR coefficients phi (x_t = sum_i phi_i x_{t-i} + w_t) by Yule-Walker, order by AIC."""
    n = sum(len(s) for s in segments)
    max_order = int(min(max_order, max(n // 20, 0)))
    if max_order == 0:
        return np.zeros(0)
    r = np.nan_to_num(autocorr(segments, max_order))
    best, best_aic = np.zeros(0), 0.0  # order 0: innovation variance 1 (normalised), log 1 = 0
    for p in range(1, max_order + 1):
        try:
            phi = linalg.solve_toeplitz(r[:p], r[1 : p + 1])
        except (linalg.LinAlgError, ValueError):
            break
        sigma2 = 1.0 - float(phi @ r[1 : p + 1])
        if not np.isfinite(sigma2) or sigma2 <= 1e-12:
            break
        aic = n * np.log(sigma2) + 2 * p
        if aic < best_aic:
            best, best_aic = phi, aic
    return best


def ar_filter(segments: list[np.ndarray], phi: np.ndarray) -> list[np.ndarray]:
    """w_t = x_t - sum_i phi_i x_{t-i} within every segment (the first len(phi) samples dropped)."""
    p = len(phi)
    out = []
    for s in segments:
        s = np.asarray(s, dtype=np.float64)
        if len(s) <= p:
            out.append(np.zeros(0))
            continue
        w = s[p:].copy()
        for i, c in enumerate(phi, start=1):
            w -= c * s[p - i : len(s) - i]
        out.append(w)
    return out


def bartlett_sd(
    a_segments: list[np.ndarray], b_segments: list[np.ndarray], max_lag: int, horizon: int = 50
) -> np.ndarray:
    """Standard deviations (k = 0..max_lag) of cross-correlation estimates of two independent series:
    sqrt((1/n_k) sum_{|h| <= H} r_aa(h) r_bb(h)), the sum never below 1."""
    n = sum(len(s) for s in a_segments)
    h = int(min(horizon, max(n // 10, 1)))
    ra, rb = np.nan_to_num(autocorr(a_segments, h)), np.nan_to_num(autocorr(b_segments, h))
    s = max(1.0 + 2.0 * float(np.sum(ra[1:] * rb[1:])), 1.0)
    _, counts = cross_sums([np.zeros(len(x)) for x in a_segments], [np.zeros(len(x)) for x in b_segments], max_lag)
    return np.sqrt(s / np.maximum(counts, 1.0))


def sidak_z(alpha: float, m: int) -> float:
    """Two-sided normal quantile whose family-wise level over m tests is alpha (Sidak)."""
    per = 1.0 - (1.0 - alpha) ** (1.0 / max(m, 1))
    return float(stats.norm.isf(per / 2.0))
