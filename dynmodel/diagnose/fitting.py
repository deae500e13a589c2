"""Fits of a spec and of its extensions, sharing loaded data and caching results by spec content."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import engine
from ..data import load_dataset
from ..data.dataset import Dataset
from ..family import Progress, no_progress
from ..model import FittedModel, Run
from ..spec import Spec, validate_spec

#: data keys that only change the preprocessing, not the loaded recordings
PREPROCESSING_KEYS = ("delay_lines", "derived_inputs", "detrend", "scaling")


@dataclass
class Fit:
    raw: dict[str, Any]  # the spec mapping (paths absolute)
    spec: Any  # the validated spec
    model: FittedModel
    runs: list[Run]
    ds: Dataset
    seconds: float

    @property
    def metrics(self) -> dict[str, Any]:
        return self.model.metrics

    def nmse(self, split: str) -> float:
        """Free-run NMSE of a split; inf when it diverged, NaN when the split is absent."""
        m = self.metrics.get(split)
        if m is None:
            return float("nan")
        return float("inf") if m.get("nmse") is None else float(m["nmse"])

    def residual(self, split: str, warmup: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(measured, free run) on the scored samples of a split, concatenated (NaN after a divergence);
        ``warmup``: the samples left out at recording starts (default the model's own tune-in; a comparison
        of two models passes the larger of their two, so that both are scored on the same samples)."""
        rows = self.ds.scored(split, warmup=self.model.warmup if warmup is None else warmup)
        if not rows:
            return np.empty((0, len(self.model.output_names))), np.empty((0, len(self.model.output_names)))
        y = np.concatenate([self.ds.recordings[r].y[a:b] for r, a, b in rows])
        yhat = np.concatenate([self.runs[r].y[a:b] for r, a, b in rows])
        return y, yhat


class Fitter:
    """Fits spec mappings derived from one user spec; datasets are loaded once per data source."""

    def __init__(self, source: str, base_dir: Path, progress: Progress = no_progress):
        self.source = source
        self.base_dir = base_dir
        self.progress = progress
        self._fits: dict[str, Fit] = {}
        self._data: dict[str, Dataset] = {}
        self._references: dict[int, Any] = {}

    def references(self, ds: Dataset):
        """The quick references of a loaded dataset (:func:`.reference.references`), computed once."""
        from .reference import references

        key = id(ds)
        if key not in self._references:
            self.progress("reference", None, "mean and linear ARX/OE references")
            self._references[key] = references(ds)
        return self._references[key]

    def _data_key(self, spec: Spec) -> str:
        data = spec.data.model_dump(mode="json")
        for key in PREPROCESSING_KEYS:
            data.pop(key, None)
        noise = data.get("noise") or {}
        seed = spec.seed if noise and noise.get("seed") is None else None
        return json.dumps([data, seed], sort_keys=True)

    def validate(self, raw: dict[str, Any]):
        return validate_spec(raw, self.source, self.base_dir)

    def fit(self, raw: dict[str, Any], seed: int | None = None, label: str = "") -> Fit:
        """Fit the spec mapping ``raw`` (with another seed if given); cached by content."""
        raw = dict(raw)
        if seed is not None:
            raw["seed"] = int(seed)
        key = json.dumps(raw, sort_keys=True, default=str)
        if key in self._fits:
            return self._fits[key]
        spec = self.validate(raw)
        dkey = self._data_key(spec)
        if dkey not in self._data:
            self.progress("data", None, "loading")
            self._data[dkey] = load_dataset(spec)
        ds = self._data[dkey]
        self.progress("fit", None, f"{label or spec.model.family} (seed {spec.seed})")
        t0 = time.perf_counter()
        model, runs = engine.fit_dataset(spec, ds, self.progress)
        fit = Fit(raw, spec, model, runs, ds, time.perf_counter() - t0)
        self._fits[key] = fit
        return fit
