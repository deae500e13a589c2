"""What a worker process does for the search: one :class:`Task` in, one :class:`TaskResult` out.

Tasks run through :func:`dynmodel.batch.run_specs` with :func:`run_task` as the point function, so they
use the sweep's executor seam (in-process, a local process pool, Dask), its per-worker data cache and its
handling of dead workers. Three kinds:

* ``fit``: fit the candidate spec on a view of the data (:mod:`.views`), score its free run on the view's
  validation split, run the input-only checks (:mod:`.checks`) on every split's inputs, measure its input
  dependence and size;
* ``reference``: the training mean and the linear ARX / OE reference of :mod:`dynmodel.diagnose.reference`
  on the view (training and validation samples only);
* ``diagnose``: fit the spec on the view (or take the search's own fit of it there) and run every detector of
  ``dynmodel diagnose`` on it; the result holds the extensions they propose (the search's moves). The
  diagnosis plans itself again once the fit says how large the model is (:func:`replanned_work`): beyond the
  work the search left it, the detectors are left out and the result says so.

Every task is a deterministic function of its fields: the result does not depend on the worker.
"""

from __future__ import annotations

import math
import os
import socket
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..batch import ModelArrays, PointResult, Variant, _one_line, cached_dataset
from .views import Layout, test_start, view

if TYPE_CHECKING:
    from ..data.dataset import Dataset
    from ..model import Run
    from ..spec import Spec


@dataclass(frozen=True)
class Task(Variant):
    """A candidate spec (``raw``, complete, with its seed) and where to fit it."""

    kind: str = "fit"  # "fit" | "reference" | "diagnose"
    layout: Layout = Layout()
    #: the dataset itself when it is not in files (the Python API's arrays); None: load ``raw``'s data
    dataset: Any = None
    #: diagnose: extensions measured per round (the diagnosis' own limit)
    moves: int = 6
    #: per split, the range of the linear reference's free run (the linear-system band, :mod:`.checks`)
    envelope: dict[str, Any] | None = None
    #: fit with this preprocessing (a warm start from a fitted model's values needs its scaling), not the view's
    preprocessor: Any = None
    #: measure the start memory (:func:`.checks.start_memory`: three free runs per recording), which the search
    #: reads only when the test inputs leave the training range
    memory: bool = False
    #: diagnose: planned seconds of work left for the whole diagnosis (None: no limit), and the candidate and search
    #: context its family's ``full_work`` hook reads to plan the diagnosis again from the fitted model's size
    allowance: float | None = None
    candidate: Any = None
    context: Any = None
    #: diagnose: the search's own fit of this spec (same seed) on this layout (:class:`~dynmodel.batch.ModelArrays`),
    #: diagnosed as it is instead of fitted again (on a held-out validation split, the leader's validated fit)
    model: Any = None
    #: diagnose: fit as a ``fit`` task does (scores, band checks, the model kept in the result), so that the search
    #: can take this fit as the model's own fit on the spec's layout after a cross-validation
    checked: bool = False


@dataclass
class TaskResult(PointResult):
    """A :class:`~dynmodel.batch.PointResult` with what the search decides on.

    ``score``: free-run NMSE (%, mean over outputs) on the view's validation split (the training split
    when the view has none); None when the run diverged there or the fit failed. ``checks``: the band
    checks per split (:func:`.checks.band_checks`). ``dependence``: input dependence on the view's
    validation split; ``nonlinearity``: how far from affine in its input the run is there
    (:func:`dynmodel.usefulness.input_nonlinearity`). ``memory``: how far its free run remembers the outputs
    it started from (:func:`.checks.start_memory`). ``complexity``: the fitted model's size. ``proposals``:
    diagnose tasks' moves as ``{"cause", "summary", "patch"}``. ``reference``: reference tasks' figures.
    ``moments``: sums over the view's validation samples that let folds be pooled into one score (``n``, per
    output ``sse``, ``sum``, ``sumsq`` of the measured output)."""

    kind: str = "fit"
    layout: dict[str, Any] = field(default_factory=dict)
    score: float | None = None
    checks: dict[str, Any] = field(default_factory=dict)
    dependence: float | None = None
    nonlinearity: float | None = None
    memory: float | None = None
    complexity: float | None = None
    proposals: list[dict[str, Any]] = field(default_factory=list)
    reference: dict[str, Any] | None = None
    selection: dict[str, Any] | None = None
    moments: dict[str, Any] | None = None
    #: the free runs over the test splits' inputs, scaled and thinned (:func:`.checks.test_runs`); not in the record
    test_runs: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        out = super().to_json()
        out.update(
            kind=self.kind,
            layout=self.layout,
            score=self.score,
            checks=self.checks,
            dependence=self.dependence,
            nonlinearity=self.nonlinearity,
            memory=self.memory,
            complexity=self.complexity,
        )
        if self.proposals:
            out["proposals"] = self.proposals
        if self.reference is not None:
            out["reference"] = self.reference
        return out


#: consecutive blocks of a validation split (of each fold) over which candidates are compared pairwise
BLOCKS = 10


def _score(metrics: dict[str, Any]) -> float | None:
    split = "validation" if "validation" in metrics else "train"
    value = (metrics.get(split) or {}).get("nmse")
    return None if value is None else float(value)


def validation_errors(model, ds, runs) -> tuple[str, list[Any], Any, Any] | None:
    """(split, rows, measured outputs, squared free-run errors) over the scored samples of the validation
    split (the training split when there is none); None when nothing is scored or the run is not finite."""
    import numpy as np

    split = "validation" if ds.ranges.get("validation") else "train"
    rows = ds.scored(split, model.warmup)
    if not rows:
        return None
    y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
    yhat = np.concatenate([runs[r].y[a:b] for r, a, b in rows])
    if not np.isfinite(yhat).all():
        return None
    return split, rows, y, (y - yhat) ** 2


def validation_moments(ds, split: str, rows: list[Any], y, err2, continued=None) -> dict[str, Any]:
    """Sums over the scored samples ``rows`` of ``split`` (:func:`validation_errors`): the count, and per output
    the squared free-run errors ``err2``, the measured output's sum and sum of squares, and the errors summed
    over blocks (:func:`_block_sums`; ``continued``: the continued run's errors where ``err2`` mixes in a fresh
    start, summed over the same blocks)."""
    return {
        "n": int(len(y)),
        "sse": err2.sum(axis=0).tolist(),
        "sum": y.sum(axis=0).tolist(),
        "sumsq": (y**2).sum(axis=0).tolist(),
        "blocks": _block_sums(ds.scored(split, 0), rows, err2, continued),
    }


def fresh_weight(ds: Dataset, layout: Layout) -> tuple[Dataset, float] | None:
    """(the view of ``layout`` with each validation range a run of its own, k) when the test sets start runs
    of their own and the layout's validation does not (:func:`.views.test_start`); None otherwise. A test
    recording of T samples carries its start-up transient once, so per sample it weighs 1 / T; in a
    validation run of V samples it weighs 1 / V: k = min(1, V / T), with the mean lengths of both."""
    if layout.kind == "recording":
        return None
    starts_fresh, window, whole = test_start(ds)
    if not starts_fresh:
        return None
    vf = view(ds, layout, fresh=(window, whole))
    val = [b - a for _, a, b in vf.ranges.get("validation", [])]
    tests = [b - a for s in ds.test_splits() for _, a, b in ds.ranges[s]]
    if not val or not tests:
        return None
    return vf, min(1.0, (sum(val) / len(val)) / (sum(tests) / len(tests)))


def _with_fresh_start(model, ds, rows, err2, fresh: Dataset, k: float):
    """The squared errors ``err2`` of the continued run over ``rows`` (the scored validation samples of
    ``ds``), with each sample's error started afresh (the same validation range run on its own in ``fresh``)
    mixed in with weight ``k``: err2 + k (fresh err2 - err2), where the fresh run scores that sample (not in
    its window or warmup). None when a fresh run diverges or leaves the finite numbers."""
    import numpy as np

    ranges, own = ds.ranges["validation"], fresh.ranges["validation"]
    if len(ranges) != len(own) or any(b - a != fb - fa for (_, a, b), (_, fa, fb) in zip(ranges, own)):
        return err2  # not the same ranges (no layout gives this): the continuation alone
    warm = model.warmup
    first = {r: a for r, a, _ in fresh.scored("validation", warm)}
    out = err2.copy()
    runs: dict[int, Any] = {}
    pos = 0
    for r, a1, b1 in rows:
        i = next(i for i, (rr, a, b) in enumerate(ranges) if rr == r and a <= a1 < b)
        rf, fa = own[i][0], own[i][1]
        if rf in first:
            if i not in runs:
                rec = fresh.recordings[rf]
                runs[i] = model.run(rec.u, rec.y[:warm] if warm else None)
            if runs[i].diverged_at is not None:
                return None
            local = np.arange(a1, b1) - ranges[i][1] + fa
            keep = local >= first[rf]
            e = (ds.recordings[r].y[a1:b1][keep] - runs[i].y[local[keep]]) ** 2
            if not np.isfinite(e).all():
                return None
            idx = pos + np.flatnonzero(keep)
            out[idx] += k * (e - err2[idx])
        pos += b1 - a1
    return out


def _block_sums(full: list[Any], rows: list[Any], err2: Any, continued: Any = None) -> dict[str, Any]:
    """The squared errors ``err2`` (of the samples of ``rows``) summed in :data:`BLOCKS` consecutive blocks of
    ``full``, the split's samples scored by a model without warmup. The blocks sit at the same samples for
    every candidate, whatever its warmup (``rows`` only start later), so that two candidates can be compared
    block by block (:func:`.select.paired_difference`): ``n`` samples scored per block, ``full`` samples per
    block, ``sse`` per block and output (and ``continued``, the same sums of ``continued`` when given: the
    continued run's errors where ``err2`` mixes in a fresh start, whose spread measures the noise of a paired
    comparison, which a start-up transient, the same on every test recording, is not)."""
    import numpy as np

    offsets: dict[int, list[tuple[int, int, int]]] = {}
    total = 0
    for rec, a0, b0 in full:
        offsets.setdefault(rec, []).append((a0, b0, total))
        total += b0 - a0
    positions = []
    for rec, a, b in rows:
        a0, _, off = next(x for x in offsets[rec] if x[0] <= a < x[1])
        positions.append(np.arange(a, b) - a0 + off)
    block = np.concatenate(positions) * BLOCKS // max(total, 1)

    def summed(errors: Any) -> list[Any]:
        sums = np.zeros((BLOCKS, errors.shape[1]))
        np.add.at(sums, block, errors)
        return sums.tolist()

    out = {
        "n": np.bincount(block, minlength=BLOCKS).tolist(),
        "full": np.bincount(np.arange(total) * BLOCKS // max(total, 1), minlength=BLOCKS).tolist(),
        "sse": summed(err2),
    }
    if continued is not None:
        out["continued"] = summed(continued)
    return out


def _fit(task: Task, spec: Spec, ds: Dataset, keep_model: bool, result: TaskResult) -> tuple[Any, list[Run]]:
    """Fit, score and check one candidate on the task's view (the ``fit`` kind); returns the model and its runs
    there."""
    from .. import engine, protocol
    from ..usefulness import input_dependence, input_nonlinearity
    from .checks import affine, band_checks, complexity, measured_starts, start_memory, test_runs, usual_runs
    from .select import moment_score

    v = view(ds, task.layout)
    model, runs = engine.fit_dataset(spec, v, pre=task.preprocessor)
    protocol.check_warmup(model.family, ds, spec.source)  # the test sets' windows too (the view has none)
    result.metrics = model.metrics
    result.score = _score(model.metrics)
    bad = model.unstable
    result.status = "diverged" if bad else "ok"
    if bad:
        result.message = f"the free run diverged on the {bad['split']} split at sample {bad['sample']}"
    errors = None if bad else validation_errors(model, v, runs)
    fresh = fresh_weight(ds, task.layout) if errors is not None and errors[0] == "validation" else None
    continued = None
    if errors is not None and fresh is not None:
        split, rows, y, err2 = errors
        mixed = _with_fresh_start(model, v, rows, err2, *fresh)
        if mixed is None:
            errors, result.status, result.score = None, "diverged", None
            result.message = "the free run diverged on a validation run started as a test recording is"
        else:
            errors, continued = (split, rows, y, mixed), err2
    result.moments = None if errors is None else validation_moments(v, *errors, continued)
    if fresh is not None and result.moments is not None:  # the score with the fresh start mixed in
        result.score = moment_score([result])
    held: dict[int, Run] = {}  # the held-input runs, shared by the two measures
    try:
        result.nonlinearity = None if bad else input_nonlinearity(model, v, runs=runs, held=held)
    except (ValueError, FloatingPointError):
        result.nonlinearity = None
    runs_from_start = usual_runs(model, ds)  # every recording's run: the band check, measured starts, start memory
    starts = None if bad else measured_starts(model, ds, runs_from_start)
    result.test_runs = None if bad else test_runs(ds, runs_from_start, model.warmup)
    result.checks = band_checks(
        model, ds, task.envelope, affine=affine(result.nonlinearity), runs=runs_from_start, starts=starts
    )
    try:
        result.dependence = None if bad else input_dependence(model, v, runs=runs, held=held)
    except (ValueError, FloatingPointError):
        result.dependence = None
    try:
        result.memory = None if bad or not task.memory else start_memory(model, ds, runs_from_start)
    except (ValueError, FloatingPointError):
        result.memory = None
    result.complexity = complexity(model)
    info = getattr(model.family, "selection_", None)
    if isinstance(info, dict):
        result.selection = {k: v for k, v in info.items() if k in ("lags", "degree", "terms", "method")}
    if keep_model:
        payload = ModelArrays.from_model(model)
        payload.train_input = payload.train_input_lengths = payload.train_output = None  # the parent has them
        result.model = payload
    return model, runs


def _reference(task: Task, ds, result: TaskResult) -> None:
    from ..diagnose.reference import references

    refs = references(view(ds, task.layout))
    result.reference = refs.to_json()
    result.status = "ok"


def _diagnose(task: Task, spec: Spec, ds: Dataset, result: TaskResult) -> None:
    from .. import engine
    from ..diagnose.detector import Settings
    from ..diagnose.fitting import Fit, Fitter
    from ..diagnose.runner import _candidates, detect
    from ..model import evaluate
    from ..threads import fit_threads

    v = view(ds, task.layout)
    fitter = Fitter(task.source, Path(task.base_dir))
    fitter._data[fitter._data_key(spec)] = v  # detectors refit patched specs on the same view
    t0 = time.perf_counter()
    if task.model is not None:  # the search's own fit of this spec on this layout: the same model, not fitted again
        model = task.model.to_model()
        model.train_input, model.train_input_lengths = v.concat_inputs("train")  # the search keeps them apart
        model.train_output = v.concat_outputs("train")
        with fit_threads():  # the runs only: its metrics came with it
            _, runs = evaluate(model, v, ["nmse"], one_step=False)
    elif task.checked:  # fitted, scored and checked as a fit task is: the search keeps it for the model's own fit
        model, runs = _fit(task, spec, ds, True, result)
        if result.status != "ok":
            return
    else:
        model, runs = engine.fit_dataset(spec, v)
    if not task.checked:  # (a checked fit is scored by _fit, whose score may mix in a fresh start)
        result.metrics, result.score, result.status = model.metrics, _score(model.metrics), "ok"
    need = replanned_work(task, model.family)
    if need is not None and task.allowance is not None and need > task.allowance:
        result.message = (
            f"the diagnosis of the leader was left out: planned again from the leader's fitted size, it needs "
            f"{need:.0f} s of work, beyond the {max(task.allowance, 0.0):.0f} s the budget leaves it"
        )
        return
    fit = Fit(dict(task.raw), spec, model, runs, v, time.perf_counter() - t0)
    findings, _ = detect(fit, Settings(reliability=False), fitter)
    result.proposals = [
        {"cause": cause, "summary": ext.summary, "patch": ext.patch} for cause, ext in _candidates(findings, task.moves)
    ]


def replanned_work(task: Task, fitted: Any) -> float | None:
    """Planned seconds of a diagnosis of ``fitted`` (the leader's spec fitted on the task's view), as the search
    plans it (:func:`dynmodel.search.plan.diagnosis_work`) from the fit's seconds its family now gives knowing the
    fitted model's size (the ``full_work`` hook); None when the family gives none. On a generated system the
    leader's estimate planned the diagnosis at 17.7 s: fitted on the whole training split it chose longer lags and
    kept 371 terms (19 in the folds), and the fit with the detectors' refit with a longer selection took 210 s."""
    from .. import registry
    from .plan import diagnosis_work as planned
    from .space import Found

    if task.candidate is None or task.context is None:
        return None
    hook = getattr(registry.families().get(task.candidate.family), "full_work", None)
    if hook is None:
        return None
    try:
        fit = hook(task.context, Found(task.candidate, fitted, {}, float("nan")))
    except Exception:  # noqa: BLE001 - an estimate must not stop the search
        return None
    if fit is None or not math.isfinite(fit):
        return None
    return planned(float(fit), task.context.n_train)


def run_task(task: Task, keep_model: bool = False) -> TaskResult:
    """Run one task in this process; never raises for a failing fit (the result says what failed)."""
    from ..executors import prepare_worker

    prepare_worker()
    t0, c0 = time.perf_counter(), time.thread_time()
    result = TaskResult(
        task.key,
        "error",
        kind=task.kind,
        layout=task.layout.to_json(),
        worker=f"{socket.gethostname()}:{os.getpid()}",
    )
    seed = task.raw.get("seed")
    result.seed = int(seed) if isinstance(seed, int) else None
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            from ..spec import validate_spec
            from ..threads import fit_threads

            spec = validate_spec(dict(task.raw), task.source, Path(task.base_dir))
            if task.dataset is not None:
                ds, result.load_seconds = task.dataset, 0.0
            else:
                ds, result.load_seconds = cached_dataset(spec)
            with fit_threads():
                if task.kind == "reference":
                    _reference(task, ds, result)
                elif task.kind == "diagnose":
                    _diagnose(task, spec, ds, result)
                else:
                    _fit(task, spec, ds, keep_model, result)
    except Exception as exc:  # recorded, never raised: one candidate must not stop the search
        result.status, result.message, result.score = "error", _one_line(exc), None
    result.warnings = list(dict.fromkeys(str(w.message).split("\n")[0] for w in caught))
    result.seconds = time.perf_counter() - t0
    result.cpu_seconds = time.thread_time() - c0
    return result
