"""Continuous-time chaotic systems of thesis chapters 4 and 5, integrated with fixed-step RK4."""

from __future__ import annotations

import numpy as np
from numba import njit
from pydantic import Field, model_validator

from dynmodel.sources import Generator, GeneratorParams


@njit(cache=True)
def _rossler(s: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """Eq. 4.54 / 5.53: z1' = b + z1 (z2 - c), z2' = -z1 - z3, z3' = z2 + a z3."""
    out = np.empty(3)
    out[0] = b + s[0] * (s[1] - c)
    out[1] = -s[0] - s[2]
    out[2] = s[1] + a * s[2]
    return out


@njit(cache=True)
def _rossler_lorenz(s: np.ndarray, a: float, b: float, c: float, sigma: float, r: float, beta: float) -> np.ndarray:
    """Eq. 5.53 drives eq. 5.54 through u = x1 + x2 + x3."""
    out = np.empty(6)
    out[:3] = _rossler(s[:3], a, b, c)
    u = s[0] + s[1] + s[2]
    out[3] = -sigma * (s[3] - s[4])
    out[4] = r * u - s[4] - u * s[5]
    out[5] = u * s[4] - beta * s[5]
    return out


@njit(cache=True)
def _integrate_rossler(s0, n_out, substeps, h, burn, a, b, c):
    s = s0.copy()
    out = np.empty((n_out, 3))
    for k in range(burn + n_out):
        for _ in range(substeps):
            k1 = _rossler(s, a, b, c)
            k2 = _rossler(s + 0.5 * h * k1, a, b, c)
            k3 = _rossler(s + 0.5 * h * k2, a, b, c)
            k4 = _rossler(s + h * k3, a, b, c)
            s = s + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if k >= burn:
            out[k - burn] = s
    return out


@njit(cache=True)
def _integrate_rossler_lorenz(s0, n_out, substeps, h, burn, a, b, c, sigma, r, beta):
    s = s0.copy()
    out = np.empty((n_out, 6))
    for k in range(burn + n_out):
        for _ in range(substeps):
            k1 = _rossler_lorenz(s, a, b, c, sigma, r, beta)
            k2 = _rossler_lorenz(s + 0.5 * h * k1, a, b, c, sigma, r, beta)
            k3 = _rossler_lorenz(s + 0.5 * h * k2, a, b, c, sigma, r, beta)
            k4 = _rossler_lorenz(s + h * k3, a, b, c, sigma, r, beta)
            s = s + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if k >= burn:
            out[k - burn] = s
    return out


class _FlowParams(GeneratorParams):
    sampling_time: float = Field(0.1, gt=0, description="time between samples")
    integration_step: float = Field(0.01, gt=0, description="RK4 step; the sampling time must be a multiple of it")
    burn_in: float = Field(200.0, ge=0, description="time integrated and discarded to reach the attractor")
    a: float = Field(0.45, description="Rossler parameter (z3' = z2 + a z3)")
    b: float = Field(2.0, description="Rossler parameter (z1' = b + z1 (z2 - c))")
    c: float = Field(4.0, description="Rossler parameter")

    @model_validator(mode="after")
    def _multiple(self):
        k = self.sampling_time / self.integration_step
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(
                f"sampling_time {self.sampling_time} is not a whole multiple of integration_step {self.integration_step}"
            )
        return self

    @property
    def substeps(self) -> int:
        return int(round(self.sampling_time / self.integration_step))


def _initial_rossler(rng: np.random.Generator) -> np.ndarray:
    return np.array([0.5, 1.0, 1.0]) + 0.5 * rng.standard_normal(3)


class RosslerCrossParams(_FlowParams):
    horizon: float = Field(10.0, ge=0, description="the output is z2 this far ahead of the input time (T)")


class RosslerCross(Generator):
    name = "rossler-cross"
    description = "Rossler cross-prediction: input z1(t), output z2(t + T), sampled at 0.1 (thesis eq. 4.54)"
    Params = RosslerCrossParams

    @classmethod
    def generate(cls, params: RosslerCrossParams, n: int, rng: np.random.Generator):
        lead = int(round(params.horizon / params.sampling_time))
        burn = int(round(params.burn_in / params.sampling_time))
        z = _integrate_rossler(
            _initial_rossler(rng),
            n + lead,
            params.substeps,
            params.integration_step,
            burn,
            params.a,
            params.b,
            params.c,
        )
        return z[:n, 0:1].copy(), z[lead : lead + n, 1:2].copy()


class RosslerLorenzParams(_FlowParams):
    integration_step: float = Field(0.025, gt=0, description="RK4 step (thesis: 0.025)")
    sigma: float = Field(10.0, description="Lorenz parameter of z1' = -sigma (z1 - z2)")
    r: float = Field(28.0, description="Lorenz parameter of z2' = r u - z2 - u z3")
    beta: float = Field(2.666, description="Lorenz parameter of z3' = u z2 - beta z3")


class RosslerLorenz(Generator):
    name = "rossler-lorenz"
    description = "Rossler drives Lorenz via u = x1+x2+x3; output z1, sampled at 0.1 (thesis eq. 5.53 / 5.54)"
    Params = RosslerLorenzParams

    @classmethod
    def generate(cls, params: RosslerLorenzParams, n: int, rng: np.random.Generator):
        burn = int(round(params.burn_in / params.sampling_time))
        s0 = np.concatenate([_initial_rossler(rng), rng.standard_normal(3)])
        s = _integrate_rossler_lorenz(
            s0,
            n,
            params.substeps,
            params.integration_step,
            burn,
            params.a,
            params.b,
            params.c,
            params.sigma,
            params.r,
            params.beta,
        )
        u = s[:, 0] + s[:, 1] + s[:, 2]
        return u[:, None], s[:, 3:4].copy()
