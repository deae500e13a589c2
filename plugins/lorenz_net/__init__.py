"""The `lorenz-net` family: networks of driven Lorenz systems, reliable by construction (thesis 4.4.2)."""

from .model import LorenzNet
from .params import LorenzNetParams

__all__ = ["LorenzNet", "LorenzNetParams"]
