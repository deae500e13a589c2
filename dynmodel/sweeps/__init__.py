"""``dynmodel sweep``: one spec fitted at every point of a grid of settings, in parallel.

:func:`sweep` validates the grid and every point before anything runs, fits the points on a local
process pool, in-process, or on a Dask cluster (:mod:`dynmodel.executors`) through
:func:`dynmodel.batch.run_specs`, and returns a :class:`SweepResult` table (also written as
results.csv / results.json with a figure when an output folder is given).
"""

from .grid import Grid, Point, build_points, load_grid, parse_grid, point_seed
from .results import SweepResult
from .run import Plan, plan, sweep

__all__ = [
    "Grid",
    "Point",
    "build_points",
    "load_grid",
    "parse_grid",
    "point_seed",
    "SweepResult",
    "Plan",
    "plan",
    "sweep",
]
