"""Linear-in-the-parameters estimation shared by the families.

* :func:`lstsq` - least squares through a QR reduction and the SVD of R (thesis A.2.1: the
  pseudo-inverse computed by SVD, with a relative singular-value cutoff).
* :func:`ridge` - ridge regression, with the factor chosen on a validation set when asked.
* :func:`fos` - Fast Orthogonal Search (thesis A.2.2, Korenberg's covariance recursion on the
  Gram matrix; no explicit Gram-Schmidt on the full vectors), stopped at a maximum number of
  terms, an error-reduction threshold, or the rise of the validation error (thesis A.3).

All functions take a feature matrix F (N, K) and targets Y (N, q) and return a
:class:`LinearFit` whose prediction is ``F @ coef + intercept``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

_CHUNK_ELEMENTS = 20_000_000  # TSQR chunk size (160 MB of float64)


@dataclass
class LinearFit:
    coef: np.ndarray  # (K, q)
    intercept: np.ndarray  # (q,)
    selected: list[np.ndarray] | None = None  # FOS: chosen feature indices per output
    info: dict = field(default_factory=dict)

    def predict(self, F: np.ndarray) -> np.ndarray:
        return F @ self.coef + self.intercept


def _as2d(Y: np.ndarray) -> np.ndarray:
    Y = np.asarray(Y, dtype=np.float64)
    return Y[:, None] if Y.ndim == 1 else Y


def qr_reduce(A: np.ndarray, Y: np.ndarray, ones: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """R (K, K) and Q^T Y (K, q) of A = Q R, by chunked TSQR (memory: one chunk).

    ``ones=True`` appends a column of ones to A (the intercept) chunk by chunk, without a copy
    of A."""
    K = A.shape[1] + int(ones)
    q = Y.shape[1]
    rows = max(2 * K, _CHUNK_ELEMENTS // (K + q))
    acc = np.zeros((0, K + q))
    for start in range(0, A.shape[0], rows):
        a = A[start : start + rows]
        block = np.empty((acc.shape[0] + a.shape[0], K + q))
        block[: acc.shape[0]] = acc
        block[acc.shape[0] :, : A.shape[1]] = a
        if ones:
            block[acc.shape[0] :, A.shape[1]] = 1.0
        block[acc.shape[0] :, K:] = Y[start : start + rows]
        acc = np.linalg.qr(block, mode="r")
    if acc.shape[0] < K:  # fewer rows than columns
        acc = np.vstack([acc, np.zeros((K - acc.shape[0], acc.shape[1]))])
    return acc[:K, :K], acc[:K, K:]


def lstsq(F: np.ndarray, Y: np.ndarray, rcond: float | None = None, fit_intercept: bool = True) -> LinearFit:
    """Minimum-norm least squares; singular values below ``rcond * s_max`` are dropped
    (default ``rcond``: machine epsilon times max(N, K), as numpy and MATLAB's pinv)."""
    Y = _as2d(Y)
    R, QtY = qr_reduce(np.asarray(F, dtype=np.float64), Y, ones=fit_intercept)
    W, rank = lstsq_factor(R, QtY, F.shape[0], rcond)
    if fit_intercept:
        return LinearFit(W[:-1], W[-1], info={"rank": rank})
    return LinearFit(W, np.zeros(Y.shape[1]), info={"rank": rank})


def lstsq_factor(R: np.ndarray, QtY: np.ndarray, n_rows: int, rcond: float | None = None) -> tuple[np.ndarray, int]:
    """Minimum-norm solution (and rank) of min ||A w - Y|| given any square factor R with
    R^T R = A^T A and R^T QtY = A^T Y (A has ``n_rows`` rows): through the SVD of R, singular
    values below ``rcond * s_max`` dropped (default eps * max(n_rows, K))."""
    U, s, Vt = np.linalg.svd(R)
    if rcond is None:
        rcond = np.finfo(np.float64).eps * max(n_rows, R.shape[0])
    keep = s > rcond * (s[0] if s.size else 0.0)
    return Vt[keep].T @ ((U[:, keep].T @ QtY) / s[keep, None]), int(keep.sum())


def ridge_path(F: np.ndarray, Y: np.ndarray, alphas=None, fit_intercept: bool = True) -> list[LinearFit]:
    """Ridge solutions of ||Y - F w - b||^2 + alpha ||w||^2 for every alpha from one SVD (the
    intercept b is not penalised; ``fit_intercept=False``: b = 0). ``alphas=None``: the grid of
    ``alpha='auto'``, 29 factors log-spaced over [1e-14, 1] times the largest squared singular
    value of the (centred) F."""
    Y = _as2d(Y)
    F = np.asarray(F, dtype=np.float64)
    fm = F.mean(axis=0) if fit_intercept else np.zeros(F.shape[1])
    ym = Y.mean(axis=0) if fit_intercept else np.zeros(Y.shape[1])
    R, QtY = qr_reduce(F - fm, Y - ym)
    return ridge_factor_path(R, QtY, fm, ym, alphas)


def ridge_factor_path(R: np.ndarray, QtY: np.ndarray, fm: np.ndarray, ym: np.ndarray, alphas=None) -> list[LinearFit]:
    """:func:`ridge_path` from a factor R, QtY of the centred features and targets (R^T R = Fc^T Fc,
    R^T QtY = Fc^T Yc) and the means ``fm``, ``ym`` (zeros: no intercept)."""
    U, s, Vt = np.linalg.svd(R)
    UtY = U.T @ QtY
    if alphas is None:
        alphas = (s[0] ** 2 if s.size and s[0] > 0 else 1.0) * np.logspace(-14, 0, 29)
    fits = []
    for a in alphas:
        W = Vt.T @ (UtY * (s / (s**2 + a))[:, None])
        fits.append(LinearFit(W, ym - fm @ W, info={"alpha": float(a)}))
    return fits


def ridge(
    F: np.ndarray,
    Y: np.ndarray,
    alpha: float | str = "auto",
    Fv: np.ndarray | None = None,
    Yv: np.ndarray | None = None,
    alphas: np.ndarray | None = None,
    fit_intercept: bool = True,
) -> LinearFit:
    """Minimise ||Y - F w - b||^2 + alpha ||w||^2 (intercept not penalised).

    ``alpha='auto'``: the factor with the lowest validation error on (Fv, Yv) from a
    log-spaced grid relative to the largest squared singular value of the centred F.
    """
    if alpha != "auto":
        return ridge_path(F, Y, [float(alpha)], fit_intercept)[0]
    if Fv is None or Yv is None:
        raise ValueError("ridge with alpha='auto' needs a validation set")
    Yv = _as2d(Yv)
    best, best_err = None, np.inf
    for fit in ridge_path(F, Y, alphas, fit_intercept):
        err = float(np.mean((Yv - fit.predict(Fv)) ** 2))
        if err < best_err:
            best, best_err = fit, err
    assert best is not None
    best.info["validation_mse"] = best_err
    return best


# ---------------------------------------------------------------- Fast Orthogonal Search


@dataclass
class FosPath:
    """The FOS selection sequence for one target."""

    order: np.ndarray  # selected pool indices, in order
    coef_path: list[np.ndarray]  # coefficients (A.14 / A.15) after each selection
    error_reduction: np.ndarray  # Q(m): reduction of the sum of squared errors by term m
    validation_error: np.ndarray | None  # mean squared validation error after each term
    best: int  # number of terms kept


#: validation error of a FOS model: (selected pool indices, their coefficients) -> an error to
#: minimise (inf when the model cannot be evaluated), e.g. the mean squared error of the validation
#: rows (from their moments) or of a NARX model's free run on the validation split
ValidationError = Callable[[list[int], np.ndarray], float]


class _Stopper:
    """The stopping rule shared by both FOS variants: with a validation pool (or a ``validation``
    error function), the number of terms with the lowest validation error, searched until
    ``patience`` terms bring no new lowest (thesis A.3); without one, every selected term is kept."""

    def __init__(
        self, Pv: np.ndarray | None, yv: np.ndarray | None, patience: int, validation: ValidationError | None = None
    ):
        if validation is None and Pv is not None and yv is not None:
            validation = lambda order, coef: float(np.mean((yv - Pv[:, order] @ coef) ** 2))  # noqa: E731
        self.validation, self.patience = validation, patience
        self.errors: list[float] = []
        self.best_m, self.best_val, self.since_best = 0, np.inf, 0

    def add(self, order: list[int], coef: np.ndarray, forced: bool) -> bool:
        """Record the model with ``order`` terms; True when the search should stop."""
        if self.validation is None:
            self.best_m = len(order)
            return False
        err = float(self.validation(list(order), coef))
        self.errors.append(err)
        if err < self.best_val * (1 - 1e-12) or forced:
            self.best_val, self.best_m, self.since_best = err, len(order), 0
            return False
        self.since_best += 1
        return self.since_best >= self.patience

    def path(self, order: list[int], coef_path: list[np.ndarray], Q: np.ndarray) -> FosPath:
        return FosPath(
            np.array(order, dtype=np.int64),
            coef_path,
            Q[: len(order)],
            np.array(self.errors) if self.errors else None,
            self.best_m,
        )


def fos_select(
    G: np.ndarray,
    c: np.ndarray,
    yy: float,
    *,
    forced: tuple[int, ...] = (),
    max_terms: int | None = None,
    threshold: float | None = None,
    Pv: np.ndarray | None = None,
    yv: np.ndarray | None = None,
    patience: int = 1,
    tol: float = 1e-10,
    ties: float = 0.0,
    validation: ValidationError | None = None,
) -> FosPath:
    """Korenberg's FOS on the Gram matrix G = P^T P of the pool P, c = P^T y, yy = y^T y.

    The recursion keeps, for every remaining candidate i, D~(m, j, i) (its inner products with
    the orthogonalised selected terms), D~(m, m, i) (its squared norm after orthogonalisation)
    and C~(m, i) (its correlation with y after orthogonalisation); the candidate with the
    largest error reduction Q~ = C~^2 / D~ is selected (appendix A.2.2). ``forced`` indices
    are selected first (e.g. the constant term).

    Stopping: ``max_terms``; ``threshold`` on Q / yy (the error-reduction ratio); or, with a
    validation pool ``Pv`` and targets ``yv``, after ``patience`` terms without a new lowest
    validation error (``patience=1``: stop at the first rise). The kept size is the best one.
    ``validation(order, coef)`` may give that error instead of ``Pv``, ``yv`` (e.g. from the
    accumulated moments of the validation rows, :mod:`dynmodel.moments`, or the error of a free run).
    ``ties``: candidates whose error reduction is within this relative tolerance of the largest
    count as equal and the first of them in pool order is chosen (e.g. the lower-degree monomial).
    """
    P = G.shape[0]
    limit = P if max_terms is None else min(max_terms, P)
    diag = np.diag(G).copy()
    Dmm = diag.copy()
    Ct = np.asarray(c, dtype=np.float64).copy()
    Dt = np.zeros((limit, P))
    alpha = np.zeros((limit, limit))
    D = np.zeros(limit)
    Cc = np.zeros(limit)
    Q = np.zeros(limit)
    available = diag > 0
    order: list[int] = []
    coef_path: list[np.ndarray] = []
    stopper = _Stopper(Pv, yv, patience, validation)
    for m in range(limit):
        if m > 0:
            prev = order[-1]
            row = G[:, prev] - alpha[m - 1, : m - 1] @ Dt[: m - 1]
            Dt[m - 1] = row
            Dmm = Dmm - row * row / D[m - 1]
            Ct = Ct - row * (Cc[m - 1] / D[m - 1])
            available[prev] = False
        valid = available & (Dmm > tol * np.maximum(diag, 1e-300))
        if not valid.any():
            break
        i = _next_term(order, forced, valid, lambda: Ct * Ct / np.where(valid, Dmm, 1.0), threshold, yy, ties)
        if i is None:
            break
        alpha[m, :m] = Dt[:m, i] / D[:m]
        D[m], Cc[m] = Dmm[i], Ct[i]
        Q[m] = Cc[m] ** 2 / D[m]
        order.append(i)
        # weights of the selected terms: solve A^T a = beta with A[k, j] = alpha(k, j) (A.14/A.15)
        beta = Cc[: m + 1] / D[: m + 1]
        A = np.eye(m + 1) + np.tril(alpha[: m + 1, : m + 1], -1)
        coef = _solve_unit_upper(A.T, beta)
        coef_path.append(coef)
        if stopper.add(order, coef, i in forced):
            break
    return stopper.path(order, coef_path, Q)


def fos_select_qr(
    R: np.ndarray,
    z: np.ndarray,
    yy: float,
    *,
    forced: tuple[int, ...] = (),
    max_terms: int | None = None,
    threshold: float | None = None,
    Pv: np.ndarray | None = None,
    yv: np.ndarray | None = None,
    patience: int = 1,
    tol: float = 1e-24,
    validation: ValidationError | None = None,
) -> FosPath:
    """FOS with the same selection rule as :func:`fos_select`, numerically stable.

    The pool P (N, K) enters through its QR reduction: the columns of R (K, K) are the pool
    vectors in an orthonormal basis of its range and z = Q^T y, so every inner product FOS needs
    is preserved. On these short vectors the orthogonalization is done explicitly by modified
    Gram-Schmidt, which keeps its accuracy when the candidates are nearly collinear (states of
    random networks, high-degree monomials), where the covariance recursion loses it: the Gram
    matrix squares the condition number. Cost per selected term: O(K^2), as the recursion.
    """
    K, P = R.shape
    limit = P if max_terms is None else min(max_terms, P)
    V = np.array(R, dtype=np.float64, copy=True)  # candidates, orthogonalized against the chosen terms
    r = np.array(z, dtype=np.float64, copy=True)  # part of y not explained yet
    norm0 = np.einsum("ij,ij->j", R, R)
    available = norm0 > 0
    T = np.zeros((limit, P))  # T[j, i] = <q_j, g_i>: the triangular factor of the chosen columns
    beta = np.zeros(limit)
    order: list[int] = []
    coef_path: list[np.ndarray] = []
    Q = np.zeros(limit)
    stopper = _Stopper(Pv, yv, patience, validation)
    for m in range(limit):
        d = np.einsum("ij,ij->j", V, V)
        valid = available & (d > tol * np.maximum(norm0, 1e-300)) & (d > 0)
        if not valid.any():
            break
        i = _next_term(order, forced, valid, lambda: (V.T @ r) ** 2 / np.where(valid, d, 1.0), threshold, yy)
        if i is None:
            break
        q = V[:, i] / np.sqrt(d[i])
        c = q @ V  # MGS: remove the new direction from every candidate
        T[m] = c
        V -= np.outer(q, c)
        available[i] = False
        beta[m] = q @ r
        r -= beta[m] * q
        Q[m] = beta[m] ** 2
        order.append(i)
        U = T[: m + 1][:, order]  # upper triangular: the chosen columns = Q_sel U
        coef = scipy.linalg.solve_triangular(U, beta[: m + 1])
        coef_path.append(coef)
        if stopper.add(order, coef, i in forced):
            break
    return stopper.path(order, coef_path, Q)


def _next_term(
    chosen: list[int],
    forced: tuple[int, ...],
    valid: np.ndarray,
    reduction,
    threshold: float | None,
    yy: float,
    ties: float = 0.0,
) -> int | None:
    """Index of the next FOS term, or None to stop: the forced terms first (skipping those numerically in
    the span of the terms already chosen), then the candidate with
    the largest error reduction Q = C^2 / D (appendix A.2.2), the first of the nearly best ones in pool
    order when ``ties`` > 0; stop when nothing is left or the best reduction falls below
    ``threshold`` times y'y. ``reduction()`` gives Q for every candidate."""
    pending = [f for f in forced if f not in chosen]
    while pending and not valid[pending[0]]:  # a forced term in the span of those chosen adds nothing
        pending.pop(0)
    if pending:
        return pending[0]
    score = np.where(valid, reduction(), -np.inf)
    i = int(np.argmax(score))
    if ties > 0.0:
        i = int(np.flatnonzero(score >= score[i] * (1.0 - ties))[0])
    if threshold is not None and score[i] < threshold * yy:
        return None
    return i


def _solve_unit_upper(U: np.ndarray, b: np.ndarray) -> np.ndarray:
    x = b.copy()
    for k in range(len(b) - 1, -1, -1):
        x[k] -= U[k, k + 1 :] @ x[k + 1 :]
    return x


def fos(
    F: np.ndarray,
    Y: np.ndarray,
    *,
    Fv: np.ndarray | None = None,
    Yv: np.ndarray | None = None,
    max_terms: int | None = None,
    threshold: float | None = None,
    patience: int = 1,
    weights: str = "lstsq",
    fit_intercept: bool = True,
    method: str = "qr",
) -> LinearFit:
    """FOS selection per output column, then weights for the kept terms.

    ``method='qr'`` (default) runs the search on the QR reduction of the pool
    (:func:`fos_select_qr`, stable for nearly collinear pools); ``'covariance'`` runs
    Korenberg's recursion of appendix A.2.2 on the Gram matrix (:func:`fos_select`).
    ``weights='lstsq'`` re-estimates the kept terms by least squares on the data (most
    accurate); ``'recursion'`` uses the FOS coefficients (eq. A.14 / A.15) directly.
    """
    Y = _as2d(Y)
    N, K = F.shape
    pool = np.hstack([np.ones((N, 1)), F]) if fit_intercept else np.asarray(F, dtype=np.float64)
    pool_v = None
    if Fv is not None:
        pool_v = np.hstack([np.ones((Fv.shape[0], 1)), Fv]) if fit_intercept else Fv
        Yv = _as2d(Yv)
    forced = (0,) if fit_intercept else ()
    if method == "qr":
        R, QtY = qr_reduce(pool, Y)
    elif method == "covariance":
        G = pool.T @ pool
    else:
        raise ValueError(f"unknown FOS method '{method}'; use 'qr' or 'covariance'")
    coef = np.zeros((K, Y.shape[1]))
    intercept = np.zeros(Y.shape[1])
    selected: list[np.ndarray] = []
    sizes = []
    for q in range(Y.shape[1]):
        y = Y[:, q]
        common = dict(
            forced=forced,
            max_terms=max_terms,
            threshold=threshold,
            Pv=pool_v,
            yv=None if Yv is None else Yv[:, q],
            patience=patience,
        )
        if method == "qr":
            path = fos_select_qr(R, QtY[:, q], float(y @ y), **common)
        else:
            path = fos_select(G, pool.T @ y, float(y @ y), **common)
        kept = path.order[: path.best]
        if weights == "recursion":
            w = path.coef_path[path.best - 1] if path.best else np.zeros(0)
        else:
            w = lstsq(pool[:, kept], y, fit_intercept=False).coef[:, 0] if len(kept) else np.zeros(0)
        full = np.zeros(pool.shape[1])
        full[kept] = w
        if fit_intercept:
            intercept[q] = full[0]
            coef[:, q] = full[1:]
            selected.append(np.sort(kept[kept > 0] - 1))
        else:
            coef[:, q] = full
            selected.append(np.sort(kept))
        sizes.append(int(len(kept)))
    return LinearFit(coef, intercept, selected, info={"terms": sizes})
