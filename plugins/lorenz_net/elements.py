"""Driven Lorenz elements (thesis eq. 4.52) and their network (eq. 4.58 / 4.59).

    x1' = alpha sigma (v - x1),   x2' = alpha (r x1 - x2 - x1 x3),   x3' = alpha (x1 x2 - b x3)

Each element is reliable for any input (the Lyapunov function of eq. 4.44 / 4.45 carries over to
the scaled form). In a network, element i is driven by v_i = sum_j C_ij xi_j + sum_k B_ik u_k with
the coupling outputs xi_j = x2_j / r_j of earlier elements (C strictly lower triangular, so the
network is a cascade of reliable systems). Over each sampling interval the drive is held at its
value at the end of the interval (zero-order hold of the input and of the upstream outputs, which
are computed first), and the element is integrated by fixed-step RK4 with ``substeps`` steps.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynmodel.kernels.tanh import FASTMATH


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _rhs(x1, x2, x3, v, s, r, b, a):
    return a * s * (v - x1), a * (r * x1 - x2 - x1 * x3), a * (x1 * x2 - b * x3)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _interval(x1, x2, x3, v, s, r, b, a, h, substeps):
    """``substeps`` RK4 steps of size h with the drive v held."""
    for _ in range(substeps):
        k1a, k1b, k1c = _rhs(x1, x2, x3, v, s, r, b, a)
        k2a, k2b, k2c = _rhs(x1 + 0.5 * h * k1a, x2 + 0.5 * h * k1b, x3 + 0.5 * h * k1c, v, s, r, b, a)
        k3a, k3b, k3c = _rhs(x1 + 0.5 * h * k2a, x2 + 0.5 * h * k2b, x3 + 0.5 * h * k2c, v, s, r, b, a)
        k4a, k4b, k4c = _rhs(x1 + h * k3a, x2 + h * k3b, x3 + h * k3c, v, s, r, b, a)
        x1 += h / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a)
        x2 += h / 6.0 * (k1b + 2.0 * k2b + 2.0 * k3b + k4b)
        x3 += h / 6.0 * (k1c + 2.0 * k2c + 2.0 * k3c + k4c)
    return x1, x2, x3


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def integrate_element(sigma, r, b, alpha, v, dt, substeps, x0, out):
    """States (n, 3) of one element driven by v (n,), from x0; returns the first non-finite
    sample (the run stops there) or -1."""
    h = dt / substeps
    x1, x2, x3 = x0[0], x0[1], x0[2]
    for t in range(v.shape[0]):
        x1, x2, x3 = _interval(x1, x2, x3, v[t], sigma, r, b, alpha, h, substeps)
        out[t, 0] = x1
        out[t, 1] = x2
        out[t, 2] = x3
        if not (abs(x1) < 1e12 and abs(x2) < 1e12 and abs(x3) < 1e12):
            out[t:, :] = np.nan
            return t
    return -1


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def step_elements(params, C, B, X, U, dt, substeps, out):
    """One sampling interval for many replicas: X, out (R, M, 3); U (R, n_inputs)."""
    R, M = X.shape[0], X.shape[1]
    h = dt / substeps
    for rep in range(R):
        for i in range(M):
            v = 0.0
            for k in range(U.shape[1]):
                v += B[i, k] * U[rep, k]
            for j in range(i):
                if C[i, j] != 0.0:
                    v += C[i, j] * out[rep, j, 1] / params[j, 1]
            x1, x2, x3 = _interval(
                X[rep, i, 0],
                X[rep, i, 1],
                X[rep, i, 2],
                v,
                params[i, 0],
                params[i, 1],
                params[i, 2],
                params[i, 3],
                h,
                substeps,
            )
            out[rep, i, 0] = x1
            out[rep, i, 1] = x2
            out[rep, i, 2] = x3


def simulate_network(
    params: np.ndarray,
    C: np.ndarray,
    B: np.ndarray,
    U: np.ndarray,
    dt: float,
    substeps: int,
    out: np.ndarray | None = None,
    only: list[int] | None = None,
    x0: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """States (n, M, 3) of the network driven by U (n, n_inputs) from rest (or from the states
    ``x0`` (M, 3): chunk after chunk, each from the last states of the previous one, this equals
    one long run).

    ``only``: recompute just these elements (in increasing order) in a given ``out``; the others
    must already hold their trajectories (the caching of the structure search). Returns the
    states and the first non-finite sample (or -1).
    """
    n, M = U.shape[0], params.shape[0]
    if out is None:
        out = np.empty((n, M, 3))
        only = None
    first_bad = -1
    buf = np.empty((n, 3))
    start = np.zeros((M, 3)) if x0 is None else np.asarray(x0, dtype=np.float64)
    for i in range(M) if only is None else only:
        v = U @ B[i]
        for j in np.flatnonzero(C[i, :i]):
            v = v + C[i, j] * out[:, j, 1] / params[j, 1]
        bad = integrate_element(
            params[i, 0],
            params[i, 1],
            params[i, 2],
            params[i, 3],
            np.ascontiguousarray(v),
            dt,
            substeps,
            start[i],
            buf,
        )
        out[:, i, :] = buf
        if bad >= 0:
            first_bad = bad if first_bad < 0 else min(first_bad, bad)
    return out, first_bad


def descendants(C: np.ndarray, changed: set[int]) -> list[int]:
    """The changed elements and every element downstream of them, in increasing (topological) order."""
    affected = set(changed)
    for i in range(C.shape[0]):
        if affected and i not in affected and np.any(C[i, sorted(affected)] != 0):
            affected.add(i)
    return sorted(affected)
