"""``model: {family: auto}``: search candidate models of every family, keep the best (docs/auto.md).

:func:`fit_auto` is what the engine calls for an auto spec; it returns an ordinary fitted model of the
winning family whose ``search`` attribute holds the record of the search (every candidate, its family,
parameters, validation metrics, fit time and verdict). Where the fits run is set with
:func:`search_options` (the CLI's ``--workers`` / ``--scheduler``); by default a local process pool with
one worker per core, and in-process when this process is itself a worker.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from contextvars import ContextVar
from typing import TYPE_CHECKING, Any

from ..data.dataset import Dataset
from ..errors import DynmodelError, Interrupted
from ..family import Progress, no_progress
from .params import AUTO, AutoParams, searchable_families
from .space import Candidate, Found, SearchContext

if TYPE_CHECKING:
    from ..spec import Spec

__all__ = [
    "AUTO",
    "AutoParams",
    "Candidate",
    "Found",
    "SearchContext",
    "SearchInterrupted",
    "fit_auto",
    "search_options",
    "searchable_families",
]

_options: ContextVar[dict[str, Any] | None] = ContextVar("dynmodel_search_options", default=None)


class SearchInterrupted(Interrupted):
    """Ctrl-C before any candidate finished: nothing to keep (exit 130)."""


@contextlib.contextmanager
def search_options(
    *, workers: int | None = None, scheduler: str | None = None, executor: Any = None, cancel: Any = None
) -> Iterator[None]:
    """Where the fits of a search started inside this block run: an ``executor`` (kept running), or one
    made from ``workers`` / ``scheduler`` as :func:`dynmodel.executors.make_executor` does; ``cancel``: a
    ``threading.Event`` that stops the search (the best model so far is kept)."""
    token = _options.set({"workers": workers, "scheduler": scheduler, "executor": executor, "cancel": cancel})
    try:
        yield
    finally:
        _options.reset(token)


def _executor(opts: dict[str, Any]):
    from ..executors import InProcessExecutor, make_executor
    from .run import _in_worker

    if opts.get("executor") is not None:
        return opts["executor"], False
    if opts.get("workers") is None and opts.get("scheduler") is None and _in_worker():
        return InProcessExecutor(), True
    return make_executor(opts.get("workers"), opts.get("scheduler")), True


def fit_auto(spec: Spec, ds: Dataset, progress: Progress = no_progress):
    """Search, then return ``(model, runs)`` like :func:`dynmodel.engine.fit_dataset`: the winner refitted or
    kept, evaluated on every split of ``ds`` with the spec's evaluation settings, ``model.search`` the record.
    Ctrl-C keeps the best model so far (the record says it was interrupted)."""
    from .. import engine, protocol
    from ..model import evaluate
    from .run import Search

    opts = dict(_options.get() or {})
    executor, own = _executor(opts)
    cancel = opts.get("cancel") or threading.Event()
    written_cost = spec.cost if "cost" in spec.model_fields_set else None
    try:
        search = Search(spec, ds, executor, progress, cancel, written_cost)
        result = search.run()
    finally:
        if own:
            executor.shutdown(wait=False, cancel_futures=True)
    model = result.model
    record = result.record
    if model is None:
        if record.get("interrupted"):
            scored = sum(1 for c in record.get("candidates", []) if c.get("levels"))
            raise SearchInterrupted(
                f"no model was kept: the search was {record['interrupted']} ({scored} candidates scored)",
                f"{spec.source}: model",
                "rerun it and let it finish, or give a smaller budget",
            )
        why = "; ".join(record.get("notes") or []) or "no candidate gave a usable model"
        raise DynmodelError(
            f"family auto found no usable model: {why}",
            f"{spec.source}: model",
            "check the data (dynmodel validate), give a larger budget, or fit one family directly",
        )
    # the winner as an ordinary model of its family, with the user's evaluation, name and output
    user = spec.resolved()
    model.spec = {
        **model.spec,
        "name": user["name"],
        "evaluation": user["evaluation"],
        "output": user["output"],
    }
    model.spec["data"] = {**user["data"], **{k: v for k, v in model.spec["data"].items() if k in _DATA_PATCH_KEYS}}
    trained = ds
    if (record.get("refit") or {}).get("refitted"):  # fitted again on the training and validation samples
        from .views import Layout, view

        trained = view(ds, Layout("all"))
    train_u, lengths = trained.concat_inputs("train")
    model.train_input, model.train_input_lengths = train_u, lengths
    model.train_output = trained.concat_outputs("train")
    model.provenance = {**engine._provenance(spec, ds), "search_seconds": record.get("seconds")}
    progress("evaluate", None, "free runs of the chosen model over every recording")
    protocol.check_warmup(model.family, ds, spec.source)
    metrics, runs = evaluate(model, ds, list(spec.evaluation.metrics), spec.evaluation.one_step)
    model.metrics = protocol.report(metrics, ds, protocol.units_of(spec, ds))
    if trained is not ds and "validation" in model.metrics:  # its samples were fitted: no hold-out score
        model.metrics["validation"]["fitted"] = True
    model.search = record
    return model, runs


#: data keys a candidate may change (data-side extensions); the rest of the data section is the user's
_DATA_PATCH_KEYS = ("delay_lines", "delay_form", "derived_inputs", "detrend", "scaling")
