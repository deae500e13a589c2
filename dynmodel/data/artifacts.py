"""Measurement artifacts in an output column that a model would learn as the system's behaviour: isolated
spikes (a sample far from both its neighbours, which agree with each other) and clipping (a sensor held at
the end of its range). Both are found from the measured samples alone and reported as notes: the data are
the user's, and only the user knows whether a flat top is a sensor limit or a physical one.

Spikes. With the centred second difference d(t) = y(t) - (y(t-1) + y(t+1)) / 2, a sample is a spike when

* |d(t)| exceeds both :data:`SPIKE_SCALES` robust deviations of d (1.4826 x its median absolute value, the
  Gaussian-consistent MAD) and :data:`SPIKE_RANGE` of the output's 1-99 % range;
* its neighbours agree: |y(t+1) - y(t-1)| <= |d(t)| / 2 (a step has neighbours that disagree);
* it comes and goes abruptly: |d(t)| exceeds :data:`SPIKE_ABRUPT` times the steps just before and after,
  |y(t-1) - y(t-2)| and |y(t+2) - y(t+1)| (a peak the system makes rises over several samples; a sharp
  peak that answers a pulse, 0.7, 1.8, 3.7, 1.9, 0.9, does not count);
* its value is rare: fewer than :data:`SPIKE_RARE` of the samples lie within |d(t)| / 4 of it (a relay or a
  comparator that chatters for one sample goes to a level it holds half the time);
* no input moves sharply at t - 1, t or t + 1 (|d_u| within the same bounds for every input): an output
  that answers a one-sample input pulse or a step is the system's, not the sensor's. Unless the candidates
  are many (:data:`SPIKE_EVIDENCE`) and fall near input moves no more often than any sample does: then
  they are independent of the input, and those near input moves count too.

A column with more than :data:`SPIKE_SHARE` of its samples flagged is not noted: spikes that common are the
signal's nature. Clipping: the column's largest (smallest) value is held by more than :data:`CLIP_SHARE`
of the samples, and by more than :data:`CLIP_RATIO` times as many as the next value below (above) it,
which tells a flat top from the highest level of a quantized signal, in at least :data:`CLIP_VISITS` separate
stretches (a signal at rest before its excitation starts is not clipped).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .dataset import Range, Recording

#: a second difference beyond this many robust deviations of its own distribution can be a spike
SPIKE_SCALES = 10.0
#: ... and beyond this fraction of the column's 1-99 % range
SPIKE_RANGE = 0.1
#: ... and beyond this many times the steps before and after it
SPIKE_ABRUPT = 3.0
#: candidates needed to tell glitches independent of the input from outputs that answer input moves
SPIKE_EVIDENCE = 10
#: a spike's value is held (to within a quarter of its size) by fewer than this share of the samples
SPIKE_RARE = 0.01
#: a column with more spikes than this share of its samples is not noted (they are its nature)
SPIKE_SHARE = 0.05
#: an extreme value held by more than this share of the samples can be a clipped sensor
CLIP_SHARE = 0.02
#: ... when it is held this many times as often as the next value inside the range
CLIP_RATIO = 5.0
#: ... in at least this many separate stretches (a quiet start before the excitation is one stretch)
CLIP_VISITS = 2


@dataclass
class Clip:
    side: str  # "maximum" or "minimum"
    value: float
    share: float


def _second_difference(x: np.ndarray) -> np.ndarray:
    d = np.zeros_like(x)
    d[1:-1] = x[1:-1] - 0.5 * (x[:-2] + x[2:])
    return d


def _bound(d: np.ndarray, x: np.ndarray) -> float:
    """The size a second difference must exceed to count as sharp: both bounds of the module docstring."""
    lo, hi = np.percentile(x, [1, 99])
    scale = 1.4826 * float(np.median(np.abs(d[1:-1]))) if d.size > 2 else 0.0
    return max(SPIKE_SCALES * scale, SPIKE_RANGE * float(hi - lo))


def _rare_values(y: np.ndarray, d: np.ndarray, candidate: np.ndarray) -> np.ndarray:
    """For each candidate sample t: whether fewer than :data:`SPIKE_RARE` of the samples lie within |d(t)| / 4
    of y(t). A relay or comparator that chatters for one sample goes to a level it holds half the time."""
    ordered = np.sort(y)
    at = np.flatnonzero(candidate)
    half = 0.25 * np.abs(d[at])
    count = np.searchsorted(ordered, y[at] + half, "right") - np.searchsorted(ordered, y[at] - half, "left")
    rare = np.zeros(y.shape[0], dtype=bool)
    rare[at] = count < SPIKE_RARE * y.shape[0]
    return rare


def _independent(candidate: np.ndarray, near: np.ndarray) -> bool:
    """Whether the candidate spikes fall near input moves no more often than samples do in general (within three
    binomial deviations, over at least :data:`SPIKE_EVIDENCE` candidates): glitches of a sensor, independent of
    the input, so the ones near an input move count too. Otherwise only those away from input moves count."""
    count = int(candidate.sum())
    if count < SPIKE_EVIDENCE:
        return False
    base = float(near.mean())
    return float(near[candidate].mean()) <= base + 3.0 * np.sqrt(base * (1.0 - base) / count)


def _input_moves(u: np.ndarray) -> np.ndarray:
    """Per sample of inputs ``u`` (n, m): whether an input moves sharply at t - 1, t or t + 1 (its second
    difference beyond :func:`_bound`)."""
    near = np.zeros(u.shape[0], dtype=bool)
    for j in range(u.shape[1] if u.ndim == 2 else 0):
        col = u[:, j]
        if u.shape[0] < 3 or not np.all(np.isfinite(col)):
            continue
        du = _second_difference(col)
        moves = np.abs(du) > _bound(du, col)
        near |= moves
        near[1:] |= moves[:-1]
        near[:-1] |= moves[1:]
    return near


def _candidates(y: np.ndarray) -> np.ndarray:
    """Per sample of one output series ``y`` (n,): whether it is sharp, its neighbours agree, it comes and
    goes abruptly and its value is rare (the module docstring's tests on the output alone)."""
    n = y.shape[0]
    none = np.zeros(n, dtype=bool)
    if n < 5 or not np.all(np.isfinite(y)):
        return none
    d = _second_difference(y)
    bound = _bound(d, y)
    if bound <= 0:
        return none
    sharp = np.abs(d) > bound
    sharp[[0, -1]] = False
    agree = np.zeros(n, dtype=bool)
    agree[1:-1] = np.abs(y[2:] - y[:-2]) <= 0.5 * np.abs(d[1:-1])
    abrupt = np.zeros(n, dtype=bool)
    step = np.abs(np.diff(y))
    around = np.maximum(step[:-3], step[3:])  # |y(t-1) - y(t-2)| and |y(t+2) - y(t+1)| for t = 2 .. n-3
    abrupt[2:-2] = np.abs(d[2:-2]) > SPIKE_ABRUPT * around
    candidate = sharp & agree & abrupt
    return candidate & _rare_values(y, d, candidate)


def _decide(pieces: list[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
    """The spikes (sample indices) of each ``(candidates, input moves)`` piece of one output column. Whether
    glitches are independent of the input is decided over all pieces together (a property of the sensor)."""
    if not pieces:
        return []
    independent = _independent(np.concatenate([c for c, _ in pieces]), np.concatenate([m for _, m in pieces]))
    found = []
    for c, m in pieces:
        hits = np.flatnonzero(c if independent else c & ~m)
        found.append(hits if hits.size <= SPIKE_SHARE * c.size else np.zeros(0, dtype=int))
    return found


def spikes(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The isolated spikes (sample indices) of one output series ``y`` (n,) driven by inputs ``u`` (n, m)."""
    return _decide([(_candidates(y), _input_moves(u))])[0]


def clipping(y: np.ndarray) -> list[Clip]:
    """The ends of the range that one output series ``y`` (n,) sits on like a clipped sensor."""
    y = y[np.isfinite(y)]
    n = y.shape[0]
    if n < 10:
        return []
    values, counts = np.unique(y, return_counts=True)
    if values.size < 3:
        return []
    found = []
    for side, top, next_ in (("maximum", -1, -2), ("minimum", 0, 1)):
        share = counts[top] / n
        at = y == values[top]
        visits = int(at[0]) + int(np.count_nonzero(at[1:] & ~at[:-1]))
        if share > CLIP_SHARE and counts[top] > CLIP_RATIO * counts[next_] and visits >= CLIP_VISITS:
            found.append(Clip(side, float(values[top]), float(share)))
    return found


#: sample positions named in a note
NAMED = 3
#: the splits whose outputs a model is fitted and chosen on: spikes there are replaced
FITTED = ("train", "validation")


@dataclass
class Artifact:
    """Spikes or clipping found in one output of one split, as :meth:`note` tells the user."""

    split: str
    output: str
    #: spikes: (recording name, sample index in its file) of each; clipping: empty
    where: list[tuple[str, int]]
    replaced: bool = False
    clip: Clip | None = None

    @property
    def kind(self) -> str:
        return "spikes" if self.clip is None else "clipping"

    def note(self) -> str:
        whose = "training" if self.split == "train" else self.split
        if self.clip is not None:
            c = self.clip
            return (
                f"the {whose} output '{self.output}' sits at its {c.side} {c.value:.6g} on {100 * c.share:.1f} % of "
                f"the samples, more than {CLIP_RATIO:g} times as often as at any other value: a saturated sensor, or a "
                "physical limit (an overflowing tank)? The model learns it as the system's behaviour; if the sensor "
                "clipped, cut those stretches out (data.segments) or measure with a wider range"
            )
        n = len(self.where)
        more = f" and {n - NAMED} more" if n > NAMED else ""
        files = {name for name, _ in self.where}
        if len(files) == 1:
            places = ", ".join(str(i) for _, i in self.where[:NAMED]) + f"{more} of '{files.pop()}'"
        else:
            places = ", ".join(f"{i} of '{name}'" for name, i in self.where[:NAMED]) + more
        what = (
            f"{n} sample(s) of the {whose} output '{self.output}' stand out as isolated spikes (far from both "
            f"neighbours, which agree with each other: {'sample' if n == 1 else 'samples'} {places})"
        )
        if self.replaced:
            scores = " (the validation scores use the replaced values)" if self.split == "validation" else ""
            return (
                f"{what}: each was replaced by the mean of its neighbours, so that a sensor glitch is not learned as "
                f"the system's answer{scores}; data.spikes: keep (spikes='keep' on arrays) fits them as measured"
            )
        if self.split in FITTED:
            return f"{what}, kept as measured (data.spikes: keep): if they are sensor glitches the model learns them"
        return f"{what}: the {whose} scores include them (test outputs are never changed)"


def find_artifacts(
    recordings: list[Recording], ranges: dict[str, list[Range]], outputs: list[str], replace_spikes: bool
) -> list[Artifact]:
    """Spikes in every split's outputs and clipping of the training outputs. With ``replace_spikes`` each spike
    of the training and validation outputs is replaced, in place, by the mean of its two neighbours (test
    outputs are never changed)."""
    from .dataset import _file_of

    found: list[Artifact] = []
    copied: set[int] = set()
    pieces = [(split, r, a, b) for split, rngs in ranges.items() for r, a, b in rngs]
    fitted = [i for i, (split, *_) in enumerate(pieces) if split in FITTED]
    moves = [_input_moves(recordings[r].u[a:b]) for _, r, a, b in pieces]
    for j, name in enumerate(outputs):
        candidates = [_candidates(recordings[r].y[a:b, j]) for _, r, a, b in pieces]
        # the test outputs weigh in on the test's own note only, never on what is fitted
        hits = _decide(list(zip(candidates, moves)))
        for i, h in zip(fitted, _decide([(candidates[i], moves[i]) for i in fitted])):
            hits[i] = h
        for split in ranges:
            where: list[tuple[str, int]] = []
            replace = split in FITTED and replace_spikes
            for (s, r, a, _), h in zip(pieces, hits):
                if s != split or not h.size:
                    continue
                rec, at = recordings[r], a + h
                if replace:
                    if r not in copied:  # never the caller's arrays (the Python API's, a benchmark's)
                        rec = recordings[r] = dataclasses.replace(rec, y=rec.y.copy())
                        copied.add(r)
                    rec.y[at, j] = 0.5 * (rec.y[at - 1, j] + rec.y[at + 1, j])
                where += [(_file_of(rec), int(rec.offset + t)) for t in at]
            if where:
                found.append(Artifact(split, name, where, replaced=replace))
    for j, name in enumerate(outputs):
        train = [recordings[r].y[a:b, j] for r, a, b in ranges.get("train", [])]
        if train:
            found += [Artifact("train", name, [], clip=c) for c in clipping(np.concatenate(train))]
    return found
