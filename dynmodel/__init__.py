"""dynmodel: black-box modeling of driven dynamical systems from input/output time series.

Python API (mirrors the CLI)::

    import dynmodel
    spec = dynmodel.load_spec("specs/quickstart.yaml")
    model = dynmodel.fit(spec)            # FittedModel, metrics in model.metrics
    dynmodel.save(model, "model.h5")
    model = dynmodel.load("model.h5")
    y = model.predict(u)                  # free run in physical units

On arrays or DataFrames (families are scikit-learn style estimators)::

    from dynmodel_plugins.narx import Narx
    narx = Narx(degree=3, lags={"u": [0, 1, 2], "y": [1, 2]}).fit(u, y)   # validation: last 20 %
    narx.predict(u_new, y_tune=y_new[: narx.warmup]); narx.score(u_new, y_new)   # R^2 of the free run
    dynmodel.save(narx, "narx.h5")
    model = dynmodel.fit("my-spec.yaml", data=(u, y))   # a spec's settings on your arrays
    result = dynmodel.sweep(spec, {"model.params.size": [100, 200], "seed": {"range": [0, 5]}})
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

from .errors import DynmodelError  # noqa: E402

if TYPE_CHECKING:
    from .model import FittedModel
    from .spec import Spec, load_spec, validate_spec

#: loaded from :mod:`dynmodel.spec` on first use (:func:`__getattr__`)
_FROM_SPEC = ("Spec", "load_spec", "validate_spec")


def __getattr__(name: str) -> Any:
    """``Spec``, ``load_spec`` and ``validate_spec``, loaded on first use: :mod:`dynmodel.spec` brings pydantic and
    numpy (0.3 s), and ``import dynmodel`` is the command line's first step, where a Ctrl-C would otherwise end in a
    traceback (:mod:`dynmodel.launch`)."""
    if name in _FROM_SPEC:
        from . import spec

        return getattr(spec, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def fit(spec: Spec | dict | str | Path, data: Any = None, progress: Any = None) -> FittedModel:
    """Fit the model described by ``spec`` (a loaded spec, a mapping or a path to a YAML file).

    ``data``: recordings given in Python instead of the spec's data source: ``(u, y)``, a DataFrame with
    the spec's input and output columns, a list of these, or ``{"train": ..., "validation": ...,
    "test": ...}`` (see :func:`dynmodel.api.fit_spec`). ``progress``: a callback ``(stage, fraction,
    message)``, or True for progress on stderr."""
    from collections.abc import Mapping

    from .errors import ParameterError
    from .spec import Spec, load_spec, validate_spec

    if not isinstance(spec, (Spec, Mapping, str, Path)):
        raise ParameterError(
            f"spec is a {type(spec).__name__}", "dynmodel.fit", "pass a YAML path, a mapping or a loaded spec"
        )
    if data is not None:
        from .api import fit_spec

        return fit_spec(spec, data, progress)
    from . import engine
    from .api import progress_reporter, warn_data_notes, warn_if_useless
    from .data import load_dataset

    if isinstance(spec, Mapping):
        spec = validate_spec(dict(spec))
    elif not isinstance(spec, Spec):
        spec = load_spec(spec)
    with progress_reporter(progress) as report:
        report("data", None, "loading")
        ds = load_dataset(spec)
        warn_data_notes(ds)
        model, runs = engine.fit_dataset(spec, ds, report)
    warn_if_useless(model, ds, runs)  # as on arrays: a model of little use is never silent
    return model


def sweep(spec, grid, executor=None, **options):
    """Fit ``spec`` at every point of ``grid`` (dotted spec keys -> lists of values) and return a
    :class:`dynmodel.sweeps.SweepResult` table; see :func:`dynmodel.sweeps.sweep` for the options."""
    from .sweeps import sweep as run

    return run(spec, grid, executor, **options)


def save(model, path):
    """Write a FittedModel, or a family fitted on arrays, to an HDF5 model file (atomically).

    As ``dynmodel fit --out`` does, an existing file is replaced only when it is a dynmodel model file:
    a CSV, a spec or any other file at ``path`` raises :class:`~dynmodel.errors.OutputError` and stays
    as it was (delete it first if it really should go)."""
    from . import store
    from .family import Family
    from .model import FittedModel
    from .paths import check_output

    if not isinstance(model, (FittedModel, Family)):
        raise TypeError(
            f"dynmodel.save writes a fitted model, not a {type(model).__name__}: pass the estimator after its "
            "fit (or dynmodel.fit's result)"
        )
    return store.save(model, check_output(path, "model", option="dynmodel.save's path"))


def load(path):
    from . import store

    return store.load(path)


__all__ = ["__version__", "DynmodelError", "Spec", "load_spec", "validate_spec", "fit", "sweep", "save", "load"]
