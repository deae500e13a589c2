"""Distances between replicas, computed while they run (thesis definition 4.4)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .tanh import FASTMATH


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def group_spread(X, n_groups, replicas, out):
    """out[g] = max_r ||X[g R + r] - X[g R]|| for groups of ``replicas`` consecutive rows;
    inf when a state is not finite."""
    m = X.shape[1]
    for grp in range(n_groups):
        base = grp * replicas
        worst = 0.0
        for r in range(replicas):
            acc = 0.0
            for i in range(m):
                d = X[base + r, i] - X[base, i]
                acc += d * d
            if not np.isfinite(acc):
                worst = np.inf
                break
            if acc > worst:
                worst = acc
        out[grp] = np.sqrt(worst)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def row_distances(X, Y, out):
    """out[r] = ||X[r] - Y[r]|| (inf when not finite)."""
    m = X.shape[1]
    for r in range(X.shape[0]):
        acc = 0.0
        for i in range(m):
            d = X[r, i] - Y[r, i]
            acc += d * d
        out[r] = np.sqrt(acc) if np.isfinite(acc) else np.inf
