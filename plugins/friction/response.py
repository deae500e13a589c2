"""Friction force along a prescribed position trajectory (the cross-prediction task of 6.2 / 6.3)."""

from __future__ import annotations

import numpy as np

from . import kernels
from .laws import AnyLaw, pack
from .trajectories import Trajectory


class LawState:
    """The internal state of a law (z, or element forces and modes); starts virgin (all zero, sticking)."""

    def __init__(self, law: AnyLaw):
        self.packed = pack(law)
        self.state = np.zeros(self.packed.n_states)
        self.mode = np.zeros(self.packed.n_states)


def friction_force(
    law: AnyLaw, x: np.ndarray, v: np.ndarray, substep: float, substeps: int, state: LawState | None = None
) -> np.ndarray:
    """Force at the samples of a trajectory given at every substep boundary.

    ``x``: (n - 1) * substeps + 1 positions, sample j at x[j * substeps], linear within a substep;
    ``v``: the n sample velocities; ``substep``: the substep length (s). ``state`` is continued
    (and updated) when given, else the law starts virgin.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    n = v.shape[0]
    if x.shape[0] != (n - 1) * substeps + 1:
        raise ValueError(f"x needs (n - 1) * substeps + 1 = {(n - 1) * substeps + 1} positions, got {x.shape[0]}")
    st = state or LawState(law)
    pk = st.packed
    return kernels.law_force(pk.kind, pk.p, pk.k, pk.nu, x, v, int(substeps), float(substep), st.state, st.mode)


def trajectory_force(
    law: AnyLaw, trajectory: Trajectory, n: int, sampling_time: float, substeps: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position, velocity, force) at n samples of ``trajectory``, from the virgin state."""
    h = sampling_time / substeps
    x_fine, v_fine, _ = trajectory.grid(0.0, h, (n - 1) * substeps + 1)
    v = v_fine[::substeps].copy()
    return x_fine[::substeps].copy(), v, friction_force(law, x_fine, v, h, substeps)
