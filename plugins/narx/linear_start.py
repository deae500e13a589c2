"""A start for the free-running estimation of a linear model: Steiglitz-McBride iterations.

Least squares on the one-step error gives the ARX estimate of y_t = sum_i a_i y_{t-i} + sum_j b_j u_{t-j} + c,
biased when the noise is on the measured output; on a lightly damped system the bias leaves the free run far
off (an eighth-order resonant band-pass, 1 % output noise: 37 - 86 % test NMSE) and Levenberg-Marquardt on
the free-running error (eq. 3.15) started there stops in a local minimum (2.8 % on lags 0..10 from rest). Steiglitz and McBride (1965)
filter the signals by the current 1 / A(q), A(q) = 1 - sum_i a_i q^-i, and solve the same least squares on the
filtered signals; at a fixed point the equation error of the filtered signals is the output error, so the
iterations approach the output-error estimate (for white output noise; the same system: 4.6e-5 %). Each
iteration is one least-squares solve; the iterate with the smallest free-running training error is returned.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from .embedding import OUTPUT
from .estimation import FreeRunProblem

#: iterations at most (the resonant band-pass converges in about ten)
ITERATIONS = 20
#: a pole of 1 / A(q) at or beyond this radius is pulled inside it before filtering
_MAX_RADIUS = 0.9995


def applies(problem: FreeRunProblem) -> bool:
    """Whether the model is one output, linear in its lagged signals (every term one factor of power 1 or
    the constant), on finite training data. The filters start from rest whatever the model's ``initial``:
    the iterate is only a start, kept when its free run (with the model's own start) fits better."""
    st = problem.st
    if st.n_out != 1 or not len(st.ptr) > 1:
        return False
    if np.any(np.diff(st.ptr) > 1) or np.any(st.pw != 1):
        return False
    return all(np.isfinite(u).all() and np.isfinite(y).all() for _, u, y in problem.series())


def _denominator(problem: FreeRunProblem, w: np.ndarray) -> np.ndarray:
    """A(q) = 1 - sum_i a_i q^-i from the weights of the output-lag terms, its poles inside _MAX_RADIUS."""
    st = problem.st
    a = np.zeros(int(st.lag.max(initial=0)) + 1)
    a[0] = 1.0
    for j in range(len(st.ptr) - 1):
        if st.ptr[j + 1] > st.ptr[j]:
            r = st.reg[st.ptr[j]]
            if st.src[r] == OUTPUT:
                a[st.lag[r]] -= w[j]
    order = int(np.flatnonzero(a)[-1])  # trailing zeros (output lags shorter than the input lags) are no poles
    poles = np.roots(a[: order + 1])
    radius = np.abs(poles)
    if poles.size and radius.max() >= _MAX_RADIUS:
        poles = poles * np.minimum(1.0, _MAX_RADIUS / np.maximum(radius, _MAX_RADIUS))
        a[: order + 1] = np.real(np.poly(poles))
    return a


def _filtered_regressors(problem: FreeRunProblem, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the terms' values and targets on the training rows, every signal filtered by 1 / A(q)."""
    st = problem.st
    pad = int(st.lag.max(initial=0))  # values before a recording's first sample are 0 (as in 3.1.1)
    X, T = [], []
    for rows, u, y in problem.series():
        uf = np.concatenate([np.zeros((pad, u.shape[1])), signal.lfilter([1.0], a, u, axis=0)])
        yf = np.concatenate([np.zeros((pad, y.shape[1])), signal.lfilter([1.0], a, y, axis=0)])
        ones = np.concatenate([np.zeros(pad), signal.lfilter([1.0], a, np.ones(len(y)))])
        rows = rows + pad
        cols = []
        for j in range(len(st.ptr) - 1):
            if st.ptr[j + 1] == st.ptr[j]:
                cols.append(ones[rows])
                continue
            r = st.reg[st.ptr[j]]
            source = yf if st.src[r] == OUTPUT else uf
            cols.append(source[rows - st.lag[r], st.ch[r]])
        X.append(np.column_stack(cols))
        T.append(yf[rows, 0])
    return np.concatenate(X), np.concatenate(T)


def steiglitz_mcbride(problem: FreeRunProblem, w0: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The Steiglitz-McBride iterate with the smallest free-running training cost (and that cost), started
    from ``w0``; None when the model is not one to which it applies (:func:`applies`)."""
    if not applies(problem):
        return None
    best_w, best_cost = None, np.inf
    w = np.asarray(w0, dtype=np.float64)
    for _ in range(ITERATIONS):
        with np.errstate(over="ignore", invalid="ignore"):
            X, T = _filtered_regressors(problem, _denominator(problem, w))
        if not (np.isfinite(X).all() and np.isfinite(T).all()):
            break
        w_next = np.linalg.lstsq(X, T, rcond=None)[0]
        if not np.all(np.isfinite(w_next)):
            break
        cost = problem.cost(w_next)
        if cost < best_cost:
            best_w, best_cost = w_next, cost
        if np.allclose(w_next, w, rtol=1e-9, atol=1e-12):
            break
        w = w_next
    return None if best_w is None else (best_w, float(best_cost))
