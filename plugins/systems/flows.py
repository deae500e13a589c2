"""Driven flows of thesis 4.4.1 / 4.4.2, integrated with fixed-step RK4 (one sampling interval per step).

* ``duffing``       single-well Duffing oscillator (eq. 4.40 / 4.41): one stable fixed point for every
                    constant input, chaotic under u = 27 sin(1.4 t), hence unreliable.
* ``lorenz-driven`` Lorenz systems driven as in eq. 4.52 (default), 4.46 or 4.43: reliable for every
                    input (Lyapunov functions eq. 4.44 / 4.45 and 4.47 / 4.48).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from dynmodel.reliability.system import InputDomain, Sine, SystemParams, TestSystem

from . import _ode


class _FlowParams(SystemParams):
    sampling_time: float = Field(0.1, gt=0, description="time between samples (one step of the check)")
    integration_step: float = Field(0.01, gt=0, description="RK4 step; the sampling time must be a multiple of it")

    @model_validator(mode="after")
    def _multiple(self):
        k = self.sampling_time / self.integration_step
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(
                f"sampling_time {self.sampling_time} is not a whole multiple of integration_step "
                f"{self.integration_step}"
            )
        return self

    @property
    def substeps(self) -> int:
        return int(round(self.sampling_time / self.integration_step))


class _Flow(TestSystem):
    """Common machinery: drive = (input at the start, input at the end) of each sampling interval."""

    continuous = True
    kind: int
    p: np.ndarray
    params: _FlowParams
    box_low: list[float]
    box_high: list[float]

    def drive(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)[:, :1]
        prev = np.empty_like(u)
        prev[0] = u[0]
        prev[1:] = u[:-1]
        return np.ascontiguousarray(np.hstack([prev, u]))

    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        out = np.empty(X.shape) if out is None else out
        _ode.step_batch(
            self.kind,
            self.p,
            np.ascontiguousarray(X),
            np.ascontiguousarray(V),
            self.params.substeps,
            self.params.integration_step,
            out,
        )
        return out

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray):
        out = np.empty(X.shape)
        Eout = np.empty(E.shape)
        _ode.tangent_batch(
            self.kind,
            self.p,
            np.ascontiguousarray(X),
            np.ascontiguousarray(V),
            np.ascontiguousarray(E),
            self.params.substeps,
            self.params.integration_step,
            out,
            Eout,
        )
        return out, Eout

    def state_box(self):
        return np.asarray(self.box_low, dtype=np.float64), np.asarray(self.box_high, dtype=np.float64)


class DuffingParams(_FlowParams):
    damping: float = Field(0.2, ge=0, description="d in x2' = -k1 x1 - k3 x1^3 - d x2 + u")
    linear: float = Field(1.0, description="k1")
    cubic: float = Field(1.0, description="k3 (k3 > 0: single well)")
    input_range: tuple[float, float] = Field((-30.0, 30.0), description="range of the input (fig. 4.9: [-30, 30])")


class Duffing(_Flow):
    name = "duffing"
    description = "single-well Duffing oscillator x1' = x2, x2' = -x1 - x1^3 - 0.2 x2 + u (thesis eq. 4.40 / 4.41)"
    Params = DuffingParams
    params: DuffingParams

    def setup(self) -> None:
        p = self.params
        self.kind = _ode.DUFFING
        self.p = np.array([p.linear, p.cubic, p.damping])
        self.state_dim = 2
        self.sampling_time = p.sampling_time
        self.inputs = InputDomain.from_range(["u"], p.input_range[0], p.input_range[1])
        # the fixed point for the largest |u| bounds the displacement; velocities of resonant swings
        umax = max(abs(p.input_range[0]), abs(p.input_range[1]), 1.0)
        xs = float(np.max(np.abs(np.roots([p.cubic, 0.0, p.linear, -umax]).real))) if p.cubic else umax / p.linear
        self.box_low, self.box_high = [-1.3 * xs, -5.0 * xs], [1.3 * xs, 5.0 * xs]
        self.rest_state = np.zeros(2)

    def signals(self) -> list[Sine]:
        return [Sine(27.0, 1.4, 0.0, label="27 sin(1.4 t) (thesis fig. 4.9)")]


class LorenzParams(_FlowParams):
    coupling: Literal["4.52", "4.46", "4.43"] = Field(
        "4.52",
        description="4.52: x1' = alpha sigma (u - x1); 4.46: x1' = -sigma x1 + u; "
        "4.43: u replaces x1 in the x2 and x3 equations",
    )
    sigma: float = Field(10.0, gt=0)
    r: float = Field(28.0)
    b: float = Field(2.666, gt=0)
    alpha: float = Field(1.0, gt=0, description="time scale of eq. 4.52 (multiplies the whole vector field)")
    integration_step: float = Field(0.025, gt=0, description="RK4 step")
    input_range: tuple[float, float] = Field((-4.0, 4.0), description="range of the input (fig. 4.10: [-4, 4])")

    @field_validator("coupling", mode="before")
    @classmethod
    def _as_text(cls, v):
        return f"{v:.2f}" if isinstance(v, float) else v


class LorenzDriven(_Flow):
    name = "lorenz-driven"
    description = "driven Lorenz system, coupling of eq. 4.52 (default), 4.46 or 4.43 (thesis 4.4.1 / 4.4.2)"
    Params = LorenzParams
    params: LorenzParams

    def setup(self) -> None:
        p = self.params
        self.kind = {"4.52": _ode.LORENZ_452, "4.46": _ode.LORENZ_446, "4.43": _ode.LORENZ_443}[p.coupling]
        self.p = np.array([p.sigma, p.r, p.b, p.alpha])
        self.state_dim = 3
        self.sampling_time = p.sampling_time
        self.inputs = InputDomain.from_range(["u"], p.input_range[0], p.input_range[1])
        self.box_low, self.box_high = [-20.0, -30.0, -10.0], [20.0, 30.0, 60.0]
        self.rest_state = np.zeros(3)
