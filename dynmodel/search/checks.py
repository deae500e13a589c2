"""What the search checks on a fitted candidate beyond its validation error, reading only **inputs** of the test
sets (and the outputs of training and validation, which it may read).

The *band check*: the candidate's free run on the inputs of every split (training, validation, every test
set) must stay inside the training output range widened by :data:`BAND` of its width on each side (on the
validation split, the range of its measured outputs too: :func:`measured_band`). A run that leaves it
diverges or extrapolates wildly where the data give no evidence; a run held at an output clip set at (or
beyond) that band counts as leaving it (the clip hides the divergence). Test outputs are never read. What
counts as leaving:

* a non-finite output, or one beyond an outer band of :data:`OUTER_BAND` widths on each side;
* more than :data:`BRIEF` samples in a row, or more than :data:`STRAY` of the scored samples, outside the
  band.

A diverging run does not come back (a run held at an output clip stays at the band's edge), so it fails;
a model that overshoots a peak for a few samples passes. On 300 training samples tested on 4000, the band
had rejected the NARX default (1.6 % test NMSE) for a two-sample overshoot of fold models, and kept a
network with 18 %. Where a test input goes beyond the training input range, the band is not widened:
forgiving a run there while that input lies beyond (EMPS: 58 %) let a NARX model drift to 143 mm test
RMSE where the band kept one with 10.5 mm. Unless the system is about linear (the search decides: the linear
reference, or a candidate affine in its input, validates about as well as the best, ``Search._decide_band``): then a split's band also covers the range of
the linear reference's own free run on that split's input, widened as the training range is (the
*linear-system band*, given as ``checks["wide"]`` where it differs; a run standing still beyond the strict band
while its input moves, held at an output clip, still leaves it, and one cut flat at a clip there is named in
``checks["wide"]["clipped"]``, see :func:`_flat_top`). A linear model's output goes beyond the
training range as far as its input, or its drift (an integrator: a cart's position), takes it; without it, a
linear plant tested at three times its training amplitude had every linear candidate rejected, and a
saturating network kept. A candidate whose own run is affine in its input (:data:`AFFINE`) gets
:data:`AFFINE_BAND` more on each side there: where the linear reference itself fits poorly (a lightly damped
resonance heavily oversampled), its run says little about how far the output goes.

A recording that starts inside a test split starts as its evaluation will, as far as its inputs tell: from
the measured outputs of its initialization window when the protocol declares one that covers the model's
tune-in; from the model's own zero state when the model reads no measured output (its evaluation starts
there too: a network, an output-error model, every sample scored). A model that starts from measured
outputs on a test without a protocol (the evaluation reads its first ones, the search may not) has no start
its inputs can tell: it is run from rest (every past output at the training mean) and, where that run
leaves the band, again **settled** (from rest, its first input held for :data:`SETTLE` samples before the
first, so that its own run brings it to a system at rest at that input), and it leaves the band only where
both runs do. Each start alone meets a state some data never show: from rest, the outputs at their mean
while the input moves elsewhere (a generated backlash: the NARX default, 0.037 % test NMSE from measured
outputs, went from there into a cycle between its output clips and was rejected, and the search chose a
network with 0.194 %); settled, an input held still where the training data never hold it (4000 samples of
the Bouc-Wen multisine and a kidney-bore seal: the NARX models chosen from rest, 0.19 and 0.34 %, left the
band settled, and the search then chose models with 7.8 and 0.52 %).

The *measured starts* (:func:`measured_starts`, outputs the search reads): a model that starts from measured
outputs is also run from :data:`STARTS` points spread over the training and validation data, each from the
measured outputs before it, as a prediction from a user's tune-in starts; where at least :data:`STRAYED` of those
runs stray from the output (and from what the run from the recording's start does there), it fails as a run
leaving the band does. One start, the validation's, cannot tell a model whose state a short tune-in sets from
one it leaves in the wrong basin.

The *input dependence* (:func:`dynmodel.usefulness.input_dependence`, on the view's validation split): a
model whose free run barely moves when the input is held at its mean ignores its input.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..data.dataset import Dataset, continued_range
from ..model import FittedModel
from .views import FIT_SPLITS

#: the band around the training output range, in range widths on each side
BAND = 0.5
#: a run within this fraction of the band's margin from its edge counts as having reached it (an output
#: clip at exactly the band holds a diverging run there)
EDGE = 0.02
#: the outer band, in training output range widths on each side
OUTER_BAND = 2 * BAND
#: a run may leave the band for at most this many samples in a row ...
BRIEF = 20
#: ... and this fraction of the scored samples
STRAY = 0.01
#: samples a settled start holds a test recording's first input for, before its first sample
SETTLE = 200
#: a candidate whose run is this close to affine in its input (:func:`dynmodel.usefulness.input_nonlinearity`)
#: counts as a linear model ...
AFFINE = 1e-4


def affine(nonlinearity: float | None) -> bool:
    """Whether a candidate's measured ``input_nonlinearity`` says its free run is affine in its input."""
    return nonlinearity is not None and nonlinearity < AFFINE


#: ... and under the linear-system band its own band is wider by this many training output range widths on each
#: side (a lightly damped resonance tested on another input realization: the true output goes 0.53 widths beyond)
AFFINE_BAND = 0.5


def band(ds: Dataset) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(low, high, width) per output: the training output range widened by BAND x its width (less the
    edge) on each side, and that range's width."""
    y = ds.concat_outputs("train")
    lo, hi = np.nanmin(y, axis=0), np.nanmax(y, axis=0)
    width = np.maximum(hi - lo, np.finfo(float).tiny)
    margin = BAND * (1.0 - EDGE) * width
    return lo - margin, hi + margin, width


def measured_band(
    ds: Dataset, split: str, lo: np.ndarray, hi: np.ndarray, margin: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The band (lo, hi) of ``split``, widened on the validation split to its measured outputs in the
    recordings that hold training samples (:func:`~dynmodel.data.dataset.continued_range`) and the same
    ``margin`` beyond them: a block held out for cross-validation can hold the recording's largest excursion,
    and a run that follows it there is right. Test outputs are never read."""
    measured = None
    if split == "validation":
        outputs = [rec.y for rec in ds.recordings]
        measured = continued_range(outputs, ds.ranges.get(split, []), ds.ranges.get("train", []))
    if measured is None:
        return lo, hi
    return np.fmin(lo, measured[0] - margin), np.fmax(hi, measured[1] + margin)


def _longest_run(mask: np.ndarray) -> int:
    """The longest stretch of consecutive True in ``mask``."""
    if not mask.any():
        return 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return int((edges[1::2] - edges[::2]).max())


def _leaves(seg: np.ndarray, lo: np.ndarray, hi: np.ndarray, width: np.ndarray) -> int | None:
    """The first sample where the run ``seg`` counts as leaving the band (lo, hi) (see the module
    docstring), or None; ``width``: the training output range's."""
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(seg).all(axis=1)
        outside = ~finite | ((seg < lo) | (seg > hi)).any(axis=1)
        if not outside.any():
            return None
        margin = (OUTER_BAND - BAND * (1.0 - EDGE)) * width
        far = ~finite | ((seg < lo - margin) | (seg > hi + margin)).any(axis=1)
    if far.any():
        return int(np.argmax(far))
    if _longest_run(outside) > BRIEF or outside.sum() > STRAY * len(seg):
        return int(np.argmax(outside))
    return None


def _held(
    seg: np.ndarray, lo: np.ndarray, hi: np.ndarray, width: np.ndarray, u: np.ndarray | None = None
) -> int | None:
    """The first sample of a stretch of more than :data:`BRIEF` samples where the run ``seg`` stands still
    beyond the strict band (lo, hi) while its input ``u`` moves (None: not compared): held at an output clip
    (a linear system's run moves with its input, and stands still only where its input is held), or None."""
    if len(seg) < 2:
        return None
    with np.errstate(invalid="ignore"):
        still = (np.abs(np.diff(seg, axis=0)) <= 1e-12 * width).all(axis=1)
        beyond = ((seg[1:] < lo) | (seg[1:] > hi)).any(axis=1)
    held = np.asarray(still & beyond)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], held.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        if b - a > BRIEF and (u is None or not (u[a + 1 : b + 1] == u[a + 1]).all()):
            return int(a) + 1
    return None


def _flat_top(seg: np.ndarray, u: np.ndarray | None, lo: np.ndarray, hi: np.ndarray) -> int | None:
    """The first sample of a flat top beyond the strict band (lo, hi): the run's extreme beyond it reached at two
    samples or more whose inputs differ (an output clip cut every peak there; a run's own dynamics do not come
    back to the same extreme exactly, and a run at rest under a held input is no clip), or None. ``u``: the
    inputs of the same samples (None: not compared)."""
    first: int | None = None
    with np.errstate(invalid="ignore"):
        for j in range(seg.shape[1]):
            col = seg[:, j]
            for beyond, pick in ((col > hi[j], np.max), (col < lo[j], np.min)):
                if beyond.sum() < 2:
                    continue
                at = np.flatnonzero(col == pick(col[beyond]))
                if len(at) < 2 or (u is not None and (u[at] == u[at[0]]).all()):
                    continue
                first = int(at[0]) if first is None else min(first, int(at[0]))
    return first


def _outside(
    seg: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    width: np.ndarray,
    u: np.ndarray | None = None,
):
    """:func:`_leaves` the band (low, high); where that is wider than the strict band (lo, hi), also a run held
    still beyond the strict band while its input ``u`` moves (:func:`_held`: at an output clip the wider band
    would hide)."""
    first = _leaves(seg, low, high, width)
    if (low < lo).any() or (high > hi).any():
        held = _held(seg, lo, hi, width, u)
        if held is not None and (first is None or held < first):
            return held
    return first


def _fit_rows(ds: Dataset) -> set[tuple[int, int]]:
    """(recording, sample) starts that lie inside a training or validation range."""
    return {(r, a) for s in ("train", "validation") for r, a, _ in ds.ranges.get(s, [])}


def _start_outputs(ds: Dataset, split: str, rec: int, warmup: int, train_mean: np.ndarray) -> tuple[np.ndarray, str]:
    """The measured outputs a run of recording ``rec`` may start from, and how: 'measured', 'window', 'rest'
    (the model's zero state), or 'either' (the training mean; the run may also start settled, see the module
    docstring)."""
    r = ds.recordings[rec]
    if warmup == 0:
        return np.empty((0, r.y.shape[1])), "rest"
    inside_fit = any(rr == rec and a == 0 for s in ("train", "validation") for rr, a, _ in ds.ranges.get(s, []))
    if inside_fit:
        return r.y[:warmup], "measured"
    window = (getattr(ds, "windows", {}) or {}).get(split)
    if window is not None and window >= warmup and np.isfinite(r.y[:warmup]).all():
        return r.y[:warmup], "window"
    return np.broadcast_to(train_mean, (warmup, r.y.shape[1])).copy(), "either"


def _run(model: FittedModel, rec: Any, start: np.ndarray | None, settle: int = 0) -> np.ndarray:
    """The free run of ``model`` on recording ``rec``'s inputs from ``start``, its first input held ``settle``
    samples before the first (when finite); NaN where the run failed."""
    u = rec.u
    pre = settle if len(u) and np.isfinite(u[0]).all() else 0
    try:
        run = model.run(np.concatenate([np.repeat(u[:1], pre, axis=0), u]) if pre else u, start)
        return np.asarray(run.y)[pre:]
    except (ValueError, FloatingPointError):
        return np.full_like(rec.y, np.nan)


#: per recording: its free run from its usual start, how that start was read, and the past outputs it started from
UsualRuns = dict[int, tuple[np.ndarray, str, np.ndarray]]


def usual_runs(model: FittedModel, ds: Dataset) -> UsualRuns:
    """Every recording's free run from the start its inputs tell (:func:`_start_outputs`), as its split (the first
    that scores it) starts it; shared by :func:`band_checks` and :func:`start_memory`."""
    train_mean = np.nanmean(ds.concat_outputs("train"), axis=0)
    warm = model.warmup
    owner: dict[int, str] = {}
    for split in ds.splits():
        for rec, _, _ in ds.ranges.get(split, []):
            owner.setdefault(rec, split)
    runs: UsualRuns = {}
    for rec, split in sorted(owner.items()):
        start, how = _start_outputs(ds, split, rec, warm, train_mean)
        runs[rec] = (_run(model, ds.recordings[rec], start if warm else None), how, start)
    return runs


#: samples kept of each test split's free run (every k-th), for the spread of a candidate's fits there
SPREAD_SAMPLES = 2000


def test_runs(ds: Dataset, runs: UsualRuns, warmup: int = 0) -> dict[str, np.ndarray]:
    """The free runs over every test split (inputs only: the runs of :func:`usual_runs`), each output divided by
    the training outputs' standard deviation, at most :data:`SPREAD_SAMPLES` samples each (every k-th from the
    range's start, so that the fits of one candidate share a grid whatever their tune-in); NaN before the first
    sample the evaluation scores (``ds.scored``: the transient, the initialization window, the model's
    ``warmup``, as the band check reads them), which :func:`spread` leaves out. Keys ``split:recording:start``."""
    std = np.nanstd(ds.concat_outputs("train"), axis=0)
    std = np.where(std > 0, std, 1.0)
    out: dict[str, np.ndarray] = {}
    for split in ds.splits():
        if not split.startswith("test"):
            continue
        scored = {(rec, b): first for rec, first, b in ds.scored(split, warmup)}
        for rec, a, b in ds.ranges.get(split, []):
            if rec in runs and b > a:
                step = max(1, -(-(b - a) // SPREAD_SAMPLES))
                run = runs[rec][0][a:b:step] / std
                unscored = -(-(scored.get((rec, b), b) - a) // step)  # grid samples before the first scored
                run[:unscored] = np.nan
                out[f"{split}:{rec}:{a}"] = np.ascontiguousarray(run)
    return out


def pair_differences(runs: list[dict[str, np.ndarray]]) -> list[float]:
    """How far each pair of a candidate's fits (its seeds, its folds) part ways on the test inputs: their runs' mean
    squared difference, in % of the training output variance (:func:`test_runs`). For any pair,
    ||a - b||^2 <= 2 (||a - y||^2 + ||b - y||^2), so the pair's mean squared error on the test (against the training
    output variance) is at least a quarter of their difference, whatever the test outputs are. Each pair is compared
    where both runs are finite: the samples the evaluation scores for both (NaN before, :func:`test_runs`)."""
    diffs = []
    for i in range(len(runs)):
        for j in range(i + 1, len(runs)):
            shared = [k for k in runs[i] if k in runs[j]]
            if not shared:
                continue
            d = np.concatenate([(runs[i][k] - runs[j][k]).ravel() for k in shared])
            d = d[np.isfinite(d)]
            if d.size:
                diffs.append(100.0 * float(np.mean(d * d)))
    return diffs


def median_difference(diffs: list[float]) -> float | None:
    """The median of :func:`pair_differences`; None without a pair (fewer than two fits, or no test split)."""
    return float(np.median(diffs)) if diffs else None


def spread(runs: list[dict[str, np.ndarray]]) -> float | None:
    """How far the fits of one candidate part ways on the test inputs: the median over pairs of fits
    (:func:`median_difference` of :func:`pair_differences`)."""
    return median_difference(pair_differences(runs))


def band_checks(
    model: FittedModel,
    ds: Dataset,
    envelope: dict[str, Any] | None = None,
    affine: bool = False,
    runs: UsualRuns | None = None,
    starts: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Per split: ``{"ok": bool, "start": how runs started, "sample": first sample outside the band or None,
    "recording": its name}`` plus ``"ok"`` over all splits, and, where the linear reference's run (``envelope``:
    per split, its low and high per output) leaves the band, or the model is ``affine`` in its input (its band is
    :data:`AFFINE_BAND` wider), the same under the linear-system band as ``"wide"`` (see :func:`linear_band`).
    Runs every recording once (``runs``: those runs, :func:`usual_runs`, when already made), and again settled
    where a run from rest of a model that starts from measured outputs left the band (see the module docstring).
    ``starts``: the runs from measured starts (:func:`measured_starts`), kept as ``"starts"`` under both bands and
    failing both when they stray."""
    train_lo, train_hi, width = band(ds)
    margin = BAND * (1.0 - EDGE) * width
    strict = {split: measured_band(ds, split, train_lo, train_hi, margin) for split in ds.splits()}
    wider: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    extra = AFFINE_BAND * width if affine else np.zeros_like(width)  # a linear model's own allowance
    for split in ds.splits():  # the linear-system band: the reference's run, widened as the training range
        lo, hi = strict[split]
        low, high = lo - extra, hi + extra
        if split in (envelope or {}):
            env_lo, env_hi = (envelope or {})[split]
            low, high = np.minimum(low, np.asarray(env_lo) - margin), np.maximum(high, np.asarray(env_hi) + margin)
        if (low < lo).any() or (high > hi).any():
            wider[split] = (low, high)
    warm = model.warmup
    if runs is None:
        runs = usual_runs(model, ds)
    settled: dict[int, np.ndarray] = {}
    out: dict[str, Any] = {"ok": True}
    wide: dict[str, Any] = {"ok": True}
    for split in ds.splits():
        lo, hi = strict[split]
        for target, (low, high) in ((out, (lo, hi)), (wide, wider.get(split, (lo, hi)))):
            entry: dict[str, Any] = {"ok": True, "sample": None, "recording": None, "start": None}
            for rec, a, b in ds.scored(split, warm):
                y, how, outputs = runs[rec]
                entry["start"] = entry["start"] or how
                u = ds.recordings[rec].u[a:b]
                seg = y[a:b]
                first = _outside(seg, low, high, lo, hi, width, u)
                if first is not None and how == "either":  # from rest it leaves: does it settled?
                    if rec not in settled:
                        settled[rec] = _run(model, ds.recordings[rec], outputs, SETTLE)
                    if _outside(settled[rec][a:b], low, high, lo, hi, width, u) is None:
                        first, seg = None, settled[rec][a:b]
                if target is wide and split in wider and entry.get("clip") is None:
                    top = _flat_top(seg, u, lo, hi)
                    entry["clip"] = None if top is None else a + top
                if first is not None:
                    entry.update(ok=False, sample=a + first, recording=ds.recordings[rec].name)
                    break
            target[split] = entry
            target["ok"] = target["ok"] and entry["ok"]
    if starts is not None:
        for target in (out, wide):
            target["starts"] = starts
            target["ok"] = target["ok"] and starts["ok"]
    if wider:
        # the first split whose run is cut flat at an output clip beyond the strict band (not a failure: the
        # choice prefers an unclipped candidate that validates about as well, :func:`.select.choose`)
        wide["clipped"] = next((sp for sp in ds.splits() if (wide.get(sp) or {}).get("clip") is not None), None)
        out["wide"] = wide
    return out


#: a run started from other past outputs that stays farther than this from the run from the usual start (RMS over
#: the last tenth of a recording, in training output standard deviations) ...
FORGETS = 0.01
#: ... and keeps more than this fraction of its gap over the first tenth (a gap that shrinks is forgotten slowly: a
#: plant whose time constant is long next to a short recording) keeps a memory of its start
KEPT = 0.5
#: samples of a recording the start memory reads (its first ones): a run keeps the memory of its start from the
#: start on (Silverbox: 7.9 standard deviations over every tenth of every recording), and three free runs of an
#: external echo state network of 400 elements over a million samples took 7 s per fit
MEMORY_SAMPLES = 50000


def start_memory(model: FittedModel, ds: Dataset, runs: UsualRuns | None = None) -> float | None:
    """How far the free run of ``model`` remembers the past outputs it started from (the replica test of the
    reliability check, thesis definition 4.4, cut to two replicas): on every recording's **inputs**, the run from
    its usual start (``runs``: :func:`usual_runs`, when already made) against runs started at rest at the bottom
    and at the top of the training output range, over a recording's first :data:`MEMORY_SAMPLES` samples; the
    largest RMS difference over their last tenth that has not shrunk below :data:`KEPT` of its value over the
    first tenth, in training output standard deviations (0 where every gap shrinks, inf where a run is not
    finite). A reliable model forgets its start; a polynomial NARX model can hold a second attractor at its
    output clip, which a run started there, or pushed there by an input beyond the training range, does not leave
    (Silverbox: the degree-4 model chosen, 7.99 standard deviations, 0.55 mV test RMSE on the arrow's tail; a
    42-term degree-3 model, 0, 0.31 mV). None for a model that reads no measured output (it always starts from
    its own state)."""
    if not model.warmup:
        return None
    if runs is None:
        runs = usual_runs(model, ds)
    y = ds.concat_outputs("train")
    low, high = np.nanmin(y, axis=0), np.nanmax(y, axis=0)
    scale = np.nanstd(y, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    worst = 0.0
    for rec, (run, _, start) in runs.items():
        recording = ds.recordings[rec]
        if recording.n > MEMORY_SAMPLES:
            recording = replace(recording, u=recording.u[:MEMORY_SAMPLES], y=recording.y[:MEMORY_SAMPLES])
        usual = run[: recording.n]  # a free run is causal: its first samples are the run over the first inputs
        tenth = recording.n // 10
        if tenth < 1:
            continue
        for level in (low, high):
            other = _run(model, recording, np.broadcast_to(level, start.shape).copy())
            with np.errstate(invalid="ignore", over="ignore"):
                first = np.sqrt(np.mean((other[:tenth] - usual[:tenth]) ** 2, axis=0)) / scale
                last = np.sqrt(np.mean((other[-tenth:] - usual[-tenth:]) ** 2, axis=0)) / scale
            if not np.isfinite(last).all():
                return math.inf
            kept = last > KEPT * np.where(np.isfinite(first), first, 0.0)
            worst = max(worst, float(np.max(np.where(kept, last, 0.0))))
    return worst


#: runs from measured outputs inside the training and validation data (:func:`measured_starts`): how many ...
STARTS = 24
#: ... of at most this many samples each, scored over their second half
START_RUN = 500
#: a run from a measured start strays when its NMSE over its second half exceeds this (a fraction) ...
STRAYS_AT = 0.1
#: ... and this many times the NMSE of the run from the recording's usual start over the same samples
STRAY_RATIO = 10.0
#: a model fails the check when this many of its starts stray (one alone may be a start at a poorly fitted moment)
STRAYED = 2


def _start_spots(ds: Dataset, warm: int) -> list[tuple[int, int, int]]:
    """Up to :data:`STARTS` (recording, start, length) spread evenly over the training and validation ranges:
    each start has ``warm`` measured outputs before it and ``length`` samples after it inside its range."""
    pieces: list[tuple[int, int, int, int]] = []  # (recording, first start, last start, run length)
    for split in FIT_SPLITS:
        for rec, a, b in ds.ranges.get(split, []):
            first = (a if ds.transient_at == "segment" else max(a, ds.transient)) + warm
            length = min(START_RUN, b - first)
            if length < max(4 * warm, 50):
                continue
            pieces.append((rec, first, b - length, length))
    counts = np.array([last - first + 1 for _, first, last, _ in pieces])
    if not counts.size:
        return []
    total = int(counts.sum())
    ends = np.cumsum(counts)
    out = []
    for k in np.unique(np.linspace(0, total - 1, min(STARTS, total)).astype(int)):
        i = int(np.searchsorted(ends, k, side="right"))
        rec, first, _, length = pieces[i]
        out.append((rec, first + int(k - (ends[i] - counts[i])), length))
    return out


def measured_starts(model: FittedModel, ds: Dataset, runs: UsualRuns) -> dict[str, Any] | None:
    """Does the free run of a model that starts from measured outputs track the output from wherever it starts?
    Runs of at most :data:`START_RUN` samples from :data:`STARTS` points spread over the training and validation
    data (outputs the search reads), each started from the measured outputs before it, as a user's prediction
    from a measured tune-in is; a run *strays* when its NMSE over its second half exceeds :data:`STRAYS_AT` and
    :data:`STRAY_RATIO` times that of the run from the recording's usual start (``runs``) over the same samples.
    The recording's own start may fall in the right basin where other states do not: an external echo state
    network of 400 elements tuned in for 20 samples from a reservoir at zero (before ``settle``) validated at
    0.03 % NMSE from the validation's start, strayed (to 290 - 900 % NMSE) from 2 of 24 starts inside its
    training data, its refit on every sample from 20 of 96, and scored 480 % on a test recording.

    ``{"ok", "starts", "strayed", "recording", "sample"}`` (where the first stray started), or None for a model
    that reads no measured output or where no start has the samples it needs."""
    warm = model.warmup
    if not warm:
        return None
    spots = _start_spots(ds, warm)
    if not spots:
        return None
    var = np.nanvar(ds.concat_outputs("train"), axis=0)
    var = np.where(var > 0, var, 1.0)
    strayed: list[tuple[int, int]] = []
    made = 0
    for rec, s, length in spots:
        recording = ds.recordings[rec]
        y = recording.y[s : s + length]
        half = length // 2
        if not (np.isfinite(recording.y[s - warm : s]).all() and np.isfinite(y[half:]).all()):
            continue  # a gap in the measured outputs: no start there
        made += 1
        try:
            run = np.asarray(model.run(recording.u[s - warm : s + length], recording.y[s - warm : s]).y)[warm:]
        except (ValueError, FloatingPointError):
            run = np.full_like(y, np.nan)
        usual = runs[rec][0][s : s + length]
        with np.errstate(invalid="ignore", over="ignore"):
            own = float(np.mean(np.mean((run[half:] - y[half:]) ** 2, axis=0) / var))
            base = float(np.mean(np.mean((usual[half:] - y[half:]) ** 2, axis=0) / var))
        if not math.isfinite(own) or (own > STRAYS_AT and (not math.isfinite(base) or own > STRAY_RATIO * base)):
            strayed.append((rec, s))
    if not made:
        return None
    first = strayed[0] if strayed else None
    return {
        "ok": len(strayed) < STRAYED,
        "starts": made,
        "strayed": len(strayed),
        "recording": None if first is None else ds.recordings[first[0]].name,
        "sample": None if first is None else int(first[1]),
    }


def remembers(memory: float | None) -> bool:
    """Whether a measured :func:`start_memory` says the model keeps a memory of its start."""
    return memory is not None and not memory <= FORGETS


def forgets(memory: float | None) -> bool:
    """Whether a measured :func:`start_memory` shows that the model forgets its start (None, a model that reads no
    measured output, shows neither: a network started from its own state can hold attractors of its own)."""
    return memory is not None and memory <= FORGETS


def linear_band(checks: dict[str, Any]) -> dict[str, Any]:
    """``checks`` under the linear-system band (``checks`` itself where that band is no wider)."""
    return checks.get("wide", checks)


def failed_split(checks: dict[str, Any]) -> str | None:
    """The first split whose band check failed, as a phrase, or None."""
    for split, entry in checks.items():
        if split == "starts" and isinstance(entry, dict) and not entry.get("ok", True):
            return (
                f"strays from the measured output when started from measured outputs inside the training data "
                f"({entry['strayed']} of {entry['starts']} starts, the first at sample {entry['sample']})"
            )
        if split != "wide" and isinstance(entry, dict) and not entry.get("ok", True):
            start = {
                "rest": " (run from rest)",
                "either": " (run from rest, and settled at its first input)",
                "window": "",
                "measured": "",
            }.get(entry.get("start") or "", "")
            return f"leaves the output band on the {split} input at sample {entry['sample']}{start}"
    return None


def complexity(model: FittedModel) -> float:
    """The fitted model's size: the values its fit estimated (:meth:`Family.fitted_values`), else, when a
    plugin's count fails, the floating-point values of its stored arrays."""
    try:
        return float(model.family.fitted_values())
    except Exception:  # noqa: BLE001 - a plugin's count must not stop the search
        return float(model.family.stored_values())
