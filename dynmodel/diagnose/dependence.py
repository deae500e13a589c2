"""Does the residual depend on a set of features of the input? An out-of-sample test.

Two least-squares predictors of the residual e are fitted on the *fit* rows (the training split):
the base features B (an intercept is always among them) and B plus the test features F. On the
held-out *check* rows (the validation split) both predict e, with errors r0 and r1. Statistic: the
out-of-sample share of the base predictor's error that F removes,

    share = 1 - sum r1^2 / sum r0^2      (check rows; at most 1, negative when F only adds noise),

and a one-sided signed-rank test on contiguous batch means of d_t = r0_t^2 - r1_t^2 (valid under the
strong serial correlation of free-run residuals, see :func:`.bootstrap.batch_means_test`). Fitting
and judging on different samples protects against the spurious fits of slow features to slow
residuals, and unlike a test that shifts or permutes the residual it stays valid, and keeps its
power, for periodic experiments (a relation learnt on some strokes must predict the next ones).
Features that add nothing make r1 slightly worse than r0 out of sample. Measured on a true null
(white residual, slow features of an independent input) the p-value falls below 0.001 in about 1 %
of the runs: the detectors' effect-size floors, not alpha alone, keep false alarms rare (see the
README's calibration). (Fitting on the validation split and judging on the training split as a
second fold was tried and dropped: time terms fitted on the short split extrapolate badly and fake
large shares.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import qr

from .bootstrap import batch_means_test


@dataclass
class Dependence:
    share: float  # out-of-sample share of the base predictor's error (check rows) that the features remove
    p_value: float
    t: float  # mean of the batch means of d over its standard error
    batches: int
    in_sample_share: float  # partial R^2 on the fit rows
    fit_rows: int
    check_rows: int
    coef: np.ndarray  # coefficients of the test features (fit rows, beyond the base)

    def to_json(self) -> dict:
        return {
            "share": self.share,
            "p_value": self.p_value,
            "t": self.t,
            "batches": self.batches,
            "in_sample_share": self.in_sample_share,
            "fit_rows": self.fit_rows,
            "check_rows": self.check_rows,
        }


def _design(base: np.ndarray | None, n: int) -> np.ndarray:
    return np.column_stack([np.ones(n), base]) if base is not None and base.size else np.ones((n, 1))


def _lstsq(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    scale = np.maximum(np.abs(X).max(axis=0), 1e-300)
    coef, *_ = np.linalg.lstsq(X / scale, y, rcond=1e-10)
    return coef / scale


def partial_share(e: np.ndarray, base: np.ndarray | None, features: np.ndarray) -> float:
    """In-sample partial R^2: the share of e's energy that ``features`` explain beyond ``base`` (+ intercept)."""
    e = np.asarray(e, dtype=np.float64)
    n = len(e)
    B = _design(base, n)
    Q0 = _basis(B)
    F = features - Q0 @ (Q0.T @ features)
    # columns the base already spans (up to rounding) carry no new information
    kept = np.sqrt((F**2).sum(axis=0)) > 1e-8 * np.maximum(np.sqrt((features**2).sum(axis=0)), 1e-300)
    Q1 = _basis(F[:, kept], 1e-7)
    ec = e - e.mean()
    total = float(ec @ ec)
    if Q1.shape[1] == 0 or total <= 0:
        return 0.0
    proj = Q1.T @ e
    return float(proj @ proj) / total


def _basis(X: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    if X.shape[1] == 0:
        return X
    scale = np.maximum(np.sqrt((X**2).sum(axis=0)), 1e-300)
    q, r, _ = qr(X / scale, mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    return q[:, d > tol * max(d.max(), 1e-300)]


def holdout_share(e: np.ndarray, base: np.ndarray | None, features: np.ndarray, check: np.ndarray) -> Dependence:
    """Out-of-sample incremental share of ``features`` for ``e`` beyond ``base``, fitted where ``check`` is
    False and judged where it is True, with its batch-means p-value."""
    e = np.asarray(e, dtype=np.float64)
    check = np.asarray(check, dtype=bool)
    fit = ~check
    n = len(e)
    B = _design(base, n)
    X = np.hstack([B, features])
    if fit.sum() <= X.shape[1] + 10 or check.sum() < 20:
        return Dependence(0.0, 1.0, 0.0, 0, 0.0, int(fit.sum()), int(check.sum()), np.zeros(features.shape[1]))
    g0 = _lstsq(B[fit], e[fit])
    g1 = _lstsq(X[fit], e[fit])
    r0 = e[check] - B[check] @ g0
    r1 = e[check] - X[check] @ g1
    total = float(r0 @ r0)
    share = float(1.0 - (r1 @ r1) / total) if total > 0 else 0.0
    t, p, k = batch_means_test(r0**2 - r1**2)
    inside = partial_share(e[fit], base[fit] if base is not None and base.size else None, features[fit])
    return Dependence(share, p, t, k, inside, int(fit.sum()), int(check.sum()), g1[B.shape[1] :])


def lagged(segments: list[np.ndarray], lags: list[int]) -> list[np.ndarray]:
    """Per segment: columns x_{t-k} for k in ``lags`` (values before the segment's start hold its first value)."""
    out = []
    for x in segments:
        n = len(x)
        cols = np.empty((n, len(lags)))
        for j, k in enumerate(lags):
            k = min(k, n)
            cols[:k, j] = x[0] if n else 0.0
            cols[k:, j] = x[: n - k]
        out.append(cols)
    return out
