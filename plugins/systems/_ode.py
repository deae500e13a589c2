"""Batched RK4 for the built-in driven flows, state and variational equation (compiled).

One call advances every replica by one sampling interval of ``substeps`` RK4 steps of size ``h``.
The drive of a row is ``(u_start, u_end)``: the input at the two ends of the interval, linearly
interpolated in between. ``kind`` selects the vector field:

* DUFFING    x1' = x2, x2' = -k1 x1 - k3 x1^3 - d x2 + u                 (eq. 4.40 / 4.41), p = (k1, k3, d)
* LORENZ_452 x1' = al s (u - x1), x2' = al (r x1 - x2 - x1 x3), x3' = al (x1 x2 - b x3)   (eq. 4.52)
* LORENZ_446 x1' = al (-s x1 + u), x2' = al (r x1 - x2 - x1 x3), x3' = al (x1 x2 - b x3)  (eq. 4.46)
* LORENZ_443 x1' = al s (x2 - x1), x2' = al (r u - x2 - u x3), x3' = al (u x2 - b x3)     (eq. 4.43)
  with p = (s, r, b, al).
"""

from __future__ import annotations

import numpy as np
from numba import njit

DUFFING, LORENZ_452, LORENZ_446, LORENZ_443 = 0, 1, 2, 3


@njit(cache=True, error_model="numpy")
def _field(kind, p, x, u, out):
    if kind == DUFFING:
        out[0] = x[1]
        out[1] = -p[0] * x[0] - p[1] * x[0] * x[0] * x[0] - p[2] * x[1] + u
    else:
        s, r, b, al = p[0], p[1], p[2], p[3]
        if kind == LORENZ_452:
            out[0] = al * s * (u - x[0])
            out[1] = al * (r * x[0] - x[1] - x[0] * x[2])
            out[2] = al * (x[0] * x[1] - b * x[2])
        elif kind == LORENZ_446:
            out[0] = al * (-s * x[0] + u)
            out[1] = al * (r * x[0] - x[1] - x[0] * x[2])
            out[2] = al * (x[0] * x[1] - b * x[2])
        else:
            out[0] = al * s * (x[1] - x[0])
            out[1] = al * (r * u - x[1] - u * x[2])
            out[2] = al * (u * x[1] - b * x[2])


@njit(cache=True, error_model="numpy")
def _jacobian(kind, p, x, u, J):
    J[:, :] = 0.0
    if kind == DUFFING:
        J[0, 1] = 1.0
        J[1, 0] = -p[0] - 3.0 * p[1] * x[0] * x[0]
        J[1, 1] = -p[2]
    else:
        s, r, b, al = p[0], p[1], p[2], p[3]
        if kind == LORENZ_443:
            J[0, 0] = -al * s
            J[0, 1] = al * s
            J[1, 1] = -al
            J[1, 2] = -al * u
            J[2, 1] = al * u
            J[2, 2] = -al * b
        else:
            J[0, 0] = -al * s
            J[1, 0] = al * (r - x[2])
            J[1, 1] = -al
            J[1, 2] = -al * x[0]
            J[2, 0] = al * x[1]
            J[2, 1] = al * x[0]
            J[2, 2] = -al * b


@njit(cache=True, error_model="numpy")
def step_batch(kind, p, X, V, substeps, h, out):
    """out[r] = state after one sampling interval from X[r] under the drive V[r] = (u0, u1)."""
    m = X.shape[1]
    k1 = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    y = np.empty(m)
    tmp = np.empty(m)
    for r in range(X.shape[0]):
        u0 = V[r, 0]
        du = (V[r, 1] - u0) / substeps
        for i in range(m):
            y[i] = X[r, i]
        for s in range(substeps):
            ua = u0 + du * s
            um = ua + 0.5 * du
            ub = ua + du
            _field(kind, p, y, ua, k1)
            for i in range(m):
                tmp[i] = y[i] + 0.5 * h * k1[i]
            _field(kind, p, tmp, um, k2)
            for i in range(m):
                tmp[i] = y[i] + 0.5 * h * k2[i]
            _field(kind, p, tmp, um, k3)
            for i in range(m):
                tmp[i] = y[i] + h * k3[i]
            _field(kind, p, tmp, ub, k4)
            for i in range(m):
                y[i] += (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for i in range(m):
            out[r, i] = y[i]


@njit(cache=True, error_model="numpy")
def _aug(kind, p, y, E, u, J, dy, dE):
    """Right-hand side of the state and of its variational equation E' = J E."""
    _field(kind, p, y, u, dy)
    _jacobian(kind, p, y, u, J)
    m = y.shape[0]
    for i in range(m):
        for j in range(E.shape[1]):
            acc = 0.0
            for q in range(m):
                acc += J[i, q] * E[q, j]
            dE[i, j] = acc


@njit(cache=True, error_model="numpy")
def tangent_batch(kind, p, X, V, E, substeps, h, out, Eout):
    """Like step_batch, and Eout[r] = (d x_end / d x_start) E[r], integrated with the same RK4."""
    m = X.shape[1]
    k = E.shape[2]
    J = np.empty((m, m))
    y = np.empty(m)
    Y = np.empty((m, k))
    ty = np.empty(m)
    tY = np.empty((m, k))
    ky = np.empty((4, m))
    kY = np.empty((4, m, k))
    for r in range(X.shape[0]):
        u0 = V[r, 0]
        du = (V[r, 1] - u0) / substeps
        for i in range(m):
            y[i] = X[r, i]
            for j in range(k):
                Y[i, j] = E[r, i, j]
        for s in range(substeps):
            ua = u0 + du * s
            us = (ua, ua + 0.5 * du, ua + 0.5 * du, ua + du)
            for stage in range(4):
                if stage == 0:
                    for i in range(m):
                        ty[i] = y[i]
                        for j in range(k):
                            tY[i, j] = Y[i, j]
                else:
                    c = h if stage == 3 else 0.5 * h
                    for i in range(m):
                        ty[i] = y[i] + c * ky[stage - 1, i]
                        for j in range(k):
                            tY[i, j] = Y[i, j] + c * kY[stage - 1, i, j]
                _aug(kind, p, ty, tY, us[stage], J, ky[stage], kY[stage])
            for i in range(m):
                y[i] += (h / 6.0) * (ky[0, i] + 2.0 * ky[1, i] + 2.0 * ky[2, i] + ky[3, i])
                for j in range(k):
                    Y[i, j] += (h / 6.0) * (kY[0, i, j] + 2.0 * kY[1, i, j] + 2.0 * kY[2, i, j] + kY[3, i, j])
        for i in range(m):
            out[r, i] = y[i]
            for j in range(k):
                Eout[r, i, j] = Y[i, j]
