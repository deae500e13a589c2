"""The `narx` family: polynomial NARX models with Fast Orthogonal Search (thesis 3.1, 3.2, A.2.2, 6.3.2)."""

from .model import Narx
from .params import NarxFamilyParams

__all__ = ["Narx", "NarxFamilyParams"]
