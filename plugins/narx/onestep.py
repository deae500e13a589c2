"""One-step estimation (MSE_1, eq. 3.14): the pool, FOS structure selection and the weights.

* :func:`make_pool` - every monomial up to the degree (eq. 3.10 / 3.11), refused above ``max_pool``.
* :func:`fos_structure` - Fast Orthogonal Search per output on the pool's Gram matrix (A.2.2),
  stopped by ``max_terms``, ``threshold`` or the rise of the one-step validation error (A.3);
  optionally shortened until the polynomial's free run stays within the divergence band (3.1.4).
* :func:`fixed_weights` - least squares for a given structure.
* :func:`ridge_candidates` - ridge weights of the selected terms for one factor or a grid (6.3.2).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from dynmodel import regression
from dynmodel.family import Progress

from . import pool as pool_mod
from .embedding import Embedding, pool_exponents, pool_size
from .params import NarxFamilyParams

#: stability(k, exponents, weights) -> True when output k's polynomial diverges in free run
StabilityCheck = Callable[[int, np.ndarray, np.ndarray], bool]
#: free_run_error(k, exponents, weights) -> free-run NMSE of output k on the validation split (inf: diverged)
FreeRunError = Callable[[int, np.ndarray, np.ndarray], float]


def make_pool(emb: Embedding, p: NarxFamilyParams) -> np.ndarray:
    """The pool of ``emb``'s regressors up to the degree (with ``input_terms: linear`` the inputs only as
    linear terms of their own)."""
    degree, n_regressors = p.max_degree, emb.size
    linear = emb.inputs if p.input_terms == "linear" else None
    K = pool_size(n_regressors, degree, p.constant, 0 if linear is None else int(linear.sum()))
    if K > p.max_pool:
        raise ValueError(
            f"the pool would hold {K} monomials ({n_regressors} regressors up to degree {degree}), more "
            f"than max_pool = {p.max_pool}; lower the degree, use fewer lags, or raise max_pool"
        )
    return pool_exponents(n_regressors, degree, p.constant, linear)


def fos_structure(
    E: np.ndarray,
    train: pool_mod.Patterns,
    val: pool_mod.Patterns | None,
    p: NarxFamilyParams,
    output_names: list[str],
    stability: StabilityCheck | None,
    progress: Progress,
    free_run_error: FreeRunError | None = None,
    gram: tuple[np.ndarray, np.ndarray] | None = None,
):
    """FOS per output on the shared Gram matrix (``gram``: G and C of the pool E when already
    computed); returns (exponents, term outputs, weights, info).

    The terms come in FOS order (the one-step error reduction, A.2.2). How many are kept is decided
    on the validation split: by the error of the free run (``stop_on: free_run``, when
    ``free_run_error`` is given: the model is used in free run, thesis 3.1.4) or of the one-step
    predictions (A.3); in both cases after ``patience`` terms without a new lowest error the
    search stops and the best size is kept."""
    if gram is None:
        progress("pool", None, f"Gram matrix of {E.shape[0]} monomials on {train.n} patterns")
        G, C = pool_mod.gram(train.X, train.Y, E)
    else:
        G, C = gram
    use_val = val is not None and p.patience is not None
    if not use_val and p.max_terms is None and p.threshold is None:
        raise ValueError(
            "FOS needs a stopping rule: a validation split (data.split.validation, used with patience), "
            "max_terms or threshold"
        )
    by_free_run = use_val and p.stop_on == "free_run" and free_run_error is not None
    lazy = pool_mod.LazyColumns(val.X, E) if val is not None and use_val and not by_free_run else None
    forced = (0,) if p.constant else ()
    rows, outs, weights, info = [], [], [], []
    for k, name in enumerate(output_names):
        y = train.Y[:, k]
        score = None
        if by_free_run:
            assert free_run_error is not None

            def score(order: list[int], coef: np.ndarray, k: int = k, name: str = name) -> float:
                progress("fos", None, f"output {name}: {len(order)} terms, free run on the validation split")
                return free_run_error(k, E[order], coef)

        path = regression.fos_select(
            G,
            C[:, k],
            float(y @ y),
            forced=forced,
            max_terms=p.max_terms,
            threshold=p.threshold,
            Pv=lazy,
            yv=val.Y[:, k] if lazy is not None and val is not None else None,
            patience=p.patience or 1,
            validation=score,
        )
        best = path.best
        if best == 0:
            raise ValueError(f"FOS selected no term for output '{name}'; lower the threshold")
        dropped = 0
        if p.drop_unstable and stability is not None:
            while best > 1 and stability(k, E[path.order[:best]], path.coef_path[best - 1]):
                best -= 1
                dropped += 1
        kept_error = None
        if by_free_run and path.validation_error is not None:
            e = float(path.validation_error[best - 1]) if best <= len(path.validation_error) else np.inf
            kept_error = 100 * e if np.isfinite(e) else None
        kept = path.order[:best]
        if p.weights == "recursion":
            w = path.coef_path[best - 1]
        else:
            w = regression.lstsq(pool_mod.evaluate(train.X, E[kept]), y, fit_intercept=False).coef[:, 0]
        rows.append(E[kept])
        outs += [k] * len(kept)
        weights.append(w)
        info.append(
            {
                "order": kept.tolist(),
                "error_reduction": (path.error_reduction[:best] / max(float(y @ y), 1e-300)).tolist(),
                "validation_mse": None
                if path.validation_error is None or by_free_run
                else path.validation_error.tolist(),
                "validation_free_run_nmse": [
                    None if not np.isfinite(e) else 100 * float(e) for e in path.validation_error
                ]
                if by_free_run and path.validation_error is not None
                else None,
                "dropped_for_stability": dropped,
                "validation_free_run_nmse_kept": kept_error,
            }
        )
        progress("fos", (k + 1) / len(output_names), f"output {name}: {len(kept)} terms")
    selection: dict[str, Any] = {
        "method": "fos",
        "pool": int(E.shape[0]),
        "terms": [len(r) for r in rows],
        "path": info,
    }
    return np.vstack(rows), np.array(outs, dtype=np.int64), np.concatenate(weights), selection


def fixed_weights(train: pool_mod.Patterns, exps: np.ndarray, outs: np.ndarray, n_out: int) -> np.ndarray:
    """Least-squares weights (SVD, A.2.1) of a given structure."""
    w = np.zeros(len(outs))
    for k in range(n_out):
        idx = np.flatnonzero(outs == k)
        F = pool_mod.evaluate(train.X, exps[idx])
        w[idx] = regression.lstsq(F, train.Y[:, k], fit_intercept=False).coef[:, 0]
    return w


def ridge_candidates(
    train: pool_mod.Patterns, exps: np.ndarray, outs: np.ndarray, w: np.ndarray, ridge: float | str
) -> tuple[list[np.ndarray], list[list[float]]]:
    """Ridge weights of the selected terms (the constant is not penalised) for the factor ``ridge``,
    or for each of 29 factors over [1e-14, 1] x the largest squared singular value (``'auto'``,
    the same grid for every output by position). Returns the weight vectors and, per vector,
    the factor of each output."""
    const = np.asarray(~exps.any(axis=1))
    per_output = []
    for k in range(int(outs.max()) + 1 if len(outs) else 0):
        idx = np.flatnonzero(outs == k)
        has_const = bool(const[idx].any())
        cols = idx[~const[idx]]
        F = pool_mod.evaluate(train.X, exps[cols])
        alphas = None if ridge == "auto" else [float(ridge)]
        per_output.append(
            (idx, cols, has_const, regression.ridge_path(F, train.Y[:, k], alphas, fit_intercept=has_const))
        )
    n_alpha = len(per_output[0][3])
    vectors, factors = [], []
    for i in range(n_alpha):
        v = w.copy()
        for idx, cols, has_const, fits in per_output:
            v[cols] = fits[i].coef[:, 0]
            if has_const:
                v[idx[const[idx]]] = fits[i].intercept[0]
        vectors.append(v)
        factors.append([fits[i].info["alpha"] for *_, fits in per_output])
    return vectors, factors
