"""The `annealed-rnn` family: tanh networks optimized by simulated annealing (thesis 5.3.4, 6.4.5)."""

from .model import AnnealedRnn
from .params import AnnealedRnnParams

__all__ = ["AnnealedRnn", "AnnealedRnnParams"]
