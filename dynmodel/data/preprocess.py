"""Map physical signals to the model's space and back: delay lines, derived inputs, detrending, scaling.

Delay lines (thesis 6.3.2) append, for every input channel, copies delayed by the given numbers
of samples; before a recording's first sample the delayed copy holds that first value. With
``delay_form: difference`` they append u(t) - u(t - d) instead, rescaled to unit standard deviation
on the training split: the same information, but invariant to where the signal lies (a position
enters as the displacements over the last d samples, which is what friction depends on). Derived
inputs (:mod:`.derived`: time functions, direction of motion, change since the last reversal)
follow them. Detrending subtracts T(t) = sum_j c_j f_j(t) from the outputs, the c_j fitted by
least squares on the training outputs together with one constant per recording and a linear term
in every input and derived input (so that the input's own slow variation does not leak into the
trend); predictions get T(t) back, so scores stay in the measured units. Every array handed to :meth:`Preprocessor.inputs`,
:meth:`~Preprocessor.outputs` and :meth:`~Preprocessor.physical_outputs` starts at a
recording's first sample (t = 0), as free runs do. Scaling is affine per channel, with
statistics from the training split only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import derived as derived_mod
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
        full[:, k * (j + 1) : k * (j + 2)] = u - full[:, k * (j + 1) : k * (j + 2)]
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
    #: derived input channels (JSON forms of the spec's items) and their scaling
    derived: list[dict[str, Any]] = field(default_factory=list)
    derived_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    derived_scale: np.ndarray = field(default_factory=lambda: np.ones(0))
    #: output trend: time functions and their coefficients (len(detrend), n_outputs)
    detrend: list[Any] = field(default_factory=list)
    trend_coef: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    #: delay lines as copies u(t - d) or differences u(t) - u(t - d) (scaled per channel)
    delay_form: str = "copy"
    difference_scale: np.ndarray = field(default_factory=lambda: np.ones(0))

    @classmethod
    def fit(
        cls,
        ds: Dataset,
        delay_lines: list[int],
        scaling: str,
        derived: list[dict[str, Any]] | None = None,
        detrend: list[Any] | None = None,
        delay_form: str = "copy",
    ) -> Preprocessor:
        """Trend coefficients, then per-channel mean and std of the training ranges (``scaling: standard``).

        Raises ValueError when a derived input names an unknown input column."""
        n_in, n_out = len(ds.input_names), len(ds.output_names)
        items = [{k: v for k, v in dict(item).items() if v is not None} for item in (derived or [])]
        derived_mod.check(items, ds.input_names, ds.output_names)
        pre = cls(
            list(ds.input_names),
            list(ds.output_names),
            ds.sampling_time,
            list(delay_lines),
            scaling,
            np.zeros(n_in),
            np.ones(n_in),
            np.zeros(n_out),
            np.ones(n_out),
            items,
            np.zeros(len(items)),
            np.ones(len(items)),
            list(detrend or []),
            np.zeros((len(detrend or []), n_out)),
            delay_form,
            np.ones(n_in * len(delay_lines)),
        )
        train = ds.scored("train")
        if pre.detrend:
            pre.trend_coef = _fit_trend(ds, train, pre.detrend, items)
        if scaling == "standard":
            us = [ds.recordings[r].u[a:b] for r, a, b in train]
            ys = [pre._detrended(ds.recordings[r].y[:b])[a:b] for r, a, b in train]
            u, y = np.concatenate(us), np.concatenate(ys)
            pre.input_offset, pre.input_scale = u.mean(axis=0), _safe_std(u)
            pre.output_offset, pre.output_scale = y.mean(axis=0), _safe_std(y)
            if items:
                ds_ = [
                    derived_mod.compute(items, ds.recordings[r].u[:b], ds.input_names, ds.sampling_time)[a:b]
                    for r, a, b in train
                ]
                d = np.concatenate(ds_)
                pre.derived_offset, pre.derived_scale = d.mean(axis=0), _safe_std(d)
        if delay_form == "difference" and delay_lines:
            diffs = [pre._delayed(ds.recordings[r].u)[a:b, n_in:] for r, a, b in train]
            pre.difference_scale = _safe_std(np.concatenate(diffs))
        return pre

    @property
    def model_input_names(self) -> list[str]:
        """Inputs, one block per delay line (``u@d``: copy, ``u~d``: difference u(t) - u(t - d)),
        then the derived inputs."""
        names = list(self.input_names)
        mark = "~" if self.delay_form == "difference" else "@"
        for d in self.delay_lines:
            names += [f"{n}{mark}{d}" for n in self.input_names]
        return names + [derived_mod.channel_name(item) for item in self.derived]

    def inputs(self, u: np.ndarray) -> np.ndarray:
        """Physical inputs (n, n_inputs) from a recording's start -> model inputs
        (n, n_inputs * (1 + len(delay_lines)) + len(derived))."""
        u = _columns(u, len(self.input_names), "input")
        um = self._delayed(u)
        if self.delay_form == "difference" and self.delay_lines:
            um[:, len(self.input_names) :] /= self.difference_scale
        if not self.derived:
            return um
        extra = derived_mod.compute(self.derived, u, self.input_names, self.sampling_time)
        return np.hstack([um, (extra - self.derived_offset) / self.derived_scale])

    def _delayed(self, u: np.ndarray) -> np.ndarray:
        scaled = (u - self.input_offset) / self.input_scale
        if self.delay_form == "difference":
            return delayed_differences(scaled, self.delay_lines)
        return delayed_copies(scaled, self.delay_lines)

    def trend(self, n: int) -> np.ndarray:
        """The output trend T(t) (n, n_outputs) over the first n samples of a recording (zero at t = 0)."""
        if not self.detrend:
            return np.zeros((n, len(self.output_names)))
        return derived_mod.time_matrix(self.detrend, n, self.sampling_time) @ self.trend_coef

    def _detrended(self, y: np.ndarray) -> np.ndarray:
        return y - self.trend(len(y)) if self.detrend else y

    def outputs(self, y: np.ndarray) -> np.ndarray:
        y = _columns(y, len(self.output_names), "output")
        return (self._detrended(y) - self.output_offset) / self.output_scale

    def physical_outputs(self, y_model: np.ndarray) -> np.ndarray:
        y = y_model * self.output_scale + self.output_offset
        return y + self.trend(len(y)) if self.detrend else y

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays = {
            "input_offset": self.input_offset,
            "input_scale": self.input_scale,
            "output_offset": self.output_offset,
            "output_scale": self.output_scale,
        }
        attrs: dict[str, Any] = {
            "input_names": self.input_names,
            "output_names": self.output_names,
            "sampling_time": self.sampling_time,
            "delay_lines": self.delay_lines,
            "scaling": self.scaling,
        }
        if self.derived:
            arrays.update(derived_offset=self.derived_offset, derived_scale=self.derived_scale)
            attrs["derived_inputs"] = self.derived
        if self.detrend:
            arrays["trend_coef"] = self.trend_coef
            attrs["detrend"] = self.detrend
        if self.delay_form != "copy":
            arrays["difference_scale"] = self.difference_scale
            attrs["delay_form"] = self.delay_form
        return arrays, attrs

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> Preprocessor:
        pre = cls(
            list(attrs["input_names"]),
            list(attrs["output_names"]),
            float(attrs["sampling_time"]),
            [int(d) for d in attrs["delay_lines"]],
            str(attrs["scaling"]),
            input_offset=np.asarray(arrays["input_offset"], dtype=np.float64),
            input_scale=np.asarray(arrays["input_scale"], dtype=np.float64),
            output_offset=np.asarray(arrays["output_offset"], dtype=np.float64),
            output_scale=np.asarray(arrays["output_scale"], dtype=np.float64),
        )
        if attrs.get("derived_inputs"):
            pre.derived = list(attrs["derived_inputs"])
            pre.derived_offset = np.asarray(arrays["derived_offset"], dtype=np.float64)
            pre.derived_scale = np.asarray(arrays["derived_scale"], dtype=np.float64)
        if attrs.get("detrend"):
            pre.detrend = list(attrs["detrend"])
            pre.trend_coef = np.asarray(arrays["trend_coef"], dtype=np.float64).reshape(len(pre.detrend), -1)
        pre.delay_form = str(attrs.get("delay_form", "copy"))  # files written before the difference form hold copies
        pre.difference_scale = np.asarray(
            arrays.get("difference_scale", np.ones(len(pre.input_names) * len(pre.delay_lines))), dtype=np.float64
        )
        return pre


def _fit_trend(
    ds: Dataset, ranges: list[tuple[int, int, int]], functions: list[Any], derived: list[dict[str, Any]]
) -> np.ndarray:
    """Coefficients (len(functions), n_outputs) of y = c_rec + sum_j c_j f_j(t) + b' v_t by least squares on
    the training ranges: one constant c_rec per recording (a recording restarts the clock), v_t the
    inputs and derived inputs (nuisance terms, not kept)."""
    recs = sorted({r for r, _, _ in ranges})
    rows, targets = [], []
    for r, a, b in ranges:
        rec = ds.recordings[r]
        F = derived_mod.time_matrix(functions, b, ds.sampling_time)[a:b]
        dummies = np.zeros((b - a, len(recs)))
        dummies[:, recs.index(r)] = 1.0
        extra = derived_mod.compute(derived, rec.u[:b], ds.input_names, ds.sampling_time)[a:b]
        rows.append(np.hstack([F, dummies, rec.u[a:b], extra]))
        targets.append(ds.recordings[r].y[a:b])
    X, Y = np.concatenate(rows), np.concatenate(targets)
    scale = np.maximum(np.abs(X).max(axis=0), 1e-300)
    coef, *_ = np.linalg.lstsq(X / scale, Y, rcond=None)
    return (coef / scale[:, None])[: len(functions)]


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
