"""External-mode models (thesis 5.3.2): how many tune-in samples does the free run need?

The closed loop (output fed back) is deliberately unreliable, so a free run starts on the right
trajectory only after a tune-in: the measured output is fed back for k samples while the network,
now an open-loop system driven by input and output, forgets its initial state.

Replicas from many initial states (the first one the rest state the model starts from) are fed
the measured training output for k samples and then run free; for each k in a grid the test
records the largest difference between their outputs over a horizon after the switch. The
required tune-in is the smallest k from which on every larger k in the grid keeps them within
the tolerance: after it the free run no longer depends on where the network started. Model files
without measured outputs fall back to the closed loop's own run from the rest state as the
"measured" signal (:func:`reference`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..family import Progress
from .system import DrivenSystem

GRID = (0, 1, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100, 150, 200, 300, 500, 700, 1000, 1500, 2000)
#: outputs agree when they differ by less than this fraction of the training output range
OUTPUT_TOL = 1e-3


@dataclass
class TuneInResult:
    configured: int
    required: int | None
    grid: list[int]
    deviations: list[float]  # per k: largest output difference between replicas / output range over the horizon
    horizon: int
    tolerance: float
    replicas: int
    note: str = ""

    def to_json(self) -> dict[str, Any]:
        return {
            "configured_tune_in": self.configured,
            "required_tune_in": self.required,
            "sufficient": None if self.required is None else self.required <= self.configured,
            "grid": self.grid,
            "replica_output_difference": self.deviations,
            "horizon": self.horizon,
            "tolerance_fraction_of_output_range": self.tolerance,
            "replicas": self.replicas,
            "note": self.note,
        }


def reference(
    system: DrivenSystem, Vin: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, int | None]:
    """Closed-loop free run from the rest state on model inputs Vin (n, d_in): outputs (n, n_out)
    and the sample where the output left ``bounds`` (None if it stayed inside)."""
    cl = system.closed_loop
    assert cl is not None
    n = len(Vin)
    x = (system.rest_state if system.rest_state is not None else np.zeros(system.state_dim))[None, :]
    f = cl.rest_output.astype(np.float64).copy()
    Y = np.full((n, cl.n_outputs), np.nan)
    for t in range(n):
        v = np.concatenate([Vin[t], f])[None, :]
        x = system.step(x, v)
        y = cl.readout(x, v)[0]
        if not np.isfinite(y).all() or (bounds is not None and (np.any(y < bounds[0]) or np.any(y > bounds[1]))):
            return Y, t
        Y[t] = y
        f = y
    return Y, None


def measure(
    system: DrivenSystem,
    Vin: np.ndarray,
    y_teach: np.ndarray,
    X0: np.ndarray,
    out_range: np.ndarray,
    horizon: int,
    max_k: int,
    progress: Progress,
) -> TuneInResult:
    """For k in the grid: replicas from X0 (the first one the rest state) fed ``y_teach`` for k
    samples, then free; the largest output difference between them over ``horizon`` samples after
    the switch, as a fraction of the output range."""
    cl = system.closed_loop
    assert cl is not None
    n = len(Vin)
    grid = [k for k in GRID if k <= max_k and k + horizon <= n]
    if not grid:
        return TuneInResult(
            cl.tune_in,
            None,
            [],
            [],
            horizon,
            OUTPUT_TOL,
            len(X0),
            f"the test input has only {n} samples, fewer than the horizon of {horizon}",
        )
    R = len(X0)
    K = len(grid)
    ks = np.repeat(np.array(grid), R)
    X = np.ascontiguousarray(np.tile(X0, (K, 1)))
    f = np.tile(cl.rest_output, (K * R, 1)).astype(np.float64)
    dev = np.zeros(K)
    steps = max(grid) + horizon
    every = max(1, steps // 10)
    width = np.maximum(out_range, 1e-300)
    kk = np.array(grid)
    for t in range(steps):
        forced = ((ks > 0) & (t <= ks))[:, None]  # kernel convention: f_t = y_{t-1} for t <= k (y_0 at t = 0)
        if t == 0:
            fb = np.where(forced, y_teach[0][None, :], cl.rest_output[None, :])
        else:
            fb = np.where(forced, y_teach[t - 1][None, :], f)
        V = np.ascontiguousarray(np.hstack([np.repeat(Vin[t][None, :], K * R, axis=0), fb]))
        X = system.step(X, V)
        Y = cl.readout(X, V)
        Yk = Y.reshape(K, R, -1)
        spread = np.max(np.abs(Yk - Yk[:, :1, :]) / width, axis=(1, 2))
        spread = np.where(np.isfinite(spread), spread, np.inf)
        window = (t >= kk) & (t < kk + horizon)
        dev = np.where(window, np.maximum(dev, spread), dev)
        f = Y
        if t % every == 0:
            progress("tune-in", t / steps, f"{K} tune-in lengths x {R} replicas, step {t + 1}/{steps}")
    ok = dev <= OUTPUT_TOL
    required = next((grid[i] for i in range(K) if ok[i:].all()), None)
    note = (
        ""
        if required is not None
        else (f"the free runs from different initial states did not agree within {max(grid)} tune-in samples")
    )
    return TuneInResult(cl.tune_in, required, grid, [float(v) for v in dev], horizon, OUTPUT_TOL, R, note)
