"""Regression patterns of a split and the Gram matrix of the monomial pool (thesis 3.1.1, A.2.2).

FOS needs only G = P^T P, P^T y and y^T y of the pool P (eq. 3.13), so P is built and reduced in
row chunks and never held whole; the validation pool is evaluated column by column, only for
the terms FOS actually selects.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import blas

from dynmodel.data.training import TrainingData

from . import kernels
from .embedding import Embedding, factor_lists

_CHUNK_ELEMENTS = 4_000_000  # pool rows x terms per chunk (32 MB)


@dataclass
class Patterns:
    """Regressors X (rows, n_regressors) and targets Y (rows, n_outputs) of one split."""

    X: np.ndarray
    Y: np.ndarray

    @property
    def n(self) -> int:
        return self.X.shape[0]


def regressor_matrices(data: TrainingData, emb: Embedding) -> list[np.ndarray]:
    return [emb.matrix(s.u, s.y) for s in data.series]


def patterns(data: TrainingData, mats: list[np.ndarray], split: str, first: int) -> Patterns:
    """Rows of ``split`` whose regressors and targets are all known. ``first``: the earliest
    usable sample of a recording (the largest lag when the first patterns are dropped, 0 with
    zero padding)."""
    xs, ys = [], []
    for s, a, b in data.segments.get(split, []):
        a = max(a, first)
        if a >= b:
            continue
        X, Y = mats[s][a:b], data.series[s].y[a:b]
        ok = np.isfinite(X).all(axis=1) & np.isfinite(Y).all(axis=1)
        xs.append(X[ok])
        ys.append(Y[ok])
    n_reg, n_out = mats[0].shape[1], data.n_outputs
    if not xs:
        return Patterns(np.zeros((0, n_reg)), np.zeros((0, n_out)))
    return Patterns(np.concatenate(xs), np.concatenate(ys))


def evaluate(X: np.ndarray, exponents: np.ndarray) -> np.ndarray:
    """Monomial values (rows, terms) of the regressor rows X."""
    ptr, reg, pw = factor_lists(exponents)
    out = np.empty((X.shape[0], exponents.shape[0]))
    kernels.monomials(np.ascontiguousarray(X), ptr, reg, pw, out)
    return out


def gram(X: np.ndarray, Y: np.ndarray, exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G = P^T P (K, K) and C = P^T Y (K, q) of the pool P over the rows of X, chunk by chunk."""
    K = exponents.shape[0]
    ptr, reg, pw = factor_lists(exponents)
    rows = max(1, _CHUNK_ELEMENTS // max(K, 1))
    G = np.zeros((K, K), order="F")
    C = np.zeros((K, Y.shape[1]))
    P = np.empty((min(rows, X.shape[0]), K))
    for a in range(0, X.shape[0], rows):
        Xc = np.ascontiguousarray(X[a:a + rows])
        Pc = P[:Xc.shape[0]]
        kernels.monomials(Xc, ptr, reg, pw, Pc)
        # Pc is C-ordered (m, K), i.e. Fortran-ordered (K, m): G += Pc^T Pc as a rank-m update
        G = blas.dsyrk(1.0, Pc.T, beta=1.0, c=G, trans=0, lower=0, overwrite_c=1)
        C += Pc.T @ Y[a:a + rows]
    G = np.triu(G) + np.triu(G, 1).T
    return np.ascontiguousarray(G), C


class LazyColumns:
    """``P[:, idx]`` of a pool evaluated on demand (and cached), for FOS's validation error."""

    def __init__(self, X: np.ndarray, exponents: np.ndarray):
        self.X = np.ascontiguousarray(X)
        self.exponents = exponents
        self.cache: dict[int, np.ndarray] = {}
        self.shape = (X.shape[0], exponents.shape[0])

    def column(self, j: int) -> np.ndarray:
        if j not in self.cache:
            self.cache[j] = evaluate(self.X, self.exponents[j:j + 1])[:, 0]
        return self.cache[j]

    def __getitem__(self, key) -> np.ndarray:
        rows, cols = key
        if rows != slice(None):
            raise IndexError("LazyColumns supports P[:, columns] only")
        cols = np.atleast_1d(np.asarray(cols, dtype=np.int64))
        if cols.size == 0:
            return np.zeros((self.X.shape[0], 0))
        return np.column_stack([self.column(int(j)) for j in cols])
