"""dynmodel: black-box modeling of driven dynamical systems from input/output time series.

Python API (mirrors the CLI)::

    import dynmodel
    spec = dynmodel.load_spec("specs/quickstart.yaml")
    model = dynmodel.fit(spec)            # FittedModel, metrics in model.metrics
    dynmodel.save(model, "model.h5")
    model = dynmodel.load("model.h5")
    y = model.predict(u)                  # free run in physical units
    result = dynmodel.sweep(spec, {"model.params.size": [100, 200], "seed": {"range": [0, 5]}})
"""

from __future__ import annotations

__version__ = "0.1.0"

from .errors import DynmodelError  # noqa: E402
from .spec import load_spec, validate_spec  # noqa: E402


def fit(spec, progress=None):
    """Fit the model described by ``spec`` (a loaded spec or a path to a YAML file)."""
    from . import engine

    if not hasattr(spec, "model"):
        spec = load_spec(spec)
    return engine.fit(spec, progress or engine.no_progress)


def sweep(spec, grid, executor=None, **options):
    """Fit ``spec`` at every point of ``grid`` (dotted spec keys -> lists of values) and return a
    :class:`dynmodel.sweeps.SweepResult` table; see :func:`dynmodel.sweeps.sweep` for the options."""
    from .sweeps import sweep as run

    return run(spec, grid, executor, **options)


def save(model, path):
    from . import store

    return store.save(model, path)


def load(path):
    from . import store

    return store.load(path)


__all__ = ["__version__", "DynmodelError", "load_spec", "validate_spec", "fit", "sweep", "save", "load"]
