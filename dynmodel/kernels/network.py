"""Recurrences of sigmoid networks with one-dimensional elements (thesis eq. 5.13 / 5.18 / 6.21).

    x_t = a * x_{t-1} + g * tanh(C x_{t-1} + c0 + B v_t)

``a`` holds the relaxation parameters, ``g`` the factor in front of tanh (1, or 1 - |a| as in
eq. 6.21). ``C`` is sparse (CSR arrays ``indptr, indices, data``), ``B`` dense. ``v_t`` is the
drive: the external input, plus the fed-back output in the external mode (eq. 5.42 / 5.43).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .tanh import FASTMATH, tanh1


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _pre(indptr, indices, data, B, c0, x, v, z):
    """z = C x + c0 + B v (CSR gather for C)."""
    m = c0.shape[0]
    nv = v.shape[0]
    for i in range(m):
        acc = c0[i]
        for j in range(nv):
            acc += B[i, j] * v[j]
        for k in range(indptr[i], indptr[i + 1]):
            acc += data[k] * x[indices[k]]
        z[i] = acc


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _post(a, g, x, z, out):
    """out = a * x + g * tanh(z) (vectorised)."""
    for i in range(z.shape[0]):
        out[i] = a[i] * x[i] + g[i] * tanh1(z[i])


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def drive(indptr, indices, data, B, c0, a, g, V, x0):
    """States (n, M) of the network driven by V (n, n_drive) from state x0 (internal mode,
    or teacher forcing when V holds the measured past outputs)."""
    n = V.shape[0]
    m = c0.shape[0]
    X = np.empty((n, m))
    z = np.empty(m)
    prev = x0.copy()
    for t in range(n):
        _pre(indptr, indices, data, B, c0, prev, V[t], z)
        _post(a, g, prev, z, X[t])
        prev = X[t]
    return X


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def drive_chunk(indptr, indices, data, B, c0, a, g, V, x, direct, F):
    """Readout features of the next ``n`` steps, written into the preallocated F (n, K):
    ``[x_t, v_t (when direct)]``, driven by V (n, n_drive) from the state ``x`` (M,), which is
    advanced in place to the last state. Chunk after chunk this equals one long :func:`drive`."""
    n = V.shape[0]
    m = c0.shape[0]
    nv = V.shape[1]
    z = np.empty(m)
    prev = x
    for t in range(n):
        _pre(indptr, indices, data, B, c0, prev, V[t], z)
        row = F[t]
        _post(a, g, prev, z, row[:m])
        if direct:
            for j in range(nv):
                row[m + j] = V[t, j]
        prev = row[:m]
    if n > 0:
        x[:] = F[n - 1, :m]


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def drive_output(indptr, indices, data, B, c0, a, g, V, x, W, D, w0, out):
    """Readout ``out[t] = W x_t + D v_t + w0`` (out (n, n_out)) of the network driven by V from
    the state ``x`` (advanced in place); no state is stored (internal mode, teacher forcing)."""
    n = V.shape[0]
    m = c0.shape[0]
    nv = V.shape[1]
    n_out = W.shape[0]
    z = np.empty(m)
    prev = x.copy()
    cur = np.empty(m)
    for t in range(n):
        _pre(indptr, indices, data, B, c0, prev, V[t], z)
        _post(a, g, prev, z, cur)
        for k in range(n_out):
            acc = w0[k]
            for i in range(m):
                acc += W[k, i] * cur[i]
            for j in range(nv):
                acc += D[k, j] * V[t, j]
            out[t, k] = acc
        tmp = prev
        prev = cur
        cur = tmp
    x[:] = prev


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def free_run_span(
    indptr,
    indices,
    data,
    B,
    c0,
    a,
    g,
    U,
    Y,
    tune_in,
    mix,
    W,
    D,
    w0,
    y_rest,
    lo,
    hi,
    clip_lo,
    clip_hi,
    x,
    start,
    stop,
    yhat,
    fb,
    X,
):
    """Samples ``start <= t < stop`` of the external-mode run of :func:`free_run_clipped`, resumable.

    ``x`` (M,) holds the state after sample ``start - 1`` (the rest state when start = 0) and is
    advanced in place; ``yhat`` and ``fb`` (n, n_out) are the whole run's outputs and fed-back
    values (rows before ``start`` must hold the earlier samples); X (stop - start, M) receives the
    states, or has no rows. On divergence at t, ``yhat[t:]`` and ``fb[t + 1:]`` become NaN and t is
    returned (else -1). Outputs are clipped to [clip_lo, clip_hi] before they are stored, checked
    and fed back (+-inf: no clipping). Spans run one after the other give exactly one
    :func:`free_run_clipped`.
    """
    m = c0.shape[0]
    n_in = U.shape[1]
    n_out = W.shape[0]
    has_y = Y.shape[0] > 0
    store = X.shape[0] > 0
    v = np.empty(n_in + n_out)
    z = np.empty(m)
    prev = x.copy()
    cur = np.empty(m)
    for t in range(start, stop):
        for j in range(n_in):
            v[j] = U[t, j]
        for k in range(n_out):
            if tune_in > 0 and t <= tune_in:
                f = Y[t - 1, k] if t > 0 else Y[0, k]
            else:
                f = yhat[t - 1, k] if t > 0 else y_rest[k]
                if mix > 0.0 and has_y:
                    f = mix * (Y[t - 1, k] if t > 0 else Y[0, k]) + (1.0 - mix) * f
            v[n_in + k] = f
            fb[t, k] = f
        _pre(indptr, indices, data, B, c0, prev, v, z)
        _post(a, g, prev, z, cur)
        if store:
            X[t - start] = cur
        bad = False
        for k in range(n_out):
            acc = w0[k]
            for i in range(m):
                acc += W[k, i] * cur[i]
            for j in range(n_in + n_out):
                acc += D[k, j] * v[j]
            if acc > clip_hi[k]:
                acc = clip_hi[k]
            elif acc < clip_lo[k]:
                acc = clip_lo[k]
            yhat[t, k] = acc
            if t >= tune_in and not (lo[k] <= acc <= hi[k]):
                bad = True
        if bad:
            x[:] = cur
            yhat[t:] = np.nan
            fb[t + 1 :] = np.nan
            return t
        tmp = prev
        prev = cur
        cur = tmp
    x[:] = prev
    return -1


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def free_run_clipped(
    indptr, indices, data, B, c0, a, g, U, Y, tune_in, mix, W, D, w0, y_rest, lo, hi, x0, store_states, clip_lo, clip_hi
):
    """External-mode run: the network is fed its own past output.

    Drive ``v_t = [u_t, f_t]`` with feedback ``f_t``:
      * ``t <= tune_in`` (tune-in): measured ``y_{t-1}`` (``y_0`` at t = 0);
      * afterwards ``mix * y_{t-1} + (1 - mix) * yhat_{t-1}`` (``mix`` = 0: pure free run;
        0 < mix < 1: the error-propagation schedule of thesis 6.3.2, needs all of ``Y``).
    Output ``yhat_t = W x_t + D v_t + w0``, clipped to [clip_lo, clip_hi] (eq. 6.25; the clipped
    value is the one fed back). A run whose output leaves [lo, hi] (or is not
    finite) after the tune-in stops; the remaining outputs are NaN and the sample index is
    returned (else -1). Outputs during the tune-in are not fed back and are not checked.

    Returns (states or empty array, yhat (n, n_out), feedback used (n, n_out), diverged_at).
    """
    n = U.shape[0]
    m = c0.shape[0]
    n_out = W.shape[0]
    X = np.empty((n if store_states else 0, m))
    yhat = np.full((n, n_out), np.nan)
    fb = np.full((n, n_out), np.nan)
    x = x0.copy()
    diverged = free_run_span(
        indptr,
        indices,
        data,
        B,
        c0,
        a,
        g,
        U,
        Y,
        tune_in,
        mix,
        W,
        D,
        w0,
        y_rest,
        lo,
        hi,
        clip_lo,
        clip_hi,
        x,
        0,
        n,
        yhat,
        fb,
        X,
    )
    return X, yhat, fb, diverged


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def free_run(indptr, indices, data, B, c0, a, g, U, Y, tune_in, mix, W, D, w0, y_rest, lo, hi, x0, store_states):
    """:func:`free_run_clipped` without clipping."""
    inf = np.full(W.shape[0], np.inf)
    return free_run_clipped(
        indptr, indices, data, B, c0, a, g, U, Y, tune_in, mix, W, D, w0, y_rest, lo, hi, x0, store_states, -inf, inf
    )


@njit(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")
def step_batch(indptr, indices, data, B, c0, a, g, X, V, out):
    """One step for many replicas at once: out[r] = update(X[r], V[r])."""
    m = c0.shape[0]
    z = np.empty(m)
    for r in range(X.shape[0]):
        _pre(indptr, indices, data, B, c0, X[r], V[r], z)
        _post(a, g, X[r], z, out[r])


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def tangent_batch(indptr, indices, data, B, c0, a, g, X, V, E, out, Eout):
    """One step of state and tangent vectors for many replicas (conditional Lyapunov exponents).

    out[r] = a * x + g * tanh(z), z = C x + c0 + B v, and
    Eout[r] = J E[r] with the Jacobian J = diag(a) + diag(g * (1 - tanh(z)^2)) C (thesis 4.4.1).
    E has shape (R, M, k).
    """
    m = c0.shape[0]
    k = E.shape[2]
    z = np.empty(m)
    s = np.empty(m)
    for r in range(X.shape[0]):
        _pre(indptr, indices, data, B, c0, X[r], V[r], z)
        for i in range(m):
            t = tanh1(z[i])
            out[r, i] = a[i] * X[r, i] + g[i] * t
            s[i] = g[i] * (1.0 - t * t)
        for i in range(m):
            for j in range(k):
                acc = 0.0
                for q in range(indptr[i], indptr[i + 1]):
                    acc += data[q] * E[r, indices[q], j]
                Eout[r, i, j] = a[i] * E[r, i, j] + s[i] * acc


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _pre_dense(Ct, B, c0, x, v, z):
    """z = C x + c0 + B v with Ct = C^T stored row-major (contiguous axpy over its rows)."""
    m = c0.shape[0]
    for i in range(m):
        acc = c0[i]
        for j in range(v.shape[0]):
            acc += B[i, j] * v[j]
        z[i] = acc
    for j in range(m):
        xj = x[j]
        if xj != 0.0:
            for i in range(m):
                z[i] += xj * Ct[j, i]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def dense_step_batch(Ct, B, c0, a, g, X, V, out):
    """step_batch for a dense C given as Ct = C^T (faster than the CSR gather when C is full)."""
    z = np.empty(c0.shape[0])
    for r in range(X.shape[0]):
        _pre_dense(Ct, B, c0, X[r], V[r], z)
        _post(a, g, X[r], z, out[r])


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def dense_tangent_batch(Ct, B, c0, a, g, X, V, E, out, Eout):
    """tangent_batch for a dense C given as Ct = C^T."""
    m = c0.shape[0]
    k = E.shape[2]
    z = np.empty(m)
    s = np.empty(m)
    ce = np.empty(m)
    for r in range(X.shape[0]):
        _pre_dense(Ct, B, c0, X[r], V[r], z)
        for i in range(m):
            t = tanh1(z[i])
            out[r, i] = a[i] * X[r, i] + g[i] * t
            s[i] = g[i] * (1.0 - t * t)
        for j in range(k):
            for i in range(m):
                ce[i] = 0.0
            for q in range(m):
                e = E[r, q, j]
                for i in range(m):
                    ce[i] += e * Ct[q, i]
            for i in range(m):
                Eout[r, i, j] = a[i] * E[r, i, j] + s[i] * ce[i]
