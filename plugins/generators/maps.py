"""Discrete-time driven maps of thesis chapter 3."""

from __future__ import annotations

import numpy as np
from numba import njit
from pydantic import Field

from dynmodel.sources import Generator, GeneratorParams


@njit(cache=True)
def _linear(u: np.ndarray, a0: float, b0: float) -> np.ndarray:
    y = np.empty_like(u)
    prev = 0.0
    for t in range(u.shape[0]):
        prev = a0 * prev + b0 * u[t]
        y[t] = prev
    return y


@njit(cache=True)
def _logistic(u: np.ndarray, alpha: float, lam: float, y0: float) -> np.ndarray:
    y = np.empty_like(u)
    prev = y0
    for t in range(u.shape[0]):
        prev = (1.0 - alpha) * lam * prev * (1.0 - prev) + alpha * u[t]
        y[t] = prev
    return y


@njit(cache=True)
def _narx(u: np.ndarray, a0: float, b0: float, c0: float) -> np.ndarray:
    y = np.empty_like(u)
    y1 = 0.0
    y2 = 0.0
    for t in range(u.shape[0]):
        yt = a0 * y1 + b0 / (1.0 + abs(y2)) + c0 * u[t]
        y[t] = yt
        y2 = y1
        y1 = yt
    return y


class LinearParams(GeneratorParams):
    a0: float = Field(0.8, gt=-1.0, lt=1.0, description="pole; |a0| < 1 for stability")
    b0: float = Field(1.0, description="input gain")
    input_std: float = Field(1.0, gt=0, description="std of the white Gaussian input")


class LinearSystem(Generator):
    name = "linear-system"
    description = "y_t = a0 y_{t-1} + b0 u_t with white Gaussian input (thesis eq. 3.19)"
    Params = LinearParams

    @classmethod
    def generate(cls, params: LinearParams, n: int, rng: np.random.Generator):
        u = params.input_std * rng.standard_normal(n)
        return u[:, None], _linear(u, params.a0, params.b0)[:, None]


class LogisticParams(GeneratorParams):
    alpha: float = Field(0.5, ge=0.0, le=1.0, description="coupling to the input")
    lam: float = Field(4.0, ge=0.0, le=4.0, description="logistic parameter lambda")
    y0: float = Field(0.0, description="output before the first sample")


class DrivenLogistic(Generator):
    name = "driven-logistic"
    description = "y_t = (1-alpha) lambda y_{t-1}(1-y_{t-1}) + alpha u_t, u ~ U[0,1] (thesis eq. 3.34)"
    Params = LogisticParams

    @classmethod
    def generate(cls, params: LogisticParams, n: int, rng: np.random.Generator):
        u = rng.random(n)
        return u[:, None], _logistic(u, params.alpha, params.lam, params.y0)[:, None]


class NarxParams(GeneratorParams):
    a0: float = Field(0.8, description="weight of y_{t-1}")
    b0: float = Field(-0.2, description="weight of 1 / (1 + |y_{t-2}|)")
    c0: float = Field(1.0, description="weight of u_t")
    input_std: float = Field(1.0, gt=0, description="std of the white Gaussian input")


class NarxSystem(Generator):
    name = "narx-system"
    description = "y_t = a0 y_{t-1} + b0/(1+|y_{t-2}|) + c0 u_t, u ~ N(0,1) (thesis eq. 3.37 / 5.47)"
    Params = NarxParams

    @classmethod
    def generate(cls, params: NarxParams, n: int, rng: np.random.Generator):
        u = params.input_std * rng.standard_normal(n)
        return u[:, None], _narx(u, params.a0, params.b0, params.c0)[:, None]
