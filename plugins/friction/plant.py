"""The friction plant of thesis 6.4.2: a mass driven by a force, friction from one of the laws plus
internal noise, under a P(D) controller that follows a reference (fig. 6.19 / 6.20 / 6.22).

    m P'' = F(t) - F_law - sigma2 P' - r_k,     F = kp (P_r - P) + kd (P_r' - P') + F_ff

with r_k ~ U[-noise, noise] N drawn anew every sample (held over the sampling interval), P and the
reference in m. The controller acts continuously (the reference is evaluated at every RK4 stage);
a feed-forward sequence F_ff(t_k) is held linearly between samples (the reference, hence the
feed-forward, is known ahead) or constant (``hold: 0``, a plain digital output). Integration: RK4
with ``substeps`` steps per sample (see ``kernels.plant_run``).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from pydantic import Field, model_validator

from dynmodel.errors import DataError
from dynmodel.sources import GeneratorParams

from . import kernels
from .laws import GMS, LUGRE, GmsLaw, Law, PackedLaw, pack
from .response import friction_force
from .trajectories import Trajectory, TrajectoryParams


def _default_law() -> GmsLaw:
    """Friction system 1 of 6.4.2: GMS with 10 elements and viscous friction 0.2; a compliant contact
    (the elements break away after 0.1 - 5 mm), see the README on the choice."""
    return GmsLaw(viscous=0.2, presliding=(1e-4, 5e-3))


def _default_reference() -> TrajectoryParams:
    """The reference of friction system 1, calibrated on the thesis's published P-control and perfect-model
    figures (6.4.5: NMSE_P 0.897 %, MAX_P 0.280, perfect alpha 99.992 %, beta 99.65 %), which the thesis's
    signal generator left unspecified: std 6 cm over 0.05 - 1.2 Hz gives NMSE_P 0.85 %, MAX_P 0.28,
    alpha 99.999 %, beta 99.5 % (std 5 cm over 0.05 - 0.5 Hz: MAX_P 0.14, beta 94.6 %); see
    benchmarks/friction_ablation.py --plant."""
    return TrajectoryParams(kind="random", std=0.06, band=(0.05, 1.2))


class PlantParams(GeneratorParams):
    mass: float = Field(5.0, gt=0, description="moving mass m (kg)")
    kp: float = Field(4000.0, ge=0, description="proportional gain K_p of the position controller (N/m)")
    kd: float = Field(0.0, ge=0, description="derivative gain (N s/m); 0: the P-controller of 6.4")
    law: Law = Field(
        default_factory=_default_law,
        description="friction law: {type: gms | lugre | dahl, ...}; "
        "keys of a GMS law not given take the plant's defaults (10 elements, viscous 0.2, "
        "pre-sliding 0.1 - 5 mm)",
    )
    noise: float = Field(0.05, ge=0, description="internal noise r ~ U[-noise, noise] (N), a new value every sample")
    reference: TrajectoryParams = Field(default_factory=_default_reference, description="reference trajectory P_r")
    sampling_time: float = Field(0.001, gt=0, description="seconds between samples")
    substeps: int = Field(10, ge=1, le=1000, description="RK4 steps per sample")

    @model_validator(mode="before")
    @classmethod
    def _law_defaults(cls, data):
        """A GMS law given in part takes the plant's defaults (friction system 1) for the rest."""
        if isinstance(data, dict) and isinstance(data.get("law"), dict) and data["law"].get("type", "gms") == "gms":
            data = {**data, "law": {**_default_law().model_dump(), **data["law"]}}
        return data

    @model_validator(mode="after")
    def _resolution(self):
        h = self.sampling_time / self.substeps
        law = self.law
        stiff = self.kp + (
            float(np.sum(law.k())) if law.type == "gms" else (law.sigma0 if law.type == "lugre" else law.sigma)
        )
        rates = {"the stick oscillation sqrt((kp + stiffness) / m)": math.sqrt(stiff / self.mass)}
        if law.type == "gms":
            rates["the slip relaxation C / (nu_i F_min)"] = law.attraction / (
                float(np.min(law.nu())) * min(law.coulomb, law.static)
            )
        if law.type == "lugre":
            rates["the damping (sigma1 + kd) / m"] = (law.sigma1 + self.kd) / self.mass
        what, rate = max(rates.items(), key=lambda kv: kv[1])
        if rate * h > 1.0:
            need = math.ceil(rate * self.sampling_time)
            raise ValueError(
                f"substeps = {self.substeps} is too coarse for {what} = {rate:.4g} 1/s (RK4 step "
                f"{h:.3g} s); use substeps >= {need}"
            )
        return self


@dataclass
class PlantState:
    """[P, V], law states and GMS modes at a sample boundary."""

    xv: np.ndarray
    S: np.ndarray
    mode: np.ndarray

    def copy(self) -> PlantState:
        return PlantState(self.xv.copy(), self.S.copy(), self.mode.copy())


@dataclass
class Record:
    position: np.ndarray
    force: np.ndarray
    friction: np.ndarray


class Plant:
    """A friction plant with a drawn reference, simulated in pieces from a saved state."""

    def __init__(self, params: PlantParams):
        self.params = params
        self.law: PackedLaw = pack(params.law)
        self.substeps = params.substeps
        self.h = params.sampling_time / params.substeps

    def reference_grid(self, trajectory: Trajectory, n: int):
        """Reference position and velocity every half substep up to t_n (2 substeps n + 1 points)."""
        x, v, _ = trajectory.grid(0.0, self.h / 2, 2 * self.substeps * n + 1)
        return x, v

    def initial_state(self, ref0: float, dref0: float) -> PlantState:
        m = self.law.n_states
        return PlantState(np.array([ref0, dref0]), np.zeros(m), np.zeros(m))

    def run(
        self,
        ref: np.ndarray,
        dref: np.ndarray,
        feedforward: np.ndarray,
        noise: np.ndarray,
        state: PlantState,
        start: int,
        stop: int,
        hold: int = 1,
    ) -> Record:
        """Samples [start, stop) from ``state`` (updated in place to t_stop)."""
        n = noise.shape[0]
        pos, frc, fri = np.empty(n), np.empty(n), np.empty(n)
        p = self.params
        bad = kernels.plant_run(
            self.law.kind,
            self.law.p,
            self.law.k,
            self.law.nu,
            p.mass,
            p.kp,
            p.kd,
            ref,
            dref,
            feedforward,
            hold,
            noise,
            self.substeps,
            self.h,
            state.xv,
            state.S,
            state.mode,
            start,
            stop,
            pos,
            frc,
            fri,
        )
        if bad >= 0:
            raise DataError(
                f"the friction plant's integration diverged at sample {bad} (t = {bad * p.sampling_time:.6g} s)",
                "friction-plant",
                "increase substeps or check the law's parameters",
            )
        return Record(pos[start:stop], frc[start:stop], fri[start:stop])

    def noise(self, n: int, rng: np.random.Generator) -> np.ndarray:
        a = self.params.noise
        return rng.uniform(-a, a, n) if a > 0 else np.zeros(n)

    def perfect_feedforward(self, trajectory: Trajectory, n: int) -> np.ndarray:
        """The plant's own law as the model (fig. 6.23): m P_r'' + F_law(P_r) + sigma2 P_r', no noise."""
        x, v, a = trajectory.grid(0.0, self.h, (n - 1) * self.substeps + 1)
        s = self.substeps
        friction = friction_force(self.params.law, x, v[::s].copy(), self.h, s)
        return self.params.mass * a[::s] + friction


def simulate(params: PlantParams, n: int, rng: np.random.Generator) -> tuple[np.ndarray, Record]:
    """A closed-loop recording without feed-forward (the indirect approach of 6.4.3, fig. 6.22):
    the reference and the record (position, control force, friction) at n samples."""
    traj = Trajectory(params.reference, rng)
    plant = Plant(params)
    ref, dref = plant.reference_grid(traj, n)
    noise = plant.noise(n, rng)
    state = plant.initial_state(ref[0], dref[0])
    rec = plant.run(ref, dref, np.zeros(n + 1), noise, state, 0, n)
    return ref[:: 2 * params.substeps][:n].copy(), rec


class TrackingTask:
    """One reference for ``dynmodel control``: P-control up to the switch, then with a feed-forward."""

    def __init__(self, plant: Plant, n: int, rng: np.random.Generator):
        self.plant, self.n = plant, n
        self.trajectory = Trajectory(plant.params.reference, rng)
        self.ref_grid, self.dref_grid = plant.reference_grid(self.trajectory, n)
        self.reference = self.ref_grid[:: 2 * plant.substeps][:n].copy()

    def perfect_feedforward(self) -> np.ndarray:
        return self.plant.perfect_feedforward(self.trajectory, self.n)

    def start(self, switch: int, rng: np.random.Generator, hold: int = 1) -> TrackingRun:
        return TrackingRun(self, switch, self.plant.noise(self.n, rng), hold)


class TrackingRun:
    """The P-controlled part [0, switch) of one noise realization; :meth:`resume` continues it."""

    def __init__(self, task: TrackingTask, switch: int, noise: np.ndarray, hold: int):
        self.task, self.switch, self.noise, self.hold = task, switch, noise, hold
        plant = task.plant
        self._state = plant.initial_state(task.ref_grid[0], task.dref_grid[0])
        rec = plant.run(task.ref_grid, task.dref_grid, np.zeros(task.n + 1), noise, self._state, 0, switch, hold)
        self.position, self.force = rec.position, rec.force

    def resume(self, feedforward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(position, control force incl. feed-forward) over [switch, n) with ``feedforward`` (n,)
        active from the switch on; the same noise, from a copy of the state at the switch."""
        task = self.task
        ff = np.zeros(task.n + 1)
        ff[self.switch : task.n] = feedforward[self.switch :]
        ff[task.n] = feedforward[-1]
        state = copy.deepcopy(self._state)
        rec = task.plant.run(task.ref_grid, task.dref_grid, ff, self.noise, state, self.switch, task.n, self.hold)
        return rec.position, rec.force


__all__ = ["PlantParams", "Plant", "simulate", "TrackingTask", "TrackingRun", "GMS", "LUGRE"]
