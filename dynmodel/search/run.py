"""``family: auto``: the search loop (docs/auto.md).

Stages, each with members fixed before it starts (see :mod:`.plan` for the budget rule):

1. ``screen``: every family's starting candidates (its ``search_space`` hook), one seed each, in their
   cheap screening variant, on the screening layout (the last :data:`SCREEN_SAMPLES` training samples;
   for short data the blocked cross-validation); the linear and mean references alongside;
2. ``grow``: the neighbours of the best :data:`GROW_FROM` candidates (the hook with ``around``);
3. ``full``: the survivors (:meth:`Search.survivors`: the best :data:`SURVIVORS`, then every other one within
   :data:`SURVIVOR_FACTOR` of the best as far as the budget's share allows) in their full variant on the
   final layout (all training samples, or the folds), random ones with every seed (a screening fit that
   already was a final one is not repeated); when the test inputs leave the training range and those that
   validate about as well as the best all remember their start, up to :data:`FORGETTING` more, the smallest first
   (:meth:`Search._stage_forgetting`);
4. ``moves``: ``dynmodel diagnose``'s detectors on the leader (the model the choice keeps so far), and the
   extensions they propose (the residual says what is missing: extend, refit, keep what validates);
5. ``refit agreement``: on a hold-out split, when the leader is a random candidate whose seeds part ways on the
   test inputs beyond its validation error and no candidate whose seeds agree validates below that floor, the
   best deterministic candidates below it fitted again on every sample (:meth:`Search._stage_refit_agreement`);

then the choice (:mod:`.select`) on the final layout, and the winner's model: the fit already made on
the full layout, or (cross-validation) a fit on the spec's own training and validation splits, which the
moves leave room for in the plan (past the safety limit, a fit already made is kept instead). Every fit
runs through :func:`dynmodel.batch.run_specs` on the executor given (a local process pool by default).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import threading
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import registry
from ..batch import PointResult, run_specs
from ..data.dataset import Dataset, is_test, last_samples
from ..data.delay import READ_ON, dead_times
from ..data.derived import position_like
from ..data.repeats import repeat_note, repeats_training
from ..errors import DynmodelError, interruption
from ..extensions import merge
from ..family import Progress, defines_hook, no_progress
from ..spec import IN_MEMORY
from .checks import affine, failed_split, forgets, linear_band, pair_differences, remembers
from .params import AutoParams, searchable_families
from .plan import HARD_LIMIT, HARD_SLACK, REFERENCE_WORKERS, SHARES, TASK_OVERHEAD, Budget, Group, diagnosis_work
from .select import (
    EXTRAPOLATION,
    POOR,
    SPREAD_FLOOR,
    SPREAD_NOTE,
    Choice,
    Summary,
    choose,
    ignores_input,
    kept_floor,
    model_size,
    parted_seeds,
    parted_words,
    sound_within,
    spread_floor,
    summarize,
)
from .space import SIGNED, Candidate, Found, SearchContext, candidates_of, estimated_work
from .views import (
    MIN_BLOCK,
    Layout,
    interior_recordings,
    phase_fold,
    possible_folds,
    possible_recording_folds,
    repeated_validation,
    spans,
    validated_folds,
    view,
)
from .worker import BLOCKS, Task, TaskResult, fresh_weight, run_task

if TYPE_CHECKING:
    from ..spec import Spec

#: training samples of the screening layout (longer training splits are cut to their last samples)
SCREEN_SAMPLES = 12000
#: cross-validate when the validation split has fewer scored samples than this ...
CV_BELOW = 1000
#: ... and the training and validation samples together are at most this many
CV_MAX = 20000
FOLDS = 5
#: why the tie is widened when the validation input repeats the training input (docs/auto.md)
REPEATED = "the validation input repeats the training input (a periodic excitation)"
#: configurations always carried from the screening to the final layout ...
SURVIVORS = 3
#: ... and, as far as the budget's share allows, every other one screened within this factor of the best (the
#: screening variant ranks the full ones coarsely: on Cascaded Tanks the model chosen screened seventh of 22)
SURVIVOR_FACTOR = 3.0
#: ... plus at most this many that validated better still but left the output band at screening only
SECOND_CHANCES = 2
#: ... and, when the models fitted in full all remember their start, at most this many more (:meth:`_stage_forgetting`)
FORGETTING = 2
#: candidates whose neighbours are measured
GROW_FROM = 2
#: a linear model (the reference, or a candidate affine in its input) within this factor of the best score shows
#: a system about linear (:meth:`Search._decide_band`; on EMPS, Silverbox and Bouc-Wen the reference is 53 to
#: 860 x behind and no candidate is affine)
LINEAR_SYSTEM = 2.0
#: ... provided the best validation NMSE (%) is below this (two random walks, 49 % at best, are no linear system)
LINEAR_FIT = 10.0
#: the chosen model's refit on every fitting sample is kept unless its free run fits them worse than the model
#: validated by more than this factor (its estimation stalled: Bouc-Wen, 2.9x; least-squares weights, whose cost
#: is the one-step error, can fit the free run a little worse: 1.009x on a generated plant)
REFIT_WORSE = 1.10
#: after a cross-validation, the winner fitted on the spec's own split gives way to its fit validated with the last
#: block held out when that fit's free run fits every training and validation sample more than this factor better
#: (:meth:`Search._against_folds`; of eight small recordings where it acted, five tested better, one the same, two
#: worse: docs/auto.md; 56 x on a seal whose validation split sits at another force level; near ties, 1.03 - 1.7 x,
#: went either way on the test)
FOLD_BETTER = 2.0
#: the modes whose candidates are validated on folds, phases or recordings left out, not on the spec's own split
CROSS_VALIDATED = ("folds", "recordings", "phase")
#: deterministic candidates fitted again on every sample when the leader's seeds part ways (:meth:`Search._stage_refit_agreement`)
REFIT_CHECKS = 2
#: rounds of diagnose's moves, and moves measured per round
MOVE_ROUNDS = 2
MOVES = 4


@dataclass
class Entry:
    """One candidate configuration and everything measured of it."""

    cand: Candidate
    origin: str
    results: dict[str, list[TaskResult]] = field(default_factory=dict)  # level -> fit results
    summaries: dict[str, Summary] = field(default_factory=dict)
    verdict: str = "not run"
    #: the screening fits count as final fits (same variant, same layouts): a deterministic candidate needs
    #: no refit, a random one only its other seeds
    reuse_screen: bool = False
    #: its full fits were planned beyond what was left of the budget (this many seconds of work, 0: they were
    #: not): its screening fit (the cheap variant on the screening samples, validated as every final fit is)
    #: stands as its final one; a random candidate's screening fits of its other seeds join it as final fits
    full_work_skipped: float = 0.0

    @property
    def stands_screened(self) -> bool:
        return self.full_work_skipped > 0

    def summarize_final(self) -> None:
        """Its final summary from the fits that count as final (:meth:`results_at`)."""
        self.summaries["final"] = summarize(sorted(self.results_at("final"), key=lambda x: x.key))  # type: ignore[assignment]

    def results_at(self, level: str) -> list[TaskResult]:
        if level == "final" and (self.reuse_screen or self.stands_screened):
            return self.results.get("screen", []) + self.results.get("final", [])
        return self.results.get(level, [])

    @property
    def label(self) -> str:
        return f"{self.cand.family}: {self.cand.summary}"

    @property
    def random(self) -> bool:
        if self.cand.stochastic is not None:
            return bool(self.cand.stochastic)
        cls = registry.families().get(self.cand.family)
        return bool(getattr(cls, "stochastic", True))

    def best_level(self) -> str | None:
        return "final" if "final" in self.summaries else ("screen" if "screen" in self.summaries else None)

    def to_json(self) -> dict[str, Any]:
        out = self.cand.to_json()
        out["origin"] = self.origin
        out["verdict"] = self.verdict
        out["screen_is_final"] = self.reuse_screen
        if self.stands_screened:
            out["stands_screened"] = True
        out["levels"] = {k: s.to_json() for k, s in self.summaries.items()}
        level = self.best_level()
        out["validation_nmse"] = (
            None if level is None or not self.summaries[level].finite else self.summaries[level].score
        )
        out["level"] = level
        out["fit_seconds"] = round(sum(r.seconds for rs in self.results.values() for r in rs), 3)
        fits = [r for rs in self.results.values() for r in rs]
        if fits:
            last = max(fits, key=lambda r: (r.layout.get("kind") == "full", r.key))
            out["metrics"] = last.metrics
            out["checks"] = last.checks
            out["selection"] = last.selection
            if last.warnings:
                out["warnings"] = last.warnings
        return out


@dataclass
class SearchResult:
    model: Any  # FittedModel of the winner (None when nothing usable was found)
    record: dict[str, Any]


def _budget_for(work: float) -> float:
    """The budget (seconds, rounded up to 100) whose allowance holds ``work`` planned seconds."""
    return 100.0 * math.ceil(work / REFERENCE_WORKERS / 100.0)


def _seed_for(spec_seed: int, key: str, index: int) -> int:
    digest = int(hashlib.sha256(key.encode()).hexdigest()[:8], 16)
    return int(np.random.SeedSequence([int(spec_seed), digest, index]).generate_state(1)[0])


def _in_worker() -> bool:
    """Is this process itself a worker of a pool or a Dask cluster (then the search runs in-process)?"""
    import multiprocessing
    import sys

    if multiprocessing.parent_process() is not None:
        return True
    if "distributed" in sys.modules:
        try:
            from distributed import get_worker

            get_worker()
            return True
        except (ImportError, ValueError):
            return False
    return False


def _progress_span(stage: str) -> tuple[float, float]:
    """The share of the progress bar a stage fills (stages run in this order, so it never goes back; the
    search plans each stage from the last one's results, so a share of the fits to come cannot be known)."""
    if stage.startswith("moves"):
        r = int(stage.split()[1].rstrip(":")) - 1
        return 0.8 + 0.2 * r / MOVE_ROUNDS, 0.8 + 0.2 * (r + 1) / MOVE_ROUNDS
    if stage.startswith("full"):
        return (0.5, 0.8) if stage == "full" else (0.75, 0.8)
    return {"screen": (0.0, 0.3), "grow": (0.3, 0.5)}[stage]


@dataclass(frozen=True)
class Ranking:
    """How a search ranks its candidates (:func:`context`): the layout kind (``mode``), its number of folds
    (0: the spec's own splits), why the validation is short (None when it is not), the period of a periodic
    excitation whose phases are held out (mode 'phase'; 0 otherwise) and, on a single hold-out (the spec's
    validation split or the tail), :func:`repeated_validation`'s finding when that hold-out repeats the
    training input (None otherwise)."""

    mode: str
    folds: int
    short: str | None
    period: int = 0
    repeated: dict[str, Any] | None = None
    #: mode 'recordings': the recordings validated when not every one is (:func:`validated_recordings`)
    inside: tuple[int, ...] = ()

    @property
    def blocked(self) -> bool:
        """Are the candidates scored on blocks of the fitting samples held out in turn (in time, or phases of a
        period)? Then they are screened on the same layouts and compared block by block."""
        return self.mode in ("folds", "phase")

    def doubt(self) -> str | None:
        """Why the validation cannot rank finely (the ``short_validation`` of :func:`.select.choose`), or None."""
        if self.mode == "folds":
            return f"{self.short}: the candidates were cross-validated in {self.folds} blocks"
        if self.mode == "phase":
            return self.short
        if self.mode == "recordings":
            return (
                f"validated on {self.left_out()}; a validation split taken from the same recordings cannot tell how "
                "a model carries over to another recording"
            )
        reasons = [self.short] if self.short and self.mode != "tail" else []
        if self.repeated is not None:
            reasons.append(REPEATED)
        return "; ".join(reasons) or None

    def left_out(self) -> str:
        """Mode 'recordings': which training recordings are left out in turn, in words."""
        if not self.inside:
            return f"each of the {self.folds} training recordings left out in turn"
        which = ", ".join(str(i + 1) for i in self.inside)
        one = len(self.inside) == 1
        return (
            f"{'recording' if one else 'recordings'} {which} of {self.folds} left out{'' if one else ' in turn'} "
            f"({'the one' if one else 'those'} between the others' operating conditions, by each input's mean and "
            "spread: the test inputs stay inside the training range, so the test asks a model to carry over "
            "between operating conditions, not beyond them)"
        )

    def repeat_caution(self) -> str | None:
        """The note on a hold-out that repeats the training input, or None."""
        return None if self.repeated is None else repeat_note(self.repeated) + "; so simpler candidates are preferred"


def context(spec: Spec, ds: Dataset, params: AutoParams, written_cost: str | None) -> tuple[SearchContext, Ranking]:
    """The search context and how its candidates are ranked (:class:`Ranking`). Modes: 'recordings': three or more
    recordings with fitting data, each left out in turn; 'folds': blocked cross-validation of short data;
    'tail': long data without a validation split, ranked on the last of :data:`FOLDS` blocks held out (the
    context's sample counts are that fold's); 'phase': a validation split that repeats the training input of
    a periodic excitation, on short data: each of :data:`FOLDS` phases of the period held out of every period
    in turn (:func:`.views.phase_fold`, fold layouts with a ``period``); 'holdout': the spec's own validation
    split."""
    n_train, n_val = ds.n_scored("train"), ds.n_scored("validation") if ds.ranges.get("validation") else 0
    max_warmup = ds.warmup_limit()
    excursions = ds.input_excursions()
    excursion = max((e["excess"] for e in excursions), default=0.0)
    short = None
    if n_val < CV_BELOW:
        short = f"the validation split has only {n_val} scored samples" if n_val else "there is no validation split"
    else:
        short = quiet_validation(ds)
    folds, left_out = possible_folds(ds, FOLDS), possible_recording_folds(ds)
    small = short is not None and n_train + n_val <= CV_MAX and folds >= 2
    mode = "recordings" if left_out else ("folds" if small else "holdout")
    if mode == "holdout" and n_val == 0 and folds >= 2:
        mode = "tail"  # ranked on the last block held out, never on the training error
        n_train, n_val = n_train - n_train // folds, n_train // folds
    held = Layout("fold", fold=folds - 1, folds=folds) if mode == "tail" else Layout("full")
    # a short validation split that repeats the training input (a few periods of a multisine) is no better
    # cross-validated in time: every block held out repeats the input of the periods around it
    # (the phases are cut back from the end of the spec's validation split: without one, the blocks stay)
    may_phase = mode == "holdout" or (mode == "folds" and n_val > 0)
    found = repeated_validation(ds, held) if mode == "tail" or may_phase else None
    repeated = found if mode in ("holdout", "tail") else None
    period = _phase_period(ds, found) if may_phase and n_train + n_val <= CV_MAX else None
    if period is not None:  # a periodic excitation: each phase of the period held out of every period in turn
        mode, small, folds, repeated = "phase", True, FOLDS, None
        short = phase_note(period, folds)
        n_train, n_val = n_train + n_val - (n_train + n_val) // folds, (n_train + n_val) // folds
    folds = {"recordings": left_out, "holdout": 0}.get(mode, folds)
    inside = validated_recordings(ds, folds, excursions) if mode == "recordings" else ()
    data = dict(spec.resolved()["data"])
    pieces = [ds.recordings[rec].u[a:b] for rec, a, b in ds.ranges.get("train", [])]
    positions = _positions(pieces, ds.input_names)
    ctx = SearchContext(
        input_names=tuple(ds.input_names),
        output_names=tuple(ds.output_names),
        sampling_time=float(ds.sampling_time),
        n_train=int(n_train),
        n_validation=int(n_val),
        data=data,
        max_warmup=max_warmup,
        excursion=float(excursion),
        small=bool(small),
        seeds=int(params.seeds),
        cost=written_cost,
        budget=float(params.budget),
        positions=positions,
        dead_times=_dead_times(ds),
        signed=_signed(pieces, ds.input_names, positions),
    )
    return ctx, Ranking(mode, folds, short, period or 0, repeated, inside)


def quiet_validation(ds: Dataset) -> str | None:
    """Why the validation split cannot rank, when its output barely moves (every output's standard deviation
    below :data:`~dynmodel.usefulness.QUIET` of the training output's: the rig idle, a sensor at rest): there a
    constant predicts the noise as well as any model; None otherwise."""
    from ..usefulness import is_quiet, variance_share

    share = variance_share(ds, "validation")
    if share is None or not is_quiet(share):
        return None
    return (
        f"the validation output barely moves (its standard deviation is {100 * np.sqrt(share.max()):.2g} % of the "
        "training output's), so it cannot tell a model from a constant"
    )


def validated_recordings(ds: Dataset, folds: int, excursions: list[dict[str, Any]]) -> tuple[int, ...]:
    """Recordings left out in turn: when every test input stays inside the training range (``excursions``:
    ``ds.input_excursions()``), only the recordings between the others' operating conditions
    (:func:`.views.interior_recordings`), so that the validation asks what the test asks (a pressure between two
    others, not beyond them: a recording at the edge, left out, makes every model extrapolate, and favours the
    simplest); () for every recording (no test set, a test set's input beyond the range, or none or every
    recording between the others)."""
    if not ds.test_splits() or any(is_test(e["split"]) for e in excursions):
        return ()
    inside = interior_recordings(ds)
    return tuple(inside) if 0 < len(inside) < folds else ()


def _positions(pieces: list[np.ndarray], names: list[str]) -> dict[str, float]:
    """The inputs (columns ``names`` of the training ``pieces``) that move like a position, with the deadband
    of their reversals."""
    out = {}
    for j, name in enumerate(names):
        deadband = position_like([p[:, j] for p in pieces])
        if deadband is not None:
            out[name] = float(f"{deadband:.3g}")
    return out


def _signed(pieces: list[np.ndarray], names: list[str], positions: dict[str, float]) -> tuple[str, ...]:
    """The ``positions`` that change sign in the training ``pieces`` (see :data:`.space.SIGNED`)."""
    if not positions:
        return ()
    u = np.concatenate(pieces)
    out = []
    for name, deadband in positions.items():
        x = u[:, names.index(name)]
        if min(np.mean(x > deadband), np.mean(x < -deadband)) >= SIGNED:
            out.append(name)
    return tuple(out)


def _dead_times(ds: Dataset) -> dict[str, int]:
    """The training inputs that act on an output only after a dead time, in samples (read on the last
    :data:`READ_ON` training samples: a fit per delay, input and output)."""
    rows = last_samples(ds.ranges.get("train", []), READ_ON)
    if not rows:
        return {}
    u = [ds.recordings[rec].u[start:stop] for rec, start, stop in rows]
    y = [ds.recordings[rec].y[start:stop] for rec, start, stop in rows]
    return dead_times(u, y, ds.input_names)


def _phase_period(ds: Dataset, found: dict[str, Any] | None) -> int | None:
    """The period of the excitation when the spec's validation split repeats the training input of its own
    recording (``found``, :func:`repeated_validation`'s finding: and a test input does not, or there is no
    test set), the recording holds at least two periods before the validation split ends, a phase window
    (1 / FOLDS of the period) keeps MIN_BLOCK scored samples and, held out, repeats no training input; None
    otherwise."""
    period = int((found or {}).get("period") or 0)
    if not period or period // FOLDS - ds.transient < MIN_BLOCK:
        return None
    r, _, b = ds.ranges["validation"][-1]
    first = min(a for rr, a, _ in spans(ds) if rr == r)
    if b - first < 2 * period:
        return None
    # the phase held out must be new to the training (a match found several periods back, or training ranges
    # that break the period, could leave a copy of it in): else the caution of a repeated validation only
    return period if repeats_training(phase_fold(ds, 0, FOLDS, period), "validation") is None else None


class Search:
    """One search (see the module docstring); :meth:`run` returns a :class:`SearchResult`."""

    def __init__(
        self,
        spec,
        ds: Dataset,
        executor=None,
        progress: Progress = no_progress,
        cancel: threading.Event | None = None,
        written_cost: str | None = None,
    ):
        self.spec = spec
        self.ds = ds
        self.params: AutoParams = spec.model.params
        self.executor = executor
        self.progress = progress
        self.cancel = cancel or threading.Event()
        self.ctx, self.ranked_on = context(spec, ds, self.params, written_cost)
        self.budget = Budget(float(self.params.budget))
        self.entries: dict[str, Entry] = {}
        self.references: list[TaskResult] = []
        self.linear_band = False  # judge band checks under the linear-system band (:meth:`_decide_band`)
        self.envelope: dict[str, Any] | None = None  # the linear reference's run per split (:meth:`_envelope`)
        self.kept: dict[str, Any] = {}  # task key -> ModelArrays
        #: (candidate key, seed) -> the moves' diagnosis of it, fitted and checked on the spec's own layout
        self.diagnosed: dict[tuple[str, int], TaskResult] = {}
        self.notes: list[str] = []
        self.stages: list[dict[str, Any]] = []
        self.interrupted: str | None = None
        self.limited = False  # stopped at the safety limit (not by the user)
        self.refit: dict[str, Any] = {"refitted": False}  # the chosen model's refit on every fitting sample
        self.refits: dict[str, TaskResult] = {}  # task key -> a refit on every fitting sample (:meth:`_refit_attempt`)
        self.fold_note: str | None = None  # why a fold's fit is the model, when it is
        self.started = time.monotonic()
        folds = self.folds
        if self.mode == "phase":  # a periodic excitation: each phase of the period held out in turn
            self.notes.append(str(self.ranked_on.short))
        if self.mode == "tail":  # the last block held out
            self.notes.append(tail_note(folds))
            self.final_layouts = [Layout("fold", fold=folds - 1, folds=folds)]
        elif folds:
            kind = "recording" if self.mode == "recordings" else "fold"
            used = validated_folds(ds, folds) if self.mode == "folds" else list(self.ranked_on.inside or range(folds))
            self.final_layouts = [Layout(kind, fold=i, folds=folds, period=self.ranked_on.period) for i in used]
        else:
            self.final_layouts = [Layout("full")]
        # a periodic excitation split period by period on a single hold-out: the validation shows the models
        # their training input again and favours the larger ones
        caution = self.ranked_on.repeat_caution()
        if caution is not None:
            self.notes.append(caution)
        fresh = fresh_weight(ds, self.final_layouts[0])
        if fresh is not None:
            self.notes.append(
                "the test data start recordings of their own, so every candidate's validation error also counts its "
                f"start as a test recording's: each validation run started afresh, weighted {fresh[1]:.2g} (the "
                "validation runs' length over the test recordings') against its continuation of the training run"
            )
        # successive halving: screened on the last SCREEN_SAMPLES of a longer training (blocked folds are short
        # data, screened as they are validated)
        self.screen_layouts = (
            self.final_layouts if self.ranked_on.blocked else [self._screened(x) for x in self.final_layouts]
        )
        self.in_memory = spec.resolved()["data"].get("path") == IN_MEMORY
        self.base = self._base_spec()

    @property
    def mode(self) -> str:
        return self.ranked_on.mode

    @property
    def folds(self) -> int:
        return self.ranked_on.folds

    # ------------------------------------------------------------------ specs and tasks
    def _base_spec(self) -> dict[str, Any]:
        raw = self.spec.resolved()
        raw.pop("model", None)
        raw["output"] = None
        raw["evaluation"] = {**raw.get("evaluation", {}), "metrics": ["nmse"], "one_step": False}
        if self.ctx.cost is None:
            raw.pop("cost", None)
        return raw

    def raw_for(self, cand: Candidate, seed: int, screening: bool) -> dict[str, Any]:
        """The complete spec of ``cand``: its patch merged into the user's spec, its model section as written
        (the base has none to merge with, and a merge would drop its nulls: ``patience: null``, every term
        kept, read as "no key" fitted the default patience's choice of terms instead)."""
        patch = cand.patch(screening)
        raw = merge(self.base, patch)
        raw["model"] = copy.deepcopy(patch["model"])
        raw["seed"] = int(seed)
        return raw

    def seeds_of(self, entry: Entry, count: int) -> list[int]:
        if not entry.random:
            return [int(self.spec.seed)]
        return [_seed_for(self.spec.seed, entry.cand.key, i) for i in range(count)]

    def _screened(self, layout: Layout) -> Layout:
        """``layout`` with its training cut to the last SCREEN_SAMPLES samples when it is longer."""
        if self._n_layout(layout) <= SCREEN_SAMPLES:
            return layout
        if layout.kind == "full":
            return Layout("screen", samples=SCREEN_SAMPLES)
        return replace(layout, samples=SCREEN_SAMPLES)

    def _n_layout(self, layout: Layout) -> int:
        if layout.samples:
            return layout.samples
        if layout.kind in ("fold", "recording"):
            return int((self.ctx.n_train + self.ctx.n_validation) * (layout.folds - 1) / layout.folds)
        return self.ctx.n_train

    def _group(self, entry: Entry, level: str, seeds: list[int], screening: bool | None = None) -> Group:
        """The fits of ``entry`` at ``level`` for ``seeds``: its screening variant on the screening layouts at the
        screening level (or when ``screening`` says so: a random candidate that stands screened, whose other seeds
        are filed as final fits), else the full variant on the final layouts."""
        screening = level == "screen" if screening is None else screening
        layouts = self.screen_layouts if screening else self.final_layouts
        tasks, work = [], 0.0
        for seed in seeds:
            raw = self.raw_for(entry.cand, seed, screening)
            for layout in layouts:
                key = f"{entry.cand.key}|{level}|{layout.label}|{seed}"
                tasks.append(self._task(key, raw, "fit", layout))
                work += estimated_work(entry.cand, self.ctx, self._n_layout(layout), screening) + TASK_OVERHEAD
        return Group(f"{entry.cand.key}|{level}", tasks, work)

    def _task(self, key: str, raw: dict[str, Any], kind: str, layout: Layout) -> Task:
        return Task(
            key,
            raw,
            self.spec.base_dir,
            self.spec.source,
            kind=kind,
            layout=layout,
            dataset=self.ds if self.in_memory else None,
            moves=MOVES,
            envelope=self.envelope if kind == "fit" else None,
            memory=kind == "fit" and self.extrapolates,
        )

    # ------------------------------------------------------------------ running a stage
    def _stopping(self) -> bool:
        return self.cancel.is_set() or self._past_limit()

    def _past_limit(self) -> bool:
        """Is the safety limit reached (then ``limited`` and ``interrupted`` say so)?"""
        limit = HARD_LIMIT * self.budget.seconds + HARD_SLACK
        if time.monotonic() - self.started > limit:
            if self.interrupted is None:
                self.limited = True
                self.interrupted = (
                    f"stopped at the safety limit of {HARD_LIMIT:g} x the budget + {HARD_SLACK:g} s in wall time "
                    f"({limit:.0f} s): the result depends on this machine's speed"
                )
            return True
        return False

    def _leader_text(self) -> str:
        ranked = self.ranking()
        if not ranked:
            return "no leader yet"
        e = self.entries[ranked[0]]
        level = e.best_level()
        if level is None:
            return "no leader yet"
        s = e.summaries[level]
        return f"leader {e.label} (validation NMSE {s.score:.4g} %)"

    def _run(self, stage: str, groups: list[Group], also: list[Task] | None = None) -> list[TaskResult]:
        """Run the tasks of ``groups`` after ``also`` (unplanned tasks: the references), heaviest first for the pool,
        record each result as it comes, return them in task order (never completion order); the stage's record
        carries the groups' planned work."""
        tasks = [*(also or []), *(t for g in groups for t in g.tasks)]
        if not tasks or self.interrupted:
            return []
        t0 = time.perf_counter()
        got: dict[str, TaskResult] = {}
        n = len(tasks)
        self.progress("search", None, f"{stage}: {n} fits; {self._leader_text()}")
        try:
            for r in run_specs(tasks, self.executor, keep_models=True, point=run_task, cancel=self._stopping):
                got[r.key] = r  # type: ignore[assignment]
                self._record(r)  # type: ignore[arg-type]
                lo, hi = _progress_span(stage)
                self.progress(
                    "search", lo + (hi - lo) * len(got) / n, f"{stage}: {len(got)}/{n}; {self._leader_text()}"
                )
        finally:  # a Ctrl-C inside the stage still records how far it got
            self.stages.append(
                {
                    "stage": stage,
                    "tasks": n,
                    "finished": len(got),
                    "seconds": round(time.perf_counter() - t0, 3),
                    "planned": round(sum(g.work for g in groups), 3),
                }
            )
        out = [got[t.key] for t in tasks if t.key in got]
        if self._stopping() and len(out) < n:
            if self.interrupted is None:
                self.interrupted = "interrupted"
            self._drop_abandoned()
        return out

    def _drop_abandoned(self) -> None:
        """Stop the fits a stopped stage left running (a local pool's workers are restarted): the model's fit
        that follows would otherwise wait for them (two abandoned fits on 80k samples held both workers)."""
        restart = getattr(self.executor, "restart", None)
        if callable(restart):
            restart()

    def _record(self, r: TaskResult) -> None:
        if r.kind == "reference":
            self.references.append(r)
            return
        if r.kind != "fit":
            return
        cand_key, level = r.key.split("|")[0], r.key.split("|")[1]
        entry = self.entries.get(cand_key)
        if entry is None:
            return
        if self.linear_band:
            r.checks = linear_band(r.checks)
        entry.results.setdefault(level, []).append(r)
        if r.model is not None:
            self.kept[r.key] = r.model
            r.model = None
        entry.summaries[level] = summarize(sorted(entry.results[level], key=lambda x: x.key))  # type: ignore[assignment]
        complete = not entry.random or len(entry.summaries["screen" if level == "screen" else level].seeds) >= (
            self.params.seeds
        )
        if (entry.reuse_screen or entry.stands_screened) and (level == "final" or complete):
            entry.summarize_final()

    def _screen_is_final(self, cand: Candidate) -> bool:
        """Are the screening fits of ``cand`` final ones (same variant, same layouts)?"""
        same_variant = not cand.screen and (cand.screen_cost in (None, cand.cost))
        return same_variant and self.screen_layouts == self.final_layouts

    # ------------------------------------------------------------------ ranking
    def ranking(self, level: str | None = None) -> list[str]:
        """Candidate keys by score at ``level`` (None: each at its best level, final ones first), usable
        ones (finite, inside the band) first, ties broken by key."""

        def key(k: str):
            e = self.entries[k]
            lv = level or e.best_level()
            s = e.summaries.get(lv) if lv else None
            if s is None:
                return (2, 1, math.inf, k)
            return (0 if s.finite and s.ok else 1, 0 if lv == "final" else 1, s.score, k)

        keys = [
            k
            for k in self.entries
            if (level is None and self.entries[k].summaries) or level in self.entries[k].summaries
        ]
        return sorted(keys, key=key)

    def _usable(self, k: str, level: str) -> bool:
        s = self.entries[k].summaries.get(level)
        return s is not None and s.finite and s.ok

    def _second_chance(self, k: str) -> bool:
        """Did ``k`` fail the band check at screening with fits the full stage does not repeat as they are (a
        cheap variant, or one seed of a random configuration)? Its full fit is checked again on its own."""
        e = self.entries[k]
        s = e.summaries["screen"]
        return s.finite and not s.ok and (e.random or not self._screen_is_final(e.cand))

    def survivors(self) -> list[str]:
        """The candidates fitted in full, in screening order (a budget that cannot fit them all keeps the best):
        the best :data:`SURVIVORS` at screening and every other one within :data:`SURVIVOR_FACTOR` of the best
        (whatever its family), and up to :data:`SECOND_CHANCES` candidates that validated better than the best
        but whose screening fit left the output band (a cheap variant's least-squares weights, or one seed, can
        leave it where the full variant does not: the default NARX on a short Bouc-Wen record does, and its full
        variant validates best and passes)."""
        ranked = [k for k in self.ranking("screen") if self._usable(k, "screen")]
        if not ranked:
            ranked = [k for k in self.ranking("screen") if self.entries[k].summaries["screen"].finite]
        if not ranked:
            return []
        best = self.entries[ranked[0]].summaries["screen"].score
        out = ranked[:SURVIVORS] + self._near_best(ranked[SURVIVORS:], best)
        again = [
            k
            for k in self.ranking("screen")
            if k not in out and self._second_chance(k) and self.entries[k].summaries["screen"].score < best
        ][:SECOND_CHANCES]
        for k in again:
            self.entries[k].origin += "; fitted in full although its screening fit left the output band"
        return sorted(out + again, key=lambda k: (self.entries[k].summaries["screen"].score, k))

    def _near_best(self, ranked: list[str], best: float | None = None) -> list[str]:
        """The keys of ``ranked`` (by screening score) within :data:`SURVIVOR_FACTOR` of the screening score
        ``best`` (default: the first one's)."""
        if not ranked:
            return []
        if best is None:
            best = self.entries[ranked[0]].summaries["screen"].score
        limit = SURVIVOR_FACTOR * max(best, 1e-12)
        return [k for k in ranked if self.entries[k].summaries["screen"].score <= limit]

    # ------------------------------------------------------------------ stages
    def _add(self, cand: Candidate, origin: str) -> Entry | None:
        if cand.key in self.entries or (cand.data and "data-extensions" in self.params.exclude):
            return None
        entry = Entry(cand, origin, reuse_screen=self._screen_is_final(cand))
        self.entries[cand.key] = entry
        return entry

    def _found(self, key: str, level: str) -> Found:
        e = self.entries[key]
        s = e.summaries[level]
        fitted = None
        pick = next(iter(self._kept_fits(e, level)), None)
        if pick is not None:
            try:
                model = self.kept[pick.key].to_model()
                fitted = model.family
            except Exception:  # noqa: BLE001 - growing without the fitted model is still possible
                fitted = None
        return Found(e.cand, fitted, pick.metrics if pick else {}, s.score)

    def _stage_screen(self) -> None:
        families = searchable_families()
        chosen = self.params.families or list(families)
        if not chosen:
            raise DynmodelError(
                "no installed model family takes part in the search (none implements search_space)",
                f"{self.spec.source}: model",
                "name a family in model.family, or install one that supports family: auto",
            )
        per_family = [candidates_of(families[name], self.ctx) for name in chosen if name in families]
        order: list[Candidate] = []
        for rank in range(max((len(c) for c in per_family), default=0)):
            order += [c[rank] for c in per_family if rank < len(c)]
        entries = [e for e in (self._add(c, "start") for c in order) if e is not None]
        groups = [self._group(e, "screen", self.seeds_of(e, 1)) for e in entries]
        minimum = len(per_family)  # the first candidate of every family
        taken = self.budget.take("screen", groups, minimum=min(minimum, len(groups)))
        refs = [
            self._task(
                f"reference|{layout.label}", self.raw_for(order[0], int(self.spec.seed), True), "reference", layout
            )
            for layout in self.final_layouts
        ]
        self._run("screen", taken, also=refs)
        for e in entries:
            if "screen" not in e.summaries:
                e.verdict = "not run (budget)"

    def _envelope(self) -> dict[str, Any] | None:
        """The range of the linear reference's free run per split (inputs, and training and validation outputs
        only), for the linear-system band; None when there is none."""
        from ..diagnose.reference import linear_envelope

        self.progress("search", 0.0, "the linear reference's free run (the band of an about linear system)")
        try:
            return linear_envelope(self.ds)
        except (ValueError, IndexError, ZeroDivisionError, FloatingPointError, np.linalg.LinAlgError):
            return None  # no linear-system band: the strict one stands

    def _decide_band(self) -> None:
        """Judge the band checks under the linear-system band (:mod:`.checks`) from here on, and those made so far,
        when the linear reference, or a candidate whose run is affine in its input (:data:`AFFINE`), validates within
        :data:`LINEAR_SYSTEM` of the best score so far (after screening, growing and the full fits), and that best
        is below :data:`LINEAR_FIT`: the data
        then show a system about linear, whose output may go beyond its training range where the reference's
        free run goes (a linear thermal process heated to twice its training power: the strict band rejected
        every linear model, 0.0008 % test NMSE, and kept a saturating network, 229 %; a cart whose position
        drifts beyond its training range, from a force inside its own).
        Where the linear reference is far behind (EMPS: 53 x, Silverbox: 860 x) and no candidate is affine, a
        nonlinear model's excursion beyond the range is not vouched for, and the strict band stands (widened on EMPS, a NARX model with the
        sign of the input went from 10.5 to 100 mm test RMSE)."""
        if self.linear_band:
            return
        screened = [s for e in self.entries.values() for s in e.summaries.values() if s and s.finite]
        if not screened:
            return
        best = min(s.score for s in screened)
        linear = [s.score for s in screened if affine(s.nonlinearity)]
        reference = self._reference_score()
        # the linear reference, or a candidate whose run is affine in its input, validates about as the best
        near = min([x for x in [reference, *linear] if x is not None], default=math.inf)
        if near > LINEAR_SYSTEM * best or best >= LINEAR_FIT:  # a poor fit says little about linearity
            return
        fits = [r for e in self.entries.values() for rs in e.results.values() for r in rs]
        if not any("wide" in r.checks for r in fits):
            return  # the reference's run stays in the band: both bands are the same
        self.linear_band = True
        for r in fits:
            r.checks = linear_band(r.checks)
        for e in self.entries.values():
            for level, rs in e.results.items():
                e.summaries[level] = summarize(sorted(rs, key=lambda x: x.key))  # type: ignore[assignment]
            if e.reuse_screen and "final" in e.summaries:
                e.summarize_final()
        self.notes.append(
            f"a linear model validates within {LINEAR_SYSTEM:g} x of the best candidate (validation NMSE "
            f"{near:.3g} % against {best:.3g} %), so the system is about linear: a candidate's output "
            "may leave the training output range where the linear reference's free run does (an input beyond its "
            "training range, a drift)"
        )

    def _stage_grow(self) -> None:
        ranked = [k for k in self.ranking("screen") if self._usable(k, "screen")][:GROW_FROM]
        new: list[Entry] = []
        families = searchable_families()
        for k in ranked:
            found = self._found(k, "screen")
            cls = families.get(found.candidate.family)
            if cls is None:
                continue
            for cand in candidates_of(cls, self.ctx, around=found):
                entry = self._add(cand, f"grown from {k}")
                if entry is not None:
                    new.append(entry)
        groups = [self._group(e, "screen", self.seeds_of(e, 1)) for e in new]
        taken = self.budget.take("grow", groups, minimum=0)
        self._run("grow", taken)
        for e in new:
            if "screen" not in e.summaries:
                e.verdict = "not run (budget)"

    @property
    def extrapolates(self) -> bool:
        """Do the validation or test inputs leave the training range by more than :data:`.select.EXTRAPOLATION` of
        its width? (Then the search fits several candidates in full, measures their start memory and prefers
        one that forgets its start.)"""
        return self.ctx.excursion > EXTRAPOLATION

    def _final_groups(self, keys: list[str]) -> list[Group]:
        """The full fits of ``keys`` the budget can take (:meth:`_affordable`): every seed, less those a screening
        fit that already was a final one made."""
        groups = []
        for k in keys:
            e = self.entries[k]
            seeds = self._unscreened_seeds(e) if e.reuse_screen else self.seeds_of(e, self.params.seeds)
            if seeds:
                groups.append(self._group(e, "final", seeds))
        return self._affordable(groups)

    def _unscreened_seeds(self, e: Entry) -> list[int]:
        """The seeds of ``e`` its screening did not fit (the others when its screening fits count as final)."""
        done = {int(r.seed or 0) for r in e.results.get("screen", [])}
        return [s for s in self.seeds_of(e, self.params.seeds) if s not in done]

    def _stage_full(self, keys: list[str]) -> None:
        groups = self._final_groups(keys)
        # the test inputs leave the training range: a validation inside it cannot rank finely how the models
        # extrapolate, so the choice is never left to a single full fit (the best SURVIVORS are fitted in full)
        least = SURVIVORS if self.extrapolates else 1
        # a second chance never takes the place of a survivor that passed its screening band check
        least += sum(1 for k in keys if self._second_chance(k))
        taken = self.budget.take("full", groups, minimum=min(least, len(groups)))
        self._run("full", taken)

    def _stage_forgetting(self) -> None:
        """When the test inputs leave the training range and every model fitted in full that validates within
        :data:`.select.ABOUT_AS_WELL` of the best remembers the outputs its run started from
        (:func:`.checks.start_memory`), up to :data:`FORGETTING` more screened candidates (within
        :data:`SURVIVOR_FACTOR` of the best screening score) are fitted in full, the smallest first: the choice
        prefers a model that forgets its start when it validates about as well (:func:`.select.choose`), and the
        screening fit cannot tell which do (its least-squares weights forgot where the weights refined on the free
        run remember: Silverbox, every NARX candidate). On Silverbox the three fitted in full remembered theirs;
        the smallest screened candidate (42 terms) forgets its start and validates 11 % behind the best."""
        if not self.extrapolates:
            return
        final = [k for k in self.ranking("final") if self._usable(k, "final")]
        if not final:
            return
        fitted = {k: self.entries[k].summaries["final"] for k in final}
        leader = fitted[final[0]]
        if not remembers(leader.memory) or sound_within(final, fitted, lambda s: forgets(s.memory), leader.score):
            return
        screened = [k for k in self.ranking("screen") if self._usable(k, "screen")]
        if not screened:
            return
        pool = [k for k in self._near_best(screened) if "final" not in self.entries[k].summaries]
        smallest = sorted(pool, key=lambda k: (model_size(self.entries[k].summaries["screen"]), k))[:FORGETTING]
        for k in smallest:
            self.entries[k].origin += (
                "; fitted in full, the smallest first, as every model fitted in full that validates about as well "
                "as the best remembers the outputs its run started from (the test inputs leave the training range)"
            )
        groups = self._final_groups(smallest)
        taken = self.budget.take("full", groups, minimum=len(groups))
        self._run("full: forgetting", taken)

    def _stage_refit_agreement(self) -> None:
        """On a hold-out split, when the model the choice keeps is a random candidate whose seeds part ways on the
        test inputs so far that all but one err there by more than its validation error (:func:`.select.kept_floor`)
        and no candidate whose seeds agree there validates below that floor, up to :data:`REFIT_CHECKS`
        deterministic candidates that validated below it, or were only screened within :data:`SURVIVOR_FACTOR` of
        it (:meth:`_near_best`; the best first, fitted in full) are fitted again on every training and validation
        sample, their choices frozen, as the model kept would be (:meth:`_refit_attempt`, made once: the final
        refit reuses it). A deterministic fit has no seeds to compare; how far its refit's run departs from its
        validated fit's on the test inputs is its evidence of the same kind (:func:`.select.refit_floor`). Seeds
        2100's sys22 (held steps of another hold time): every internal network fitted in full parted ways (the one
        kept validated at 0.025 % and tested 1.51 %); the NARX default, screened out at 0.07 %, tested 0.137 %."""
        if self.mode != "holdout":
            return
        key, _, level = self.decide()
        if key is None or level != "final":
            return
        leader = self.entries[key].summaries["final"]
        if not parted_seeds(leader):
            return
        floor = kept_floor(leader)
        below = []
        for k in self.ranking():
            e, lv = self.entries[k], self.entries[k].best_level()
            if e.random or lv is None or not self._usable(k, lv) or ignores_input(e.summaries[lv]):
                continue
            # a screening fit (the cheap variant) ranks its full fit only as the survivors' rule reads it (seeds
            # 300's sys21: the NARX default screened at 0.019 %, 1.6x the networks' floor, validates at 0.0104 %)
            screened_only = lv == "screen" and not e.reuse_screen
            if self._near_best([k], floor) if screened_only else e.summaries[lv].score < floor:
                below.append(e)
        below = below[:REFIT_CHECKS]
        if not below or self._past_limit():
            return
        why = f"; fitted again on every sample, as the seeds of the leader ({self.entries[key].label}) part ways"
        for e in below:
            e.origin += f"{why} on the test inputs"
        groups = self._final_groups([e.cand.key for e in below if "final" not in e.summaries])
        if groups:
            self._run("full: refit agreement", self.budget.take("full", groups, minimum=len(groups)))
        every = view(self.ds, Layout("all"))
        for e in below:
            s = e.summaries.get("final")
            if self._stopping() or s is None or not (s.finite and s.ok) or e.stands_screened:
                continue
            # on a hold-out split a deterministic candidate has one fit: the model the choice would keep
            validated = next((r.test_runs for r in self._kept_fits(e, "final") if r.test_runs), None)
            model = self._keep(e, "final", False)
            if validated is None or model is None:
                continue
            config, warm = self._frozen(model)
            if config is None:
                continue
            r, failed, _ = self._refit_attempt(e, model, "final", config, warm, self._fit_error(model, every))
            if r is not None and failed is None and r.test_runs:
                apart = pair_differences([validated, r.test_runs])
                s.refit_apart = apart[0] if apart else None

    def _affordable(self, groups: list[Group]) -> list[Group]:
        """The full fits the budget can still take. A candidate whose full fits (every fold) are planned beyond
        all that is left of the allowance is not fitted in full, even as a stage's first: its screening fits then
        stand as its final ones (the cheap variant on the screening samples, validated on the same hold-out,
        folds or recordings left out; a random candidate's over all its seeds, the others fitted now), with a
        note; chosen, it is the model as it was validated (on a hold-out that fit itself, its median seed's for a
        random one, otherwise its screening variant fitted on the screening samples of the whole training split).
        On a generated Wiener-Hammerstein system of 100k samples the leader's full fit (degree 3, lags up to 11, a
        pool of 2600 monomials) was planned at 1976 s of the 600 s allowance and took 876 s alone: the search took
        905 s for a budget of 300 s; on three recordings of 50k samples its three folds, planned at 2975 s, ran
        into the safety limit (1022 s)."""
        room = self.budget.allowance - self.budget.planned
        kept, skipped = [], []
        randoms = False
        for g in groups:
            e = self.entries[g.key.split("|")[0]]
            screen = e.summaries.get("screen")
            usable = screen is not None and screen.finite and screen.ok
            work = g.work * self._rework(e) if usable and not e.random else g.work
            if work <= room or not usable:
                kept.append(g)
                continue
            e.full_work_skipped = work
            skipped.append(e.label)
            # a random candidate is judged over several seeds all the same: its screening fit of one seed is
            # joined by the screening fits of its other seeds, filed as final ones (the median is over them all)
            seeds = self._unscreened_seeds(e) if e.random else []
            randoms = randoms or e.random
            if seeds:
                kept.append(self._group(e, "final", seeds, screening=True))
            else:
                e.summarize_final()
        if skipped:
            samples = self.screen_layouts[0].samples
            where = f"on the last {samples} training samples" if samples else "on the training split"
            named = "; ".join(skipped[:3]) + (f"; and {len(skipped) - 3} more" if len(skipped) > 3 else "")
            self.notes.append(
                f"not fitted in full, each one's full fits planned beyond the {max(room, 0.0):.0f} s of work left of "
                f"the {self.budget.allowance:.0f} s a budget of {self.budget.seconds:g} s allows ({REFERENCE_WORKERS} "
                f"workers' worth): {named}; their screening fits (the cheap variant, {where}"
                + (f"; a random family's over {self.params.seeds} seeds" if randoms else "")
                + ") stand as their final ones"
            )
        return kept

    def _rework(self, e: Entry) -> float:
        """How many times the candidate's own estimate its family now puts its full fit at, knowing its screening
        fit (:meth:`Family.full_work`; at least 1: a smaller answer never adds a fit to the plan)."""
        cls = registry.families().get(e.cand.family)
        hook = getattr(cls, "full_work", None)
        if hook is None or not e.cand.work:
            return 1.0
        try:
            again = hook(self.ctx, self._found(e.cand.key, "screen"))
        except Exception:  # noqa: BLE001 - an estimate must not stop the search
            return 1.0
        if again is None or not math.isfinite(again):
            return 1.0
        return max(1.0, float(again) / float(e.cand.work))

    def _stage_moves(self) -> None:
        if "moves" in self.params.exclude:
            return
        for round_ in range(MOVE_ROUNDS):
            ranked = [k for k in self.ranking("final") if self._usable(k, "final")]
            if not ranked or self.interrupted:
                return
            # the leader is the model the choice keeps so far, which may set the best validated one aside (it
            # remembers its start, ignores its input, or a simpler one ties): extending a model set aside gives
            # candidates set aside for the same reason
            chosen, _, level = self.decide()
            leading = chosen if chosen in ranked and level == "final" else ranked[0]
            leader = self.entries[leading]
            median = leader.summaries["final"].median_seed
            seed = median if median is not None else int(self.spec.seed)
            raw = self.raw_for(leader.cand, seed, False)
            # the detectors refit the leader's spec (a held-out refit with more terms, a reference model); the
            # task plans itself again from the fitted leader's size and stops within the work left to it
            refit = self._refit_work(leader)
            room = SHARES["moves"] * self.budget.allowance - refit - self.budget.planned
            model = self._fitted_in_full(leader)
            # after a cross-validation the model's own fit (:meth:`_final_model`) is this very fit, checked alike
            checked = model is None and self._fitted_as_diagnosed(leader)
            task = replace(
                self._task(f"diagnose|{round_}|{leader.cand.key}", raw, "diagnose", Layout("full")),
                allowance=room,
                candidate=leader.cand,
                context=self.ctx,
                model=model,
                checked=checked,
                envelope=self.envelope if checked else None,
                memory=checked and self.extrapolates,
            )
            diag = Group("diagnose", [task], diagnosis_work(estimated_work(leader.cand, self.ctx), self.ctx.n_train))
            if not self.budget.take("moves", [diag], minimum=0, reserve=refit):
                return
            results = self._run(f"moves {round_ + 1}: diagnose the leader", [diag])
            if checked and results and results[0].model is not None:
                self.diagnosed[(leader.cand.key, seed)] = results[0]
            if results and results[0].status == "ok" and results[0].message:
                self.notes.append(results[0].message)
            if not results or results[0].status != "ok" or not results[0].proposals:
                return
            new: list[Entry] = []
            for prop in results[0].proposals:
                if prop["cause"] == "inadequate-structure" or (
                    "data-extensions" in self.params.exclude and "data" in prop["patch"]
                ):
                    continue
                cand = self._candidate_from(leader, raw, prop)
                if cand is None:
                    continue
                entry = self._add(cand, f"move from {leader.cand.key}: {prop['cause']}")
                if entry is not None:
                    new.append(entry)
            groups = [self._group(e, "final", self.seeds_of(e, self.params.seeds)) for e in new]
            taken = self.budget.take("moves", groups, minimum=0, reserve=refit)
            if not taken:
                return
            self._run(f"moves {round_ + 1}", taken)
            if self.decide()[0] == leading:
                return  # no move is chosen over the leader

    def _fitted_in_full(self, e: Entry) -> Any:
        """The kept model of ``e``'s full variant fitted on the spec's own layout at its median seed, when the search
        made that fit (a held-out validation split), else None: the spec the diagnosis fits there, already fitted
        (on Bouc-Wen the leader's fit took about 70 s of the diagnosis' 136)."""
        if e.stands_screened or "final" not in e.summaries:
            return None
        for r in self._kept_fits(e, "final"):
            if Layout(**r.layout) == Layout("full"):
                return self.kept[r.key]
        return None

    def _fitted_as_diagnosed(self, e: Entry) -> bool:
        """Is ``e``'s model fitted after the search (:meth:`_final_model`) as the moves' diagnosis fits it: its full
        spec on the spec's own layout (not the tail layout, not its screening variant)?"""
        return self.mode != "tail" and not e.stands_screened

    def _refit_work(self, leader: Entry) -> float:
        """Planned work of the model's fits after the search, which the moves leave room for: on a holdout none
        for the model itself (the fit validated is the model), else the leader's fit on the whole training split
        (cross-validated folds, recordings left out); and its refit on every fitting sample
        (:meth:`_refit_on_all`) when its family can freeze its configuration."""
        cls = registry.families().get(leader.cand.family)
        frozen = cls is not None and defines_hook(cls, "frozen_config") and not leader.stands_screened
        every = self.ds.n_scored("train") + self.ds.n_scored("validation")
        work = estimated_work(leader.cand, self.ctx, every) + TASK_OVERHEAD if frozen else 0.0
        if self.mode in ("holdout", "tail"):
            return work
        if leader.stands_screened:  # its screening variant on the screening samples (see _final_model)
            full = self._screened(Layout("full"))
            return estimated_work(leader.cand, self.ctx, self._n_layout(full), True) + TASK_OVERHEAD
        return work + estimated_work(leader.cand, self.ctx) + TASK_OVERHEAD

    def _candidate_from(self, leader: Entry, raw: dict[str, Any], prop: dict[str, Any]) -> Candidate | None:
        """The candidate a diagnosis proposal makes of the leader's spec (patch merged, then validated)."""
        from ..spec import validate_spec

        patched = merge(raw, prop["patch"])
        try:
            validate_spec(dict(patched), self.spec.source, self.spec.base_dir)
        except (DynmodelError, ValueError):
            return None
        model = patched.get("model") or {}
        allowed = self.params.families or list(searchable_families())
        if model.get("family") not in allowed:  # a switch to a family the user left out (or not searchable)
            return None
        data = {
            k: patched["data"][k] for k in patched.get("data", {}) if patched["data"].get(k) != self.base["data"].get(k)
        }
        cost = patched.get("cost")
        if self.ctx.cost is not None and cost != self.ctx.cost:
            return None
        work = estimated_work(leader.cand, self.ctx) * 1.5
        return Candidate(
            family=str(model.get("family")),
            params=dict(model.get("params") or {}),
            summary=f"{leader.cand.summary}; {prop['summary']}",
            cost=cost,
            data=data,
            work=work,
            stochastic=leader.cand.stochastic,
        )

    # ------------------------------------------------------------------ the choice and the model
    def _reference_score(self) -> float | None:
        refs = sorted(self.references, key=lambda r: r.key)
        values = []
        for r in refs:
            lin = (r.reference or {}).get("linear") or {}
            nmse = lin.get("nmse") or {}
            v = nmse.get("validation", nmse.get("train"))
            if v is None:
                return None
            values.append(float(v))
        return float(np.mean(values)) if values else None

    def _deciding_levels(self) -> dict[str, str]:
        """Candidate -> the level of the score the choice compares: the full fits when one of them is usable
        (the screening variants rank them coarsely). Otherwise every candidate at its deepest level: a search
        stopped early may not have fitted the best screened candidates in full, and one whose screening fit
        is already final must not win only because it looks fitted in full (a Ctrl-C after screening kept an
        output-error model 100x worse than the NARX candidates screened); when every full fit was rejected,
        the best screened candidate not yet fitted in full is (and is checked again)."""
        if not self.interrupted and any(self._usable(k, "final") for k in self.entries):
            return {k: "final" for k, e in self.entries.items() if "final" in e.summaries}
        return {k: lv for k, e in self.entries.items() if (lv := e.best_level()) is not None}

    def decide(self) -> tuple[str | None, Choice, str]:
        """(winner, the choice, the winner's level)."""
        levels = self._deciding_levels()
        summaries = {k: self.entries[k].summaries[lv] for k, lv in levels.items()}
        labels = {k: e.label for k, e in self.entries.items()}
        choice = choose(
            summaries,
            labels,
            short_validation=self.ranked_on.doubt(),
            excursion=self.ctx.excursion,
            reference=self._reference_score(),
            uses_inputs=self.ctx.n_inputs > 0,
            fold_blocks=BLOCKS if self.ranked_on.blocked else 0,
        )
        for k, e in self.entries.items():
            if k in choice.verdicts:
                e.verdict = choice.verdicts[k]
            elif k not in levels and "screen" in e.summaries:
                s = e.summaries["screen"]
                if not s.finite:
                    e.verdict = f"screening: no usable fit ({s.status})"
                elif not s.ok:
                    e.verdict = f"screening: rejected, {s.failure or 'leaves the output band'}"
                else:
                    e.verdict = "screened out (validates worse)"
        level = levels[choice.key] if choice.key else ("final" if "final" in levels.values() else "screen")
        return choice.key, choice, level

    def _final_model(self, key: str, level: str, anyway: bool = False):
        """The winner's FittedModel on the spec's own layout (re-evaluated by the caller). ``anyway``: every
        candidate left the output band somewhere and this one is kept anyway (:func:`.select.choose`), so its final
        fit is too, whatever its band check (the evaluation reports it; before, the search then failed with "kept
        the best on validation anyway" in its message and no model). Validated on a
        holdout, the fit validated is the model. Otherwise it is fitted again on the whole training split,
        unless the safety limit is reached before or during that fit: a fit already made is kept (the screening
        fit, or the fold model that trained on the most samples), so that the search ends near its limit (the
        refit on the whole training split took as long again: 276 s on 120k samples after a limit of 210 s;
        on three recordings of 50k samples, 9 minutes after a limit of 1020 s)."""
        e = self.entries[key]
        s = e.summaries[level]
        past = self._past_limit()  # (after a Ctrl-C too, which ``limited`` does not report)
        if (self.mode in ("holdout", "tail") and level == "final") or past:
            model = self._keep(e, level, past)
            if model is not None or past:
                return model
        if keeps_a_fold(self.mode, self.ds):
            model = self._keep(e, level, False, last=True)
            if model is not None:
                return model
        seed = s.median_seed if s.median_seed is not None else int(self.spec.seed)
        layout = self.final_layouts[0] if self.mode == "tail" else Layout("full")
        if e.stands_screened:  # as it was validated: its screening variant, on the screening samples of all the data
            layout = self._screened(layout)
        raw = self.raw_for(e.cand, seed, e.stands_screened)
        task = self._task(f"{e.cand.key}|model|{layout.label}|{seed}", raw, "fit", layout)
        if self.interrupted:  # the user waits for this one fit: say so (on a long record it takes minutes)
            self.progress(
                "search",
                None,
                f"{self.interrupted}: fitting the best so far, {e.label}, on the whole training split "
                "(Ctrl-C again stops without a model)",
            )
        cancel_set = self.cancel.is_set()
        diagnosed = self.diagnosed.get((e.cand.key, seed)) if self._fitted_as_diagnosed(e) else None
        results: list[PointResult]
        if diagnosed is not None:  # the moves' diagnosis made this fit (same spec, seed and layout), checked alike
            results = [copy.copy(diagnosed)]
        else:
            results = list(run_specs([task], self.executor, keep_models=True, point=run_task, cancel=self._past_limit))
        if not results and self._past_limit():  # the limit was reached during the fit
            self._drop_abandoned()
            return self._keep(e, level, True)
        if not results or results[0].model is None:  # the next best is tried: one fit must not waste the search
            why = (results[0].message or "").split(" Fix: ")[0] if results else "no result"
            s.failure = f"failed when fitted on the whole training split: {why}"  # its verdict when ranked again
            self.notes.append(f"{e.label} validated best but {s.failure}")
            return None
        r: TaskResult = results[0]  # type: ignore[assignment]
        if self.linear_band:
            r.checks = linear_band(r.checks)
        if not cancel_set and not anyway and not r.checks.get("ok", False):
            e.verdict = f"rejected after its final fit: {failed_split(r.checks)}"
            s.failure = "failed its final fit's band check"
            return None
        assert r.model is not None  # checked above
        return self._against_folds(e, level, r.model.to_model())

    def _against_folds(self, e: Entry, level: str, model):
        """``model`` (the winner fitted on the spec's own split, after it was validated on folds or recordings left
        out), or its fit validated with the last block held out (of recordings, the one trained on the most
        samples) when that fit's free run fits every training and validation sample more than :data:`FOLD_BETTER`
        x better (:meth:`_fit_error`). The cross-validation validated the configuration; a family then still
        makes choices of its own (a ridge factor, the terms, a training length), on the spec's short validation
        split alone for ``model``, inside the fold for the fold's fit. On 500 samples of a seal whose validation
        split sits at another force level, the ridge factor chosen there (607) gave a constant output: 104 % NMSE
        on those samples against the fold's fit's 1.9 % (test: 62 474 -> 242 %). Keeping whichever fits better
        was tried and not kept: near ties went either way on the test (docs/auto.md)."""
        if self.mode not in CROSS_VALIDATED:
            return model
        fits = [r for r in self._kept_fits(e, level) if r.checks.get("ok", False)]
        if not fits:
            return model
        pick = min(fits, key=lambda r: self._held_last(r, True))
        fold = self.kept[pick.key].to_model()
        every = view(self.ds, Layout("all"))
        mine, theirs = self._fit_error(model, every), self._fit_error(fold, every)
        if theirs is None or (mine is not None and mine <= FOLD_BETTER * theirs):
            return model
        what = "its free run fails there" if mine is None else f"NMSE {mine:.4g} %"
        self.notes.append(
            f"the model is {e.label} as validated with {Layout(**pick.layout).label} held out: it fits the training "
            f"and validation samples clearly better ({theirs:.4g} %) than fitted on the spec's own split ({what}), "
            "where its family made its own choices on the validation split alone"
        )
        return fold

    def _refit_on_all(self, e: Entry, model, level: str):
        """The chosen configuration fitted again on every training and validation sample together, its choices
        made on validation frozen (:meth:`dynmodel.family.Family.frozen_config`: a NARX model's terms and ridge
        factor), so that the model kept learns from every sample the search may read: the validation split, the
        block held out, the recording left out. ``model`` (the fit the search validated) is kept instead when
        its family cannot freeze it, it stands as screened, the search was stopped, or the refit fails, leaves
        the output band, or fits those samples worse than the model validated by more than :data:`REFIT_WORSE`
        (:meth:`_fit_error`: its estimation stalled); ``self.refit`` says which. The validation scores of a
        refitted model are no longer a hold-out: the note says so, with the search's validation NMSE."""
        if self.ds.n_scored("validation"):
            where = "the training and validation samples together"
            scores = "its validation scores below are no longer a hold-out"
        else:
            where = "the whole training split, the samples held out to validate it included"
            scores = "the training scores below include them"
        config, warm = self._frozen(model)
        why = None
        if config is None:
            why = f"the {e.cand.family} family cannot freeze the choices this fit made on validation"
        elif e.stands_screened or level != "final":
            why = "it was not fitted in full"
        elif self.interrupted or self._past_limit():
            why = "the search was stopped"
        if why is not None:
            self.refit["why"] = why
            return model
        assert config is not None
        every = view(self.ds, Layout("all"))
        before = self._fit_error(model, every)  # the model validated's fit error on those samples
        self.progress("search", None, f"fitting {e.label} again on all {every.n_scored('train')} training samples")
        try:
            r, failed, retry = self._refit_attempt(e, model, level, config, warm, before)
            if retry and config.get("warm") and not self._stopping():
                # a failed or stalled estimation from one start: once more from the other
                start = "its own start" if warm else "the model validated's values"
                self.progress("search", None, f"fitting {e.label} again, from {start}")
                first, warm = failed, not warm
                r, failed, _ = self._refit_attempt(e, model, level, config, warm, before)
                if failed is not None:
                    failed = f"{first}; from {start}: {failed}"
        except KeyboardInterrupt as exc:  # the model validated is a whole model: keep it
            self.interrupted = f"{interruption(exc)} while the chosen model was fitted again on every sample"
            r, failed = None, "it did not finish"
        if r is None and self._stopping():
            self._drop_abandoned()
            self.refit["why"] = "the search was stopped during the refit"
            return model
        if failed is not None:
            self.refit["why"] = f"the refit failed ({failed})"
            self.notes.append(
                f"{e.label} fitted again on {where} failed ({failed}); the model kept is the one validated"
            )
            return model
        assert r is not None and r.model is not None  # kept
        score = e.summaries[level].score
        self.refit = {
            "refitted": True,
            "samples": int(every.n_scored("train")),
            "params": config["warm" if warm else "params"],
            "cost": config.get("cost"),
            "warm_start": warm,
            "validation_nmse": score if math.isfinite(score) else None,
            "seconds": round(r.seconds, 3),
        }
        self.notes.append(
            f"the chosen {e.label} was fitted again on {where} ({every.n_scored('train')} samples), its choices "
            f"made on validation frozen{', started from its validated values' if warm else ''}: {scores} (the "
            f"search's validation NMSE: {score:.4g} %)"
        )
        return r.model.to_model()

    @staticmethod
    def _frozen(model) -> tuple[dict[str, Any] | None, bool]:
        """``model``'s configuration with the choices its fit made on validation frozen
        (:meth:`dynmodel.family.Family.frozen_config`; None: its family cannot freeze them), and whether its refit
        starts first from the values validated (``warm``)."""
        try:
            config = model.family.frozen_config()
        except (ValueError, RuntimeError):
            config = None
        return config, config is not None and bool(config.get("warm_first")) and bool(config.get("warm"))

    def _refit_attempt(
        self, e: Entry, model, level: str, config: dict[str, Any], warm: bool, before: float | None
    ) -> tuple[TaskResult | None, str | None, bool]:
        """One refit of ``e`` on every training and validation sample, its choices frozen (``config``:
        :meth:`dynmodel.family.Family.frozen_config` of ``model``, the fit validated; ``warm``: from the model
        validated's values, with its preprocessing, for those values mean what they meant only in its scaling):
        its result, why it is not kept (None: kept), and whether the other start may do better: after a failed or
        stalled estimation, not after a run that leaves the band (the configuration itself is then unsafe on that
        input: Bouc-Wen, 4000 samples, refitted from least squares, left it on the test input; from the values
        validated it stayed inside, and tested 1.8 x worse than the model validated). ``before``: the model
        validated's fit error on those samples (:meth:`_fit_error`). Made once per start
        (:meth:`_stage_refit_agreement` may have made it)."""
        seed = e.summaries[level].median_seed
        raw = self.raw_for(e.cand, seed if seed is not None else int(self.spec.seed), False)
        raw["model"] = {"family": e.cand.family, "params": config["warm" if warm else "params"]}
        if config.get("cost"):
            raw["cost"] = config["cost"]
        task = self._task(f"{e.cand.key}|{'warm' if warm else 'all'}|{seed}", raw, "fit", Layout("all"))
        if warm:
            task = replace(task, preprocessor=model.preprocessor)
        r: TaskResult | None = self.refits.get(task.key)
        if r is None:
            results = list(run_specs([task], self.executor, keep_models=True, point=run_task, cancel=self._stopping))
            r = results[0] if results else None  # type: ignore[assignment]
            if r is not None:
                self.refits[task.key] = r
        if r is None:
            return None, "it did not finish", False
        if self.linear_band:
            r.checks = linear_band(r.checks)
        if r.model is None or r.status != "ok":
            return r, failed_split(r.checks) or r.message or r.status, True
        if not r.checks.get("ok", False):
            return r, failed_split(r.checks) or r.message or r.status, False
        if self.extrapolates and forgets(e.summaries[level].memory) and remembers(r.memory):
            return (
                r,
                "its free run remembers the outputs it started from, where the model validated forgets them",
                True,
            )
        if r.score is None or before is None or r.score <= REFIT_WORSE * before:  # a NaN score is worse too
            return r, None, False
        stalled = f"its free run fits those samples clearly worse than the model validated: NMSE {r.score:.4g} %"
        return r, f"{stalled} against {before:.4g} %", True

    @staticmethod
    def _fit_error(model, ds: Dataset) -> float | None:
        """The free-run NMSE (%, mean over outputs) of ``model`` over the training split of ``ds``, None when it
        cannot be run there. The refit minimised its cost on these samples: where it fits them clearly worse than the
        model validated, its estimation stalled (a long record whose free-run sensitivities build up), and the
        model validated is kept."""
        from ..model import evaluate

        try:
            metrics, _ = evaluate(model, ds, ["nmse"], one_step=False)
        except (ValueError, FloatingPointError):
            return None
        value = (metrics.get("train") or {}).get("nmse")
        return None if value is None else float(value)

    def _keep(self, e: Entry, level: str, past_limit: bool, last: bool = False):
        """The model of a fit of ``e`` already made at ``level``: its median seed's, on the layout that trained on
        the most samples (a recording or block left out; ties: the first; ``last``: of blocks in time, the one
        held out last, a validation that follows its training as a test does), one that passed its own band check
        when there is one; with a note when the safety limit (or, ``last``, the missing validation split) made it
        stand in for the fit on the spec's own layout. None when no fitted model was kept (the next candidate is
        tried)."""
        fits = self._kept_fits(e, level)
        if not fits:
            return None

        pick = min(fits, key=lambda r: (not r.checks.get("ok", False), *self._held_last(r, last)))
        layout = Layout(**pick.layout)
        if last:
            how = (
                f"with {layout.label}"
                if layout.kind == "recording"
                else f"without the last 1/{layout.folds} of every training recording, held out to validate it"
            )
            self.fold_note = (  # said unless the refit on every sample replaces that fit (:meth:`_refit_on_all`)
                f"there is no validation split, so the model kept is {e.label} as fitted {how}: fitted on the whole "
                "training split it would have nothing to choose its size or training length on (add a validation "
                f"split, e.g. split: {_with_validation(self.spec)}, to fit it on more data)"
            )
        if past_limit and (level == "screen" or self.mode in CROSS_VALIDATED):
            how = (
                f"as screened ({layout.label}, its screening variant)"
                if level == "screen" and not self._screen_is_final(e.cand)
                else f"as fitted on {layout.label}"
            )
            self.notes.append(
                f"the model kept is {e.label} {how}, not refitted on the whole training split, so that the "
                "search ends near its safety limit; a larger budget fits it in full"
            )
        return self.kept[pick.key].to_model()

    def _kept_fits(self, e: Entry, level: str) -> list[TaskResult]:
        """The fits of ``e`` at ``level`` whose model was kept, of its median seed, by task key."""
        seed = e.summaries[level].median_seed
        return sorted((r for r in e.results_at(level) if r.seed == seed and r.key in self.kept), key=lambda r: r.key)

    def _held_last(self, r: TaskResult, last: bool) -> tuple[int, str]:
        """The order of fits in which the one kept comes first: the one that trained on the most samples (a
        recording or block left out; ties: the first), or (``last``) of blocks in time the one held out last."""
        if last and r.layout.get("kind") == "fold":
            return -Layout(**r.layout).fold, r.key
        return -view(self.ds, Layout(**r.layout)).n_scored("train"), r.key

    def run(self) -> SearchResult:
        choice: Choice | None = None
        level = "screen"
        key = None
        try:
            self.envelope = self._envelope()
            self._stage_screen()
            self._decide_band()
            if not self.interrupted:
                self._stage_grow()
            self._decide_band()
            surv = self.survivors() if not self.interrupted else []
            if not self.interrupted:
                self._stage_full(surv)
                self._decide_band()
            if not self.interrupted:
                self._stage_forgetting()
            if not self.interrupted:
                self._stage_moves()
            if not self.interrupted:
                self._stage_refit_agreement()
        except KeyboardInterrupt as exc:
            self.interrupted = interruption(exc)
            self._drop_abandoned()  # the stage's running fits would hold the workers the best one's fit needs
        model = None
        tried: set[str] = set()
        while True:
            key, choice, level = self.decide()
            if key is None or key in tried:
                break
            tried.add(key)
            try:
                model = self._final_model(key, level, anyway=choice is not None and choice.anyway)
            except KeyboardInterrupt as exc:
                self.interrupted = (
                    f"{interruption(exc)} while the best candidate so far ({self.entries[key].label}) was fitted "
                    "on the whole training split"
                )
                model = None
                break
            if model is not None:
                self.entries[key].verdict = "chosen"
                model = self._refit_on_all(self.entries[key], model, level)
                break
            failed = self.entries[key].summaries[level]
            failed.ok = False
            failed.failure = failed.failure or "failed its final fit's band check"
        return SearchResult(model, self.record(key if model is not None else None, choice, level))

    # ------------------------------------------------------------------ the record
    def record(self, key: str | None, choice: Choice | None, level: str) -> dict[str, Any]:
        ranked = self.ranking()
        entries = [self.entries[k] for k in ranked] + [e for k, e in self.entries.items() if k not in ranked]
        notes = list(self.notes) + (choice.notes if choice else [])
        if self.fold_note and not self.refit.get("refitted"):
            notes.append(self.fold_note)
        if self.limited:
            notes.insert(0, f"the search {self.interrupted}; a larger budget, or fewer samples, searches further")
        winner = self.entries.get(key) if key else None
        families = sorted({e.cand.family for e in self.entries.values() if e.summaries})
        tried = sum(1 for e in self.entries.values() if e.summaries)
        if winner is not None and winner.stands_screened:
            samples = self._screened(Layout("full")).samples
            notes.append(
                f"the model is {winner.label} in its screening variant"
                + (f" on the last {samples} training samples" if samples else "")
                + f", as it was validated; a budget of "
                f"{_budget_for(winner.full_work_skipped + self.budget.planned):.0f} s fits it in full"
            )
        if winner is not None:
            score = winner.summaries[level].score
            if score >= POOR:
                notes.append(
                    f"even the best model is poor: validation NMSE {score:.3g} % after {tried} candidates of "
                    f"{', '.join(families)}; the data may not determine the output from the input (check the "
                    "input and output columns, the sampling, a dead time), or need more data"
                )
            kept = winner.summaries[level]
            if spread_floor(kept) > max(SPREAD_NOTE * score, SPREAD_FLOOR):
                notes.append(
                    f"the {kept.fits} fits of {winner.label} that were validated (its seeds and folds) part ways on "
                    f"the test inputs: {parted_words(kept)}, against {score:.3g} % on validation; expect a test "
                    "error above the validation one. "
                    "Test inputs unlike the training ones do this (a wider range, another spectrum or hold time): "
                    "training data like them, or another family (model.params.families), may narrow it"
                )
        # the first layout's (not the first to finish: that depends on the executor and its timing)
        ref = min(self.references, key=lambda r: r.key).reference if self.references else None
        return {
            "version": 1,
            "spec": {"model": {"family": "auto", "params": self.params.model_dump(mode="json")}},
            "seed": int(self.spec.seed),
            "mode": self.mode,
            "folds": self.folds,
            "layouts": {
                "screen": [lay.to_json() for lay in self.screen_layouts],
                "final": [lay.to_json() for lay in self.final_layouts],
            },
            "context": {
                "n_train": self.ctx.n_train,
                "n_validation": self.ctx.n_validation,
                "max_warmup": self.ctx.max_warmup,
                "excursion": self.ctx.excursion,
                "small": self.ctx.small,
                "positions": dict(self.ctx.positions),
                "dead_times": dict(self.ctx.dead_times),
                "signed": list(self.ctx.signed),
            },
            "budget": self.budget.to_json(),
            "stages": self.stages,
            "reference": ref,
            "reference_validation_nmse": self._reference_score(),
            "level": level,
            "winner": key,
            "winner_summary": winner.label if winner else None,
            "cautious": choice.cautious if choice else [],
            "notes": notes,
            "interrupted": self.interrupted,
            "safety_limit": self.limited,
            "refit": self.refit if winner else {"refitted": False},
            "seconds": round(time.monotonic() - self.started, 3),
            "candidates": [e.to_json() for e in entries],
        }


def phase_note(period: int, folds: int) -> str:
    """Why and how a search whose validation split repeats the training input ranks its candidates (mode
    'phase', :func:`.views.phase_fold`)."""
    return (
        f"the validation input repeats the training input (a periodic excitation of {period} samples), so it "
        f"cannot tell how a model does on a new input: each 1/{folds} of the period was held out of every "
        "period's training in turn and validated in the last period, and the choice refitted on the whole "
        "training split"
    )


def tail_note(folds: int, planned: bool = False) -> str:
    """Why and how a search without a validation split ranks its candidates (mode 'tail')."""
    are, is_ = ("are", "is") if planned else ("were", "was")
    return (
        f"there is no validation split: the candidates {are} ranked on their free run over the last 1/{folds} "
        f"of every training recording, held out from their fits, and the chosen one {is_} fitted again on all "
        "of it with its choices frozen, where its family can (else kept as fitted on the rest); add a validation "
        "split, e.g. split: {train: 0.8, validation: 0.2}, to choose where it lies"
    )


def keeps_a_fold(mode: str, ds: Dataset) -> bool:
    """Cross-validated data without a validation split (``split: {train: 0.7, test: 0.3}`` on a short record, or
    recordings left out in turn, none with a validation part): a fit on the whole training split would have
    nothing to choose its terms, ridge factor or training length on (the NARX default's term search, the annealed
    network's schedule: each refuses), so the model kept is a fold's fit, validated where it was held out."""
    return mode in ("folds", "recordings") and not ds.n_scored("validation")


def _with_validation(spec: Spec) -> str:
    """A split with a validation part, for a spec that has none: its test part kept when it has one."""
    split = spec.resolved()["data"].get("split") or {}
    return "{train: 0.6, validation: 0.2, test: 0.2}" if split.get("test") else "{train: 0.8, validation: 0.2}"


def describe_plan(spec: Spec, ds: Dataset) -> list[str]:
    """What ``dynmodel validate`` says about an auto spec: the families, the budget, the layout, the
    protocol limits and the starting candidates (nothing is fitted)."""
    params: AutoParams = spec.model.params
    written = spec.cost if "cost" in spec.model_fields_set else None
    ctx, ranking = context(spec, ds, params, written)
    mode, k, short = ranking.mode, ranking.folds, ranking.short
    families = searchable_families()
    chosen = params.families or list(families)
    lines = [
        f"family: auto searches {', '.join(chosen)} with a budget of {params.budget:g} s (planned for 2 cores), "
        f"{params.seeds} seed(s) per random configuration"
    ]
    if mode == "folds":
        first = "" if len(validated_folds(ds, k)) == k else "; the first block, where the free run starts, only trains"
        lines.append(
            f"ranking: blocked cross-validation in {k} blocks of the training and validation samples ({short}){first}"
        )
    elif mode == "recordings":
        lines.append(f"ranking: free-run NMSE on {ranking.left_out()}, the model trained on the others")
    elif mode == "tail":
        lines.append(f"ranking: {tail_note(k, planned=True)}")
    elif mode == "phase":
        lines.append(f"ranking: {short}")
    else:
        n = min(SCREEN_SAMPLES, ctx.n_train)
        lines.append(
            f"ranking: free-run NMSE on the validation split ({ctx.n_validation} scored samples); candidates are "
            f"screened on {n} training samples first, the best refitted on all {ctx.n_train}"
        )
    held = (
        "the recording left out whose fit trained on the most samples"
        if mode == "recordings"
        else "the last block held out"
    )
    if keeps_a_fold(mode, ds):
        lines.append(
            "final model: there is no validation split, so the chosen candidate is fitted again on the whole "
            "training split with its choices made on validation frozen, where its family can; otherwise it is "
            f"kept as fitted with {held} (a fit on the whole training split would have nothing to choose its size "
            f"on; add a validation split, e.g. split: {_with_validation(spec)}, to fit it on more data)"
        )
    else:
        which = "the chosen candidate"
        if mode in CROSS_VALIDATED:
            which += (
                f" (fitted on the spec's split, or as validated with {held}, when that fits those samples more than "
                f"{FOLD_BETTER:g} x better)"
            )
        lines.append(
            f"final model: {which} is fitted again on the training and validation samples together, "
            "with its choices made on validation frozen (a structure, a factor), where its family can"
        )
    if ctx.max_warmup is not None:
        lines.append(f"the protocol lets a run start from at most {ctx.max_warmup} measured outputs")
    held_out = Layout("fold", fold=k - 1, folds=k, period=ranking.period)
    fresh = fresh_weight(ds, held_out if mode in ("folds", "tail", "phase") else Layout("full"))
    if fresh is not None:
        lines.append(
            "the test data start recordings of their own: each validation run is also started afresh, as a test "
            f"recording is, and that start counts with weight {fresh[1]:.2g} (validation over test length)"
        )
    caution = ranking.repeat_caution()
    if caution is not None:
        lines.append(caution)
    if ctx.excursion > 0.05:
        lines.append(
            f"the validation or test inputs leave the training range by up to {100 * ctx.excursion:.0f} % of its width: simpler, "
            "bounded candidates are preferred"
        )
    if ctx.positions:
        lines.append(
            f"inputs that move like a position: {', '.join(ctx.positions)} (the families may offer the direction of "
            "motion and the travel since the last reversal as inputs: friction, hysteresis)"
        )
    if ctx.signed:
        lines.append(
            f"of those, inputs that change sign: {', '.join(ctx.signed)} (a velocity: the families may offer its sign "
            "as an input, on which a Coulomb or LuGre force switches)"
        )
    if ctx.dead_times:
        delays = ", ".join(f"{name} after {d} samples" for name, d in ctx.dead_times.items())
        lines.append(f"inputs that act after a dead time: {delays} (the families may offer lags from it)")
    if written:
        lines.append(f"every candidate uses the cost you wrote ({written})")
    for name in chosen:
        cands = candidates_of(families[name], ctx)
        work = sum(estimated_work(c, ctx) for c in cands)
        lines.append(f"{name}: {len(cands)} starting candidates (about {work:.0f} s of fits on one core)")
    return lines


def record_json(record: dict[str, Any]) -> str:
    return json.dumps(record, default=str)
