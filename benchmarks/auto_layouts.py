"""family: auto on layouts of several outputs and recordings, next to each family's default.

    python benchmarks/auto_layouts.py                        # every case (about 12 min on 2 cores)
    python benchmarks/auto_layouts.py --only accelerations --no-defaults

Generated data, 1 % output noise on the training recordings, tested on noise-free recordings of their own
(no initialization window):

* ``accelerations``: one force on the first of three masses in a chain (semi-implicit Euler, dt 0.01 s),
  a clearance of +-0.01 in the spring between the second and the third, the three accelerations measured
  (as a ground-vibration test measures them); a random-phase multisine at four levels, one recording of
  6000 samples each, left out in turn by the search; the test at a level between two of them. The planned
  work of the search counts every output (docs/auto.md, "Budget and determinism"): it took 801 s of its
  300 s budget when it counted one;
* ``joints``: six coupled joints with Coulomb-like friction (tanh), six forces and six positions, 20000
  samples of one recording split 80 / 20, the test its continuation;
* ``steps``: six step-test recordings of 3000, 2500, 4000, 200, 1500 and 60 samples (a Wiener plant: a
  second-order filter, then a saturation), left out in turn; the test one more of 3000.

Printed per case: the test NMSE (%, mean over outputs) of ``family: auto`` (default budget) and of the narx and
esn defaults, the model auto chose and its wall time. Asserts nothing; the data come from fixed seeds.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_files, run_generated
from scipy import signal

Series = dict[str, np.ndarray]
DEFAULTS = ("narx", "esn")


def _multisine(rng: np.random.Generator, n: int, level: float) -> np.ndarray:
    """Random-phase multisine over 0.2 .. 8 % of the sampling rate, std ``level``."""
    f = np.fft.rfftfreq(n)
    band = (f > 0.002) & (f < 0.08)
    spectrum = np.zeros(len(f), complex)
    spectrum[band] = np.exp(2j * np.pi * rng.random(band.sum()))
    u = np.fft.irfft(spectrum, n)
    return level * u / u.std()


def _chain(u: np.ndarray) -> np.ndarray:
    """Accelerations of three unit masses: springs 400 (ground), 300, a clearance spring 300 beyond +-0.01,
    50 (ground), damping 2."""
    x, v = np.zeros(3), np.zeros(3)
    acc = np.zeros((len(u), 3))
    for t, force in enumerate(u):
        d = x[2] - x[1]
        clear = 300.0 * np.sign(d) * max(abs(d) - 0.01, 0.0)
        a = np.array(
            [
                force - 400.0 * x[0] + 300.0 * (x[1] - x[0]) - 2.0 * v[0],
                -300.0 * (x[1] - x[0]) + clear - 2.0 * v[1],
                -clear - 2.0 * v[2] - 50.0 * x[2],
            ]
        )
        acc[t] = a
        v = v + 0.01 * a
        x = x + 0.01 * v
    return acc


def _accelerations(rng: np.random.Generator) -> tuple[list[Series], list[Series]]:
    train = []
    for i, level in enumerate((2.0, 5.0, 8.0, 11.0)):
        u = _multisine(np.random.default_rng(10 + i), 6000, level)
        acc = _chain(u)
        acc = acc + 0.01 * acc.std(0) * rng.standard_normal(acc.shape)
        train.append({"u": u, "y1": acc[:, 0], "y2": acc[:, 1], "y3": acc[:, 2]})
    u = _multisine(np.random.default_rng(99), 6000, 6.5)
    acc = _chain(u)
    return train, [{"u": u, "y1": acc[:, 0], "y2": acc[:, 1], "y3": acc[:, 2]}]


def _joints(rng: np.random.Generator) -> tuple[list[Series], list[Series]]:
    n, cut = 25000, 20000
    U = np.column_stack([signal.lfilter(*signal.butter(2, 0.03), rng.standard_normal(n)) * 3 for _ in range(6)])
    x, v = np.zeros(6), np.zeros(6)
    Y = np.zeros((n, 6))
    for t in range(n):
        coupling = np.zeros(6)
        coupling[:-1] += 40.0 * (x[1:] - x[:-1])
        coupling[1:] += 40.0 * (x[:-1] - x[1:])
        a = U[t] + coupling - 20.0 * x - v - 0.8 * np.tanh(v / 0.05)
        v = v + 0.01 * a
        x = x + 0.01 * v
        Y[t] = x
    noisy = Y + 0.01 * Y.std(0) * rng.standard_normal(Y.shape)

    def cols(u: np.ndarray, y: np.ndarray) -> Series:
        return {**{f"u{i}": u[:, i] for i in range(6)}, **{f"y{i}": y[:, i] for i in range(6)}}

    return [cols(U[:cut], noisy[:cut])], [cols(U[cut:], Y[cut:])]


def _steps(rng: np.random.Generator) -> tuple[list[Series], list[Series]]:
    runs = []
    for n in (3000, 2500, 4000, 200, 1500, 60, 3000):
        u = np.repeat(rng.uniform(-1, 1, n // 50 + 1), 50)[:n] + 0.05 * rng.standard_normal(n)
        y0 = np.tanh(1.5 * signal.lfilter([0, 0.06, 0.03], [1, -1.55, 0.64], u))
        runs.append(({"u": u, "y": y0 + 0.01 * rng.standard_normal(n)}, {"u": u, "y": y0}))
    return [noisy for noisy, _ in runs[:-1]], [runs[-1][1]]


CASES: dict[str, Callable[[], tuple[list[Series], list[Series]]]] = {
    "accelerations": lambda: _accelerations(np.random.default_rng(5)),
    "joints": lambda: _joints(np.random.default_rng(37)),
    "steps": lambda: _steps(np.random.default_rng(108)),
}


def _write(folder: Path, name: str, runs: list[Series]) -> list[str]:
    paths = []
    for i, series in enumerate(runs):
        path = folder / f"{name}-{i}.csv"
        np.savetxt(path, np.column_stack(list(series.values())), delimiter=",", header=",".join(series), comments="")
        paths.append(str(path))
    return paths


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    train, test = CASES[name]()
    columns = list(train[0])
    split = {"train": 0.8, "validation": 0.2}
    data = {
        "path": _write(folder, f"{name}-train", train),
        "input": [c for c in columns if c.startswith("u")],
        "output": [c for c in columns if c.startswith("y")],
        "split": split,
        "test": {"path": _write(folder, f"{name}-test", test)},
    }
    return fit_files(name, folder, args, split, list(DEFAULTS), data)


def main() -> None:
    run_generated(__doc__, list(CASES), run_case, list(DEFAULTS), "test NMSE % on noise-free test recordings", False)


if __name__ == "__main__":
    main()
