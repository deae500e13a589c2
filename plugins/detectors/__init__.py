"""Built-in detectors of ``dynmodel diagnose`` (entry-point group ``dynmodel.detectors``), one module each."""

from .delay import MissingDelay
from .direction import DirectionDependence
from .drift import SensorDrift
from .instability import FreeRunInstability
from .memory import InsufficientMemory
from .noise_bias import NoiseBias
from .nonlinearity import StaticNonlinearity
from .oscillation import UnmodeledOscillation
from .reliability import UnreliableModel

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
]
