"""Linear readouts from accumulated moments (:mod:`dynmodel.moments`), never from stored rows.

The same solvers as :mod:`dynmodel.regression`, fed with square-root factors of the Gram matrix
instead of the feature matrix: least squares (SVD of the factor, thesis A.2.1), ridge with the
factor chosen on the validation rows, and Fast Orthogonal Search (thesis A.2.2) stopped on the
validation error (A.3). Validation errors come from the moments of the validation rows:
``||y - F w - b||^2 = ||R_v [-w; 1]||^2 + n_v (mean_y - mean_F w - b)^2``. Each function returns a
:class:`~dynmodel.regression.LinearFit` equal, up to rounding, to its array counterpart on the rows.
"""

from __future__ import annotations

import numpy as np

from .moments import Moments
from .regression import LinearFit, fos_select_qr, lstsq_factor, qr_reduce, ridge_factor_path


def lstsq(train: Moments, rcond: float | None = None) -> LinearFit:
    """:func:`dynmodel.regression.lstsq` (minimum-norm, intercept as a column of ones)."""
    S, Z = train.pool_factor("last")
    W, rank = lstsq_factor(S, Z, train.n, rcond)
    return LinearFit(W[:-1], W[-1], info={"rank": rank})


def ridge_path(train: Moments, alphas=None) -> list[LinearFit]:
    """:func:`dynmodel.regression.ridge_path` (intercept not penalised)."""
    K = train.n_features
    R = train.factor()
    return ridge_factor_path(R[:K, :K], R[:K, K:], train.mean[:K], train.mean[K:], alphas)


def validation_mse(validation: Moments, fit: LinearFit) -> float:
    """Mean squared error of ``fit`` over the validation rows and targets."""
    return float(validation.residual_ss(fit.coef, fit.intercept).sum() / (validation.n * validation.n_targets))


def ridge(train: Moments, alpha: float | str = "auto", validation: Moments | None = None, alphas=None) -> LinearFit:
    """:func:`dynmodel.regression.ridge`: ``alpha='auto'`` picks the factor of the grid with the
    lowest validation error."""
    if alpha != "auto":
        return ridge_path(train, [float(alpha)])[0]
    if validation is None:
        raise ValueError("ridge with alpha='auto' needs a validation set")
    best, best_err = None, np.inf
    for fit in ridge_path(train, alphas):
        err = validation_mse(validation, fit)
        if err < best_err:
            best, best_err = fit, err
    assert best is not None
    best.info["validation_mse"] = best_err
    return best


def fos(
    train: Moments,
    validation: Moments | None = None,
    *,
    max_terms: int | None = None,
    threshold: float | None = None,
    patience: int = 1,
    weights: str = "lstsq",
) -> LinearFit:
    """:func:`dynmodel.regression.fos` (``method='qr'``, with an intercept): the selection runs on
    the square-root factor of the pool [1, F]; ``weights='lstsq'`` re-estimates the kept terms by
    least squares through the same factor."""
    K, q = train.n_features, train.n_targets
    S, Z = train.pool_factor("first")
    yy = train.target_energy()
    coef = np.zeros((K, q))
    intercept = np.zeros(q)
    selected: list[np.ndarray] = []
    sizes = []
    for k in range(q):
        score = None if validation is None else _terms_error(validation, k)
        path = fos_select_qr(
            S,
            Z[:, k],
            float(yy[k]),
            forced=(0,),
            max_terms=max_terms,
            threshold=threshold,
            patience=patience,
            validation=score,
        )
        kept = path.order[: path.best]
        if not len(kept):
            w = np.zeros(0)
        elif weights == "recursion":
            w = path.coef_path[path.best - 1]
        else:
            Rk, zk = qr_reduce(S[:, kept], Z[:, [k]])
            w = lstsq_factor(Rk, zk, train.n)[0][:, 0]
        full = np.zeros(K + 1)
        full[kept] = w
        intercept[k], coef[:, k] = full[0], full[1:]
        selected.append(np.sort(kept[kept > 0] - 1))
        sizes.append(int(len(kept)))
    return LinearFit(coef, intercept, selected, info={"terms": sizes})


def _terms_error(validation: Moments, target: int):
    """Validation MSE of a FOS model on the pool [1, F] (pool index 0: the constant)."""

    def error(order: list[int], coef: np.ndarray) -> float:
        idx = np.asarray(order)
        feats = idx > 0
        const = float(coef[~feats].sum())
        return validation.terms_residual_ss(target, idx[feats] - 1, coef[feats], const) / validation.n

    return error
