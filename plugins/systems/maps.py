"""Driven maps of thesis 4.4.1 and 5.3.1.

* ``gaussian-map``  x_t = exp(-a^2 (x_{t-1} - b)^2) + u_t (eq. 4.37, a = 3.5, b = 0.5): fixed points,
                    n-cycles and chaos for constant inputs in [0, 1] (fig. 4.8), hence unreliable.
* ``tanh-network``  x_t = tanh(C x_{t-1} + c0 + b u_t) (eq. 4.49 / 5.22), by default the 2-element
                    network of eq. 5.28 (sigma 3.07, rho 0.79: a fixed point and a 2-cycle at u = 0);
                    ``sigma`` / ``rho`` rescale C.
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from pydantic import Field, model_validator

from dynmodel.reliability.evidence import largest_singular_value, spectral_radius
from dynmodel.reliability.networks import SigmoidNetwork
from dynmodel.reliability.system import InputDomain, SystemParams, TestSystem

EQ_5_28 = [[0.34, 2.31], [-0.56, -1.93]]


class GaussianMapParams(SystemParams):
    a: float = Field(3.5, description="width parameter a of eq. 4.37")
    b: float = Field(0.5, description="centre b of eq. 4.37")
    input_range: tuple[float, float] = Field((0.0, 1.0), description="range of the input (fig. 4.8: [0, 1])")


class GaussianMap(TestSystem):
    name = "gaussian-map"
    description = "driven Gaussian map x_t = exp(-a^2 (x_{t-1} - b)^2) + u_t, a = 3.5, b = 0.5 (thesis eq. 4.37)"
    Params = GaussianMapParams
    params: GaussianMapParams

    def setup(self) -> None:
        p = self.params
        self.state_dim = 1
        self.inputs = InputDomain.from_range(["u"], p.input_range[0], p.input_range[1])
        self._a2 = p.a * p.a

    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        return np.exp(-self._a2 * (X - self.params.b) ** 2) + V[:, :1]

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray):
        e = np.exp(-self._a2 * (X - self.params.b) ** 2)
        J = -2.0 * self._a2 * (X - self.params.b) * e
        return e + V[:, :1], J[:, :, None] * E

    def state_box(self):
        """x_t lies in [u_t, u_t + 1]."""
        lo, hi = self.params.input_range
        return np.array([lo]), np.array([hi + 1.0])


class TanhNetworkParams(SystemParams):
    C: list[list[float]] = Field(
        default_factory=lambda: [list(r) for r in EQ_5_28], description="connection matrix (default: eq. 5.28)"
    )
    b: Optional[list[float]] = Field(None, description="input weights (default: ones)")
    c0: Optional[list[float]] = Field(None, description="biases (default: zeros)")
    sigma: Optional[float] = Field(None, gt=0, description="rescale C to this largest singular value")
    rho: Optional[float] = Field(None, gt=0, description="rescale C to this spectral radius")
    input_range: tuple[float, float] = Field((-1.0, 1.0), description="range of the input")

    @model_validator(mode="after")
    def _shapes(self):
        m = len(self.C)
        if m == 0 or any(len(r) != m for r in self.C):
            raise ValueError("C must be a square matrix")
        for key in ("b", "c0"):
            v = getattr(self, key)
            if v is not None and len(v) != m:
                raise ValueError(f"{key} has {len(v)} entries but C has {m} rows")
        if self.sigma is not None and self.rho is not None:
            raise ValueError("give sigma or rho, not both")
        return self


class TanhNetwork(TestSystem):
    name = "tanh-network"
    description = "x_t = tanh(C x_{t-1} + c0 + b u_t), default the 2-element network of eq. 5.28 (thesis 5.3.1)"
    Params = TanhNetworkParams
    params: TanhNetworkParams

    def setup(self) -> None:
        p = self.params
        C = np.asarray(p.C, dtype=np.float64)
        if p.sigma is not None:
            C = C * (p.sigma / largest_singular_value(C))
        elif p.rho is not None:
            C = C * (p.rho / spectral_radius(C))
        m = C.shape[0]
        b = np.ones(m) if p.b is None else np.asarray(p.b, dtype=np.float64)
        c0 = np.zeros(m) if p.c0 is None else np.asarray(p.c0, dtype=np.float64)
        inputs = InputDomain.from_range(["u"], p.input_range[0], p.input_range[1])
        self.net = SigmoidNetwork(C, b[:, None], c0, inputs=inputs)
        self.C = C
        self.state_dim = m
        self.inputs = inputs
        self.rest_state = np.zeros(m)

    def step(self, X, V, out=None):
        return self.net.step(X, V, out)

    def tangent(self, X, V, E):
        return self.net.tangent(X, V, E)

    def state_box(self):
        return self.net.state_box()

    def evidence(self):
        return self.net.evidence()
