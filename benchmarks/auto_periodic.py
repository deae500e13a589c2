"""family: auto on periodic excitations: records of several periods of one multisine, next to each family's
default.

    python benchmarks/auto_periodic.py                     # every case (about 10 min on 2 cores)
    python benchmarks/auto_periodic.py --only wh --no-defaults

Each case is six periods of one 2000-sample random-phase multisine (band 1 to 20 % of the sampling rate,
unit RMS) applied to a generated system in steady state, with 2 % white output noise; the spec splits it
5/6 training and 1/6 validation, so the validation split is the last period: the training input again. The
test file is another realization of the multisine (other phases, one period in steady state, noise-free).
So the validation cannot tell how a model does on a new input, and the search ranks its candidates on the
phases of the period held out in turn (docs/auto.md, "A periodic excitation"):

* ``wh``: first-order linear, tanh(1.5 v), first-order linear plus a square (Wiener-Hammerstein);
* ``wh2``: first-order linear, v / (1 + |v|), first-order linear;
* ``hammer``: tanh(1.5 u) before a resonant second-order system (poles 0.9 at +-0.3 rad);
* ``silver``: a damped Duffing oscillator, x'' + 0.6 x' + x + 2 x^3 = u (semi-implicit Euler, 10 substeps);
* ``lin4``: a second-order linear system;
* ``duffing``: a lightly damped cubic oscillator integrated per sample (its validation is poor in every
  layout while its models test near 1 %: the case the phases rank worse).

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of the narx and esn defaults,
the model auto chose and its wall time. Asserts nothing; the data come from fixed seeds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_series, run_generated

PERIOD = 2000
PERIODS = 6
NOISE = 0.02
DEFAULTS = ("narx", "esn")


def multisine(rng: np.random.Generator, n: int, band: tuple[float, float] = (0.01, 0.2)) -> np.ndarray:
    """One period of a random-phase multisine with flat amplitude over ``band`` (fractions of the sampling
    rate), scaled to unit RMS."""
    k = np.arange(1, n // 2)
    keep = (k / n >= band[0]) & (k / n <= band[1])
    spectrum = np.zeros(n // 2 + 1, complex)
    spectrum[1 : n // 2][keep] = np.exp(2j * np.pi * rng.random(int(keep.sum())))
    u = np.fft.irfft(spectrum, n)
    return u / u.std()


def simulate(kind: str, u: np.ndarray) -> np.ndarray:
    """The output of system ``kind`` (see the module docstring) from rest."""
    y = np.zeros(len(u))
    x1 = x2 = 0.0
    for t in range(len(u)):
        if kind == "duffing":
            a = -0.05 * x2 - 0.02 * x1 - 0.1 * x1**3 + 0.08 * u[t]
            x2 += a
            x1 += x2
            y[t] = x1
        elif kind == "wh":
            v = 0.7 * x1 + 0.3 * u[t]
            x1 = v
            x2 = 0.8 * x2 + 0.2 * np.tanh(1.5 * v)
            y[t] = x2 + 0.3 * x2**2
        elif kind == "silver":
            for _ in range(10):
                a = u[t] - 0.6 * x2 - x1 - 2.0 * x1**3
                x2 += 0.01 * a
                x1 += 0.01 * x2
            y[t] = x1
        elif kind == "hammer":
            x1, x2 = 1.8 * np.cos(0.3) * x1 - 0.81 * x2 + 0.05 * np.tanh(1.5 * u[t]), x1
            y[t] = x1
        elif kind == "lin4":
            x1, x2 = 1.5 * x1 - 0.7 * x2 + 0.1 * u[t] + 0.05 * (u[t - 1] if t else 0.0), x1
            y[t] = x1
        elif kind == "wh2":
            v = 0.5 * x1 + 0.5 * u[t]
            x1 = v
            w = v / (1 + abs(v))
            x2 = 0.9 * x2 + 0.1 * w
            y[t] = x2
    return y


CASES = ("wh", "wh2", "hammer", "silver", "lin4", "duffing")


def generate(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(u, y, u_test, y_test): PERIODS periods in steady state (two periods of run-in dropped) with noise, and
    one period of another realization, noise-free."""
    rng = np.random.default_rng(0)
    u = np.tile(multisine(rng, PERIOD), PERIODS + 2)
    y = simulate(kind, u)[2 * PERIOD :]
    u = u[2 * PERIOD :]
    y = y + NOISE * y.std() * rng.standard_normal(len(y))
    ut = np.tile(multisine(rng, PERIOD), 3)
    yt = simulate(kind, ut)[2 * PERIOD :]
    return u, y, ut[2 * PERIOD :], yt


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    u, y, ut, yt = generate(name)
    split = {"train": 5 / 6, "validation": 1 / 6}
    return fit_series(name, folder, args, {"u": u, "y": y}, {"u": ut, "y": yt}, list(DEFAULTS), split)


def main() -> None:
    run_generated(
        __doc__, list(CASES), run_case, list(DEFAULTS), "test NMSE % on a new multisine realization", families=False
    )


if __name__ == "__main__":
    main()
