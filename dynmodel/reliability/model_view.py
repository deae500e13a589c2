"""A saved model's driven system in physical units: the family's view (model space) behind the
model's preprocessing (scaling, delay lines), with the training input and range from the file.

For external-mode models the system is the *open loop*: driven by the input and by the output,
which the check then supplies itself (measured output during the tune-in, thesis 5.3.2).
"""

from __future__ import annotations

import numpy as np

from ..data.training import DIVERGENCE_MARGIN
from ..errors import DynmodelError
from ..model import FittedModel
from . import tune_in
from .system import DrivenSystem, Evidence, InputDomain, Sine


def training_output_range(bounds: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Model-space training output range from the stored divergence band (range +- margin x width)."""
    lo_b, hi_b = (np.asarray(b, dtype=np.float64) for b in bounds)
    width = (hi_b - lo_b) / (1.0 + 2.0 * DIVERGENCE_MARGIN)
    return lo_b + DIVERGENCE_MARGIN * width, hi_b - DIVERGENCE_MARGIN * width


class ModelSystem(DrivenSystem):
    """Wraps ``model.family.driven_system()``; inputs in physical units."""

    def __init__(self, model: FittedModel, inner: DrivenSystem, source: str = ""):
        self.model = model
        self.inner = inner
        self.name = f"{model.family.name} model{f' {source}' if source else ''}"
        self.description = str(model.spec.get("name", ""))
        pre = model.preprocessor
        self.pre = pre
        self.n_in = len(pre.input_names)
        self.state_dim = inner.state_dim
        self.sampling_time = float(pre.sampling_time)
        self.continuous = inner.continuous
        self.default_length = inner.default_length
        self.rest_state = inner.rest_state
        self.closed_loop = inner.closed_loop
        self.reference_note = ""
        record = None if model.train_output is None else pre.outputs(np.asarray(model.train_output, dtype=np.float64))
        inner.fit_outputs(*training_output_range(model.bounds), record)
        u = model.train_input
        if u is not None and len(u):
            u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
            dom = InputDomain.from_samples(list(pre.input_names), u)
        else:
            lo = inner.inputs.low[: self.n_in] * pre.input_scale + pre.input_offset
            hi = inner.inputs.high[: self.n_in] * pre.input_scale + pre.input_offset
            dom = InputDomain.from_range(list(pre.input_names), lo, hi)
        self.training_input = u
        self.training_lengths = model.train_input_lengths
        if self.closed_loop is not None:
            self.out_range_model = training_output_range(model.bounds)
            lo, hi = (pre.physical_outputs(r[None, :])[0] for r in self.out_range_model)
            out = InputDomain.from_range([f"{n} (fed back)" for n in pre.output_names], lo, hi)
            if pre.scaling == "standard":
                out.mean, out.std = pre.output_offset.copy(), pre.output_scale.copy()
            dom = dom.concat(out)
            self._pair_training_output()
        self.inputs = dom

    def _pair_training_output(self) -> None:
        """The open loop's recorded signal: training input and measured training output, or (older
        files without outputs) the closed loop's own run from the rest state on the training input."""
        u = self.training_input
        if u is None:
            return
        y = self.model.train_output
        if y is not None and len(y) == len(u):
            self.training_input = np.hstack([u, np.asarray(y, dtype=np.float64).reshape(len(u), -1)])
            self.teacher_source = "training input and measured training output"
            return
        lengths = self.training_lengths
        if lengths is not None and len(lengths):
            edges = np.cumsum(np.concatenate([[0], lengths]))
            k = int(np.argmax(np.diff(edges)))
            u = u[edges[k] : edges[k + 1]]
        y, stop = self.reference(u)
        self.teacher_source = "training input, taught with the closed loop's own run from the rest state"
        if stop is not None:
            self.reference_note = (
                f"the model file holds no training outputs, and the closed loop run from the rest "
                f"state on the training input left the output range at sample {stop}"
            )
            u, y = u[:stop], y[:stop]
        if len(u) < 10:
            self.training_input, self.training_lengths = None, None
            return
        self.training_input = np.hstack([u, self.pre.physical_outputs(y)])
        self.training_lengths = np.array([len(u)])

    # -- mapping ---------------------------------------------------------------------------
    def model_inputs(self, u: np.ndarray) -> np.ndarray:
        return self.pre.inputs(np.asarray(u, dtype=np.float64).reshape(len(u), -1)[:, : self.n_in])

    def drive(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        um = self.model_inputs(u)
        if self.closed_loop is not None:
            um = np.hstack([um, self.pre.outputs(u[:, self.n_in :])])
        return self.inner.drive(um)

    def reference(self, u: np.ndarray) -> tuple[np.ndarray, int | None]:
        """Closed-loop free run (model-space outputs) from the rest state on physical inputs u."""
        return tune_in.reference(self.inner, self.model_inputs(u), self.model.bounds)

    # -- delegation ------------------------------------------------------------------------
    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        return self.inner.step(X, V, out)

    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray):
        return self.inner.tangent(X, V, E)

    def state_box(self):
        return self.inner.state_box()

    def sample_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.inner.sample_states(rng, n)

    def scale(self) -> float:
        return self.inner.scale()

    def evidence(self) -> list[Evidence]:
        return self.inner.evidence()

    def signals(self) -> list[Sine]:
        return self.inner.signals()


def model_system(model: FittedModel, source: str = "") -> ModelSystem:
    """The driven system of a fitted model, or a one-line error when its family has none."""
    view = model.family.driven_system()
    if view is None:
        raise DynmodelError(
            f"the '{model.family.name}' family does not expose a driven-system view, so its "
            "reliability cannot be checked",
            source or None,
            "check a network family's model (e.g. esn), or a built-in system with --system NAME",
        )
    return ModelSystem(model, view, source)
