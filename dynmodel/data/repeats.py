"""Inputs that repeat the training input: a validation or test split whose input is a copy of a stretch of the
training input (a periodic excitation, such as the periods of a multisine measured in steady state, split
period by period) shows a model the input it was fitted on again. Its error then measures how well the model
fits that input, not how it does on a new one, and it ranks larger models too well: on the Bouc-Wen record
(five periods of one multisine, the last one the validation split) a degree-3 NARX with lags up to 5
validates at 0.059 % NMSE against 0.078 % for lags up to 4, and scores 0.150 % against 0.102 % on a new
multisine realization; with the first fifth of the period held out of every period, both validate as they
test (0.17 and 0.12 %).

The check cuts each range of the split into at most :data:`CHUNKS` chunks of :data:`CHUNK` samples and looks
for each, with an FFT cross-correlation, at every shift of every training range: a chunk repeats when some
shift matches it to a relative RMS mismatch of at most :data:`MISMATCH`,

    min_s  || v - x[s : s + m] ||  /  || v - mean(v) ||  <=  MISMATCH,

with every input scaled by its training standard deviation (the norm runs over samples and inputs). A chunk
whose input barely moves (a rig at standstill) repeats nothing: its own variation is the denominator. The split
repeats the training input when every chunk does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .dataset import Dataset

#: samples per chunk compared (a shorter range is compared whole)
CHUNK = 1000
#: at most this many chunks per range, spread evenly over it
CHUNKS = 8
#: a chunk shorter than this is not compared
MIN_CHUNK = 50
#: largest relative RMS mismatch of a repeat (a measured periodic input carries its measurement noise)
MISMATCH = 0.05


def best_match(x: np.ndarray, v: np.ndarray, cache: dict[Any, np.ndarray] | None = None) -> tuple[int, float]:
    """(shift, mismatch): the shift ``s`` of ``x`` (n, k) where ``x[s:s+m]`` best matches ``v`` (m, k), m <= n,
    and the relative RMS mismatch there (see the module docstring); ``(-1, inf)`` when ``v`` does not vary.
    ``cache``: a dict kept with ``x`` across calls, holding its running energy and its spectra by FFT size
    (every chunk of a split is compared with the same training ranges)."""
    cache = {} if cache is None else cache
    n, m = len(x), len(v)
    centred = float(np.sum((v - v.mean(axis=0)) ** 2))
    if m == 0 or m > n or not centred > 1e-12 * float(np.sum(v * v)):  # a held input (rounding aside)
        return -1, float("inf")
    size = 1 << int(np.ceil(np.log2(n + m)))
    # sum_t v[t] x[s + t] for every shift s = 0 .. n - m, summed over the inputs
    if size not in cache:
        cache[size] = np.fft.rfft(x, size, axis=0)
    cross = np.fft.irfft(cache[size] * np.fft.rfft(v[::-1], size, axis=0), size, axis=0)
    cross = cross.sum(axis=1)[m - 1 : n]
    if "energy" not in cache:
        cache["energy"] = np.concatenate([[0.0], np.cumsum(np.sum(x * x, axis=1))])
    energy = cache["energy"]
    window = energy[m:] - energy[: n - m + 1]
    squared = window - 2.0 * cross + float(np.sum(v * v))
    # the latest of the equally good shifts: in a periodic record the nearest copy, one period back
    s = int(np.flatnonzero(squared <= squared.min() + 1e-9 * centred)[-1])
    return s, float(np.sqrt(max(squared[s], 0.0) / centred))


def _chunks(a: int, b: int) -> list[tuple[int, int]]:
    """At most CHUNKS chunks of CHUNK samples spread evenly over [a, b) (the whole range when shorter)."""
    if b - a <= CHUNK:
        return [(a, b)] if b - a >= MIN_CHUNK else []
    count = min(CHUNKS, (b - a) // CHUNK)
    starts = np.linspace(a, b - CHUNK, count).astype(int)
    return [(int(s), int(s) + CHUNK) for s in starts]


def repeats_training(ds: Dataset, split: str) -> dict[str, Any] | None:
    """Does the input of ``split`` repeat the training input (every chunk of every range found in a training
    range, see the module docstring)? ``{split, chunks, mismatch (the worst chunk's), period}`` when it does,
    ``period`` being the distance in samples back to the match when that lies in the same recording (a
    periodic excitation's period or a multiple of it; None otherwise); None when it does not, or when the
    split or the training split is empty."""
    train_ranges = ds.ranges.get("train", [])
    ranges = ds.ranges.get(split, [])
    if not train_ranges or not ranges:
        return None
    train, _ = ds.concat_inputs("train")
    mean, std = train.mean(axis=0), train.std(axis=0)
    std = np.where(std > 0, std, 1.0)
    caches: list[dict[Any, np.ndarray]] = [{} for _ in train_ranges]  # per training range, across the chunks
    scaled = [((ds.recordings[r].u[a:b] - mean) / std, r, a, c) for (r, a, b), c in zip(train_ranges, caches)]
    worst, period, chunks = 0.0, None, 0
    for r, a, b in ranges:
        u = (ds.recordings[r].u[a:b] - mean) / std  # the range only, scaled once for its chunks
        for lo, hi in _chunks(a, b):
            v = u[lo - a : hi - a]
            found = min(
                ((mis, tr, ta + s) for x, tr, ta, cache in scaled for s, mis in [best_match(x, v, cache)] if s >= 0),
                default=(float("inf"), -1, -1),
            )
            if not found[0] <= MISMATCH:
                return None
            chunks += 1
            worst = max(worst, found[0])
            if found[1] == r and found[2] < lo:
                period = lo - found[2] if period is None else min(period, lo - found[2])
    if not chunks:
        return None
    return {"split": split, "chunks": chunks, "mismatch": worst, "period": period}


def repeat_note(found: dict[str, Any]) -> str:
    """A user's sentence for :func:`repeats_training`'s finding."""
    period = f", {found['period']} samples back" if found.get("period") else ""
    within = "exactly" if found["mismatch"] < 1e-6 else f"within {100 * found['mismatch']:.2g} % RMS"
    return (
        f"the {found['split']} input repeats the training input ({within}{period}, as the periods of a periodic "
        "excitation do): its error measures how a model fits that input again, not how it does on a new one, and "
        "favours larger models; a recording with another realization of the excitation (a multisine with other "
        "phases) measures that"
    )
