"""Compiled (numba) hot loops. Every kernel here has a plain-numpy twin in the tests or benchmarks."""

from .network import (
    dense_step_batch,
    dense_tangent_batch,
    drive,
    drive_chunk,
    drive_output,
    free_run,
    free_run_clipped,
    free_run_span,
    step_batch,
    tangent_batch,
)
from .spread import group_spread, row_distances
from .tanh import tanh_vec

__all__ = [
    "tanh_vec",
    "drive",
    "drive_chunk",
    "drive_output",
    "free_run",
    "free_run_clipped",
    "free_run_span",
    "step_batch",
    "tangent_batch",
    "dense_step_batch",
    "dense_tangent_batch",
    "group_spread",
    "row_distances",
]
