"""Compiled (numba) hot loops. Every kernel here has a plain-numpy twin in the tests or benchmarks."""
from .tanh import tanh_vec
from .network import drive, drive_features, free_run, step_batch

__all__ = ["tanh_vec", "drive", "drive_features", "free_run", "step_batch"]
