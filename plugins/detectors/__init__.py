"""Built-in detectors of ``dynmodel diagnose`` (entry-point group ``dynmodel.detectors``), one module each."""

from .delay import MissingDelay
from .direction import DirectionDependence
from .drift import SensorDrift
from .dynamics import MissingDynamics
from .instability import FreeRunInstability
from .memory import InsufficientMemory
from .noise_bias import NoiseBias
from .nonlinearity import StaticNonlinearity
from .oscillation import UnmodeledOscillation
from .output_nonlinearity import OutputNonlinearity
from .reliability import UnreliableModel
from .stopped_early import StructureStoppedEarly

__all__ = [
    "MissingDelay",
    "DirectionDependence",
    "SensorDrift",
    "FreeRunInstability",
    "InsufficientMemory",
    "NoiseBias",
    "StaticNonlinearity",
    "UnmodeledOscillation",
    "UnreliableModel",
    "OutputNonlinearity",
    "MissingDynamics",
    "StructureStoppedEarly",
]
