"""Data generators (entry-point group ``dynmodel.sources``): the friction laws driven along a
trajectory (position -> force, 6.2 / 6.3) and the closed-loop friction plant (6.4)."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from pydantic import Field

from dynmodel.sources import Generator, GeneratorParams

from .laws import DahlFields, GmsFields, LuGreFields
from .plant import Plant, PlantParams, TrackingTask, simulate
from .response import trajectory_force
from .trajectories import Trajectory, TrajectoryParams

_UNITS = {"m": 1.0, "mm": 1e3, "um": 1e6}


def _presliding() -> TrajectoryParams:
    return TrajectoryParams(kind="random", std=5e-6, band=(0.02, 1.0))


class _DrivenFields(GeneratorParams):
    trajectory: TrajectoryParams = Field(default_factory=_presliding, description="the prescribed position (m)")
    sampling_time: float = Field(0.004, gt=0, description="seconds between samples (6.2: 250 Hz)")
    substeps: int = Field(
        10, ge=1, le=10000, description="integration substeps per sample (position linear within one)"
    )
    position_unit: Literal["m", "mm", "um"] = Field(
        "m", description="unit of the recorded position column (parameters stay in SI units)"
    )


class DahlData(DahlFields, _DrivenFields):
    pass


class LuGreData(LuGreFields, _DrivenFields):
    pass


class GmsData(GmsFields, _DrivenFields):
    pass


class _DrivenLaw(Generator):
    input_names = ("position",)
    output_names = ("force",)

    @classmethod
    def generate(cls, params, n: int, rng: np.random.Generator):
        traj = Trajectory(params.trajectory, rng)
        x, _, force = trajectory_force(params, traj, n, params.sampling_time, params.substeps)
        return (x * _UNITS[params.position_unit])[:, None], force[:, None]


class Dahl(_DrivenLaw):
    name = "dahl"
    description = "Dahl friction (eq. 6.8) along a prescribed position: position (m) -> force (N)"
    Params = DahlData


class LuGre(_DrivenLaw):
    name = "lugre"
    description = "LuGre friction (eq. 6.10-6.12, standard or Olsson damping) along a prescribed position"
    Params = LuGreData


class Gms(_DrivenLaw):
    name = "gms"
    description = "generalized Maxwell-slip friction (eq. 6.13-6.16) along a prescribed position"
    Params = GmsData


class FrictionControlPlant:
    """The plant as ``dynmodel control`` drives it (see ``dynmodel.control.Plant``)."""

    reference_inputs: ClassVar[tuple[str, ...]] = ("position", "reference")
    force_output: ClassVar[str] = "force"

    def __init__(self, params: PlantParams):
        self.params = params
        self.plant = Plant(params)
        self.sampling_time = params.sampling_time
        law = params.law
        self.description = (
            f"mass {params.mass:g} kg, P-controller kp = {params.kp:g} N/m"
            + (f", kd = {params.kd:g} N s/m" if params.kd else "")
            + f", {law.type} friction"
            + (f" ({law.elements} elements)" if law.type == "gms" else "")
            + f", viscous {law.viscous:g} N s/m, noise U[-{params.noise:g}, {params.noise:g}] N"
        )

    def tracking_task(self, n: int, rng: np.random.Generator) -> TrackingTask:
        return TrackingTask(self.plant, n, rng)


class FrictionPlant(Generator):
    name = "friction-plant"
    description = (
        "mass + friction law + noise under P-control following a random reference (6.4): "
        "inputs position, reference (m); outputs force (control), friction (N)"
    )
    Params = PlantParams
    input_names = ("position", "reference")
    output_names = ("force", "friction")

    @classmethod
    def generate(cls, params: PlantParams, n: int, rng: np.random.Generator):
        ref, rec = simulate(params, n, rng)
        return np.column_stack([rec.position, ref]), np.column_stack([rec.force, rec.friction])

    @classmethod
    def control_plant(cls, params: PlantParams) -> FrictionControlPlant:
        return FrictionControlPlant(params)
