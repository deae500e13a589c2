"""The data a search candidate is fitted and validated on: views of the spec's dataset.

A view keeps the training and validation samples of the dataset and drops every other split (test sets),
so a fit inside the search cannot read a test output: the search's checks on test *inputs* run separately
(:mod:`.checks`). The layouts:

* ``full``: the spec's own training and validation splits;
* ``screen``: the same, with the training split cut to its last ``samples`` samples (spread over the
  training ranges in proportion to their lengths): candidates are ranked cheaply on part of the data
  first, the survivors refitted on all of it (successive halving);
* ``fold i of k``: blocked cross-validation for short data. The training and validation samples of every
  recording (adjacent ranges merged into one span) are cut into ``k`` consecutive blocks; fold ``i``
  validates on block ``i`` of every span and trains on the others. A validation block continues the free
  run of its recording (as a validation split that follows the training split does); when the spec's
  validation split has an initialization window, the block is a recording of its own with that window;
  without one the first block is never validated (:func:`validated_folds`);
* ``recording i of k``: leave one recording out, when the training and validation samples come from
  :data:`MIN_RECORDINGS` or more recordings (runs at other operating conditions: other pressures, loads,
  amplitudes). Fold ``i`` validates on all of recording ``i``'s training and validation samples, trained
  on the other recordings': how well a model carries over to a recording it has not seen, which is what
  a test recording asks and a validation split taken from the same recordings cannot tell (the search leaves
  out only those between the others' operating conditions, :func:`interior_recordings`, when the test inputs
  stay inside the training range);
* ``all``: every training and validation sample as training, no validation: the chosen configuration's refit
  (its choices made on validation frozen);
* ``fold k of k`` alone: long data without a validation split (the spec's split is training only) are
  ranked on the last block of every span, held out, never on the training error.

A fold or a recording left out can also cut its training to its last ``samples`` samples, as ``screen``
does: the screening variant on long data.

**The start of a test recording.** When every test set starts free runs of its own (a separate test file,
or a test range given an initialization window) while the validation split continues the free run of its
training recording, :func:`view` with ``fresh`` gives the same layout with each validation range (or
block, or held-out tail) as a recording of its own, started as a test recording is (:func:`test_start`). The
search scores a candidate on both (:mod:`.worker`): a model that starts from its zero state (an internal
network) or from rest carries a start-up transient on every test recording, which the continuation hides.

Every layout is a deterministic function of the dataset and its arguments.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..data.dataset import Dataset, Recording, compact_ranges, last_samples, own_runs
from ..data.repeats import repeats_training

FIT_SPLITS = ("train", "validation")
#: smallest validation block of a fold (samples)
MIN_BLOCK = 20
#: leave one recording out when the fitting data hold at least this many recordings
MIN_RECORDINGS = 3
#: a recording left out is between the others' operating conditions when each input's mean goes beyond the others'
#: means by at most this fraction of the input's standard deviation over every recording (a level held with noise
#: moves its mean by a fraction of that noise) ...
INSIDE_LEVEL = 0.25
#: ... and its standard deviation beyond theirs by at most this fraction of the largest (:func:`interior_recordings`)
INSIDE_SPREAD = 0.1


@dataclass(frozen=True)
class Layout:
    kind: str = "full"  # "full" | "screen" | "fold" | "recording" | "all"
    samples: int = 0  # screen, and a screened fold or recording left out: training samples kept; 0 all
    fold: int = 0
    folds: int = 0
    period: int = 0  # fold: the period of a periodic excitation whose phases are held out (0: blocks in time)

    @property
    def label(self) -> str:
        name = {
            "screen": "screen",
            "fold": f"{'phase' if self.period else 'fold'} {self.fold + 1}/{self.folds}",
            "recording": f"recording {self.fold + 1}/{self.folds} left out",
            "all": "training and validation together",
        }.get(self.kind, "full")
        return f"{name} ({self.samples} training samples)" if self.samples else name

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _windows(ds: Dataset) -> dict[str, int]:
    return dict(getattr(ds, "windows", {}) or {})


def _rebuild(ds: Dataset, recordings: list[Recording], ranges: dict[str, list[tuple[int, int, int]]]) -> Dataset:
    """``ds`` with other recordings and ranges; split-keyed settings of dropped splits removed."""
    changes: dict[str, Any] = {"recordings": recordings, "ranges": ranges}
    for name in ("windows", "lead_in", "noise_std"):
        value = getattr(ds, name, None)
        if isinstance(value, dict):
            changes[name] = {k: v for k, v in value.items() if k in ranges}
    if isinstance(getattr(ds, "score_all", None), set):
        changes["score_all"] = {k for k in ds.score_all if k in ranges}
    return dataclasses.replace(ds, **changes)


def _cut(rec: Recording, start: int, stop: int, name: str | None = None) -> Recording:
    """Samples [start, stop) of a recording as a recording of its own (arrays shared, not copied)."""
    out = dataclasses.replace(rec, u=rec.u[start:stop], y=rec.y[start:stop])
    if name is not None:
        out.name = name
    if hasattr(out, "offset"):
        out.offset = int(getattr(rec, "offset", 0)) + start
    return out


def screen(ds: Dataset, samples: int | None) -> Dataset:
    """The training split cut to its last ``samples`` samples (None: all of it), validation unchanged,
    test sets dropped; recordings start at their first kept sample."""
    pieces: dict[str, list[tuple[int, int, int]]] = {"train": last_samples(ds.ranges.get("train", []), samples)}
    if ds.ranges.get("validation"):
        pieces["validation"] = list(ds.ranges["validation"])
    return _compact(ds, pieces)


def _compact(ds: Dataset, pieces: dict[str, list[tuple[int, int, int]]]) -> Dataset:
    """Recordings that hold any of ``pieces``, each cut to [first piece start, last piece stop)."""
    cuts, ranges = compact_ranges(pieces)
    recordings = [
        ds.recordings[r] if (a, b) == (0, ds.recordings[r].n) else _cut(ds.recordings[r], a, b) for r, a, b in cuts
    ]
    renumbered = {r: i for i, (r, _, _) in enumerate(cuts)}  # a run cut from a recording keeps pointing at it
    recordings = [
        rec if rec.origin is None else dataclasses.replace(rec, origin=renumbered.get(rec.origin)) for rec in recordings
    ]
    return _rebuild(ds, recordings, ranges)


def spans(ds: Dataset) -> list[tuple[int, int, int]]:
    """The training and validation ranges of every recording, adjacent ones merged, in recording order."""
    rows = sorted((r, a, b) for s in FIT_SPLITS for r, a, b in ds.ranges.get(s, []))
    merged: list[list[int]] = []
    for r, a, b in rows:
        if merged and merged[-1][0] == r and merged[-1][2] >= a:
            merged[-1][2] = max(merged[-1][2], b)
        else:
            merged.append([r, a, b])
    return [(r, a, b) for r, a, b in merged]


#: a test recording whose inputs stay within HELD_BY x the training input range of their first value over
#: its first HELD_SAMPLES samples starts at rest (a rig at standstill): a model's start from rest is its own
HELD_SAMPLES = 10
HELD_BY = 1e-3


def _held_start(ds: Dataset, recs: list[int]) -> bool:
    """Do the inputs of any recording of ``recs`` stay at their first value over its first
    :data:`HELD_SAMPLES` samples (within :data:`HELD_BY` of the training input range; without a training
    split, of that recording's own range)?"""
    import numpy as np

    def width(u):
        return np.nanmax(u, axis=0) - np.nanmin(u, axis=0)

    train = width(ds.concat_inputs("train")[0]) if ds.ranges.get("train") else None
    for rec in recs:
        head = ds.recordings[rec].u[:HELD_SAMPLES]
        scale = train if train is not None else width(ds.recordings[rec].u)
        if np.all(np.nanmax(np.abs(head - head[0]), axis=0) <= HELD_BY * scale):
            return True
    return False


def test_start(ds: Dataset) -> tuple[bool, int, bool]:
    """(fresh, window, whole): ``fresh`` when every test range starts a free run of its own (a recording that
    holds no training or validation sample, from its first sample) while the validation does not (it has no
    window of its own and is not scored whole), and, without a test window, no test recording starts at rest
    (its inputs held, :func:`_held_start`: a model started from rest then starts as the system does, and a
    validation run cut from the middle of the motion would count a transient the test does not have; a
    generated friction plant: 3.1 % test NMSE where counting it chose a model with 287 %); ``window``: the
    smallest initialization window of the test sets (0 without one) and ``whole``: every test set is scored
    whole (from rest, no measured output), which validation runs of their own then follow."""
    tests = [s for s in ds.ranges if s not in FIT_SPLITS and ds.ranges[s]]
    every = getattr(ds, "score_all", None) or set()
    if not tests or "validation" in _windows(ds) or "validation" in every:
        return False, 0, False
    fitting = {r for s in FIT_SPLITS for r, _, _ in ds.ranges.get(s, [])}
    if not all(r not in fitting and a == 0 for s in tests for r, a, _ in ds.ranges[s]):
        return False, 0, False
    window = min((_windows(ds).get(s, 0) for s in tests), default=0)
    if not window and _held_start(ds, [r for s in tests for r, _, _ in ds.ranges[s]]):
        return False, 0, False
    return True, window, all(s in every for s in tests)


def _own_validation_runs(ds: Dataset) -> Dataset:
    """Every validation range that starts inside a recording as a recording of its own (its free run starts
    at its first sample), as the data loader does for a split with an initialization window."""
    recordings, ranges = list(ds.recordings), {k: list(v) for k, v in ds.ranges.items()}
    own_runs(recordings, ranges, {"validation"})
    return _rebuild(ds, recordings, ranges)


def possible_folds(ds: Dataset, wanted: int, min_block: int = MIN_BLOCK) -> int:
    """The number of folds (at most ``wanted``, at least 2, or 0 when even 2 do not fit) whose validation
    blocks keep at least ``min_block`` scored samples after the transient and the validation window."""
    window = _windows(ds).get("validation", 0)
    longest = max((b - a for _, a, b in spans(ds)), default=0)
    for k in range(wanted, 1, -1):
        if longest // k - ds.transient - window >= min_block:
            return k
    return 0


def validated_folds(ds: Dataset, k: int) -> list[int]:
    """The folds of ``k`` that are validated. Without a validation window, not the first: its block is where
    the free run of the recording starts, so a model with an internal state (a network) would be scored on
    its start-up transient, which a validation or test split that follows the training split never shows
    (on a short seal-friction record that one block made a network look five times worse than it is). The
    first block is then always training. With a window every block is a run of its own that starts from
    it, as the protocol's test sets do, and every fold is validated."""
    if _windows(ds).get("validation", 0) or k < 2:
        return list(range(k))
    return list(range(1, k))


def fold(ds: Dataset, i: int, k: int, apart: bool = False) -> Dataset:
    """Fold ``i`` of ``k`` (see the module docstring); ``apart``: every validation block a run of its own
    even without a validation window."""
    window = _windows(ds).get("validation", 0)
    train: list[tuple[int, int, int]] = []
    val: list[tuple[int, int, int]] = []
    recordings = list(ds.recordings)
    separate: list[tuple[int, int, int]] = []
    for r, a, b in spans(ds):
        n = b - a
        lo, hi = a + (i * n) // k, a + ((i + 1) * n) // k
        if lo > a:
            train.append((r, a, lo))
        if hi < b:
            train.append((r, hi, b))
        if window or apart:
            separate.append((r, lo, hi))
        else:
            val.append((r, lo, hi))
    for r, lo, hi in separate:
        rec = ds.recordings[r]
        recordings.append(_cut(rec, lo, hi, f"validation:{rec.name}[{lo}:{hi}]"))
        val.append((len(recordings) - 1, 0, hi - lo))
    pieces = {"train": train, "validation": val}
    out = _rebuild(ds, recordings, {s: rows for s, rows in pieces.items() if rows})
    return _compact(out, {s: rows for s, rows in pieces.items() if rows})


def _by_recording(ds: Dataset) -> list[list[tuple[int, int, int]]]:
    """The spans of every recording that holds training or validation samples, in recording order, each with
    the runs cut from it (a validation split with an initialization window is a run of its own of the same
    recording: the CED benchmark's two recordings were left out as four)."""
    groups: dict[int, list[tuple[int, int, int]]] = {}
    for r, a, b in spans(ds):
        origin = ds.recordings[r].origin
        groups.setdefault(r if origin is None else origin, []).append((r, a, b))
    return [groups[r] for r in sorted(groups)]


def possible_recording_folds(ds: Dataset, min_recordings: int = MIN_RECORDINGS) -> int:
    """The number of recordings to leave out in turn (0 when fewer than ``min_recordings`` hold fitting data,
    or one of them is too short to validate ``MIN_BLOCK`` samples after the transient and the window)."""
    groups = _by_recording(ds)
    if len(groups) < min_recordings:
        return 0
    window = _windows(ds).get("validation", 0)
    for g in groups:
        if max(b - a for _, a, b in g) - ds.transient - window < MIN_BLOCK:
            return 0
    return len(groups)


def interior_recordings(ds: Dataset) -> list[int]:
    """The recordings (indices as in :func:`recording_fold`) at operating conditions between the others': for
    every input, its mean and its standard deviation lie inside the range of the other recordings' means
    (widened by :data:`INSIDE_LEVEL` x the input's standard deviation over every recording) and of their standard
    deviations (widened by :data:`INSIDE_SPREAD` of their largest). Left out, such a recording asks a model to
    carry over between operating conditions (a pressure between two others, an amplitude between two others),
    not beyond them; the recordings of one excitation repeated are every one inside."""
    groups = _by_recording(ds)
    inputs = [np.concatenate([ds.recordings[r].u[a:b] for r, a, b in g]) for g in groups]
    means = np.array([np.nanmean(u, axis=0) for u in inputs])
    stds = np.array([np.nanstd(u, axis=0) for u in inputs])
    spread = np.nanstd(np.concatenate(inputs), axis=0)
    inside = []
    for i in range(len(groups)):
        others = np.arange(len(groups)) != i
        lo, hi = means[others].min(axis=0) - INSIDE_LEVEL * spread, means[others].max(axis=0) + INSIDE_LEVEL * spread
        top = stds[others].max(axis=0)
        slo, shi = stds[others].min(axis=0) - INSIDE_SPREAD * top, top * (1.0 + INSIDE_SPREAD)
        if np.all((means[i] >= lo) & (means[i] <= hi) & (stds[i] >= slo) & (stds[i] <= shi)):
            inside.append(i)
    return inside


def recording_fold(ds: Dataset, i: int) -> Dataset:
    """Recording ``i`` (of those with fitting data) as the validation, the others as training."""
    groups = _by_recording(ds)
    train = [s for j, g in enumerate(groups) if j != i for s in g]
    val = list(groups[i])
    return _compact(ds, {"train": train, "validation": val})


def view(ds: Dataset, layout: Layout, fresh: tuple[int, bool] | None = None) -> Dataset:
    """The dataset a candidate is fitted on under ``layout``: the split of the layout's kind, then its
    training cut to the last ``layout.samples`` samples (0: all). ``fresh``: (window, whole) of test sets that
    start runs of their own (:func:`test_start`): every validation range a run of its own, started as they
    are (from that window, or scored whole)."""
    if fresh is not None:
        window, whole = fresh
        if window:
            ds = dataclasses.replace(ds, windows={**_windows(ds), "validation": window})
        if whole:
            ds = dataclasses.replace(ds, score_all={*ds.score_all, "validation"})
    if layout.kind == "fold" and layout.period:
        ds = phase_fold(ds, layout.fold, layout.folds, layout.period)
        if fresh is not None:
            ds = _own_validation_runs(ds)
    elif layout.kind == "fold":
        ds = fold(ds, layout.fold, layout.folds, apart=fresh is not None)
    elif layout.kind == "recording":
        ds = recording_fold(ds, layout.fold)
    elif layout.kind == "all":
        ds = _compact(ds, {"train": spans(ds)})
    elif fresh is not None:
        ds = _own_validation_runs(ds)
    return screen(ds, layout.samples or None)


def repeated_validation(ds: Dataset, layout: Layout) -> dict[str, Any] | None:
    """The finding of :func:`~dynmodel.data.repeats.repeats_training` when the validation input of ``layout``
    repeats its training input (a periodic excitation split period by period) while a test input does not, or
    there is no test set (the model will meet new inputs); None otherwise. A test set that repeats the training
    input too is scored on that input again, and the validation then ranks candidates as it does."""
    found = repeats_training(view(ds, layout), "validation")
    if found is None:
        return None
    tests = [s for s in ds.ranges if s not in FIT_SPLITS and ds.ranges[s]]
    if tests and all(repeats_training(ds, s) is not None for s in tests):
        return None
    return found


def phase_fold(ds: Dataset, i: int, k: int, period: int) -> Dataset:
    """Fold ``i`` of ``k`` of a periodic excitation whose validation split repeats the training input: the
    ``i``-th of ``k`` consecutive phase windows of the period, counted back from the end of the last validation
    range, is held out of every period of that recording, and its copy in the last period validates. So the
    validation shows every model a stretch of the input that no training sample holds, which the spec's
    validation split (another period) does not. The validation window continues the free run of the training
    samples before it; other recordings train whole."""
    r, _, b = ds.ranges["validation"][-1]
    lo_phase, hi_phase = (i * period) // k, ((i + 1) * period) // k
    start = b - period  # the last period
    train: list[tuple[int, int, int]] = []
    for rr, a0, b0 in spans(ds):
        if rr != r:
            train.append((rr, a0, b0))
            continue
        pos = a0
        shift = -((start - a0) // period) * period - period  # the copy of the window that starts before a0
        while start + shift + lo_phase < b0:
            lo, hi = max(start + shift + lo_phase, a0), min(start + shift + hi_phase, b0)
            if lo < hi:
                if pos < lo:
                    train.append((rr, pos, lo))
                pos = max(pos, hi)
            shift += period
        if pos < b0:
            train.append((rr, pos, b0))
    return _compact(ds, {"train": train, "validation": [(r, start + lo_phase, start + hi_phase)]})
