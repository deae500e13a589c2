"""Run many fully specified specs through an executor and collect per-point results as they finish.

This is the engine of ``dynmodel sweep`` and of searches that propose their own candidate specs::

    from dynmodel.batch import Variant, run_specs
    from dynmodel.executors import make_executor

    variants = [Variant(f"c{i}", raw, base_dir) for i, raw in enumerate(candidate_specs)]
    with make_executor(workers=2) as ex:
        for result in run_specs(variants, ex, keep_models=True, budget=600, cancel=stop_event):
            result.status, result.metrics["validation"]["nmse"], result.seed, result.seconds
            model = result.model.to_model()       # a FittedModel; dynmodel.save(model, path)

A point's spec is used exactly as given (its ``seed`` included), so fitting it alone with
``dynmodel fit`` gives bit-identical metrics. Workers load each recording once per process (cached
by the resolved data section) and return plain arrays, never files. A point that fails is a result
with status ``error`` and a one-line message, a point whose free run diverges one with status
``diverged``; the run goes on. A worker process killed mid-point (kill -9, out of memory) breaks a
local process pool: the pool is rebuilt and the unfinished points are resubmitted, the suspects one
at a time so that a point which kills its worker again is charged alone (``max_retries`` times,
then recorded as an error). Dask reschedules such points itself (up to its ``allowed-failures``).
"""

from __future__ import annotations

import json
import os
import socket
import threading
import time
import traceback
import warnings
from collections import OrderedDict, deque
from collections.abc import Callable, Generator, Iterable
from concurrent.futures import CancelledError, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from .errors import DynmodelError, Interrupted

if TYPE_CHECKING:
    from .data.dataset import Dataset
    from .spec import Spec

Status = Literal["ok", "diverged", "error"]

#: data keys that change only the preprocessing, not the loaded recordings (not part of the cache key)
PREPROCESSING_KEYS = ("delay_lines", "derived_inputs", "detrend", "scaling", "delay_form")
#: recordings kept per worker process (least recently used dropped first)
DATA_CACHE_SIZE = 4


@dataclass(frozen=True)
class Variant:
    """One fully specified spec to fit.

    ``raw`` is a complete spec mapping, as a user could write it (its ``seed`` is used as given);
    relative data paths resolve against ``base_dir``, which must be readable by the workers (absolute
    paths, as :meth:`Spec.resolved` writes them, run anywhere). ``source`` names the point in
    error messages."""

    key: str
    raw: dict[str, Any]
    base_dir: str | Path = "."
    source: str = "<spec>"


@dataclass
class ModelArrays:
    """A fitted model as plain arrays and JSON-able attributes (what :mod:`dynmodel.store` writes),
    sent from a worker to the parent; :meth:`to_model` rebuilds the FittedModel."""

    family: str
    params: dict[str, Any]
    arrays: dict[str, Any]
    attrs: dict[str, Any]
    pre_arrays: dict[str, Any]
    pre_attrs: dict[str, Any]
    bounds: tuple[Any, Any]
    spec: dict[str, Any]
    metrics: dict[str, Any]
    provenance: dict[str, Any]
    train_input: Any = None
    train_input_lengths: Any = None
    train_output: Any = None
    search: dict[str, Any] | None = None  # family auto: the record of the search that chose the model

    @classmethod
    def from_model(cls, model) -> ModelArrays:
        arrays, attrs = model.family.to_arrays()
        pre_arrays, pre_attrs = model.preprocessor.to_arrays()
        return cls(
            model.family.name,
            dict(model.spec["model"].get("params") or {}),
            dict(arrays),
            _jsonable(attrs),
            dict(pre_arrays),
            _jsonable(pre_attrs),
            (model.bounds[0], model.bounds[1]),
            model.spec,
            model.metrics,
            _jsonable(model.provenance),
            model.train_input,
            model.train_input_lengths,
            model.train_output,
            None if model.search is None else _jsonable(model.search),
        )

    def to_model(self):
        """The FittedModel (as :func:`dynmodel.store.load` would rebuild it from a file)."""
        import numpy as np

        from . import registry
        from .data.preprocess import Preprocessor
        from .model import FittedModel

        family = registry.family(self.family).from_arrays(
            self.params, {k: np.asarray(v) for k, v in self.arrays.items()}, self.attrs
        )
        pre = Preprocessor.from_arrays(self.pre_arrays, self.pre_attrs)
        bounds = (np.asarray(self.bounds[0]), np.asarray(self.bounds[1]))
        return FittedModel(
            family,
            pre,
            bounds,
            self.spec,
            self.metrics,
            self.provenance,
            self.train_input,
            self.train_input_lengths,
            self.train_output,
            search=self.search,
        )


def _jsonable(value: Any) -> Any:
    """Attributes as the model file stores them (JSON types), so a rebuilt model equals a loaded one."""
    from .store import _json_default

    return json.loads(json.dumps(value, default=_json_default))


@dataclass
class PointResult:
    """The outcome of one variant.

    ``metrics``: split name -> metrics entry (as ``FittedModel.metrics``; empty on error);
    ``seconds``: wall time in the worker (spec, data unless cached, fit, evaluation);
    ``load_seconds``: the part spent loading data (0 when the worker had it cached);
    ``cpu_seconds``: CPU time of the thread that ran the fit (wall time well above it: a busy machine);
    ``seed``: the spec seed the fit used; ``attempts``: submissions of this point (>1 after a worker
    died); ``worker``: host:pid of the process that ran it; ``warnings``: distinct warning texts."""

    key: str
    status: Status
    message: str | None = None
    metrics: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    load_seconds: float = 0.0
    cpu_seconds: float = 0.0
    seed: int | None = None
    attempts: int = 1
    worker: str = ""
    warnings: list[str] = field(default_factory=list)
    model: ModelArrays | None = None

    def to_json(self) -> dict[str, Any]:
        """Everything but the model, as JSON types."""
        return {
            "key": self.key,
            "status": self.status,
            "message": self.message,
            "metrics": self.metrics,
            "seconds": self.seconds,
            "load_seconds": self.load_seconds,
            "cpu_seconds": self.cpu_seconds,
            "seed": self.seed,
            "attempts": self.attempts,
            "worker": self.worker,
            "warnings": list(self.warnings),
        }


# ---------------------------------------------------------------- in the worker

_data_cache: OrderedDict[str, Any] = OrderedDict()
_data_lock = threading.Lock()


def data_key(spec: Spec) -> str:
    """What decides the loaded recordings of ``spec``: its resolved data section without the
    preprocessing keys, and the spec seed when added noise takes its seed from it."""
    data = spec.resolved()["data"]
    for key in PREPROCESSING_KEYS:
        data.pop(key, None)
    noise = data.get("noise") or {}
    seed = spec.seed if noise and noise.get("seed") is None and noise.get("std") else None
    return json.dumps([data, seed], sort_keys=True, default=str)


def cached_dataset(spec: Spec) -> tuple[Dataset, float]:
    """(dataset, seconds spent loading: 0 when this process had it already)."""
    from .data import load_dataset

    key = data_key(spec)
    with _data_lock:
        if key in _data_cache:
            _data_cache.move_to_end(key)
            return _data_cache[key], 0.0
        t0 = time.perf_counter()
        ds = load_dataset(spec)
        _data_cache[key] = ds
        while len(_data_cache) > DATA_CACHE_SIZE:
            _data_cache.popitem(last=False)
        return ds, time.perf_counter() - t0


def clear_data_cache() -> None:
    with _data_lock:
        _data_cache.clear()


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, DynmodelError):
        return exc.line()
    text = " ".join(str(exc).split())
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" at {Path(where.filename).name}:{where.lineno}" if where else ""
    return f"internal error: {type(exc).__name__}: {text}{at} (a bug: please report it)"


def fit_point(variant: Variant, keep_model: bool = False) -> PointResult:
    """Fit one variant (runs in a worker): never raises for a failing fit, returns its result."""
    from .executors import prepare_worker

    prepare_worker()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    t0, c0 = time.perf_counter(), time.thread_time()
    seed = variant.raw.get("seed") if isinstance(variant.raw.get("seed"), int) else None
    load_seconds = 0.0
    caught: list[warnings.WarningMessage] = []
    from .anneal import interrupts_propagate

    try:
        with warnings.catch_warnings(record=True) as caught, interrupts_propagate():
            warnings.simplefilter("always")
            from . import engine
            from .spec import validate_spec

            spec = validate_spec(dict(variant.raw), variant.source, Path(variant.base_dir))
            seed = int(spec.seed)
            ds, load_seconds = cached_dataset(spec)
            model, _ = engine.fit_dataset(spec, ds)
            if _cut_short(model):  # a family: auto point whose search caught the Ctrl-C: not a finished point
                raise KeyboardInterrupt("the point's search was interrupted")
        bad = model.unstable
        status: Status = "diverged" if bad else "ok"
        message = None
        if bad:
            message = (
                f"the free run diverged on the {bad['split']} split at sample {bad['sample']} "
                f"(t = {bad['time']:.6g}) of recording '{bad['recording']}'. Fix: {model.family.stability_hint}"
            )
        payload = ModelArrays.from_model(model) if keep_model else None
        metrics = model.metrics
    except Interrupted as exc:  # the user stopped it (a search with nothing to keep): stop the batch too
        raise KeyboardInterrupt(exc.line()) from None
    except Exception as exc:  # recorded, never raised: one point must not stop the others
        status, message, metrics, payload = "error", _one_line(exc), {}, None
    texts = list(dict.fromkeys(str(w.message).split("\n")[0] for w in caught))
    return PointResult(
        variant.key,
        status,
        message,
        metrics,
        seconds=time.perf_counter() - t0,
        load_seconds=load_seconds,
        cpu_seconds=time.thread_time() - c0,
        seed=seed,
        worker=worker,
        warnings=texts,
        model=payload,
    )


# ---------------------------------------------------------------- in the parent


def _cut_short(model) -> bool:
    """Was the fit of ``model`` stopped by the user (a ``family: auto`` search interrupted with Ctrl-C keeps its
    best candidate so far; its safety limit is no interruption)?"""
    search = getattr(model, "search", None)
    return bool(isinstance(search, dict) and search.get("interrupted") and not search.get("safety_limit"))


def _is_killed_worker(exc: BaseException) -> bool:
    return type(exc).__name__ == "KilledWorker"


def _cancel_test(cancel: threading.Event | Callable[[], bool] | None) -> Callable[[], bool]:
    """``cancel`` (an event, anything with ``is_set()``, a callable or None) as a callable: is it set?"""
    is_set = getattr(cancel, "is_set", None)
    if callable(is_set):
        return lambda: bool(is_set())
    if callable(cancel):
        return cancel
    return lambda: False


def run_specs(
    variants: Iterable[Variant],
    executor: Executor | None = None,
    *,
    keep_models: bool = False,
    cancel: threading.Event | Callable[[], bool] | None = None,
    budget: float | None = None,
    wait_running: bool = False,
    max_retries: int = 2,
    poll: float = 0.2,
    point: Callable[[Any, bool], PointResult] | None = None,
) -> Generator[PointResult, None, None]:
    """Fit every variant on ``executor`` and yield a :class:`PointResult` as each one finishes.

    - ``executor``: any ``concurrent.futures.Executor``; None makes a local process pool with one
      worker per core (:func:`dynmodel.executors.make_executor`) and shuts it down at the end.
    - ``keep_models``: workers send each fitted model back (``result.model``, :class:`ModelArrays`).
    - ``variants`` is consumed lazily, only as slots free up: a search may yield new candidates from a
      generator that reads the results so far.
    - Stopping: when ``cancel`` is set (a ``threading.Event`` or a callable returning True) or
      ``budget`` seconds have passed since the call, nothing more is submitted and points not yet
      started are cancelled; points already running are waited for when ``wait_running`` is True,
      otherwise abandoned (not yielded; an executor made here stops its workers at once). Closing the
      generator (``break`` in the loop, ``close()``) stops the same way. Finished results are never
      lost: each was yielded when it finished.
    - ``max_retries``: resubmissions of a point whose worker process died, before it is recorded as
      an error (local process pools; Dask applies its own ``allowed-failures``).
    - ``point``: the function a worker runs, ``point(variant, keep_model) -> PointResult`` (default
      :func:`fit_point`); a module-level function, so that it pickles (a search passes its own, with a
      :class:`Variant` subclass carrying what it needs, see :mod:`dynmodel.search.worker`).
    """
    from .executors import describe, make_executor, slots

    own = executor is None
    if executor is None:
        executor = make_executor()
    started = time.monotonic()
    cancelled = _cancel_test(cancel)

    def stopping() -> bool:
        return cancelled() or (budget is not None and time.monotonic() - started >= budget)

    source = iter(variants)
    exhausted = False
    retry: deque[tuple[Variant, int]] = deque()  # (variant, submissions so far), run before new ones
    suspects: set[str] = set()  # in flight when a worker died: rerun one at a time until cleared
    crashes: dict[str, int] = {}  # deaths of a worker running the point alone
    inflight: dict[Future, tuple[Variant, int]] = {}
    abandon = False
    restarts = 0  # pool rebuilds after a worker died
    answered = False  # has any worker returned a result yet?

    def next_variant() -> tuple[Variant, int] | None:
        nonlocal exhausted
        if retry:
            return retry.popleft()
        if exhausted:
            return None
        try:
            return next(source), 0
        except StopIteration:
            exhausted = True
            return None

    def outcome(future: Future, variant: Variant, attempts: int) -> PointResult | None:
        """The result of a finished future; None when it was cancelled or its pool broke."""
        try:
            result = future.result()
        except (CancelledError, BrokenProcessPool):
            return None
        except Exception as exc:
            if _is_killed_worker(exc):
                message = (
                    "the worker process running this point died repeatedly (killed, out of memory, or a crash "
                    "in compiled code) and Dask gave up on it. Fix: check the workers' memory, then rerun"
                )
            else:
                message = f"could not run the point on {describe(executor)}: {_one_line(exc)}"
            return _error(variant, message, attempts)
        result.attempts = attempts
        return result

    try:
        while True:
            stop = stopping()
            if not stop:
                capacity = 1 if suspects else slots(executor)
                while len(inflight) < capacity:
                    item = next_variant()
                    if item is None:
                        break
                    try:
                        future = executor.submit(point or fit_point, item[0], keep_models)
                    except BrokenProcessPool:
                        retry.appendleft(item)
                        if inflight:
                            break  # the in-flight futures fail with the pool and trigger the rebuild below
                        _restart_or_fail(executor, [item[0]])
                        continue
                    inflight[future] = (item[0], item[1] + 1)
            if not inflight:
                if stop or (exhausted and not retry):
                    return
                continue
            done, _ = wait(list(inflight), timeout=poll, return_when="FIRST_COMPLETED")
            if stop:
                for future in list(inflight):
                    if future not in done and (not wait_running or not future.running()) and future.cancel():
                        inflight.pop(future)
                abandon = not wait_running and any(f not in done for f in inflight)
            broken: list[tuple[Variant, int]] = []
            for future in done:
                variant, attempts = inflight.pop(future)
                result = outcome(future, variant, attempts)
                if result is not None:
                    suspects.discard(variant.key)
                    yield result
                elif not future.cancelled() and isinstance(future.exception(), BrokenProcessPool):
                    broken.append((variant, attempts))
            if stop and not wait_running:
                return
            answered = answered or any(not f.cancelled() and f.exception() is None for f in done)
            if not broken or stop:
                continue
            restarts += 1
            if not answered and restarts > max_retries + 1:
                raise DynmodelError(
                    f"the worker processes of {describe(executor)} died {restarts} times before returning any result",
                    "run_specs",
                    'when calling from a script, put the call under `if __name__ == "__main__":` (worker '
                    "processes are spawned and import the script); check memory, or run with workers=1",
                )
            # a worker died: the whole pool fails; collect every point it held, then rebuild it
            rest = list(inflight)
            wait(rest, timeout=30)
            for future in rest:
                variant, attempts = inflight.pop(future)
                result = outcome(future, variant, attempts) if future.done() else None
                if result is not None:
                    suspects.discard(variant.key)
                    yield result
                else:
                    broken.append((variant, attempts))
            _restart_or_fail(executor, [v for v, _ in broken])
            if len(broken) == 1:  # it ran alone: its own death
                crashes[broken[0][0].key] = crashes.get(broken[0][0].key, 0) + 1
            for variant, attempts in sorted(broken, key=lambda item: item[0].key, reverse=True):
                if crashes.get(variant.key, 0) > max_retries:
                    suspects.discard(variant.key)
                    yield _error(
                        variant,
                        f"the worker process running this point died {crashes[variant.key]} times (killed, out "
                        "of memory, or a crash in compiled code). Fix: check memory use, or fit it alone with "
                        "dynmodel fit to see the crash",
                        attempts,
                    )
                    continue
                suspects.add(variant.key)
                retry.appendleft((variant, attempts))
    finally:
        abandon = abandon or bool(inflight)  # left early (stopped, or the caller closed the generator)
        for future in inflight:
            future.cancel()
        if own:
            executor.shutdown(wait=not abandon, cancel_futures=True)


def _error(variant: Variant, message: str, attempts: int) -> PointResult:
    seed = variant.raw.get("seed") if isinstance(variant.raw.get("seed"), int) else None
    return PointResult(variant.key, "error", message, seed=seed, attempts=attempts)


def _restart_or_fail(executor: Executor, lost: list[Variant]) -> None:
    restart = getattr(executor, "restart", None)
    if callable(restart):
        restart()
        return
    keys = ", ".join(v.key for v in lost[:5]) + (" ..." if len(lost) > 5 else "")
    raise DynmodelError(
        f"a worker process died and broke the process pool while running {keys}",
        type(executor).__name__,
        "use dynmodel.executors.make_executor(workers=N), whose pool is rebuilt and the points retried",
    )
