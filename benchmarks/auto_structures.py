"""family: auto on structures a default does not reach, next to each family's default.

    python benchmarks/auto_structures.py                    # every case (about 4 min on 2 cores)
    python benchmarks/auto_structures.py --only deadtime --no-defaults

Each case is one generated recording with 1 % output noise (0.5 % for the oversampled one), trained on its
first part (80 % training, 20 % validation) and tested on the noise-free continuation of the same run, a
test file of its own (no initialization window):

* ``deadtime``: steps held 60 samples, tanh, a dead time of 25 samples, a first-order lag (pole 0.97): the
  default's lags (0 .. 6) do not reach the input's effect (docs/auto.md, "A dead time");
* ``backlash``: a smooth random input through a backlash of width 0.4 and a first-order lag; the test
  starts mid-motion, where a start from rest at the training mean is a state no data show (docs/auto.md,
  the band check);
* ``oversampled``: a hardening oscillator (q'' = u - 0.2 q' - q - q^3) sampled 600 times per period;
* ``offset``: an input of about 1000 varying by +-1 and an output of a few micro-units (scaling);
* ``shortlin``: 600 samples of a lightly damped linear plant (cross-validated);
* ``resonant``: an eighth-order band-pass (Chebyshev type I of order 4, 3 dB ripple, band 0.02 .. 0.06 of
  Nyquist, poles up to |z| = 0.997) driven by band-limited noise, 8000 samples (docs/auto.md, "A lightly
  damped linear system"; there the test is a recording of its own, from rest).

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of the narx and esn defaults
(and the example ``arx`` family's when it is installed), the model auto chose and its wall time. Asserts
nothing; the data come from fixed seeds, so the figures are the same on every machine.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_series, run_generated
from scipy import signal

Series = dict[str, np.ndarray]
DEFAULTS = ("narx", "esn", "arx")


def _cut(
    u: np.ndarray, y0: np.ndarray, rng: np.random.Generator, at: int, noise: float = 0.01
) -> tuple[Series, Series]:
    """The run (u, y0) measured with white output noise (``noise`` x the output's std): its first ``at`` samples
    for training, the rest, noise-free, as the test."""
    y = y0 + noise * y0.std() * rng.standard_normal(len(y0))
    return {"u": u[:at], "y": y[:at]}, {"u": u[at:], "y": y0[at:]}


def _deadtime(rng: np.random.Generator) -> tuple[Series, Series]:
    n, delay = 9000, 25
    u = np.repeat(rng.uniform(-2, 2, n // 60 + 1), 60)[:n] + 0.1 * rng.standard_normal(n)
    x = np.concatenate([np.zeros(delay), np.tanh(u)[: n - delay]])
    return _cut(u, signal.lfilter([0.03], [1, -0.97], x), rng, 7000)


def _backlash(rng: np.random.Generator) -> tuple[Series, Series]:
    n, half_width = 9000, 0.2
    u = signal.lfilter(*signal.butter(2, 0.02), rng.standard_normal(n)) * 6
    z = np.zeros(n)
    for t in range(1, n):
        z[t] = min(max(z[t - 1], u[t] - half_width), u[t] + half_width)
    return _cut(u, signal.lfilter([0.1], [1, -0.9], z), rng, 7000)


def _oversampled(rng: np.random.Generator) -> tuple[Series, Series]:
    n, dt = 24000, 0.01
    u = signal.lfilter(*signal.butter(2, 0.004), rng.standard_normal(n)) * 20
    q, v = np.zeros(n), np.zeros(n)
    for t in range(1, n):
        v[t] = v[t - 1] + dt * (u[t - 1] - 0.2 * v[t - 1] - q[t - 1] - q[t - 1] ** 3)
        q[t] = q[t - 1] + dt * v[t]
    return _cut(u, q, rng, 18000, 0.005)


def _offset(rng: np.random.Generator) -> tuple[Series, Series]:
    n = 8000
    du = signal.lfilter(*signal.butter(2, 0.1), rng.standard_normal(n))
    y0 = 1e-6 * signal.lfilter([0, 0.2, 0.1], [1, -1.3, 0.5], du + 0.3 * du**2) + 3e-6
    return _cut(1000 + 0.5 * du, y0, rng, 6500)


def _shortlin(rng: np.random.Generator) -> tuple[Series, Series]:
    n = 900
    u = rng.standard_normal(n)
    return _cut(u, signal.lfilter([0, 0.1, 0.05], [1, -1.7, 0.85], u), rng, 600, 1 / 30)


def _resonant(rng: np.random.Generator) -> tuple[Series, Series]:
    n = 8000
    u = signal.lfilter(*signal.butter(4, 0.2), rng.standard_normal(n))
    y0 = 5 * signal.lfilter(*signal.cheby1(4, 3, [0.02, 0.06], btype="band"), u / u.std())
    return _cut(u / u.std(), y0, rng, 6000)


CASES: dict[str, Callable[[], tuple[Series, Series]]] = {
    "deadtime": lambda: _deadtime(np.random.default_rng(2)),
    "backlash": lambda: _backlash(np.random.default_rng(4)),
    "oversampled": lambda: _oversampled(np.random.default_rng(1)),
    "offset": lambda: _offset(np.random.default_rng(3)),
    "shortlin": lambda: _shortlin(np.random.default_rng(5)),
    "resonant": lambda: _resonant(np.random.default_rng(6)),
}


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    return fit_series(name, folder, args, *CASES[name](), list(DEFAULTS))


def main() -> None:
    run_generated(__doc__, list(CASES), run_case, list(DEFAULTS), "test NMSE % on the noise-free continuation")


if __name__ == "__main__":
    main()
