"""Orchestration: spec -> data -> family.fit -> fitted model -> evaluation."""

from __future__ import annotations

import platform
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any

import numpy as np

from . import __version__, protocol, registry
from .data import Preprocessor, load_dataset, training_data
from .data.dataset import Dataset
from .errors import DataError, DynmodelError, ParameterError
from .family import Family, Progress, no_progress
from .model import FittedModel, Run, evaluate
from .threads import fit_threads

if TYPE_CHECKING:
    from .api import ArraySpec
    from .spec import Spec


def family_rng(seed: int) -> np.random.Generator:
    """The generator handed to ``family.fit`` (independent of the noise stream)."""
    return np.random.default_rng(np.random.SeedSequence([seed, 0x66616D]))


def _provenance(spec: Spec | ArraySpec, ds: Dataset) -> dict[str, Any]:
    import h5py
    import numba
    import scipy

    return {
        "dynmodel_version": __version__,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "seed": int(spec.seed),
        "training_data_sha256": ds.fingerprint(),
        "spec_file": spec.source,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "h5py": h5py.__version__,
    }


def preprocessor(spec: Spec | ArraySpec, ds: Dataset) -> Preprocessor:
    """The spec's preprocessing (delay lines, derived inputs, detrending, scaling) fitted on ``ds``."""
    d = spec.data
    _check_delay_lines(list(d.delay_lines), ds, spec.source)
    derived = [item.model_dump(mode="json", exclude_none=True) for item in d.derived_inputs]
    detrend = [fn if isinstance(fn, str) else fn.model_dump(mode="json") for fn in d.detrend]
    try:
        return Preprocessor.fit(ds, list(d.delay_lines), d.scaling, derived, detrend, d.delay_form)
    except DynmodelError:
        raise
    except ValueError as exc:
        raise DataError(str(exc), f"{spec.source}: data", "correct data.derived_inputs") from None


def _check_delay_lines(delay_lines: list[int], ds: Dataset, source: str) -> None:
    """A delay line must see the input it delays: one that reaches back beyond the start of a recording on
    most training samples holds the recording's first value there, a constant the model learns nothing
    from (an ESN with a delay line as long as its training split scored 100 % NMSE without a word)."""
    if not delay_lines:
        return
    rows = ds.scored("train")
    total = sum(b - a for _, a, b in rows)
    longest = max(delay_lines)
    seen = sum(max(0, b - max(a, longest)) for _, a, b in rows)
    if total and seen < 0.5 * total:
        raise DataError(
            f"the delay line of {longest} samples reaches back before the recording's start on "
            f"{100 * (1 - seen / total):.0f} % of the training samples, where it holds a constant",
            f"{source}: data.delay_lines",
            f"use delay lines shorter than {max(1, total // 2)} samples (half the training split's {total})",
        )


@contextmanager
def family_errors(spec: Spec | ArraySpec) -> Iterator[None]:
    """A family's ValueError (its one-line refusal of parameters or data) as the spec's ParameterError; the
    package's own errors pass unchanged."""
    try:
        yield
    except DynmodelError:
        raise
    except ValueError as exc:
        raise ParameterError(
            str(exc), f"{spec.source}: model ({spec.model.family})", "adjust model.params or the data split"
        ) from exc


def check_plan(spec: Spec, ds: Dataset) -> Family | list[str]:
    """The spec's family, unfitted, after checking it can be fitted and scored on ``ds`` (its
    tune-in leaves scored samples in every split); one-line errors otherwise (``validate`` uses it).
    For ``family: auto``: the lines that describe the search's plan (nothing is fitted)."""
    if spec.model.family == "auto":
        from .search.run import describe_plan

        return describe_plan(spec, ds)
    return checked_family(spec, ds)


def checked_family(spec: Spec, ds: Dataset) -> Family:
    """The spec's family (not ``auto``), unfitted, checked as in :func:`check_plan`."""
    from .data.checks import check_warmup

    family_cls = registry.family(spec.model.family)
    try:
        family = family_cls(**spec.model.params.model_dump(mode="python"))
    except ValueError as exc:
        raise ParameterError(str(exc), f"{spec.source}: model ({spec.model.family})", "adjust model.params") from None
    check_warmup(ds, family.warmup, spec.source)
    protocol.check_warmup(family, ds, spec.source)  # before a long fit, where the parameters fix it
    splits = {split for split, rows in ds.ranges.items() if rows}
    with family_errors(spec):
        family.check_data(preprocessor(spec, ds).model_input_names, list(ds.output_names), splits)
    return family


def fit_dataset(
    spec: Spec, ds: Dataset, progress: Progress = no_progress, pre: Preprocessor | None = None
) -> tuple[FittedModel, list[Run]]:
    """Fit the spec's model on an already loaded dataset and evaluate it on every split (``family: auto``:
    search the families first, see :mod:`dynmodel.search`). ``pre``: this preprocessing instead of the one the
    spec fits on ``ds``'s training split (a refit warm-started from a model's values keeps that model's)."""
    if spec.model.family == "auto":
        from .search import fit_auto

        return fit_auto(spec, ds, progress)
    family = checked_family(spec, ds)
    return fit_family(family, spec, ds, progress, pre)


def fit_family(
    family: Family,
    spec: Spec | ArraySpec,
    ds: Dataset,
    progress: Progress = no_progress,
    pre: Preprocessor | None = None,
) -> tuple[FittedModel, list[Run]]:
    """Fit a constructed ``family`` on ``ds`` with the spec's preprocessing (or ``pre``), cost and seed, and
    evaluate it on every split (the engine path of ``dynmodel fit`` and of ``Family.fit`` on arrays), with one
    BLAS thread so that the result does not depend on the machine (see :mod:`dynmodel.threads`)."""
    with fit_threads():
        return _fit_family(family, spec, ds, progress, pre)


def _fit_family(
    family: Family, spec: Spec | ArraySpec, ds: Dataset, progress: Progress, pre: Preprocessor | None = None
) -> tuple[FittedModel, list[Run]]:
    from .data.checks import check_warmup

    check_warmup(ds, family.warmup, spec.source)  # also for a family constructed in Python (no checked_family)
    if pre is None:
        pre = preprocessor(spec, ds)
    td = training_data(ds, pre)
    assert spec.cost is not None, "the cost is set for every family but auto (which searches)"
    with family_errors(spec):
        family.fit(td, spec.cost, family_rng(spec.seed), progress)
    protocol.check_warmup(family, ds, spec.source)
    train_u, lengths = ds.concat_inputs("train")
    model = FittedModel(
        family,
        pre,
        td.output_bounds(),
        spec.resolved(),
        provenance=_provenance(spec, ds),
        train_input=train_u,
        train_input_lengths=lengths,
        train_output=ds.concat_outputs("train"),
    )
    progress("evaluate", None, "free runs over every recording")
    metrics, runs = evaluate(model, ds, list(spec.evaluation.metrics), spec.evaluation.one_step)
    model.metrics = protocol.report(metrics, ds, protocol.units_of(spec, ds))
    return model, runs


def fit(spec: Spec, progress: Progress = no_progress) -> FittedModel:
    """Load the data of ``spec``, fit its model, evaluate free runs on every split."""
    progress("data", None, "loading")
    ds = load_dataset(spec)
    model, _ = fit_dataset(spec, ds, progress)
    return model
