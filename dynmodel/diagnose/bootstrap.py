"""Uncertainty of an NMSE comparison: paired circular block bootstrap and a batch-means test.

Both resample or average contiguous blocks, so the serial correlation of free-run errors is kept
(an i.i.d. bootstrap would understate the spread by the integrated autocorrelation time).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .correlation import integrated_time


def block_length(e: np.ndarray) -> int:
    """Twice the integrated autocorrelation time of e, at least n^(1/3), at most n / 10."""
    n = len(e)
    tau = integrated_time([np.asarray(e, dtype=np.float64)], max_lag=min(2000, n // 4))
    return int(np.clip(np.ceil(2 * tau), np.ceil(n ** (1 / 3)), max(n // 10, 1)))


def paired_nmse(
    y: np.ndarray, before: np.ndarray, after: np.ndarray, rng: np.random.Generator, resamples: int = 500
) -> dict:
    """Circular block bootstrap of test NMSE before / after (same blocks for both) and of the
    relative reduction 1 - NMSE_after / NMSE_before; mean, std and 95 % percentile interval."""
    y, e1, e2 = (np.asarray(a, dtype=np.float64).ravel() for a in (y, before, after))
    n = len(y)
    L = block_length(e1)
    k = int(np.ceil(n / L))
    starts = rng.integers(0, n, size=(resamples, k))
    idx = (starts[:, :, None] + np.arange(L)[None, None, :]).reshape(resamples, -1)[:, :n] % n
    var = y[idx].var(axis=1)
    n1 = 100 * (e1[idx] ** 2).mean(axis=1) / var
    n2 = 100 * (e2[idx] ** 2).mean(axis=1) / var
    red = 1 - n2 / n1

    def summary(x: np.ndarray) -> dict:
        return {
            "mean": float(x.mean()),
            "std": float(x.std(ddof=1)),
            "interval_95": [float(np.quantile(x, 0.025)), float(np.quantile(x, 0.975))],
        }

    return {
        "method": "circular block bootstrap of the test residuals",
        "block_length": L,
        "resamples": resamples,
        "test_nmse_before": summary(n1),
        "test_nmse_after": summary(n2),
        "relative_reduction": summary(red),
    }


MIN_BATCHES, MAX_BATCHES = 10, 40


def batch_count(d: np.ndarray) -> int:
    """Contiguous batches at least three integrated autocorrelation times of d long, 10 to 40 of them."""
    n = len(d)
    tau = integrated_time([np.asarray(d, dtype=np.float64)], max_lag=min(2000, max(n // 4, 1)))
    length = max(5, int(np.ceil(3 * tau)))
    return int(np.clip(n // length, MIN_BATCHES, MAX_BATCHES)) if n >= 2 * MIN_BATCHES else max(2, n // 2)


def batch_means_test(d: np.ndarray, batches: int | None = None) -> tuple[float, float, int]:
    """One-sided test that d is positive: Wilcoxon's signed-rank test on the means of contiguous batches
    (about independent when batches are long against d's autocorrelation; the rank test is robust to
    the skew of squared errors). Returns (mean of the batch means / their standard error, p, batches)."""
    d = np.asarray(d, dtype=np.float64)
    k = int(batches or batch_count(d))
    means = np.array([b.mean() for b in np.array_split(d, k)])
    sd = means.std(ddof=1)
    z = float(means.mean() / (sd / np.sqrt(k))) if sd > 0 else (np.inf if means.mean() > 0 else 0.0)
    if np.all(means == 0):
        return 0.0, 1.0, k
    p = float(stats.wilcoxon(means, alternative="greater", zero_method="zsplit").pvalue)
    return z, p, k
