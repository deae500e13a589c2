"""The data object a family's ``fit`` receives: model-space series and scored ranges.

Families see only recordings that hold training or validation samples, cut after the last of
them; outputs inside test ranges are NaN so that no family can peek at the test split.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dataset import Dataset, Range
from .preprocess import Preprocessor

#: a free run is declared diverged when it leaves the training output range widened by this
#: many range widths on either side
DIVERGENCE_MARGIN = 10.0


@dataclass
class Series:
    u: np.ndarray  # (n, n_model_inputs), scaled, with delay lines
    y: np.ndarray  # (n, n_outputs), scaled; NaN inside test ranges

    @property
    def n(self) -> int:
        return self.u.shape[0]


@dataclass
class TrainingData:
    series: list[Series]
    segments: dict[str, list[Range]]  # split -> (series index, first scored sample, stop)
    input_names: list[str]
    output_names: list[str]
    sampling_time: float
    #: physical output = model output * output_scale + output_offset (to convert user-given values)
    output_offset: np.ndarray | None = None
    output_scale: np.ndarray | None = None
    #: the most measured outputs a run may start from on a split with a protocol (its initialization window;
    #: 0 where every sample is scored), None without one: a family that chooses its tune-in on the data keeps
    #: within it
    warmup_limit: int | None = None

    def to_model_outputs(self, values: np.ndarray) -> np.ndarray:
        """Physical output values (per output column) in model space."""
        v = np.asarray(values, dtype=np.float64)
        if self.output_offset is None or self.output_scale is None:
            return v
        return (v - self.output_offset) / self.output_scale

    @property
    def n_inputs(self) -> int:
        return self.series[0].u.shape[1]

    @property
    def n_outputs(self) -> int:
        return self.series[0].y.shape[1]

    def has(self, split: str) -> bool:
        return bool(self.segments.get(split))

    def stack(self, split: str, per_series: list[np.ndarray]) -> np.ndarray:
        """Rows of ``split`` taken from per-series arrays (e.g. network states), stacked
        (a view, without copying, when the split is a single segment)."""
        pieces = [per_series[s][a:b] for s, a, b in self.segments[split]]
        return pieces[0] if len(pieces) == 1 else np.concatenate(pieces)

    def targets(self, split: str) -> np.ndarray:
        return self.stack(split, [s.y for s in self.series])

    def output_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Model-space band outside of which a free run counts as diverged."""
        y = self.targets("train")
        lo, hi = y.min(axis=0), y.max(axis=0)
        width = np.maximum(hi - lo, 1e-12)
        return lo - DIVERGENCE_MARGIN * width, hi + DIVERGENCE_MARGIN * width


def training_data(ds: Dataset, pre: Preprocessor) -> TrainingData:
    fit_splits = ("train", "validation")
    used = sorted({r for s in fit_splits for r, _, _ in ds.ranges.get(s, [])})
    index = {r: i for i, r in enumerate(used)}
    series: list[Series] = []
    for r in used:
        rec = ds.recordings[r]
        end = max(b for s in fit_splits for rr, _, b in ds.ranges.get(s, []) if rr == r)
        y = pre.outputs(rec.y[:end]).copy()
        for rr, a, b in ds.ranges.get("test", []):
            if rr == r and a < end:
                y[a : min(b, end)] = np.nan
        series.append(Series(pre.inputs(rec.u)[:end], y))
    segments = {s: [(index[r], a, b) for r, a, b in ds.scored(s)] for s in fit_splits if ds.ranges.get(s)}
    return TrainingData(
        series,
        segments,
        pre.model_input_names,
        list(pre.output_names),
        ds.sampling_time,
        np.asarray(pre.output_offset, dtype=np.float64),
        np.asarray(pre.output_scale, dtype=np.float64),
        ds.warmup_limit(),
    )
