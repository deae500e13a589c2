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

from .embedding import INPUT, OUTPUT
from .estimation import FreeRunProblem

#: iterations at most (the resonant band-pass converges in about ten)
ITERATIONS = 20
#: a pole of 1 / A(q) at or beyond this radius is pulled inside it before filtering
_MAX_RADIUS = 0.9995
#: the source of the constant term in :func:`_terms`
_CONSTANT = -1


def applies(problem: FreeRunProblem) -> bool:
    """Whether the model is one output, linear in its lagged signals (every term one factor of power 1 or
    the constant), on finite training data. The filters start from rest whatever the model's ``initial``:
    the iterate is only a start, kept when its free run (with the model's own start) fits better."""
    st = problem.st
    if st.n_out != 1 or not len(st.reg):  # one output, at least one lagged signal
        return False
    if np.any(np.diff(st.ptr) > 1) or np.any(st.pw != 1):
        return False
    return all(np.isfinite(u).all() and np.isfinite(y).all() for _, u, y in problem.series())


def _terms(problem: FreeRunProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(source, channel, lag) of each term of a linear model (source _CONSTANT for the constant)."""
    st = problem.st
    factor = st.reg[np.minimum(st.ptr[:-1], len(st.reg) - 1)]  # each term's single regressor
    constant = st.ptr[1:] == st.ptr[:-1]
    return np.where(constant, _CONSTANT, st.src[factor]), st.ch[factor], np.where(constant, 0, st.lag[factor])


def _denominator(terms: tuple[np.ndarray, np.ndarray, np.ndarray], w: np.ndarray) -> np.ndarray:
    """A(q) = 1 - sum_i a_i q^-i from the weights of the output-lag terms, its poles inside _MAX_RADIUS."""
    src, _, lag = terms
    a = np.zeros(int(lag.max(initial=0)) + 1)
    a[0] = 1.0
    fed_back = src == OUTPUT
    np.subtract.at(a, lag[fed_back], w[fed_back])
    order = int(np.flatnonzero(a)[-1])  # trailing zeros (output lags shorter than the input lags) are no poles
    poles = np.roots(a[: order + 1])
    radius = np.abs(poles)
    if poles.size and radius.max() >= _MAX_RADIUS:
        poles = poles * np.minimum(1.0, _MAX_RADIUS / np.maximum(radius, _MAX_RADIUS))
        a[: order + 1] = np.real(np.poly(poles))
    return a


def _filtered_regressors(
    problem: FreeRunProblem, terms: tuple[np.ndarray, np.ndarray, np.ndarray], a: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the terms' values and targets on the training rows, every signal filtered by 1 / A(q)."""
    src, ch, lag = terms
    pad = int(lag.max(initial=0))  # values before a recording's first sample are 0 (as in 3.1.1)
    X, T = [], []
    for rows, u, y in problem.series():
        uf = np.concatenate([np.zeros((pad, u.shape[1])), signal.lfilter([1.0], a, u, axis=0)])
        yf = np.concatenate([np.zeros((pad, y.shape[1])), signal.lfilter([1.0], a, y, axis=0)])
        ones = np.concatenate([np.zeros(pad), signal.lfilter([1.0], a, np.ones(len(y)))])
        at = (rows + pad)[:, None] - lag[None, :]
        cols = np.empty(at.shape)
        for source, values in ((OUTPUT, yf), (INPUT, uf)):
            of = src == source
            cols[:, of] = values[at[:, of], ch[of]]
        cols[:, src == _CONSTANT] = ones[rows + pad, None]
        X.append(cols)
        T.append(yf[rows + pad, 0])
    return np.concatenate(X), np.concatenate(T)


def steiglitz_mcbride(problem: FreeRunProblem, w0: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The Steiglitz-McBride iterate with the smallest free-running training cost (and that cost), started
    from ``w0``; None when the model is not one to which it applies (:func:`applies`)."""
    if not applies(problem):
        return None
    terms = _terms(problem)
    best_w, best_cost = None, np.inf
    w = np.asarray(w0, dtype=np.float64)
    for _ in range(ITERATIONS):
        with np.errstate(over="ignore", invalid="ignore"):
            X, T = _filtered_regressors(problem, terms, _denominator(terms, w))
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
