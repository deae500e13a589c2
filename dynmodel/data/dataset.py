"""From the ``data`` section of a spec to recordings with train / validation / test ranges.

A *recording* is one continuous series: states and free runs restart at its first sample.
Each split is a list of ``(recording, start, stop)`` ranges; the ``transient`` samples at the
start of every range are excluded from fitting and scoring; scores pool over recordings.

Split keys: ``train``, ``validation``, and for test sets ``test`` (a single unnamed one) or
``test:<name>`` (each named one). A validation or test split with an initialization window
(benchmark protocols) has recordings of its own: the first ``window`` samples of each may
initialize the model and are not scored; with ``score_all`` every sample is scored.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import registry
from ..errors import DataError, SpecError
from ..spec import SPLITS
from . import resample
from .artifacts import Artifact, find_artifacts
from .checks import check_signals
from .finite import check_finite, non_finite
from .readers import read_columns

if TYPE_CHECKING:
    from ..api import ArraySpec
    from ..spec import Spec

Range = tuple[int, int, int]  # (recording index, start, stop)
_SPLIT_PREFIX = re.compile(r"^(validation|test(:[A-Za-z][A-Za-z0-9_-]*)?):")


def last_samples(ranges: list[Range], samples: int | None) -> list[Range]:
    """``ranges`` cut to at most ``samples`` samples in all (None: unchanged): the last ones of each range,
    in proportion to its length (the last range takes what rounding left); ranges left empty are dropped."""
    total = sum(b - a for _, a, b in ranges)
    if samples is None or samples >= total:
        return list(ranges)
    kept: list[Range] = []
    left = samples
    for i, (r, a, b) in enumerate(ranges):
        share = left if i == len(ranges) - 1 else int(round(samples * (b - a) / total))
        share = min(share, b - a, left)
        left -= share
        if share > 0:
            kept.append((r, b - share, b))
    return kept


def continued_range(
    outputs: list[np.ndarray], ranges: list[Range], train: list[Range]
) -> tuple[np.ndarray, np.ndarray] | None:
    """(low, high) per output of the measured ``outputs`` (per recording) over the ``ranges`` that lie in a
    recording holding ``train`` samples (NaN for a column without a measured sample), or None when none does.
    A validation range that continues a training recording is reached by a free run from the training data, so
    an output there beyond the training range is a measured one, not a diverging run; a validation recording of
    its own starts from its own measured outputs, whose level a model can carry over (the pneumatic seal, each
    pressure's recording left out in turn), and is left out."""
    trained = {r for r, _, _ in train}
    pieces = [outputs[r][a:b] for r, a, b in ranges if r in trained]
    if not pieces:
        return None
    y = np.concatenate(pieces)
    seen = np.isfinite(y).any(axis=0)
    lo, hi = np.full(y.shape[1], np.nan), np.full(y.shape[1], np.nan)
    lo[seen], hi[seen] = np.nanmin(y[:, seen], axis=0), np.nanmax(y[:, seen], axis=0)
    return lo, hi


def compact_ranges(pieces: dict[str, list[Range]]) -> tuple[list[Range], dict[str, list[Range]]]:
    """The recordings ``pieces`` (split -> ranges) use, each as (recording, first start, last stop) in recording
    order, and ``pieces`` re-indexed onto that list and shifted to each cut's start (empty splits dropped)."""
    used = sorted({r for rows in pieces.values() for r, _, _ in rows})
    cuts = [
        (
            r,
            min(a for rows in pieces.values() for rr, a, _ in rows if rr == r),
            max(b for rows in pieces.values() for rr, _, b in rows if rr == r),
        )
        for r in used
    ]
    index = {r: i for i, (r, _, _) in enumerate(cuts)}
    shift = {r: a for r, a, _ in cuts}
    ranges = {s: [(index[r], a - shift[r], b - shift[r]) for r, a, b in rows] for s, rows in pieces.items() if rows}
    return cuts, ranges


def beyond_range(u: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[tuple[float, int]]:
    """Per column of ``u`` (n, k): how far it goes beyond [lo, hi], as a fraction of hi - lo (0 inside), and the
    sample where it goes farthest (-1 for an empty ``u``)."""
    width = np.maximum(hi - lo, np.finfo(float).tiny)
    out = []
    for j in range(u.shape[1]):
        if u.shape[0] == 0:
            out.append((0.0, -1))
            continue
        excess = np.maximum(u[:, j] - hi[j], lo[j] - u[:, j]) / width[j]
        k = int(np.nanargmax(excess)) if np.isfinite(excess).any() else 0
        out.append((max(float(excess[k]), 0.0) if np.isfinite(excess[k]) else 0.0, k))
    return out


#: an input whose training std is below this fraction of its std in the other splits is noted
#: (:meth:`Dataset.training_input_notes`)
QUIET = 0.1
#: a validation or test split with fewer scored samples than this is noted (:meth:`Dataset.small_split_notes`)
FEW_SCORED = 30


def _file_of(rec: Recording) -> str:
    """The file a recording was read from, by name: without a split's prefix (``test:``) or a segment's range."""
    name = rec.name.rsplit("[", 1)[0] if rec.name.endswith("]") else rec.name
    return name.split(":", 1)[1] if ":" in name and name.split(":", 1)[0] in ("validation", "test") else name


def _same_samples(a: Recording, b: Recording) -> bool:
    """Do two recordings hold the same samples over at least half of the shorter one, from their starts?"""
    n = min(a.n, b.n)
    return (
        n > 0
        and n >= 0.5 * max(a.n, b.n)
        and np.array_equal(a.u[:n], b.u[:n])
        and np.array_equal(a.y[:n], b.y[:n], equal_nan=True)
    )


def is_test(split: str) -> bool:
    """Is ``split`` a test split key (``test`` or ``test:<name>``)?"""
    return split == "test" or split.startswith("test:")


@dataclass
class Recording:
    """One continuous input/output series in physical units."""

    name: str
    u: np.ndarray  # (n, n_inputs)
    y: np.ndarray  # (n, n_outputs)
    #: first sample of this recording in its file (a segment of a longer file starts later)
    offset: int = 0
    #: the source's own column names (a separate test file may name its columns differently)
    input_columns: list[str] | None = None
    output_columns: list[str] | None = None
    #: index (in the dataset as loaded) of the recording this run was cut from to start a free run of its
    #: own (:func:`own_runs`: a validation or test range with an initialization window); None for a recording
    #: of its own. The search leaves out a recording with the runs cut from it (``search.views``).
    origin: int | None = None

    @property
    def n(self) -> int:
        return self.u.shape[0]

    def span(self, start: int, stop: int) -> str:
        """``file[start:stop]`` with sample indices of the file (not of the segment)."""
        base = self.name.rsplit("[", 1)[0] if self.offset or self.name.endswith("]") else self.name
        return f"{base}[{self.offset + start}:{self.offset + stop}]"


@dataclass
class Dataset:
    recordings: list[Recording]
    ranges: dict[str, list[Range]]
    transient: int
    input_names: list[str]
    output_names: list[str]
    sampling_time: float
    transient_at: str = "segment"
    #: initialization window per split key (validation and test splits of a protocol)
    windows: dict[str, int] = field(default_factory=dict)
    #: split keys scored on every sample (no window, no transient, no measured start)
    score_all: set[str] = field(default_factory=set)
    #: the source's reporting units per output: {output: (scale, name)} (benchmark sources)
    units: dict[str, tuple[float, str]] = field(default_factory=dict)
    #: per split key: unscored samples at the start of each recording, simulated from the input alone (a
    #: steady-state test period preceded by a copy of itself)
    lead_in: dict[str, int] = field(default_factory=dict)
    #: spikes and clipping found in the measured outputs when loaded (:func:`.artifacts.find_artifacts`)
    artifacts: list[Artifact] = field(default_factory=list)

    def allowed_warmup(self) -> dict[str, int]:
        """Per validation / test split with a protocol: the measured output samples a run may use."""
        allowed = {key: 0 for key in self.score_all}
        allowed.update({key: w for key, w in self.windows.items() if key not in self.score_all})
        return allowed

    def warmup_limit(self) -> int | None:
        """The fewest measured outputs any protocol split lets a run start from (None: no protocol)."""
        return min(self.allowed_warmup().values(), default=None)

    def splits(self) -> list[str]:
        """Split keys with samples: train, validation, then the test sets in the spec's order."""
        fixed = [s for s in ("train", "validation") if self.ranges.get(s)]
        return fixed + [s for s in self.ranges if s not in ("train", "validation") and self.ranges[s]]

    def source_names(self) -> list[str]:
        """The recordings' sources for a summary line: names without the split prefix and sample ranges."""
        names = [re.sub(r"(\[\d*:\d*\])+$", "", _SPLIT_PREFIX.sub("", r.name)) for r in self.recordings]
        return list(dict.fromkeys(names))

    def test_splits(self) -> list[str]:
        """The test split keys: ``test`` or ``test:<name>`` for each named test set."""
        return [s for s in self.splits() if is_test(s)]

    def scored(self, split: str, warmup: int = 0) -> list[Range]:
        """Ranges of ``split`` without the transient and the initialization window (and without
        ``warmup`` samples at recording starts); every sample for a ``score_all`` split."""
        out = []
        for rec, start, stop in self.ranges.get(split, []):
            if split in self.score_all:
                first = start + self.lead_in.get(split, 0)
            else:
                if self.transient_at == "segment":
                    first = start + self.transient
                else:  # only the recording's first samples, where the state restarts
                    first = max(start, self.transient)
                first = max(first, warmup, start + self.windows.get(split, 0), start + self.lead_in.get(split, 0))
            if first < stop:
                out.append((rec, first, stop))
        return out

    def n_scored(self, split: str, warmup: int = 0) -> int:
        return sum(stop - start for _, start, stop in self.scored(split, warmup))

    def fingerprint(self, splits: tuple[str, ...] = ("train", "validation")) -> str:
        """SHA-256 of the samples the model is fitted on (provenance)."""
        h = hashlib.sha256()
        for split in splits:
            for rec, start, stop in self.ranges.get(split, []):
                r = self.recordings[rec]
                h.update(split.encode())
                h.update(np.ascontiguousarray(r.u[start:stop]).tobytes())
                h.update(np.ascontiguousarray(r.y[start:stop]).tobytes())
        return h.hexdigest()

    @property
    def n_loaded(self) -> int:
        """The recordings as read or generated (runs cut from them to start on their own not counted)."""
        return sum(r.origin is None for r in self.recordings)

    def concat_inputs(self, split: str) -> tuple[np.ndarray, np.ndarray]:
        """Inputs of ``split`` concatenated, and the lengths of the pieces."""
        pieces = [self.recordings[rec].u[start:stop] for rec, start, stop in self.ranges.get(split, [])]
        if not pieces:
            return np.empty((0, len(self.input_names))), np.empty(0, dtype=np.int64)
        return np.concatenate(pieces), np.array([len(p) for p in pieces], dtype=np.int64)

    def input_excursions(self, margin: float = 0.05) -> list[dict]:
        """Inputs of the validation and test splits that go beyond the range the training split
        covers by more than ``margin`` of that range: there the model extrapolates (a readout or a
        polynomial fitted inside the range can do anything outside it). One entry per split and
        input: ``{split, input, excess (fraction of the training range), recording, sample}``."""
        train, _ = self.concat_inputs("train")
        if train.shape[0] == 0:
            return []
        lo, hi = train.min(axis=0), train.max(axis=0)
        found = []
        for split in self.splits()[1:]:
            beyond = [beyond_range(self.recordings[rec].u[a:b], lo, hi) for rec, a, b in self.ranges.get(split, [])]
            for j, name in enumerate(self.input_names):
                worst = (0.0, -1, -1)
                for (rec, start, _), per_input in zip(self.ranges.get(split, []), beyond):
                    excess, k = per_input[j]
                    if excess > worst[0]:
                        worst = (excess, rec, start + k)
                if worst[0] > margin:
                    columns = self.recordings[worst[1]].input_columns
                    found.append(
                        {
                            "split": split,
                            "input": columns[j] if columns else name,
                            "excess": worst[0],
                            "recording": self.recordings[worst[1]].name,
                            "sample": worst[2],
                        }
                    )
        return found

    def small_split_notes(self, warmup: int = 0) -> list[str]:
        """A validation or test split with fewer than :data:`FEW_SCORED` scored samples: its scores say little (a
        2-sample validation split scored 335 % NMSE and chose the model)."""
        notes = []
        for split in self.splits():
            n = self.n_scored(split, warmup)
            if split != "train" and n < FEW_SCORED:
                notes.append(
                    f"the {split} split has only {n} scored sample(s): its scores say little (give it at least "
                    f"{FEW_SCORED}, e.g. a larger share in data.split or a shorter transient)"
                )
        return notes

    def training_input_notes(self) -> list[str]:
        """An input that repeats another one on every training sample, and one that barely moves in the training
        split while it does elsewhere (std below :data:`QUIET` of the other splits'): the model cannot learn how the
        output answers it (a record excited only after its first 75 %, split 60 / 20 / 20: the search kept a
        one-term model at 62 % test NMSE)."""
        train, _ = self.concat_inputs("train")
        if train.shape[0] < 2:
            return []
        others = [self.concat_inputs(s)[0] for s in self.splits() if s != "train"]
        rest = np.concatenate([o for o in others if o.shape[0]]) if any(o.shape[0] for o in others) else None
        if rest is None or rest.shape[0] < 2:
            return []
        notes = []
        for j, name in enumerate(self.input_names):
            same = next(
                (other for i, other in enumerate(self.input_names[:j]) if np.array_equal(train[:, i], train[:, j])),
                None,
            )
            if same is not None:
                notes.append(
                    f"the input '{name}' equals the input '{same}' on every training sample: it adds nothing the model "
                    "can use; remove one of them from data.input"
                )
            quiet, moving = float(np.std(train[:, j])), float(np.std(rest[:, j]))
            if moving > 0 and quiet < QUIET * moving:
                notes.append(
                    f"the input '{name}' barely moves in the training split (std {quiet:.3g}, {moving:.3g} in the "
                    "other splits): the model cannot learn how the output answers it there; put the excitation in "
                    "the training split (data.split, e.g. as sample ranges) or cut the quiet part (data.segments)"
                )
        return notes

    def overlap_notes(self) -> list[str]:
        """A validation or test split that shares samples with the training split (overlapping ranges of one
        recording), or a separate recording that is a training recording again (the training file given as the
        test): its scores then measure, in part or whole, how the model fits data it was trained on."""
        train = self.ranges.get("train", [])
        train_recs = {r for r, _, _ in train}
        notes = []
        for split in self.splits():
            if split == "train":
                continue
            shared = sum(self._shared(r, a, b, r2, a2, b2) for r, a, b in self.ranges[split] for r2, a2, b2 in train)
            if shared:
                n = sum(b - a for _, a, b in self.ranges[split])
                notes.append(
                    f"the {split} split shares {shared} of its {n} samples with the training split: its scores "
                    "measure, that far, how the model fits its own training data (give the splits disjoint ranges)"
                )
                continue
            for rec in sorted({r for r, _, _ in self.ranges[split]} - train_recs):
                same = next(
                    (t for t in sorted(train_recs) if _same_samples(self.recordings[rec], self.recordings[t])), None
                )
                if same is not None:
                    notes.append(
                        f"the {split} recording '{self.recordings[rec].name}' holds the samples of the training "
                        f"recording '{self.recordings[same].name}': its scores measure how the model fits its own "
                        "training data (give a recording of its own)"
                    )
                    break
        return notes

    def _shared(self, r: int, a: int, b: int, r2: int, a2: int, b2: int) -> int:
        """Samples two ranges hold in common: the same recording's overlap, or, for segments of one file (same
        file name, overlapping file indices), the overlap whose samples are equal (two files of one name in
        different folders differ)."""
        if r == r2:
            return max(0, min(b, b2) - max(a, a2))
        x, z = self.recordings[r], self.recordings[r2]
        if _file_of(x) != _file_of(z):
            return 0
        lo, hi = max(x.offset + a, z.offset + a2), min(x.offset + b, z.offset + b2)
        if hi <= lo:
            return 0
        i, j = lo - x.offset, lo - z.offset
        same = np.array_equal(x.u[i : i + hi - lo], z.u[j : j + hi - lo]) and np.array_equal(
            x.y[i : i + hi - lo], z.y[j : j + hi - lo], equal_nan=True
        )
        return hi - lo if same else 0

    def artifact_notes(self) -> list[str]:
        """:attr:`artifacts` as sentences for a user."""
        return [a.note() for a in self.artifacts]

    def excursion_notes(self) -> list[str]:
        """:meth:`input_excursions` as sentences for a user."""
        return [
            f"the {e['split']} input '{e['input']}' leaves the training range by {100 * e['excess']:.0f} % of its "
            f"width (sample {e['sample']} of '{e['recording']}'): the model extrapolates there, and the "
            f"{e['split']} scores include it"
            for e in self.input_excursions()
        ]

    def repeat_notes(self) -> dict[str, str]:
        """Per validation or test split whose input repeats the training input (a periodic excitation split
        period by period, :mod:`.repeats`): a sentence for a user."""
        from .repeats import repeat_note, repeats_training

        found = {split: repeats_training(self, split) for split in self.splits()[1:]}
        return {split: repeat_note(f) for split, f in found.items() if f is not None}

    def concat_outputs(self, split: str) -> np.ndarray:
        """Outputs of ``split`` concatenated (the pieces of :meth:`concat_inputs`)."""
        pieces = [self.recordings[rec].y[start:stop] for rec, start, stop in self.ranges.get(split, [])]
        return np.concatenate(pieces) if pieces else np.empty((0, len(self.output_names)))


# ---------------------------------------------------------------- loading sources


def _read_recording(p: Any, src: dict[str, Any], resolve) -> tuple[np.ndarray, np.ndarray | None, Path, str]:
    """One file (or an {input, output} pair of files) of a file source: the input and output columns
    side by side, the time column (None without one), the path for messages and the recording's name."""
    inputs, outputs = [str(s).strip() for s in src["input"]], [str(s).strip() for s in src["output"]]
    time_col = src.get("time_column")
    extra = [time_col] if time_col is not None else []
    # an empty cell reads as NaN, as the text 'NaN' does, so that a gap meets the same checks and advice (a
    # training gap: data.segments around it; a test output: left out of the score), whichever way it was written
    opts = {
        "header": src.get("header", True),
        "columns": src.get("columns"),
        "delimiter": src.get("delimiter"),
        "gaps": True,
    }
    if isinstance(p, dict):  # the input columns in one file, the output columns in another
        in_path, out_path = resolve(p["input"]), resolve(p["output"])
        icols = read_columns(in_path, list(src["input"]) + extra, **opts)
        ocols = read_columns(out_path, list(src["output"]), **opts)
        n_in, n_out = len(next(iter(icols.values()))), len(next(iter(ocols.values())))
        if n_in != n_out:
            raise DataError(
                f"the input file {in_path.name} has {n_in} samples and the output file {n_out}",
                str(out_path),
                "pair the input and output files of one recording",
            )
        columns = [icols[k] for k in inputs] + [ocols[k] for k in outputs]
        t = icols[str(time_col).strip()] if time_col is not None else None
        return np.column_stack(columns).astype(np.float64), t, in_path, f"{in_path.name}/{out_path.name}"
    path = resolve(p)
    cols = read_columns(path, list(src["input"]) + list(src["output"]) + extra, **opts)
    data = np.column_stack([cols[k] for k in inputs + outputs]).astype(np.float64)
    return data, (cols[str(time_col).strip()] if time_col is not None else None), path, path.name


def _only(data: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``data`` with the rows not used set to 0 (sample numbers in messages stay the file's)."""
    return data if rows.all() else np.where(rows[:, None], data, 0.0)


def _gap_fix(data: np.ndarray, rows: np.ndarray) -> str:
    """How to fit around the non-finite samples of the used ``rows``: the data.segments between them (each a
    recording of its own), when they leave stretches of at least 2 samples; else interpolate or fill."""
    from .finite import FILL

    good = np.isfinite(data).all(axis=1) & rows
    edges = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(np.int8), [0]])))
    runs = [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2]) if b - a > 1]
    if not runs or len(runs) > 8:
        return FILL
    shown = ", ".join(f"[{a}, {b}]" for a, b in runs)
    return f"{FILL}, or fit around them: data.segments: [{shown}] (each a recording of its own)"


def _file_recordings(
    src: dict[str, Any], resolve, missing_outputs: bool = False
) -> tuple[list[Recording], float | None]:
    """The recordings of a file source, and the sampling time its time column gives (None without one).
    ``missing_outputs``: the outputs may be NaN (unknown: a test set whose outputs the user holds back)."""
    paths = src["path"] if isinstance(src["path"], list) else [src["path"]]
    selectors = list(src["input"]) + list(src["output"])
    n_in = len(src["input"])
    recs: list[Recording] = []
    steps: list[tuple[float, str]] = []
    for p in paths:
        data, t, path, label = _read_recording(p, src, resolve)
        names = [str(s) for s in selectors]
        # only the samples the segments use must be finite (with resample, segments index the resampled grid)
        used = (src.get("segments") if not src.get("resample") else None) or [(0, data.shape[0])]
        rows = np.zeros(data.shape[0], dtype=bool)
        for a, b in used:
            rows[max(a, 0) : max(b, 0)] = True
        if missing_outputs:  # NaN outputs are unknown ones (never scored); inf is still an error
            check_finite(_only(data[:, :n_in], rows), names[:n_in], str(path))
            check_finite(np.where(np.isnan(data[:, n_in:]), 0.0, _only(data[:, n_in:], rows)), names[n_in:], str(path))
        else:
            problem = non_finite(_only(data, rows), names)
            if problem is not None:  # the segments hint reads the whole file: only when there is a gap
                raise DataError(problem, str(path), _gap_fix(data, rows))
        segments = src.get("segments") or [(0, data.shape[0])]
        if t is not None and src.get("segments") and not src.get("resample"):
            # recordings cut out of one file: only each one's own stamps need be uniform (the cuts may skip gaps)
            for a, b in segments:
                if 0 <= a < b - 1 < data.shape[0]:
                    _, step = resample.uniform(
                        t[a:b] * float(src.get("time_unit") or 1.0), data[a:b], None, f"{path}[{a}:{b}]"
                    )
                    steps.append((step, f"{path}[{a}:{b}]"))
        elif t is not None:
            data, step = resample.uniform(t * float(src.get("time_unit") or 1.0), data, src.get("resample"), str(path))
            steps.append((step, str(path)))
            segments = src.get("segments") or [(0, data.shape[0])]
        for a, b in segments:
            if not 0 <= a < b <= data.shape[0]:
                raise DataError(
                    f"segment [{a}, {b}] lies outside the file's {data.shape[0]} samples",
                    str(path),
                    "correct data.segments",
                )
            name = label if len(segments) == 1 and (a, b) == (0, data.shape[0]) else f"{label}[{a}:{b}]"
            recs.append(
                Recording(
                    name,
                    data[a:b, :n_in].copy(),
                    data[a:b, n_in:].copy(),
                    offset=int(a),
                    input_columns=names[:n_in],
                    output_columns=names[n_in:],
                )
            )
    if not steps:
        return recs, None
    first, where = steps[0]
    for step, other in steps[1:]:
        if abs(step - first) > resample.SAME_STEP * first:
            raise DataError(
                f"sampled every {step:.6g} s while {Path(where).name} is sampled every {first:.6g} s",
                other,
                f"add 'resample: {first:.6g}' to put every recording on one grid",
            )
    return recs, first


def _generator_recording(src: dict[str, Any], where: str) -> tuple[Recording, float, list[str], list[str]]:
    gen = registry.source(src["generator"])
    try:
        params = gen.Params.model_validate(src.get("params") or {})
    except ValueError as exc:
        from ..spec import validation_summary

        raise SpecError(
            f"invalid generator params ({validation_summary(exc)})",
            f"{where}.params",
            f"see the '{src['generator']}' section of `dynmodel schema`",
        ) from None
    rng = np.random.default_rng(int(src.get("seed", 0)))
    u, y = gen.generate(params, int(src.get("n", 10000)), rng)
    u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
    y = np.asarray(y, dtype=np.float64).reshape(len(y), -1)
    in_names, out_names = list(gen.input_names), list(gen.output_names)
    for chosen, names, key in [(src.get("input"), in_names, "input"), (src.get("output"), out_names, "output")]:
        if chosen and list(chosen) != names:
            unknown = [c for c in chosen if c not in names]
            if unknown:
                raise SpecError(
                    f"generator '{gen.name}' has no {key} '{unknown[0]}'", f"{where}.{key}", f"use a subset of {names}"
                )
    if src.get("input"):
        idx = [in_names.index(c) for c in src["input"]]
        u, in_names = u[:, idx], [in_names[i] for i in idx]
    if src.get("output"):
        idx = [out_names.index(c) for c in src["output"]]
        y, out_names = y[:, idx], [out_names[i] for i in idx]
    check_finite(np.column_stack([u, y]), in_names + out_names, f"{where} (generator {gen.name})")
    label = f"{gen.name}(seed={src.get('seed', 0)})"
    st = src.get("sampling_time") or gen.sampling_time(params)
    return Recording(label, u, y), float(st), in_names, out_names


SOURCE_KEYS = (
    "path",
    "input",
    "output",
    "header",
    "columns",
    "delimiter",
    "segments",
    "sampling_time",
    "time_column",
    "time_unit",
    "resample",
    "generator",
    "params",
    "n",
    "seed",
)


def _merge_source(main: dict[str, Any], override: dict[str, Any], split: str, index: int = 0) -> dict[str, Any]:
    """A separate recording: the main source's keys, replaced by those given under data.<split>
    (``index``: the position of a named test set, which offsets a generator's default seed)."""
    given = {k: v for k, v in override.items() if v is not None and k in SOURCE_KEYS}
    base = {k: main.get(k) for k in SOURCE_KEYS if main.get(k) is not None}
    if "path" in given:
        base.pop("generator", None)
        base.pop("params", None)
        base.pop("n", None)
        base.pop("seed", None)
        base.pop("segments", None)
    if "generator" in given:
        base.pop("path", None)
        if given["generator"] != main.get("generator"):
            base.pop("params", None)
    base_params = base.get("params")
    if "params" in given and isinstance(base_params, dict):
        given["params"] = {**base_params, **given["params"]}
    merged = {**base, **given}
    if (
        "generator" in merged
        and "seed" not in given
        and merged.get("generator") == main.get("generator")
        and merged.get("params") == main.get("params")
    ):
        merged["seed"] = int(main.get("seed", 0)) + {"validation": 1, "test": 2}[split] * 1000 + index
    return merged


def _load_source(src: dict[str, Any], resolve, where: str, missing_outputs: bool = False):
    if "generator" in src:
        rec, generated_st, ins, outs = _generator_recording(src, where)
        return [rec], generated_st, ins, outs
    if "input" not in src or "output" not in src:
        raise SpecError(
            "a file source needs 'input' and 'output' column lists", where, "add input: [...] and output: [...]"
        )
    if src.get("resample") is not None and src.get("time_column") is None:
        raise SpecError("resample needs the time stamps", f"{where}.resample", "add time_column: NAME (and time_unit)")
    recs, step = _file_recordings(src, resolve, missing_outputs)
    st: Any = src.get("sampling_time")
    if step is not None:
        if st is not None and abs(float(st) - step) > resample.UNIFORM_TOLERANCE * step:
            raise SpecError(
                f"sampling_time {st:g} disagrees with the time column's step of {step:.6g} s",
                f"{where}.sampling_time",
                "remove sampling_time (the time column gives it)",
            )
        st = step
    elif st is None and not missing_outputs:
        _unused_time_column(src, resolve)
    return recs, float(st or 1.0), [str(s) for s in src["input"]], [str(s) for s in src["output"]]


#: column names read as time stamps when the spec names none (as dynmodel predict does)
TIME_NAMES = ("t", "time", "time_s", "t_s", "zeit")


def time_named(names: list[str], taken: list[str]) -> str | None:
    """The first of ``names`` (case aside) that :data:`TIME_NAMES` calls a time column, other than ``taken``."""
    lower = {n.lower(): n for n in names if n not in taken}
    return next((lower[c] for c in TIME_NAMES if c in lower), None)


def _unused_time_column(src: dict[str, Any], resolve) -> None:
    """Note a column named as time (t, time, ...) with uniform steps other than 1 s that the spec does not use: the
    sampling time then stays 1 s (plots, times in seconds, predict's check of a new file's time column)."""
    import warnings

    from ..textfiles import DataNote
    from .readers import list_columns

    first = src["path"][0] if isinstance(src["path"], list) else src["path"]
    if not isinstance(first, str):
        return
    opts: dict[str, Any] = {"header": bool(src.get("header", True)), "delimiter": src.get("delimiter")}
    try:
        path = resolve(first)
        names = list(src.get("columns") or list_columns(path, **opts))
    except (DataError, SpecError, OSError, ValueError):
        return
    name = time_named(names, [str(c) for c in src["input"] + src["output"]])
    if name is None:
        return
    try:
        t = read_columns(path, [name], columns=src.get("columns"), **opts)[name]
    except (DataError, OSError, ValueError):
        return
    steps = np.diff(t)
    if len(steps) < 2 or not np.isfinite(steps).all():
        return
    step = float(np.median(steps))
    uniform = step > 0 and float(np.max(np.abs(steps - step))) <= resample.UNIFORM_TOLERANCE * step
    if uniform and abs(step - 1.0) > resample.UNIFORM_TOLERANCE:
        warnings.warn(
            DataNote(
                f"{path.name}: the column '{name}' steps by {step:.6g} but data.time_column is not set, so the "
                f"sampling time is 1 s per sample (plots, times in seconds, predict's check of a new file's time "
                f"column); add time_column: {name} (and time_unit if it is not in seconds)"
            ),
            stacklevel=2,
        )


def _split_bounds(split: dict[str, Any], n: int) -> dict[str, tuple[int, int]]:
    bounds: dict[str, tuple[int, int]] = {}
    given = [(k, split[k]) for k in SPLITS if split.get(k) is not None]
    if given and isinstance(given[0][1], (list, tuple)):
        return {k: (int(v[0]), int(v[1])) for k, v in given}
    start = 0.0
    for k, frac in given:
        a = int(round(start * n))
        start += float(frac)
        b = int(round(min(start, 1.0) * n))
        bounds[k] = (a, b)
    return bounds


@dataclass
class _Separate:
    """A separate validation or test set: its recordings and what the spec and the protocol say of it."""

    key: str
    recordings: list[Recording]
    window: int | None = None  # the test set's own init_window (spec)
    score: str | None = None  # the test set's own score (spec)
    protocol_window: int | None = None  # the benchmark protocol's window
    protocol_all: bool = False  # the benchmark protocol scores every sample
    lead_in: int = 0  # unscored samples at the start of each recording (a steady-state lead-in)


#: recordings of one source with its sampling time, input names and output names
LoadedSource = tuple[list[Recording], float, list[str], list[str]]


def _check_separate(what: str, loaded: LoadedSource, main: LoadedSource, where: str) -> None:
    """A separate recording must have the main data's channels and sampling time."""
    _, st_s, ins, outs = loaded
    _, st, in_names, out_names = main
    if len(ins) != len(in_names) or len(outs) != len(out_names):
        raise DataError(
            f"the separate {what} recording has {len(ins)} inputs / {len(outs)} outputs, "
            f"the main data {len(in_names)} / {len(out_names)}",
            where,
            "select the same input and output columns",
        )
    if abs(st_s - st) > resample.SAME_STEP * st:
        raise DataError(
            f"the separate {what} recording is sampled every {st_s}, the main data every {st}",
            f"{where}.sampling_time",
            "resample to a common sampling time",
        )


def _in_memory_sources(sources: Mapping[str, LoadedSource], source: str) -> list[_Separate]:
    """Separate validation / test recordings given in memory (the Python API's arrays)."""
    out = []
    for key in ("validation", "test"):
        if key in sources:
            _check_separate(key, sources[key], sources["data"], f"{source}: data.{key}")
            out.append(_Separate(key, list(sources[key][0])))
    return out


def _separate_sources(data: dict[str, Any], resolve, source: str, main: LoadedSource) -> list[_Separate]:
    """The separate validation and test recordings of a file or generator source."""
    wanted: list[tuple[str, dict[str, Any], str, int]] = []
    if data.get("validation"):
        wanted.append(("validation", data["validation"], "data.validation", 0))
    test = data.get("test")
    if isinstance(test, dict):
        wanted.append(("test", test, "data.test", 0))
    elif isinstance(test, list):
        wanted += [(f"test:{t['name']}", t, f"data.test[{i}]", i) for i, t in enumerate(test)]
    out: list[_Separate] = []
    for key, override, where, index in wanted:
        src = _merge_source(data, override, "validation" if key == "validation" else "test", index)
        loaded = _load_source(src, resolve, where, missing_outputs=key != "validation")
        what = "validation" if key == "validation" else f"test set '{key[5:]}'" if ":" in key else "test"
        _check_separate(what, loaded, main, f"{source}: {where}")
        recs = loaded[0]
        out.append(_Separate(key, recs, override.get("init_window"), override.get("score")))
    return out


def _benchmark_sources(data: dict[str, Any], bench) -> list[_Separate]:
    """The test sets of a benchmark source (those named in data.test, in that order, else all)."""
    chosen = bench.tests
    if data.get("test"):
        by_name = {t.name: t for t in bench.tests}
        chosen = [by_name[n] for n in data["test"] if n in by_name]
    return [
        _Separate(
            "test" if t.name is None else f"test:{t.name}",
            t.recordings,
            protocol_window=t.window,
            protocol_all=t.score_all,
            lead_in=t.lead_in,
        )
        for t in chosen
    ]


def _load_benchmark(data: dict[str, Any], resolve):
    bench = registry.benchmark(str(data["benchmark"]))
    return bench.load(resolve(str(data["root"])))


def _protocol(
    data: dict[str, Any], spec, bench, separate: list[_Separate], keys: list[str]
) -> tuple[dict[str, int], set[str]]:
    """Initialization windows and score-everything splits per validation / test key.

    Precedence: a named test set's own ``init_window`` / ``score``, then ``evaluation.score: all``, then
    ``data.init_window``, then the benchmark's protocol; without any, no window (scored as before)."""
    iw = data.get("init_window")
    per = {"validation": iw, "test": iw} if isinstance(iw, int) else dict(iw or {})
    own = {s.key: s for s in separate}
    global_all = spec.evaluation.score == "all"
    windows: dict[str, int] = {}
    every: set[str] = set()
    for key in keys:
        base = "validation" if key == "validation" else "test"
        sep = own.get(key, _Separate(key, []))
        w_proto, all_proto = sep.protocol_window, sep.protocol_all
        if key == "validation" and bench is not None:
            w_proto, all_proto = bench.window, bench.score_all
        explicit = sep.window if sep.window is not None else per.get(base)
        if sep.score is not None:
            score_all = sep.score == "all"
        elif global_all:
            score_all = True
        elif explicit is not None:
            score_all = False
        else:
            score_all = all_proto
        window = explicit if explicit is not None else w_proto
        if score_all:
            every.add(key)
        elif window is not None:
            windows[key] = int(window)
    return windows, every


def own_runs(recordings: list[Recording], ranges: dict[str, list[Range]], keys: set[str]) -> None:
    """Give every range of these splits that starts inside a recording a recording of its own, so
    that its free run starts at its first sample (initialized from its own window)."""
    for key in keys:
        moved = []
        for rec, a, b in ranges.get(key, []):
            if a > 0:
                r = recordings[rec]
                root = rec if r.origin is None else r.origin
                recordings.append(
                    replace(
                        r,
                        name=f"{r.name}[{a}:{b}]",
                        u=r.u[a:b].copy(),
                        y=r.y[a:b].copy(),
                        offset=r.offset + a,
                        origin=root,
                    )
                )
                moved.append((len(recordings) - 1, 0, b - a))
            else:
                moved.append((rec, a, b))
        ranges[key] = moved


def _check_units(spec: Spec | ArraySpec, out_names: list[str]) -> None:
    for name in spec.evaluation.units:
        if name not in out_names:
            raise SpecError(
                f"'{name}' is not an output", f"{spec.source}: evaluation.units", f"the outputs are {out_names}"
            )


def load_dataset(spec: Spec | ArraySpec, sources: Mapping[str, LoadedSource] | None = None) -> Dataset:
    """Read or generate every recording of ``spec.data`` and lay out the splits.

    ``sources`` replaces the reading with recordings already in memory (the Python API's arrays):
    ``"data"`` for the main source, optionally ``"validation"`` / ``"test"`` for separate recordings;
    the spec's own sources are then not read, everything else (splits, transient, noise) applies."""
    data = spec.data.model_dump(mode="python")
    resolve = spec.resolve_path
    bench = None
    if sources:
        main_recs, st, in_names, out_names = sources["data"]
        separate = _in_memory_sources(sources, spec.source)
    elif data.get("benchmark") is not None:
        bench = _load_benchmark(data, resolve)
        main_recs, st, in_names, out_names = bench.train, bench.sampling_time, bench.input_names, bench.output_names
        separate = _benchmark_sources(data, bench)
    else:
        main_recs, st, in_names, out_names = _load_source(data, resolve, "data")
        separate = _separate_sources(data, resolve, spec.source, (main_recs, st, in_names, out_names))
    _check_units(spec, out_names)
    recordings: list[Recording] = list(main_recs)
    ranges: dict[str, list[Range]] = {s: [] for s in SPLITS}

    given = {"validation" if s.key == "validation" else "test" for s in separate}
    split = data.get("split")
    if split is None:
        split = {"train": 0.6, "validation": 0.2, "test": 0.2}
        if "test" in given and "validation" in given:
            split = {"train": 1.0}
        elif "test" in given:
            split = {"train": 0.8, "validation": 0.2}
        elif "validation" in given:
            split = {"train": 0.8, "test": 0.2}
    for s in given:
        if split.get(s) is not None:
            if sources:  # dynmodel.fit(spec, data={...})
                where, fix = f"the '{s}' recording of data=", f"remove {s} from the spec's data.split or from data="
            else:
                where = "the benchmark's test sets" if bench is not None else f"a separate data.{s} source"
                fix = "remove it from data.split"
            raise SpecError(
                f"the {s} split is given twice: in data.split and as {where}", f"{spec.source}: data.split.{s}", fix
            )
    if split.get("train") is None:
        raise SpecError(
            "data.split has no train part", f"{spec.source}: data.split", "add train: 0.7 (or a sample range)"
        )

    for i, rec in enumerate(main_recs):
        for s, (a, b) in _split_bounds(split, rec.n).items():
            if b > rec.n:
                raise DataError(
                    f"the {s} range [{a}, {b}] needs {b} samples but recording '{rec.name}' has {rec.n}",
                    f"{spec.source}: data.split.{s}",
                    "shorten the range, or provide more data (data.n for generators)",
                )
            if b > a:
                ranges[s].append((i, a, b))

    for sep in separate:
        for rec in sep.recordings:
            rec = replace(rec, name=f"{sep.key}:{rec.name}")
            recordings.append(rec)
            ranges.setdefault(sep.key, []).append((len(recordings) - 1, 0, rec.n))

    keys = [k for k, v in ranges.items() if v and k != "train"]
    windows, every = _protocol(data, spec, bench, separate, keys)
    own_runs(recordings, ranges, set(windows) | every)
    ds = Dataset(
        recordings,
        {k: v for k, v in ranges.items() if v},
        int(data.get("transient", 0)),
        list(in_names),
        list(out_names),
        st,
        transient_at=data.get("transient_at", "segment"),
        windows=windows,
        score_all=every,
        units=dict(bench.units) if bench is not None else {},
        lead_in={s.key: s.lead_in for s in separate if s.lead_in},
    )
    _add_noise(ds, data.get("noise"), spec.seed)
    _check_sizes(ds, spec.source)
    check_signals(ds, spec.source)  # a corrupt value is refused before it could pass for a spike
    replace_spikes = data.get("spikes", "replace") == "replace"
    ds.artifacts = find_artifacts(ds.recordings, ds.ranges, ds.output_names, replace_spikes)
    return ds


def _add_noise(ds: Dataset, noise: dict[str, Any] | None, seed: int) -> None:
    """Add N(0, (std * sigma_y)^2) to the outputs of the chosen splits (sigma_y: clean std of that recording)."""
    if not noise or noise["std"] == 0:
        return
    seq = np.random.SeedSequence(noise["seed"] if noise.get("seed") is not None else [seed, 0x6E6F697365])
    rng = np.random.default_rng(seq)
    clean_std = [r.y.std(axis=0) for r in ds.recordings]
    for split in noise["splits"]:
        for rec, start, stop in ds.ranges.get(split, []):
            r = ds.recordings[rec]
            r.y[start:stop] += noise["std"] * clean_std[rec] * rng.standard_normal((stop - start, r.y.shape[1]))


def _check_sizes(ds: Dataset, source: str) -> None:
    for split, rngs in ds.ranges.items():
        if ds.n_scored(split) == 0:
            longest = max(stop - start for _, start, stop in rngs)
            window = ds.windows.get(split, 0)
            if window >= longest:
                raise DataError(
                    f"the {split} split has no sample left after the initialization window of {window} "
                    f"(its longest recording has {longest} samples)",
                    f"{source}: data.init_window",
                    "lower the window or enlarge the split",
                )
            raise DataError(
                f"the {split} split has no sample left after the transient of {ds.transient} "
                f"(its longest segment has {longest} samples)",
                f"{source}: data.transient",
                "lower data.transient or enlarge the split",
            )
    if "train" not in ds.ranges:
        raise DataError("no training samples", f"{source}: data.split", "give a train part")
    if ds.n_scored("train") < 10:
        raise DataError(
            f"only {ds.n_scored('train')} training samples after the transient",
            f"{source}: data",
            "provide more data or lower data.transient",
        )


def describe(ds: Dataset) -> list[dict[str, Any]]:
    """Per split: recordings, samples and scored samples (for `dynmodel validate`)."""
    rows = []
    for split in ds.splits():
        rows.append(
            {
                "split": split,
                "segments": [ds.recordings[r].span(a, b) for r, a, b in ds.ranges[split]],
                "samples": sum(b - a for _, a, b in ds.ranges[split]),
                "scored": ds.n_scored(split),
            }
        )
    return rows
