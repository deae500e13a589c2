"""family: auto on a six-input six-output plant (the own-past output-error model, docs/auto.md).

    python benchmarks/auto_mimo.py                                  # the installed families, about 5 min on 2 cores
    python benchmarks/auto_mimo.py --families narx esn annealed-rnn   # the built-in ones only

Six joints with coupled inertia (M = I + 0.2 (1 - I) / 6), stiffness 1..3, damping 0.5..1.5 and Coulomb
friction 0.1..0.3 (tanh(v / 0.01)), driven by six independent low-pass random torques (Butterworth, 0.02 of
Nyquist), Euler steps of 0.01 s; outputs: the six joint velocities with 1 % white sensor noise. 40 000
samples, the default split (60 / 20 / 20 in time order), `family: auto` with the default budget. Printed: the
test NMSE (%) pooled over the outputs, the chosen candidate, the search's seconds. Asserts nothing.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.signal import butter, lfilter

import dynmodel

JOINTS = 6


def robot(n: int = 40000, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(torques (n, 6), joint velocities (n, 6)) of the plant in the module docstring."""
    rng = np.random.default_rng(seed)
    b, a = butter(2, 0.02)
    u = np.column_stack([lfilter(b, a, rng.standard_normal(n)) * 20 for _ in range(JOINTS)])
    inertia = np.eye(JOINTS) + 0.2 * (np.ones((JOINTS, JOINTS)) - np.eye(JOINTS)) / JOINTS
    inverse = np.linalg.inv(inertia)
    stiffness, damping, coulomb = (
        np.linspace(1, 3, JOINTS),
        np.linspace(0.5, 1.5, JOINTS),
        np.linspace(0.1, 0.3, JOINTS),
    )
    dt, v, q = 0.01, np.zeros(JOINTS), np.zeros(JOINTS)
    y = np.zeros((n, JOINTS))
    for t in range(n):
        acc = inverse @ (u[t] - stiffness * q - damping * v - coulomb * np.tanh(v / 0.01))
        v = v + dt * acc
        q = q + dt * v
        y[t] = v
    return u, y + 0.01 * y.std(axis=0) * rng.standard_normal(y.shape)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--families", nargs="*", help="restrict the search (default: every installed family)")
    parser.add_argument("--budget", type=float, help="search budget in seconds (default: auto's own)")
    args = parser.parse_args()
    u, y = robot()
    inputs, outputs = [f"tau{j}" for j in range(JOINTS)], [f"v{j}" for j in range(JOINTS)]
    params = {k: v for k, v in (("families", args.families), ("budget", args.budget)) if v}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "robot.csv"
        np.savetxt(path, np.column_stack([u, y]), delimiter=",", header=",".join(inputs + outputs), comments="")
        spec = {
            "name": "robot",
            "data": {"path": str(path), "input": inputs, "output": outputs, "sampling_time": 0.01},
            "model": {"family": "auto", "params": params},
            "seed": 0,
        }
        t0 = time.perf_counter()
        model = dynmodel.fit(spec)
        wall = time.perf_counter() - t0
    print(f"test NMSE {model.metrics['test']['nmse']:.4g} %  ({wall:.0f} s)  chose {model.search['winner_summary']}")


if __name__ == "__main__":
    main()
