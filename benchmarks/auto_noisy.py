"""family: auto on noisy measurements of generated systems, next to each family's default.

    python benchmarks/auto_noisy.py                   # every case (about 5 min on 2 cores)
    python benchmarks/auto_noisy.py --only linear-snr3 --json noisy.json
    python benchmarks/auto_noisy.py --families narx esn annealed-rnn    # built-in families only

Each case is one recording measured with output noise (trained on its first part, 80 % training and 20 %
validation) and tested on the noise-free continuation of the same run, so the test NMSE is the model's
own error, not the noise. Every candidate then validates near the noise floor, where the choice must
tell a real gain from noise (docs/auto.md, "When the only doubt is the size of the gain"):

* ``linear-snr3``: a second-order linear plant, white output noise with a third of the output's std
  (a noise floor of 10 % validation NMSE);
* ``linear-snr10``: the same kind of plant with a tenth;
* ``hammerstein-snr3``: a mild cubic before second-order dynamics (a few % of the output), noise as above;
* ``wiener-hammerstein-snr3``: linear, tanh plus a square, linear; noise as above;
* ``duffing-coloured``: a hardening oscillator, low-pass (coloured) noise of a quarter of the output's std;
* ``glitches``: a mild square before second-order dynamics, 1 % noise, and 20 isolated glitches of 6 output
  stds in 4000 training samples: they set a validation floor of about 15 %, the record is short, so the
  candidates are cross-validated (the fold-by-fold comparison of docs/auto.md).

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of the narx and esn defaults
(and of the example ``arx`` family when it is installed), the model auto chose and its wall time. Asserts
nothing. The data are generated from fixed seeds, so the figures are the same on every machine.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_series, run_generated
from scipy import signal

Series = dict[str, np.ndarray]


def _linear(rng: np.random.Generator, snr: float) -> tuple[Series, Series]:
    n = 6000
    u = signal.lfilter(*signal.butter(2, 0.1), rng.standard_normal(n)) * 3
    y0 = signal.lfilter([0, 0.2, 0.1], [1, -1.3, 0.5], u)
    y = y0 + rng.standard_normal(n) * y0.std() / snr
    return {"u": u[:5000], "y": y[:5000]}, {"u": u[5000:], "y": y0[5000:]}


def _hammerstein(rng: np.random.Generator) -> tuple[Series, Series]:
    n = 7000
    u = signal.lfilter(*signal.butter(2, 0.08), rng.standard_normal(n)) * 2.5
    y0 = signal.lfilter([0, 0.15, 0.1], [1, -1.4, 0.55], u + 0.08 * u**3)
    y = y0 + rng.standard_normal(n) * y0.std() / 3
    return {"u": u[:5500], "y": y[:5500]}, {"u": u[5500:], "y": y0[5500:]}


def _wiener_hammerstein(rng: np.random.Generator) -> tuple[Series, Series]:
    n = 8000
    u = signal.lfilter(*signal.butter(3, 0.15), rng.standard_normal(n)) * 2
    x = signal.lfilter([0, 0.3, 0.2], [1, -1.2, 0.45], u)
    y0 = signal.lfilter([0.4, 0.3], [1, -0.3], np.tanh(x) + 0.2 * x**2)
    y = y0 + rng.standard_normal(n) * y0.std() / 3
    return {"u": u[:6500], "y": y[:6500]}, {"u": u[6500:], "y": y0[6500:]}


def _duffing(rng: np.random.Generator) -> tuple[Series, Series]:
    """q'' = u - 0.4 q' - q - 0.5 q^3 (semi-implicit Euler, dt 0.05), coloured measurement noise."""
    n, dt = 8000, 0.05
    u = signal.lfilter(*signal.butter(2, 0.05), rng.standard_normal(n)) * 4
    q, v = np.zeros(n), np.zeros(n)
    for t in range(1, n):
        v[t] = v[t - 1] + dt * (u[t - 1] - 0.4 * v[t - 1] - q[t - 1] - 0.5 * q[t - 1] ** 3)
        q[t] = q[t - 1] + dt * v[t]
    e = signal.lfilter([1], [1, -0.8], rng.standard_normal(n))
    e *= q.std() / 4 / e.std()
    return {"u": u[:6500], "y": (q + e)[:6500]}, {"u": u[6500:], "y": q[6500:]}


def _glitches(rng: np.random.Generator) -> tuple[Series, Series]:
    """A mild square before second-order dynamics, 1 % white noise, and sensor glitches: 0.5 % of the
    training samples off by 6 output stds. A short record (4000 samples), so the search cross-validates."""
    n = 5500
    u = signal.lfilter(*signal.butter(2, 0.15), rng.standard_normal(n)) * 2
    y0 = signal.lfilter([0, 0.2], [1, -1.5, 0.7], u + 0.3 * u**2)
    y = y0 + rng.standard_normal(n) * y0.std() / 100
    hit = rng.choice(4000, 20, replace=False)
    y[hit] += 6 * y0.std() * rng.choice([-1.0, 1.0], 20)
    return {"u": u[:4000], "y": y[:4000]}, {"u": u[4000:], "y": y0[4000:]}


CASES: dict[str, Callable[[], tuple[Series, Series]]] = {
    "linear-snr3": lambda: _linear(np.random.default_rng(5), 3),
    "linear-snr10": lambda: _linear(np.random.default_rng(7), 10),
    "hammerstein-snr3": lambda: _hammerstein(np.random.default_rng(21)),
    "wiener-hammerstein-snr3": lambda: _wiener_hammerstein(np.random.default_rng(11)),
    "duffing-coloured": lambda: _duffing(np.random.default_rng(13)),
    "glitches": lambda: _glitches(np.random.default_rng(17)),
}
DEFAULTS = ("narx", "esn", "arx")


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    return fit_series(name, folder, args, *CASES[name](), list(DEFAULTS))


def main() -> None:
    run_generated(
        __doc__,
        list(CASES),
        run_case,
        list(DEFAULTS),
        "test NMSE % on the noise-free continuation (validation at the noise floor)",
    )


if __name__ == "__main__":
    main()
