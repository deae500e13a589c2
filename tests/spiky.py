"""A resonant plant measured by a glitching sensor: shared by tests/test_artifacts.py and
benchmarks/auto_spikes.py."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter


def steps(n: int, rng: np.random.Generator) -> np.ndarray:
    """Random levels in [-1, 1] held for 1 to 15 samples (a typical lab excitation)."""
    holds = rng.integers(1, 16, n)
    levels = rng.uniform(-1, 1, n)
    return np.repeat(levels, holds)[:n]


def plant(u: np.ndarray) -> np.ndarray:
    """x_t = 1.5 x_{t-1} - 0.7 x_{t-2} + 0.5 u_{t-1} + 0.1 u_{t-2}, y = x + 0.1 x^2: lightly damped, mildly
    nonlinear."""
    x = lfilter([0.0, 0.5, 0.1], [1.0, -1.5, 0.7], u)
    return x + 0.1 * x**2


def spiky(
    n: int = 3000, seed: int = 0, share: float = 0.01, size: float = 10.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(input, measured output, clean output, glitch samples): white sensor noise of 2 % of the output std, and
    ``share`` of the samples (isolated ones, at least 4 apart) off by ``size`` output stds, either sign."""
    rng = np.random.default_rng(seed)
    u = steps(n, rng)
    x = plant(u)
    clean = x + 0.02 * np.std(x) * rng.standard_normal(n)
    glitches = np.sort(rng.choice(np.arange(2, n - 2), int(share * n), replace=False))
    glitches = glitches[np.diff(glitches, prepend=-9) > 3]
    y = clean.copy()
    y[glitches] += size * np.std(clean) * rng.choice([-1, 1], glitches.size)
    return u, y, clean, glitches
