"""Driven-system view of sigmoid networks x_t = a x_{t-1} + g tanh(C x_{t-1} + c0 + B v_t)
(thesis eq. 4.49, 5.22, 6.21), on the compiled kernels, and their linear output feedback (5.3.2).

Any network family can return these from ``Family.driven_system()``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import kernels
from .evidence import largest_singular_value, tanh_network_evidence
from .system import ClosedLoop, DrivenSystem, Evidence, InputDomain

DENSE_MIN_SIZE = 64
DENSE_MAX_SIZE = 5000
DENSE_MIN_FILL = 0.05


class SigmoidNetwork(DrivenSystem):
    """x_t = a x_{t-1} + g tanh(C x_{t-1} + c0 + B v_t) for many replicas at once."""

    name = "sigmoid-network"
    description = "network of tanh elements (thesis eq. 4.49 / 5.22 / 6.21)"

    def __init__(
        self,
        C,
        B: np.ndarray,
        c0: np.ndarray,
        a: np.ndarray | None = None,
        g: np.ndarray | None = None,
        inputs: InputDomain | None = None,
        closed_loop: ClosedLoop | None = None,
        name: str | None = None,
        description: str | None = None,
    ):
        C = sp.csr_matrix(C, dtype=np.float64)
        C.sort_indices()
        m = C.shape[0]
        self.C = C
        self.B = np.ascontiguousarray(np.asarray(B, dtype=np.float64).reshape(m, -1))
        self.c0 = np.ascontiguousarray(c0, dtype=np.float64)
        self.a = np.zeros(m) if a is None else np.ascontiguousarray(a, dtype=np.float64)
        self.g = np.ones(m) if g is None else np.ascontiguousarray(g, dtype=np.float64)
        self.state_dim = m
        d = self.B.shape[1]
        self.inputs = (
            inputs
            if inputs is not None
            else InputDomain.from_range([f"v{j}" for j in range(d)], -np.ones(d), np.ones(d))
        )
        self.closed_loop = closed_loop
        self.rest_state = np.zeros(m)
        if name:
            self.name = name
        if description:
            self.description = description
        self._args = (
            C.indptr.astype(np.int64),
            C.indices.astype(np.int64),
            C.data.astype(np.float64),
            self.B,
            self.c0,
            self.a,
            self.g,
        )
        # dense connection matrices: contiguous compiled loops over C^T beat the sparse gather
        # (and, unlike BLAS, do not stall when the machine is busy)
        use_dense = DENSE_MIN_SIZE <= m <= DENSE_MAX_SIZE and C.nnz >= DENSE_MIN_FILL * m * m
        self._dense = np.ascontiguousarray(C.T.toarray()) if use_dense else None

    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        out = np.empty(X.shape) if out is None else out
        X, V = np.ascontiguousarray(X), np.ascontiguousarray(V)
        if self._dense is not None:
            kernels.dense_step_batch(self._dense, *self._args[3:], X, V, out)
        else:
            kernels.step_batch(*self._args, X, V, out)
        return out

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out = np.empty(X.shape)
        Eout = np.empty(E.shape)
        X, V, E = np.ascontiguousarray(X), np.ascontiguousarray(V), np.ascontiguousarray(E)
        if self._dense is not None:
            kernels.dense_tangent_batch(self._dense, *self._args[3:], X, V, E, out, Eout)
        else:
            kernels.tangent_batch(*self._args, X, V, E, out, Eout)
        return out, Eout

    def state_box(self) -> tuple[np.ndarray, np.ndarray]:
        """|x_i| <= g_i / (1 - |a_i|) once the start is inside: [-1, 1]^M for a = 0, g = 1."""
        half = self.g / (1.0 - np.abs(self.a))
        return -half, half

    def evidence(self) -> list[Evidence]:
        return tanh_network_evidence(self.C, self.a, self.g, self.c0)


class LinearFeedback(ClosedLoop):
    """Readout y_t = W x_t + D v_t + w0 fed back as the last ``n_outputs`` drive channels."""

    def __init__(
        self,
        W: np.ndarray,
        D: np.ndarray,
        w0: np.ndarray,
        tune_in: int,
        rest_output: np.ndarray,
        C=None,
        B_back: np.ndarray | None = None,
    ):
        self.W = np.ascontiguousarray(W, dtype=np.float64)
        self.D = np.ascontiguousarray(D, dtype=np.float64)
        self.w0 = np.ascontiguousarray(w0, dtype=np.float64)
        self.n_outputs = self.W.shape[0]
        self.tune_in = int(tune_in)
        self.rest_output = np.asarray(rest_output, dtype=np.float64)
        self._C, self._B_back = C, B_back

    def readout(self, X: np.ndarray, V: np.ndarray) -> np.ndarray:
        return X @ self.W.T + V @ self.D.T + self.w0

    def facts(self) -> list[Evidence]:
        if self._C is None or self._B_back is None:
            return []
        Ct = sp.csr_matrix(self._C).toarray() + self._B_back @ self.W
        s = largest_singular_value(Ct)
        direct = self.D[:, -self.n_outputs :]
        note = "" if not np.any(direct) else " (ignoring the direct link of the fed-back output)"
        return [
            Evidence(
                "sigma(C + b_back w^T)",
                s,
                "undecided",
                f"closed-loop matrix of eq. 5.34{note}: the feedback makes the free run unreliable on "
                "purpose (5.3.2), so it needs a tune-in",
            )
        ]
