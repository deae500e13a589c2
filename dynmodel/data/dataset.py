"""From the ``data`` section of a spec to recordings with train / validation / test ranges.

A *recording* is one continuous series: states and free runs restart at its first sample.
Each split is a list of ``(recording, start, stop)`` ranges; the ``transient`` samples at the
start of every range are excluded from fitting and scoring; scores pool over recordings.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import registry
from ..errors import DataError, SpecError
from ..spec import SPLITS
from . import resample
from .checks import check_signals
from .readers import read_columns

Range = tuple[int, int, int]  # (recording index, start, stop)


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

    def splits(self) -> list[str]:
        return [s for s in SPLITS if self.ranges.get(s)]

    def scored(self, split: str, warmup: int = 0) -> list[Range]:
        """Ranges of ``split`` without the transient (and without ``warmup`` samples at recording starts)."""
        out = []
        for rec, start, stop in self.ranges.get(split, []):
            if self.transient_at == "segment":
                first = start + self.transient
            else:  # only the recording's first samples, where the state restarts
                first = max(start, self.transient)
            first = max(first, warmup)
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
        width = np.maximum(hi - lo, np.finfo(float).tiny)
        found = []
        for split in [s for s in self.ranges if s != "train"]:
            for j, name in enumerate(self.input_names):
                worst = (0.0, -1, -1)
                for rec, start, stop in self.ranges.get(split, []):
                    u = self.recordings[rec].u[start:stop, j]
                    if u.size == 0:
                        continue
                    excess = np.maximum(u - hi[j], lo[j] - u) / width[j]
                    k = int(np.argmax(excess))
                    if excess[k] > worst[0]:
                        worst = (float(excess[k]), rec, start + k)
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

    def excursion_notes(self) -> list[str]:
        """:meth:`input_excursions` as sentences for a user."""
        return [
            f"the {e['split']} input '{e['input']}' leaves the training range by {100 * e['excess']:.0f} % of its "
            f"width (sample {e['sample']} of '{e['recording']}'): the model extrapolates there, and the "
            f"{e['split']} scores include it"
            for e in self.input_excursions()
        ]

    def concat_outputs(self, split: str) -> np.ndarray:
        """Outputs of ``split`` concatenated (the pieces of :meth:`concat_inputs`)."""
        pieces = [self.recordings[rec].y[start:stop] for rec, start, stop in self.ranges.get(split, [])]
        return np.concatenate(pieces) if pieces else np.empty((0, len(self.output_names)))


# ---------------------------------------------------------------- loading sources


def _check_finite(arr: np.ndarray, names: list[str], where: str) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        rows, cols = np.nonzero(bad)
        row, col = int(rows[0]), int(cols[0])
        kind = "NaN" if np.isnan(arr[row, col]) else "inf"
        count = int(bad[:, col].sum())
        raise DataError(
            f"column '{names[col]}' has {kind} at sample {row} ({count} non-finite value"
            f"{'s' if count > 1 else ''} in that column)",
            where,
            "remove, interpolate or fill those samples before fitting",
        )


def _file_recordings(src: dict[str, Any], resolve) -> tuple[list[Recording], float | None]:
    """The recordings of a file source, and the sampling time its time column gives (None without one)."""
    paths = src["path"] if isinstance(src["path"], list) else [src["path"]]
    selectors = list(src["input"]) + list(src["output"])
    n_in = len(src["input"])
    time_col = src.get("time_column")
    recs: list[Recording] = []
    steps: list[tuple[float, str]] = []
    for p in paths:
        path = resolve(p)
        wanted = selectors + ([time_col] if time_col is not None else [])
        cols = read_columns(
            path, wanted, header=src.get("header", True), columns=src.get("columns"), delimiter=src.get("delimiter")
        )
        data = np.column_stack([cols[str(s).strip()] for s in selectors]).astype(np.float64)
        names = [str(s) for s in selectors]
        _check_finite(data, names, str(path))
        if time_col is not None:
            t = cols[str(time_col).strip()] * float(src.get("time_unit") or 1.0)
            data, step = resample.uniform(t, data, src.get("resample"), str(path))
            steps.append((step, str(path)))
        segments = src.get("segments") or [(0, data.shape[0])]
        for a, b in segments:
            if not 0 <= a < b <= data.shape[0]:
                raise DataError(
                    f"segment [{a}, {b}] lies outside the file's {data.shape[0]} samples",
                    str(path),
                    "correct data.segments",
                )
            name = path.name if len(segments) == 1 and (a, b) == (0, data.shape[0]) else f"{path.name}[{a}:{b}]"
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
    _check_finite(np.column_stack([u, y]), in_names + out_names, f"{where} (generator {gen.name})")
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


def _merge_source(main: dict[str, Any], override: dict[str, Any], split: str) -> dict[str, Any]:
    """A separate recording: the main source's keys, replaced by those given under data.<split>."""
    given = {k: v for k, v in override.items() if v is not None}
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
    if "params" in given and isinstance(base.get("params"), dict):
        given["params"] = {**base["params"], **given["params"]}
    merged = {**base, **given}
    if (
        "generator" in merged
        and "seed" not in given
        and merged.get("generator") == main.get("generator")
        and merged.get("params") == main.get("params")
    ):
        merged["seed"] = int(main.get("seed", 0)) + {"validation": 1, "test": 2}[split] * 1000
    return merged


def _load_source(src: dict[str, Any], resolve, where: str):
    if "generator" in src:
        rec, st, ins, outs = _generator_recording(src, where)
        return [rec], st, ins, outs
    if "input" not in src or "output" not in src:
        raise SpecError(
            "a file source needs 'input' and 'output' column lists", where, "add input: [...] and output: [...]"
        )
    if src.get("resample") is not None and src.get("time_column") is None:
        raise SpecError("resample needs the time stamps", f"{where}.resample", "add time_column: NAME (and time_unit)")
    recs, step = _file_recordings(src, resolve)
    st = src.get("sampling_time")
    if step is not None:
        if st is not None and abs(float(st) - step) > resample.UNIFORM_TOLERANCE * step:
            raise SpecError(
                f"sampling_time {st:g} disagrees with the time column's step of {step:.6g} s",
                f"{where}.sampling_time",
                "remove sampling_time (the time column gives it)",
            )
        st = step
    return recs, float(st or 1.0), [str(s) for s in src["input"]], [str(s) for s in src["output"]]


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


#: recordings of one source with its sampling time, input names and output names
LoadedSource = tuple[list[Recording], float, list[str], list[str]]


def load_dataset(spec, sources: Mapping[str, LoadedSource] | None = None) -> Dataset:
    """Read or generate every recording of ``spec.data`` and lay out the splits.

    ``sources`` replaces the reading with recordings already in memory (the Python API's arrays):
    ``"data"`` for the main source, optionally ``"validation"`` / ``"test"`` for separate recordings;
    the spec's own sources are then not read, everything else (splits, transient, noise) applies."""
    data = spec.data.model_dump(mode="python")
    resolve = spec.resolve_path
    main_recs, st, in_names, out_names = sources["data"] if sources else _load_source(data, resolve, "data")
    recordings: list[Recording] = list(main_recs)
    ranges: dict[str, list[Range]] = {s: [] for s in SPLITS}

    separate: dict[str, Any] = {s: data.get(s) for s in ("validation", "test") if data.get(s)}
    if sources:
        separate = {s: sources[s] for s in ("validation", "test") if s in sources}
    split = data.get("split")
    if split is None:
        split = {"train": 0.6, "validation": 0.2, "test": 0.2}
        if "test" in separate and "validation" in separate:
            split = {"train": 1.0}
        elif "test" in separate:
            split = {"train": 0.8, "validation": 0.2}
        elif "validation" in separate:
            split = {"train": 0.8, "test": 0.2}
    for s in separate:
        if split.get(s) is not None:
            raise SpecError(
                f"the {s} split is given twice: in data.split and as a separate data.{s} source",
                f"{spec.source}: data.split.{s}",
                "remove one of them",
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

    for s, override in separate.items():
        if sources:
            recs, st_s, ins, outs = override
        else:
            recs, st_s, ins, outs = _load_source(_merge_source(data, override, s), resolve, f"data.{s}")
        if len(ins) != len(in_names) or len(outs) != len(out_names):
            raise DataError(
                f"the separate {s} recording has {len(ins)} inputs / {len(outs)} outputs, "
                f"the main data {len(in_names)} / {len(out_names)}",
                f"{spec.source}: data.{s}",
                "select the same input and output columns",
            )
        if abs(st_s - st) > resample.SAME_STEP * st:
            raise DataError(
                f"the separate {s} recording is sampled every {st_s}, the main data every {st}",
                f"{spec.source}: data.{s}.sampling_time",
                "resample to a common sampling time",
            )
        for rec in recs:
            rec.name = f"{s}:{rec.name}"
            recordings.append(rec)
            ranges[s].append((len(recordings) - 1, 0, rec.n))

    ds = Dataset(
        recordings,
        {k: v for k, v in ranges.items() if v},
        int(data.get("transient", 0)),
        in_names,
        out_names,
        st,
        transient_at=data.get("transient_at", "segment"),
    )
    _add_noise(ds, data.get("noise"), spec.seed)
    _check_sizes(ds, spec.source)
    check_signals(ds, spec.source)
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
