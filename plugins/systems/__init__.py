"""Built-in test systems for `dynmodel reliability-check --system NAME` (thesis 4.4.1, 5.3.1)."""

from .flows import Duffing, LorenzDriven
from .maps import GaussianMap, TanhNetwork

__all__ = ["Duffing", "LorenzDriven", "GaussianMap", "TanhNetwork"]
