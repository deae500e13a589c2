"""The driven-system view of a Lorenz network for `dynmodel reliability-check` (thesis 4.4.1)."""

from __future__ import annotations

import numpy as np

from dynmodel.reliability.system import DrivenSystem, Evidence, Implication, InputDomain

from .elements import simulate_network, step_elements


class LorenzNetworkSystem(DrivenSystem):
    """x_t = Phi(x_{t-1}, u_t): one sampling interval of the network (states of element i in columns
    3i .. 3i+2), with the drive held over the interval as in the model itself."""

    name = "lorenz-net"
    description = "network of driven Lorenz systems (eq. 4.52, 4.59)"
    continuous = True

    def __init__(self, params: np.ndarray, C: np.ndarray, B: np.ndarray, dt: float, substeps: int, inputs: InputDomain):
        self.params, self.C, self.B = params, C, B
        self.m = params.shape[0]
        self.state_dim = 3 * self.m
        self.sampling_time = dt
        self.substeps = substeps
        self.inputs = inputs
        self.rest_state = np.zeros(self.state_dim)
        self._box: tuple[np.ndarray, np.ndarray] | None = None

    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        R = X.shape[0]
        res = np.empty((R, self.m, 3))
        step_elements(
            self.params,
            self.C,
            self.B,
            np.ascontiguousarray(X.reshape(R, self.m, 3)),
            np.ascontiguousarray(V),
            self.sampling_time,
            self.substeps,
            res,
        )
        return res.reshape(R, self.state_dim)

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tangent vectors by central differences of the step map (error O(eps^2))."""
        fx = self.step(X, V)
        k = E.shape[2]
        eps = 1e-6 * max(self.scale(), 1.0)
        DE = np.empty_like(E)
        for j in range(k):
            d = E[:, :, j]
            norm = np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
            unit = d / norm
            DE[:, :, j] = (self.step(X + eps * unit, V) - self.step(X - eps * unit, V)) / (2 * eps) * norm
        return fx, DE

    def state_box(self) -> tuple[np.ndarray, np.ndarray]:
        """The range the states reach under white noise and the extreme constant inputs of the
        input domain, widened by half its width."""
        if self._box is None:
            rng = np.random.default_rng(0)
            n = 2000
            u = self.inputs.mean + self.inputs.std * rng.standard_normal((n, self.inputs.n))
            u = np.vstack([u, np.tile(self.inputs.low, (n // 2, 1)), np.tile(self.inputs.high, (n // 2, 1))])
            X, _ = simulate_network(self.params, self.C, self.B, u, self.sampling_time, self.substeps)
            X = X.reshape(len(u), -1)
            lo, hi = np.nanmin(X, axis=0), np.nanmax(X, axis=0)
            pad = 0.5 * np.maximum(hi - lo, 1e-3)
            self._box = (lo - pad, hi + pad)
        return self._box

    def evidence(self) -> list[Evidence]:
        positive = bool(np.all(self.params > 0))
        lower = bool(np.all(np.triu(self.C) == 0))
        h = self.sampling_time / self.substeps
        stiff = float(
            np.max(self.params[:, 3] * np.maximum.reduce([self.params[:, 0], self.params[:, 2], np.ones(self.m)])) * h
        )
        implies: Implication = "reliable" if positive and lower and stiff < 1.0 else "undecided"
        statement = (
            "every element has sigma, b, alpha > 0, so it forgets its initial state for any drive "
            "(Lyapunov function of eq. 4.44 / 4.45), and the couplings are strictly lower triangular, so "
            f"the network is a cascade of such elements; RK4 step x rate = {stiff:.2g}"
            + ("" if implies == "reliable" else " (the numerical tests decide)")
        )
        return [Evidence("cascade of driven Lorenz elements", float(np.min(self.params)), implies, statement)]
