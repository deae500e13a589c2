"""Position trajectories with exact velocity and acceleration: the drive of the friction laws and
the reference of the friction plant (thesis 6.2 - 6.4).

* ``random``     sum of ``components`` sines at frequencies drawn uniformly from ``band``, random
                 phases: a band-limited, Gaussian-like signal of standard deviation ``std``;
                 non-periodic, and a longer record starts with the same samples as a shorter one
* ``multisine``  every harmonic of 1 / ``period`` inside ``band``, random phases (periodic)
* ``reversals``  smooth (half-cosine) moves through the turning points ``points`` at peak speed
                 ``speed``, then at rest: nested loops that show the non-local memory of
                 pre-sliding hysteresis (fig. 6.2 / 6.5)

Small ``std`` (micrometres) keeps a friction contact in pre-sliding (6.2); large ``std`` at a few
hertz gives gross sliding with sticking at the reversals (6.3). ``fade_in`` starts the random and
multisine signals from rest at ``offset`` (x = offset + w(t) s(t), w a quintic ramp from 0 to 1 with
continuous first and second derivatives), so a plant or a virgin friction state starts consistently.
"""

from __future__ import annotations

import math
from typing import Literal, Optional

import numpy as np
from numba import njit
from pydantic import BaseModel, ConfigDict, Field, model_validator

from dynmodel.kernels.tanh import FASTMATH


class TrajectoryParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["random", "multisine", "reversals"] = Field("random", description="trajectory type")
    std: float = Field(1e-5, gt=0, description="random / multisine: standard deviation of the position (m)")
    band: tuple[float, float] = Field((0.05, 1.0), description="random / multisine: frequency band (Hz)")
    components: int = Field(64, ge=1, le=4096, description="random: number of sines")
    period: float = Field(20.0, gt=0, description="multisine: period (s); the harmonics of 1 / period in band")
    points: Optional[list[float]] = Field(None, description="reversals: turning points (m), starting point first")
    speed: float = Field(1e-5, gt=0, description="reversals: peak speed of every move (m/s)")
    offset: float = Field(0.0, description="added to the position (m)")
    fade_in: float = Field(1.0, ge=0, description="random / multisine: seconds of the smooth ramp from rest")

    @model_validator(mode="after")
    def _check(self):
        lo, hi = self.band
        if not 0 < lo <= hi:
            raise ValueError(f"band = [{lo:g}, {hi:g}] must satisfy 0 < low <= high (Hz)")
        if self.kind == "reversals" and (self.points is None or len(self.points) < 2):
            raise ValueError("kind reversals needs points: at least two positions (m), e.g. [0, 2e-6, -2e-6, 1e-6]")
        if self.kind == "multisine" and not any(
            lo <= m / self.period <= hi for m in range(int(lo * self.period), int(hi * self.period) + 2)
        ):
            raise ValueError(f"no harmonic of 1 / period = {1 / self.period:g} Hz lies in band [{lo:g}, {hi:g}]")
        return self


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _sines(t0: float, dt: float, n: int, amp: np.ndarray, omega: np.ndarray, phase: np.ndarray):
    """sum_c amp_c sin(omega_c t + phase_c) and its two derivatives at t0 + i dt, i < n; the phasor
    is rotated step by step and re-anchored every 512 samples (accurate to ~1e-14 of amp)."""
    x = np.zeros(n)
    v = np.zeros(n)
    a = np.zeros(n)
    for c in range(amp.shape[0]):
        A, w = amp[c], omega[c]
        cr, ci = math.cos(w * dt), math.sin(w * dt)
        zr = zi = 0.0
        for i in range(n):
            if i % 512 == 0:
                arg = w * (t0 + i * dt) + phase[c]
                zr, zi = math.cos(arg), math.sin(arg)
            x[i] += A * zi
            v[i] += A * w * zr
            a[i] -= A * w * w * zi
            zr, zi = zr * cr - zi * ci, zr * ci + zi * cr
    return x, v, a


class Trajectory:
    """A drawn trajectory; :meth:`grid` evaluates it with derivatives on a uniform time grid."""

    def __init__(self, params: TrajectoryParams, rng: np.random.Generator):
        self.params = params
        p = params
        lo, hi = p.band
        if p.kind == "random":
            f = rng.uniform(lo, hi, p.components)
            self.amp = np.full(p.components, p.std * math.sqrt(2.0 / p.components))
            self.omega = 2 * math.pi * f
            self.phase = rng.uniform(0, 2 * math.pi, p.components)
        elif p.kind == "multisine":
            m = np.arange(max(1, math.ceil(lo * p.period - 1e-9)), math.floor(hi * p.period + 1e-9) + 1)
            self.omega = np.asarray(2 * math.pi * m / p.period, dtype=np.float64)
            self.amp = np.full(m.size, p.std * math.sqrt(2.0 / m.size))
            self.phase = rng.uniform(0, 2 * math.pi, m.size)
        else:
            pts = np.asarray(p.points, dtype=np.float64)
            delta = np.diff(pts)
            dur = math.pi * np.abs(delta) / (2 * p.speed)
            self.points, self.delta, self.duration = pts, delta, dur
            self.starts = np.concatenate([[0.0], np.cumsum(dur)])

    @property
    def total_duration(self) -> float:
        """reversals: time to pass every turning point (afterwards the position rests)."""
        return float(self.starts[-1]) if self.params.kind == "reversals" else math.inf

    def grid(self, t0: float, dt: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at t0 + i dt, i < n."""
        p = self.params
        if p.kind == "reversals":
            return self._reversals(t0 + dt * np.arange(n))
        x, v, a = _sines(float(t0), float(dt), int(n), self.amp, self.omega, self.phase)
        if p.fade_in > 0:
            t = t0 + dt * np.arange(n)
            ramp = t < p.fade_in
            if ramp.any():
                T = p.fade_in
                s = t[ramp] / T  # quintic smoothstep: w, w', w'' continuous at both ends
                w = s**3 * (10 - 15 * s + 6 * s * s)
                w1 = 30 * s * s * (1 - s) ** 2 / T
                w2 = 60 * s * (1 - s) * (1 - 2 * s) / T**2
                xs, vs, as_ = x[ramp], v[ramp], a[ramp]
                x[ramp], v[ramp], a[ramp] = w * xs, w1 * xs + w * vs, w2 * xs + 2 * w1 * vs + w * as_
        return x + p.offset, v, a

    def _reversals(self, t: np.ndarray):
        x = np.full(t.shape, self.points[-1])
        v = np.zeros(t.shape)
        a = np.zeros(t.shape)
        x[t < 0] = self.points[0]
        for j, (d, dur) in enumerate(zip(self.delta, self.duration)):
            if dur == 0:
                continue
            sel = (t >= self.starts[j]) & (t < self.starts[j + 1])
            s = (t[sel] - self.starts[j]) / dur
            x[sel] = self.points[j] + d * (1 - np.cos(np.pi * s)) / 2
            v[sel] = d * np.pi * np.sin(np.pi * s) / (2 * dur)
            a[sel] = d * np.pi**2 * np.cos(np.pi * s) / (2 * dur**2)
        return x + self.params.offset, v, a
