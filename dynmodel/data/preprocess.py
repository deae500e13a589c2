"""Map physical signals to the model's space and back: delay lines and scaling.

Delay lines (thesis 6.3.2) append, for every input channel, copies delayed by the given numbers
of samples; before a recording's first sample the delayed copy holds that first value. With
``delay_form: difference`` they append u(t) - u(t - d) instead, rescaled to unit standard deviation
on the training split: the same information, but invariant to where the signal lies (a position
enters as the displacements over the last d samples, which is what friction depends on).
Scaling is affine per channel, with statistics from the training split only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .dataset import Dataset


def delayed_copies(u: np.ndarray, delays: list[int]) -> np.ndarray:
    """``[u, u(t - d1), u(t - d2), ...]``; samples before the start repeat ``u[0]``."""
    if not delays:
        return u
    n = u.shape[0]
    out = [u]
    for d in delays:
        shifted = np.empty_like(u)
        k = min(d, n)
        shifted[:k] = u[0]
        shifted[k:] = u[: n - k]
        out.append(shifted)
    return np.concatenate(out, axis=1)


def delayed_differences(u: np.ndarray, delays: list[int]) -> np.ndarray:
    """``[u, u - u(t - d1), u - u(t - d2), ...]`` (zero before the start)."""
    if not delays:
        return u
    k = u.shape[1]
    full = delayed_copies(u, delays)
    for j in range(len(delays)):
        full[:, k * (j + 1):k * (j + 2)] = u - full[:, k * (j + 1):k * (j + 2)]
    return full


@dataclass
class Preprocessor:
    input_names: list[str]
    output_names: list[str]
    sampling_time: float
    delay_lines: list[int] = field(default_factory=list)
    scaling: str = "standard"
    input_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    input_scale: np.ndarray = field(default_factory=lambda: np.ones(0))
    output_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    output_scale: np.ndarray = field(default_factory=lambda: np.ones(0))
    delay_form: str = "copy"  # copy | difference
    difference_scale: np.ndarray = field(default_factory=lambda: np.ones(0))  # difference form, per channel

    @classmethod
    def fit(cls, ds: Dataset, delay_lines: list[int], scaling: str, delay_form: str = "copy") -> "Preprocessor":
        """Per-channel mean and std of the training ranges (``scaling: standard``)."""
        n_in, n_out = len(ds.input_names), len(ds.output_names)
        pre = cls(list(ds.input_names), list(ds.output_names), ds.sampling_time, list(delay_lines), scaling,
                  np.zeros(n_in), np.ones(n_in), np.zeros(n_out), np.ones(n_out), delay_form)
        if scaling == "standard":
            us = [ds.recordings[r].u[a:b] for r, a, b in ds.scored("train")]
            ys = [ds.recordings[r].y[a:b] for r, a, b in ds.scored("train")]
            u, y = np.concatenate(us), np.concatenate(ys)
            pre.input_offset, pre.input_scale = u.mean(axis=0), _safe_std(u)
            pre.output_offset, pre.output_scale = y.mean(axis=0), _safe_std(y)
        pre.difference_scale = np.ones(n_in * len(delay_lines))
        if delay_form == "difference" and delay_lines:
            diffs = [pre._delayed(ds.recordings[r].u)[a:b, n_in:] for r, a, b in ds.scored("train")]
            pre.difference_scale = _safe_std(np.concatenate(diffs))
        return pre

    @property
    def model_input_names(self) -> list[str]:
        """Inputs, then one block per delay line: ``u@d`` (copy) or ``u~d`` (difference u(t) - u(t - d))."""
        names = list(self.input_names)
        mark = "~" if self.delay_form == "difference" else "@"
        for d in self.delay_lines:
            names += [f"{n}{mark}{d}" for n in self.input_names]
        return names

    @property
    def n_model_inputs(self) -> int:
        return len(self.input_names) * (1 + len(self.delay_lines))

    def _delayed(self, u: np.ndarray) -> np.ndarray:
        scaled = (u - self.input_offset) / self.input_scale
        if self.delay_form == "difference":
            return delayed_differences(scaled, self.delay_lines)
        return delayed_copies(scaled, self.delay_lines)

    def inputs(self, u: np.ndarray) -> np.ndarray:
        """Physical inputs (n, n_inputs) -> model inputs (n, n_inputs * (1 + len(delay_lines)))."""
        u = _columns(u, len(self.input_names), "input")
        v = self._delayed(u)
        if self.delay_form == "difference" and self.delay_lines:
            v[:, len(self.input_names):] /= self.difference_scale
        return v

    def outputs(self, y: np.ndarray) -> np.ndarray:
        y = _columns(y, len(self.output_names), "output")
        return (y - self.output_offset) / self.output_scale

    def physical_outputs(self, y_model: np.ndarray) -> np.ndarray:
        return y_model * self.output_scale + self.output_offset

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays = {"input_offset": self.input_offset, "input_scale": self.input_scale,
                  "output_offset": self.output_offset, "output_scale": self.output_scale}
        attrs = {"input_names": self.input_names, "output_names": self.output_names,
                 "sampling_time": self.sampling_time, "delay_lines": self.delay_lines, "scaling": self.scaling}
        if self.delay_form != "copy":
            arrays["difference_scale"] = self.difference_scale
            attrs["delay_form"] = self.delay_form
        return arrays, attrs

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> "Preprocessor":
        delays = [int(d) for d in attrs["delay_lines"]]
        form = str(attrs.get("delay_form", "copy"))  # files written before the difference form hold copies
        diff = np.asarray(arrays.get("difference_scale", np.ones(len(attrs["input_names"]) * len(delays))),
                          dtype=np.float64)
        return cls(list(attrs["input_names"]), list(attrs["output_names"]), float(attrs["sampling_time"]),
                   delays, str(attrs["scaling"]),
                   *(np.asarray(arrays[k], dtype=np.float64) for k in
                     ("input_offset", "input_scale", "output_offset", "output_scale")), form, diff)


def _columns(a: np.ndarray, k: int, what: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[1] != k:
        raise ValueError(f"expected {k} {what} column(s), got an array of shape {a.shape}")
    return a


def _safe_std(a: np.ndarray) -> np.ndarray:
    s = a.std(axis=0)
    return np.where(s > 0, s, 1.0)
