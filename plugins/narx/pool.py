"""Regression patterns of a split and the Gram matrix of the monomial pool (thesis 3.1.1, A.2.2).

FOS needs only G = P^T P, P^T y and y^T y of the pool P (eq. 3.13), so P is built and reduced in
row chunks and never held whole; the validation pool is evaluated column by column, only for
the terms FOS actually selects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import blas

from dynmodel.data.training import TrainingData

from . import kernels
from .embedding import Embedding, factor_lists

_CHUNK_ELEMENTS = 4_000_000  # pool rows x terms per chunk (32 MB)
_MOMENT_LIMIT = 200_000  # largest monomial table for the one-pass Gram matrix


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


def first_sample(emb: Embedding, start: str) -> int:
    """The first sample of a recording that makes a pattern: after the largest lag (``start: drop``), or 0
    (the lags before the recording zero-padded)."""
    return emb.max_lag if start == "drop" else 0


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
    """G = P^T P (K, K) and C = P^T Y (K, q) of the pool P over the rows of X.

    G[i, j] is the sum of the monomial with exponents e_i + e_j, so when the monomials of
    degree <= 2 x the pool's degree are at least 8 times fewer than the pairs of pool terms
    (5 regressors, degree 5: 3003 against 31878) their sums are accumulated in one compiled pass
    (:func:`moment_gram`, measured 2.7x faster than BLAS there, and immune to BLAS threads
    contending for a busy machine); otherwise the pool is built in row chunks and reduced by
    BLAS (:func:`chunked_gram`)."""
    E = np.asarray(exponents, dtype=np.int64)
    top = 2 * int(E.sum(axis=1).max()) if E.size else 0
    K = E.shape[0]
    if math.comb(E.shape[1] + top, top) <= min(_MOMENT_LIMIT, K * (K + 1) // 16):
        return moment_gram(X, Y, E)
    return chunked_gram(X, Y, E)


def chunked_gram(X: np.ndarray, Y: np.ndarray, exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G and C with the pool evaluated in row chunks and reduced by BLAS (syrk)."""
    K = exponents.shape[0]
    ptr, reg, pw = factor_lists(exponents)
    rows = max(1, _CHUNK_ELEMENTS // max(K, 1))
    G = np.zeros((K, K), order="F")
    C = np.zeros((K, Y.shape[1]))
    P = np.empty((min(rows, X.shape[0]), K))
    for a in range(0, X.shape[0], rows):
        Xc = np.ascontiguousarray(X[a : a + rows])
        Pc = P[: Xc.shape[0]]
        kernels.monomials(Xc, ptr, reg, pw, Pc)
        # Pc is C-ordered (m, K), i.e. Fortran-ordered (K, m): G += Pc^T Pc as a rank-m update
        G = blas.dsyrk(1.0, Pc.T, beta=1.0, c=G, trans=0, lower=0, overwrite_c=1)
        C += Pc.T @ Y[a : a + rows]
    G = np.triu(G) + np.triu(G, 1).T
    return np.ascontiguousarray(G), C


def moment_table(n: int, top: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every monomial of degree <= top in n variables, by degree: exponents (M, n), and for each
    the monomial it extends (parent) by one factor of variable var (the constant has -1)."""
    exps = [np.zeros((1, n), dtype=np.int64)]
    parent, var = [np.array([-1])], [np.array([-1])]
    last = np.array([-1])  # largest variable index of each monomial of the previous degree
    first, count = 0, 1
    for _ in range(top):
        prev = exps[-1]
        p_idx, v_idx, rows = [], [], []
        for v in range(n):
            sel = np.flatnonzero(last <= v)
            p_idx.append(first + sel)
            v_idx.append(np.full(sel.size, v))
            r = prev[sel].copy()
            r[:, v] += 1
            rows.append(r)
        last = np.concatenate(v_idx)
        exps.append(np.vstack(rows))
        parent.append(np.concatenate(p_idx))
        var.append(last)
        first, count = count, count + len(last)
    return np.vstack(exps), np.concatenate(parent).astype(np.int64), np.concatenate(var).astype(np.int64)


def _keys(E: np.ndarray, base: int) -> np.ndarray:
    return E @ (base ** np.arange(E.shape[1], dtype=np.int64))


def moment_gram(X: np.ndarray, Y: np.ndarray, exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """G and C from the sums of every monomial of degree <= 2 x the pool's degree (one pass)."""
    E = np.asarray(exponents, dtype=np.int64)
    d = int(E.sum(axis=1).max())
    table, parent, var = moment_table(E.shape[1], 2 * d)
    n_low = int(np.sum(table.sum(axis=1) <= d))
    rows = max(16, min(256, _CHUNK_ELEMENTS // (4 * len(table))))
    acc, acc_y = kernels.moment_sums(np.ascontiguousarray(X.T), np.ascontiguousarray(Y.T), parent, var, n_low, rows)
    base = 2 * d + 1
    keys = _keys(table, base)
    order = np.argsort(keys)
    k = _keys(E, base)
    pos = order[np.searchsorted(keys, k[:, None] + k[None, :], sorter=order)]
    return acc[pos], acc_y[order[np.searchsorted(keys, k, sorter=order)]]


class LazyColumns:
    """``P[:, idx]`` of a pool evaluated on demand (and cached), for FOS's validation error."""

    def __init__(self, X: np.ndarray, exponents: np.ndarray):
        self.X = np.ascontiguousarray(X)
        self.exponents = exponents
        self.cache: dict[int, np.ndarray] = {}
        self.shape = (X.shape[0], exponents.shape[0])

    def column(self, j: int) -> np.ndarray:
        if j not in self.cache:
            self.cache[j] = evaluate(self.X, self.exponents[j : j + 1])[:, 0]
        return self.cache[j]

    def __getitem__(self, key) -> np.ndarray:
        rows, cols = key
        if rows != slice(None):
            raise IndexError("LazyColumns supports P[:, columns] only")
        cols = np.atleast_1d(np.asarray(cols, dtype=np.int64))
        if cols.size == 0:
            return np.zeros((self.X.shape[0], 0))
        return np.column_stack([self.column(int(j)) for j in cols])
