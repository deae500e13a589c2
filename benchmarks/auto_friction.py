"""family: auto on the friction generators, next to the narx and esn defaults.

    python benchmarks/auto_friction.py                    # every case (about 6 min on 2 cores)
    python benchmarks/auto_friction.py --only dahl --no-defaults

Each case is a cross-prediction position -> force (thesis 6.2 - 6.3) from ``dynmodel generate`` with the
generator's defaults: the training recording is seed 1 (split 80 / 20 into training and validation), the
test recording seed 2, another random trajectory (docs/friction.md):

* ``dahl``, ``lugre``, ``gms``: the friction laws along a random micrometre trajectory, 12000 samples at
  250 Hz (pre-sliding hysteresis and sliding);
* ``plant``: the control force of the P-controlled friction plant (6.4.2) from its position, 20000 samples
  at 1 kHz;
* ``lugre-velocity``: the ``lugre`` case driven by its sliding velocity (the position differentiated, as a
  tribometer that logs the velocity gives it): velocity -> force.

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of the narx and esn defaults,
the model auto chose and its wall time. Asserts nothing; the data come from fixed seeds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_series, run_generated

DEFAULTS = ("narx", "esn")
CASES = {
    "dahl": ("dahl", 12000),
    "lugre": ("lugre", 12000),
    "gms": ("gms", 12000),
    "plant": ("friction-plant", 20000),
    "lugre-velocity": ("lugre", 12000),
}
#: the generators' sampling rate for the friction laws (Hz): a velocity in units per second
RATE = 250.0


def generate(generator: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(position, force) of one generated recording."""
    from dynmodel.data import load_dataset
    from dynmodel.spec import validate_spec

    raw = {"data": {"generator": generator, "n": n, "seed": seed, "input": ["position"], "output": ["force"]}}
    rec = load_dataset(validate_spec(raw, generator)).recordings[0]
    return rec.u[:, 0], rec.y[:, 0]


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    generator, n = CASES[name]
    runs = []
    for seed in (1, 2):  # training and validation, then the test
        u, y = generate(generator, n, seed)
        runs.append({"u": np.gradient(u) * RATE if name.endswith("-velocity") else u, "y": y})
    return fit_series(name, folder, args, *runs, list(DEFAULTS))


def main() -> None:
    run_generated(__doc__, list(CASES), run_case, list(DEFAULTS), "test NMSE % on another random trajectory")


if __name__ == "__main__":
    main()
