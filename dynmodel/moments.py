"""Second moments of long row streams, accumulated chunk by chunk (memory independent of N).

A linear readout (least squares, ridge, Fast Orthogonal Search) needs only the inner products of
its feature columns and targets. For rows ``a_t = [f_t, y_t]`` (K features, q targets) both classes
keep the count n, the mean and the centred Gram matrix ``sum_t (a_t - mean)(a_t - mean)^T``; a
chunk of rows is merged with the pairwise update of Chan, Golub and LeVeque (the chunk is centred
on its own mean, and the difference of the means enters as one rank-one term), so the result does
not depend on how the rows were cut and no large offset cancels.

* :class:`Moments` holds the centred Gram matrix in square-root form, as the upper-triangular R
  with ``R^T R = sum_t (a_t - mean)(a_t - mean)^T``, updated by one Householder QR per chunk
  (LAPACK ``tpqrt`` on ``[R; sqrt(n_a n_b / n) (mean_b - mean_a); A_b - mean_b]``). This is the
  chunked TSQR the array solvers of :mod:`dynmodel.regression` run on a stored matrix: the
  singular values of the features keep their full float64 range, which the states of random
  networks need (their Gram matrix squares a condition number of 1e8 and more).
* :class:`GramMoments` holds the centred Gram matrix itself (one BLAS product per chunk: half the
  work of the QR and a quarter of its time), for objectives that solve the normal equations.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.linalg import lapack

from .data.training import TrainingData

#: elements (rows x columns) of one chunk of rows: 4 M float64 = 32 MB
CHUNK_ELEMENTS = 4_000_000
_QR_BLOCK = 32  # LAPACK tpqrt block size (measured best for K from 60 to 1000)


def chunk_rows(width: int) -> int:
    """Rows per chunk for rows of ``width`` numbers: about 32 MB, at least 256 rows."""
    return max(256, CHUNK_ELEMENTS // max(width, 1))


class Moments:
    """Count, mean and square-root centred Gram matrix of rows ``[f_t, y_t]``; see the module doc."""

    def __init__(self, n_features: int, n_targets: int):
        self.n_features, self.n_targets = int(n_features), int(n_targets)
        p = self.n_features + self.n_targets
        self.n = 0
        self.mean = np.zeros(p)
        self.R = np.zeros((p, p), order="F")
        self.finite = True
        self._work: dict[int, np.ndarray] = {}  # LAPACK input buffers by chunk length, reused

    @property
    def width(self) -> int:
        return self.n_features + self.n_targets

    def reset(self) -> None:
        """Forget every row (the buffers are kept for the next accumulation)."""
        self.n = 0
        self.mean[:] = 0.0
        self.R[:] = 0.0
        self.finite = True

    def add(self, F: np.ndarray, Y: np.ndarray) -> None:
        """Merge the rows of ``F`` (c, K) and ``Y`` (c, q)."""
        c = F.shape[0]
        if c == 0:
            return
        K, p = self.n_features, self.width
        work = self._work.get(c)
        if work is None:
            if len(self._work) >= 4:  # blocks of many lengths: keep the memory bounded
                self._work.clear()
            work = self._work[c] = np.empty((c + 1, p), order="F")
        mean_b = np.empty(p)
        mean_b[:K] = F.mean(axis=0)
        mean_b[K:] = Y.mean(axis=0)
        if not np.isfinite(mean_b).all():
            self.finite = False
        np.subtract(F, mean_b[:K], out=work[1:, :K])
        np.subtract(Y, mean_b[K:], out=work[1:, K:])
        n = self.n + c
        diff = mean_b - self.mean
        work[0] = np.sqrt(self.n * c / n) * diff
        _, _, _, info = lapack.dtpqrt(0, min(_QR_BLOCK, p), self.R, work, overwrite_a=1, overwrite_b=1)
        if info != 0:  # pragma: no cover - LAPACK argument error
            raise RuntimeError(f"LAPACK tpqrt failed (info {info})")
        self.mean += (c / n) * diff
        self.n = n

    def factor(self) -> np.ndarray:
        """The triangular factor R (p, p) with R^T R = centred Gram matrix (a copy)."""
        return np.triu(self.R)

    def gram(self) -> np.ndarray:
        """The centred Gram matrix sum_t (a_t - mean)(a_t - mean)^T."""
        R = self.factor()
        return R.T @ R

    def pool_factor(self, ones: str = "first") -> tuple[np.ndarray, np.ndarray]:
        """Square-root factors of the uncentred pool with a column of ones: S (K+1, K+1) and
        Z (K+1, q) with S^T S = P^T P, S^T Z = P^T Y and Z^T Z <= Y^T Y for P = [1, F]
        (``ones='first'``) or [F, 1] (``'last'``). Exact rewriting of the centred factor:
        [1, F] = [1 / sqrt(n), Q] [[sqrt(n), sqrt(n) mean_F], [0, R_FF]]."""
        K = self.n_features
        R = self.factor()
        rn = np.sqrt(self.n)
        S = np.zeros((K + 1, K + 1))
        Z = np.zeros((K + 1, self.n_targets))
        top = np.concatenate([[rn], rn * self.mean[:K]])
        if ones == "first":
            S[0], S[1:, 1:] = top, R[:K, :K]
            Z[0], Z[1:] = rn * self.mean[K:], R[:K, K:]
        elif ones == "last":
            S[:K, :K], S[K, :K], S[K, K] = R[:K, :K], top[1:], rn
            Z[:K], Z[K] = R[:K, K:], rn * self.mean[K:]
        else:
            raise ValueError(f"ones must be 'first' or 'last', not {ones!r}")
        return S, Z

    def target_energy(self) -> np.ndarray:
        """y^T y per target (uncentred)."""
        K = self.n_features
        R = self.factor()
        return self.n * self.mean[K:] ** 2 + np.einsum("ij,ij->j", R[:, K:], R[:, K:])

    def residual_ss(self, coef: np.ndarray, intercept: np.ndarray) -> np.ndarray:
        """Sum over the rows of (y - f coef - intercept)^2, per target, for coef (K, q).

        The centred part is ||R [-coef; I]||^2 (as accurate as forming the residuals), the
        constant part n (mean_y - mean_f coef - intercept)^2."""
        K, q = self.n_features, self.n_targets
        coef = np.asarray(coef, dtype=np.float64).reshape(K, q)
        RE = self.R[:, K:] - self.R[:, :K] @ coef  # R [-coef; I]; R is upper triangular
        offset = self.mean[K:] - self.mean[:K] @ coef - intercept
        return np.einsum("ij,ij->j", RE, RE) + self.n * offset**2

    def terms_residual_ss(self, target: int, cols: np.ndarray, coef: np.ndarray, const: float) -> float:
        """Sum over the rows of (y_target - f[:, cols] coef - const)^2 (a readout of a few terms)."""
        K = self.n_features
        r = self.R[:, K + target] - self.R[:, cols] @ coef
        offset = self.mean[K + target] - self.mean[cols] @ coef - const
        return float(r @ r + self.n * offset**2)


class GramMoments:
    """Count, mean and centred Gram matrix G (p, p) of rows ``[f_t, y_t]``, merged chunk by chunk."""

    def __init__(self, n_features: int, n_targets: int):
        self.n_features, self.n_targets = int(n_features), int(n_targets)
        p = self.n_features + self.n_targets
        self.n = 0
        self.mean = np.zeros(p)
        self.G = np.zeros((p, p))
        self.finite = True
        self._work: np.ndarray | None = None

    def reset(self) -> None:
        """Forget every row (the buffers are kept for the next accumulation)."""
        self.n = 0
        self.mean[:] = 0.0
        self.G[:] = 0.0
        self.finite = True

    def add(self, F: np.ndarray, Y: np.ndarray) -> None:
        c = F.shape[0]
        if c == 0:
            return
        K, p = self.n_features, self.n_features + self.n_targets
        if self._work is None or self._work.shape[0] < c:
            self._work = np.empty((c, p))
        work = self._work[:c]
        mean_b = np.empty(p)
        mean_b[:K] = F.mean(axis=0)
        mean_b[K:] = Y.mean(axis=0)
        if not np.isfinite(mean_b).all():
            self.finite = False
        np.subtract(F, mean_b[:K], out=work[:, :K])
        np.subtract(Y, mean_b[K:], out=work[:, K:])
        n = self.n + c
        diff = mean_b - self.mean
        self.G += work.T @ work
        if self.n:
            self.G += (self.n * c / n) * np.outer(diff, diff)
        self.mean += (c / n) * diff
        self.n = n


# ------------------------------------------------------------------ streaming over the fit splits


def split_blocks(
    data: TrainingData, series: int, rows: int, splits: tuple[str, ...] = ("train", "validation")
) -> list[tuple[int, int, str | None]]:
    """Consecutive blocks (start, stop, split) that cover series ``series`` from its first sample
    to the last one scored in ``splits``, each at most ``rows`` long and inside one split's range
    (split None: samples no split scores, e.g. a transient). A network is driven block after block
    and each block's rows go to the moments of its split."""
    ranges = [(a, b, name) for name in splits for s, a, b in data.segments.get(name, []) if s == series and b > a]
    if not ranges:
        return []
    end = max(b for _, b, _ in ranges)
    cuts = sorted({0, end, *(a for a, _, _ in ranges), *(b for _, b, _ in ranges)})
    blocks: list[tuple[int, int, str | None]] = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        label = next((name for a, b, name in ranges if a <= lo and hi <= b), None)
        for start in range(lo, hi, rows):
            blocks.append((start, min(start + rows, hi), label))
    return blocks


#: features of rows [start, stop) of series k: produce(k, start, stop) -> (stop - start, K) array.
#: Called block after block from start = 0 for each series (the producer carries the state).
Producer = Callable[[int, int, int], np.ndarray]


def accumulate(
    data: TrainingData,
    produce: Producer,
    n_features: int,
    splits: tuple[str, ...] = ("train", "validation"),
    rows: int | None = None,
    moments: type[Moments] | type[GramMoments] | None = None,
    into: dict | None = None,
) -> dict[str, Moments]:
    """Moments of ``[features, y]`` per split (those of ``splits`` the data has), with the features
    produced block by block: memory of one block whatever the length of the recordings. ``into``:
    moments (per split) to reset and fill instead of new ones of class ``moments``, so that a
    caller evaluating many networks reuses their buffers."""
    if into is not None:
        out = {name: into[name] for name in splits if data.has(name)}
        for m in out.values():
            m.reset()
    else:
        cls = moments or Moments
        out = {name: cls(n_features, data.n_outputs) for name in splits if data.has(name)}
    rows = rows or chunk_rows(n_features + data.n_outputs)
    for k, series in enumerate(data.series):
        for start, stop, label in split_blocks(data, k, rows, tuple(out)):
            F = produce(k, start, stop)
            if label is not None:
                out[label].add(F, series.y[start:stop])
    return out  # type: ignore[return-value]
