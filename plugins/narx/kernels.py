"""Compiled (numba) loops of the polynomial NARX model.

The model (eq. 3.8 with monomials 3.10): for every output k,

    yhat_t[k] = sum_{j: out(j) = k} w_j prod_f x_t[reg_f]^{pow_f},

where the regressors x_t are inputs u[t - lag] and *fed-back* outputs f[t - lag]. In a free run
the fed-back signal is the prediction; in the error-propagation scheme of thesis 6.3.2 it is the
mixture f_t[k] = mix[k] y_t[k] + (1 - mix[k]) yhat_t[k] (mix = 1: one-step prediction, mix = 0:
free run; one value per output, so that one output can run free while the others are measured).
Before ``start`` the measured outputs are used (the initial past of a free run); values before a
recording's first sample are 0. An optional clip [clip_lo, clip_hi] bounds the output (eq. 6.25);
a value outside the divergence band [lo, hi] (or NaN) stops the run and is reported.

:func:`free_run_jacobian` also propagates the forward sensitivities
S_t = d yhat_t / d w (n_outputs x n_terms):

    S_t[k] = phi_t[k] + sum_r (d g_k / d x_r) * c_{t - lag_r} * S_{t - lag_r}[ch_r]

for the output regressors r, with phi_t[k, j] the monomial j when out(j) = k, and c the
derivative of the fed-back signal with respect to the prediction (1 - mix[k], 0 for measured values
and 0 where the output was clipped).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynmodel.kernels.tanh import FASTMATH


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _ipow(v, e):
    m = v
    for _ in range(e - 1):
        m *= v
    return m


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _fill(t, U, fb, src, ch, lag, x):
    for r in range(x.shape[0]):
        k = t - lag[r]
        if k < 0:
            x[r] = 0.0
        elif src[r] == 0:
            x[r] = U[k, ch[r]]
        else:
            x[r] = fb[k, ch[r]]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def monomials(X, ptr, reg, pw, out):
    """out[i, j] = prod_f X[i, reg_f]^pow_f over the factors of term j (the pool, eq. 3.13)."""
    n_terms = ptr.shape[0] - 1
    for i in range(X.shape[0]):
        for j in range(n_terms):
            p = 1.0
            for f in range(ptr[j], ptr[j + 1]):
                p *= _ipow(X[i, reg[f]], pw[f])
            out[i, j] = p


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def free_run(U, Y, src, ch, lag, ptr, reg, pw, out, w, n_out, start, mix, clip_lo, clip_hi, lo, hi):
    """Run the model over U (n, n_in). Returns (yhat (n, n_out), diverged sample or -1).

    ``Y`` holds measured outputs: rows before ``start`` are the initial past (copied to yhat);
    where mix[k] > 0 every finite measured value takes part in the fed-back mixture.
    """
    n = U.shape[0]
    n_terms = w.shape[0]
    yhat = np.full((n, n_out), np.nan)
    fb = np.zeros((n, n_out))
    x = np.empty(src.shape[0])
    acc = np.empty(n_out)
    n_meas = Y.shape[0]
    for t in range(min(start, n)):
        for k in range(n_out):
            yhat[t, k] = Y[t, k]
            fb[t, k] = Y[t, k]
    for t in range(start, n):
        _fill(t, U, fb, src, ch, lag, x)
        for k in range(n_out):
            acc[k] = 0.0
        for j in range(n_terms):
            mon = 1.0
            for f in range(ptr[j], ptr[j + 1]):
                mon *= _ipow(x[reg[f]], pw[f])
            acc[out[j]] += w[j] * mon
        bad = False
        for k in range(n_out):
            v = acc[k]
            if v != v:
                bad = True
            if v > clip_hi[k]:
                v = clip_hi[k]
            elif v < clip_lo[k]:
                v = clip_lo[k]
            if not (lo[k] <= v <= hi[k]):
                bad = True
            yhat[t, k] = v
            f = v
            if mix[k] > 0.0 and t < n_meas:
                m = Y[t, k]
                if m == m:
                    f = mix[k] * m + (1.0 - mix[k]) * v
            fb[t, k] = f
        if bad:
            for k in range(n_out):
                yhat[t, k] = np.nan
            return yhat, t
    return yhat, -1


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def free_run_jacobian(U, Y, src, ch, lag, ptr, reg, pw, out, w, n_out, start, mix, clip_lo, clip_hi, lo, hi):
    """:func:`free_run` plus the sensitivities J (n, n_out, n_terms) = d yhat_t / d w by the
    forward recursion of the module docstring (exact, no finite differences)."""
    n = U.shape[0]
    n_terms = w.shape[0]
    n_reg = src.shape[0]
    yhat = np.full((n, n_out), np.nan)
    fb = np.zeros((n, n_out))
    dfb = np.zeros((n, n_out))  # d fb_t / d yhat_t
    J = np.zeros((n, n_out, n_terms))
    x = np.empty(n_reg)
    acc = np.empty(n_out)
    G = np.zeros((n_out, n_reg))
    n_meas = Y.shape[0]
    for t in range(min(start, n)):
        for k in range(n_out):
            yhat[t, k] = Y[t, k]
            fb[t, k] = Y[t, k]
    for t in range(start, n):
        _fill(t, U, fb, src, ch, lag, x)
        for k in range(n_out):
            acc[k] = 0.0
            for r in range(n_reg):
                G[k, r] = 0.0
        for j in range(n_terms):
            k = out[j]
            mon = 1.0
            for f in range(ptr[j], ptr[j + 1]):
                mon *= _ipow(x[reg[f]], pw[f])
            acc[k] += w[j] * mon
            J[t, k, j] = mon
            # d monomial / d x_r for the fed-back regressors among its factors
            for f in range(ptr[j], ptr[j + 1]):
                r = reg[f]
                if src[r] == 0 or t - lag[r] < start:
                    continue
                d = pw[f] * _ipow(x[r], pw[f] - 1) if pw[f] > 1 else 1.0
                for g in range(ptr[j], ptr[j + 1]):
                    if g != f:
                        d *= _ipow(x[reg[g]], pw[g])
                G[k, r] += w[j] * d
        for k in range(n_out):
            for r in range(n_reg):
                gk = G[k, r]
                if gk == 0.0:
                    continue
                s = t - lag[r]
                c = gk * dfb[s, ch[r]]
                if c != 0.0:
                    row = J[s, ch[r]]
                    for j in range(n_terms):
                        J[t, k, j] += c * row[j]
        bad = False
        for k in range(n_out):
            v = acc[k]
            clipped = False
            if v != v:
                bad = True
            if v > clip_hi[k]:
                v = clip_hi[k]
                clipped = True
            elif v < clip_lo[k]:
                v = clip_lo[k]
                clipped = True
            if not (lo[k] <= v <= hi[k]):
                bad = True
            if clipped:
                for j in range(n_terms):
                    J[t, k, j] = 0.0
            yhat[t, k] = v
            f = v
            dfb[t, k] = 1.0
            if mix[k] > 0.0 and t < n_meas:
                m = Y[t, k]
                if m == m:
                    f = mix[k] * m + (1.0 - mix[k]) * v
                    dfb[t, k] = 1.0 - mix[k]
            fb[t, k] = f
        if bad:
            for k in range(n_out):
                yhat[t, k] = np.nan
            return yhat, J, t
    return yhat, J, -1


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def model_gradient(X, ptr, reg, pw, out, w, n_out, fed_back):
    """D[t, k, r] = d yhat_t[k] / d x_t[r] of the model along the regressor rows X, for the
    regressors with ``fed_back[r]`` (0 elsewhere)."""
    n, n_reg = X.shape
    D = np.zeros((n, n_out, n_reg))
    for t in range(n):
        for j in range(w.shape[0]):
            for f in range(ptr[j], ptr[j + 1]):
                r = reg[f]
                if not fed_back[r]:
                    continue
                d = pw[f] * _ipow(X[t, r], pw[f] - 1) if pw[f] > 1 else 1.0
                for g in range(ptr[j], ptr[j + 1]):
                    if g != f:
                        d *= _ipow(X[t, reg[g]], pw[g])
                D[t, out[j], r] += w[j] * d
    return D


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def candidate_sensitivities(X, D, ch, lag, fed, live, cptr, creg, cpw, cout, start, t0, t1, prev):
    """Free-run sensitivities of candidate terms, rows t0 <= t < t1.

    S[t, k, c] = d yhat_t[k] / d v_c, where v_c is the weight of candidate c (a monomial for
    output cout[c]) added to the model at v_c = 0:
        S_t[k, c] = [k == cout[c]] m_c(x_t) + sum_{r fed back} D[t, k, r] S_{t - lag_r}[ch_r, c],
    with S = 0 before ``start`` and at outputs that were clipped (live[t, k] = False). ``prev``
    holds rows t0 - P .. t0 - 1 (P = prev.shape[0] >= the largest fed-back lag).
    """
    n_out = D.shape[1]
    K = cptr.shape[0] - 1
    P = prev.shape[0]
    S = np.zeros((t1 - t0, n_out, K))
    for t in range(t0, t1):
        i = t - t0
        if t < start:
            continue
        for c in range(K):
            k = cout[c]
            if live[t, k]:
                m = 1.0
                for f in range(cptr[c], cptr[c + 1]):
                    m *= _ipow(X[t, creg[f]], cpw[f])
                S[i, k, c] = m
        for k in range(n_out):
            if not live[t, k]:
                continue
            for r in range(fed.shape[0]):
                if not fed[r]:
                    continue
                d = D[t, k, r]
                s = t - lag[r]
                if d == 0.0 or s < start:
                    continue
                if s >= t0:
                    row = S[s - t0, ch[r]]
                else:
                    row = prev[P - (t0 - s), ch[r]]
                for c in range(K):
                    S[i, k, c] += d * row[c]
    return S


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def moment_sums(XT, YT, parent, var, n_low, chunk):
    """Sums over the samples of every monomial of a table built factor by factor (monomial k is
    monomial parent[k] times regressor var[k]; k = 0 is the constant), and of the first ``n_low``
    monomials times each target: (acc (M,), acc_y (n_low, q)). XT: (n_reg, N), YT: (q, N)."""
    N = XT.shape[1]
    M = parent.shape[0]
    q = YT.shape[0]
    acc = np.zeros(M)
    acc_y = np.zeros((n_low, q))
    buf = np.empty((M, chunk))
    for a in range(0, N, chunk):
        m = min(N, a + chunk) - a
        for i in range(m):
            buf[0, i] = 1.0
        acc[0] += m
        for j in range(q):
            s = 0.0
            for i in range(m):
                s += YT[j, a + i]
            acc_y[0, j] += s
        for k in range(1, M):
            row = buf[parent[k]]
            x = XT[var[k]]
            out = buf[k]
            s = 0.0
            for i in range(m):
                v = row[i] * x[a + i]
                out[i] = v
                s += v
            acc[k] += s
            if k < n_low:
                for j in range(q):
                    s = 0.0
                    for i in range(m):
                        s += out[i] * YT[j, a + i]
                    acc_y[k, j] += s
    return acc, acc_y
