"""A fitted NARX model as a driven system, for ``dynmodel reliability-check`` (thesis definition 4.4).

The free run y_k(t) = clip(sum_j w_j prod_r x_r(t)^p_jr) of a polynomial NARX model is a driven system whose
state is its own past outputs, x(t) = [y_k(t-1), ..., y_k(t-L)] for every output k (L the longest output lag,
at least 1), driven by the current and past inputs v(t) = [u_j(t), ..., u_j(t-L_u)]. It is reliable when two
free runs started from different past outputs forget the difference: the model's output then depends on its
input alone. A polynomial in the fed-back outputs can have several attractors (a constant and a limit cycle,
or two levels), so a NARX model is not reliable by construction as a contracting network is.

The tangent map is the companion matrix of the output lags: row k L holds d y_k(t) / d x(t-1) (zero where the
output clip holds the output), the other rows shift the state by one sample.
"""

from __future__ import annotations

import numpy as np

from dynmodel.reliability.system import DrivenSystem, InputDomain

from .embedding import INPUT, Embedding, factor_lists
from .kernels import model_gradient, monomials

#: the state box without a training output range: standard-scaled outputs mostly lie within +-2
DEFAULT_BOX = 2.0


class NarxSystem(DrivenSystem):
    """x(t) = f(x(t-1), v(t)) of a polynomial NARX free run, in model space, for many replicas at once."""

    name = "narx"
    state_is_tune_in = True

    def __init__(
        self,
        embedding: Embedding,
        exponents: np.ndarray,
        term_output: np.ndarray,
        weights: np.ndarray,
        n_inputs: int,
        n_outputs: int,
        clip: tuple[np.ndarray, np.ndarray],
        description: str = "",
    ):
        src, ch, lag = embedding.arrays()
        outs = src != INPUT
        self.n_in, self.n_out = n_inputs, n_outputs
        self.L = max(1, int(lag[outs].max()) if outs.any() else 1)  # state: output lags 1..L
        self.Lu = int(lag[~outs].max()) if (~outs).any() else 0  # drive: input lags 0..Lu
        # where each regressor's value sits: a column of the state (outputs) or of the drive (inputs)
        self.column = np.where(outs, ch * self.L + lag - 1, ch * (self.Lu + 1) + lag)
        self.fed_back = outs
        self.exponents = np.asarray(exponents, dtype=np.int64)
        self.term_output = np.asarray(term_output, dtype=np.int64)
        self.weights = np.asarray(weights, dtype=np.float64)
        # the compiled kernels' sparse form of the terms, and the weights as a (terms, outputs) matrix
        self._factors = factor_lists(self.exponents)
        self._weight_matrix = np.zeros((len(self.weights), n_outputs))
        self._weight_matrix[np.arange(len(self.weights)), self.term_output] = self.weights
        self.clip_lo, self.clip_hi = (np.asarray(c, dtype=np.float64) for c in clip)
        self.state_dim = n_outputs * self.L
        self.rest_state = np.zeros(self.state_dim)
        self.inputs = InputDomain.from_range(
            [f"u{j}" for j in range(n_inputs)], -DEFAULT_BOX * np.ones(n_inputs), DEFAULT_BOX * np.ones(n_inputs)
        )
        lo = np.where(np.isfinite(self.clip_lo), self.clip_lo, -DEFAULT_BOX)
        hi = np.where(np.isfinite(self.clip_hi), self.clip_hi, DEFAULT_BOX)
        self.fit_outputs(lo, hi)
        self.description = description or f"NARX model, {len(self.weights)} terms, output lags up to {self.L}"

    def fit_outputs(self, low: np.ndarray, high: np.ndarray, record: np.ndarray | None = None) -> None:
        """The training output range (the state box) and the training outputs, whose windows of L samples are
        the past outputs a measured start presents (see :meth:`sample_states`)."""
        lo, hi = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
        self._box = (np.repeat(lo, self.L), np.repeat(hi, self.L))
        self._record = None
        if record is not None and len(record) > self.L and np.isfinite(record).all():
            self._record = np.asarray(record, dtype=np.float64).reshape(len(record), -1)

    def sample_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Past outputs a free run can start from: the rest state, a system at rest at levels across the
        training output range (every lag at one level), and windows of L consecutive training outputs. Not
        the corners of the box: y(t-1) at the top and y(t-2) at the bottom is a velocity no recording shows,
        and a polynomial fed such a start tells nothing of the model's use."""
        if n <= 0:
            return np.zeros((0, self.state_dim))
        lo, hi = self._box
        out = np.empty((n, self.state_dim))
        levels = max(1, n // 2 if self._record is not None else n)
        for i in range(levels):
            out[i] = lo + (hi - lo) * (i + 0.5) / levels if levels > 1 else 0.5 * (lo + hi)
        if self._record is not None:
            starts = rng.integers(self.L, len(self._record), size=n - levels)
            for i, t in zip(range(levels, n), starts):
                window = self._record[t - self.L : t][::-1]  # y(t-1), ..., y(t-L) per output
                out[i] = window.T.reshape(-1)
        out[0] = self.rest_state
        return out

    # -- dynamics --------------------------------------------------------------------------
    def drive(self, u: np.ndarray) -> np.ndarray:
        """Inputs (n, n_in) -> [u_j(t), u_j(t-1), ..., u_j(t-Lu)] per input (the rest value 0 before the start)."""
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        n = len(u)
        V = np.zeros((n, self.n_in * (self.Lu + 1)))
        for j in range(self.n_in):
            for lag in range(self.Lu + 1):
                V[lag:, j * (self.Lu + 1) + lag] = u[: n - lag, j] if lag else u[:, j]
        return V

    def _regressors(self, X: np.ndarray, V: np.ndarray) -> np.ndarray:
        """(R, n_regressors): each regressor's value for every replica."""
        R = np.empty((X.shape[0], len(self.column)))
        R[:, self.fed_back] = X[:, self.column[self.fed_back]]
        R[:, ~self.fed_back] = V[:, self.column[~self.fed_back]]
        return R

    def _outputs(self, R: np.ndarray) -> np.ndarray:
        """(replicas, n_out): the polynomial of every output before the clip (the monomials of every replica by
        the compiled kernel, then one product with the weights)."""
        mons = np.empty((R.shape[0], len(self.weights)))
        monomials(np.ascontiguousarray(R), *self._factors, mons)
        with np.errstate(over="ignore", invalid="ignore"):
            return mons @ self._weight_matrix

    def _shifted(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        new = np.empty_like(X)
        for k in range(self.n_out):
            a = k * self.L
            new[:, a] = y[:, k]
            new[:, a + 1 : a + self.L] = X[:, a : a + self.L - 1]
        return new

    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        y = np.clip(self._outputs(self._regressors(X, V)), self.clip_lo, self.clip_hi)
        return self._shifted(X, y)

    def _state_gradient(self, R: np.ndarray) -> np.ndarray:
        """G[r, k, m] = d acc_k / d X_m for every replica (only fed-back regressors depend on the state), by the
        compiled model gradient."""
        G = np.zeros((R.shape[0], self.n_out, self.state_dim))
        ptr, reg, pw = self._factors
        D = model_gradient(
            np.ascontiguousarray(R), ptr, reg, pw, self.term_output, self.weights, self.n_out, self.fed_back
        )
        for r in np.flatnonzero(self.fed_back):
            G[:, :, self.column[r]] += D[:, :, r]
        return G

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        R = self._regressors(X, V)
        acc = self._outputs(R)
        y = np.clip(acc, self.clip_lo, self.clip_hi)
        G = self._state_gradient(R)
        held = (acc < self.clip_lo) | (acc > self.clip_hi)  # the clip's derivative is zero there
        G[held] = 0.0
        dE = np.empty_like(E)
        for k in range(self.n_out):
            a = k * self.L
            dE[:, a, :] = np.einsum("rm,rmq->rq", G[:, k, :], E)
            dE[:, a + 1 : a + self.L, :] = E[:, a : a + self.L - 1, :]
        return self._shifted(X, y), dE

    # -- where to start --------------------------------------------------------------------
    def state_box(self) -> tuple[np.ndarray, np.ndarray]:
        return self._box
