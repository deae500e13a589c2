"""Echo state networks: internal and external approach (thesis 5.2.3, 5.3.2).

Internal mode (eq. 5.41): x_t = a x_{t-1} + g tanh(C x_{t-1} + c0 + B u_t), y_t = W x_t + w0.
External mode (eq. 5.42 / 5.43): the delayed output is a second drive, measured while training
(teacher forcing), fed back from the network's own output in free run after ``tune_in``
measured samples. With ``cost: mse_inf`` the output weights of an external network are refined
on free-running error by the predictor-corrector algorithm of section 5.3.2.
"""

from __future__ import annotations

import warnings
from typing import Any, ClassVar, Literal, TypeVar, cast

import numpy as np
import scipy.sparse as sp

from dynmodel import kernels, readout, regression
from dynmodel.data.training import TrainingData
from dynmodel.family import Family, FamilyParams, Progress, Simulation, constructor_arguments, no_progress
from dynmodel.moments import Moments

from .network import Network, build_network, largest_singular_value, spectral_radius, stack_networks
from .params import EsnParams, Readout, Refinement, Scale, Weights
from .streaming import RunBuffers, free_run_moments, free_runs, output_of, settled_state, teacher_forced_moments

#: raised when the teacher-forced drive meets a missing (test) output
_NEEDS_OUTPUTS = (
    "the external mode needs measured outputs before every training and validation sample; "
    "put the test split after the training and validation splits"
)


def _teacher_feedback(y: np.ndarray) -> np.ndarray:
    """f_t = y_{t-1}, with y_0 held at t = 0."""
    f = np.empty_like(y)
    f[0] = y[0]
    f[1:] = y[:-1]
    return f


_Esn = TypeVar("_Esn", bound="EchoStateNetwork")


class EchoStateNetwork(Family):
    name = "esn"
    description = "echo state network, internal or external approach (thesis 5.2.3, 5.3.2)"
    Params: ClassVar[type[FamilyParams]] = EsnParams

    @property
    def stability_hint(self) -> str:  # type: ignore[override]  # a class attribute in Family, per mode here
        if self.external:
            return "use cost: mse_inf, the internal mode or a smaller spectral scale"
        return (
            "the readout extrapolates (an internal network has no feedback to blow up): use a ridge readout, "
            "fewer elements, or inputs within the training range"
        )

    warmup_hint = "set tune_in to at most {window}, or use mode: internal (no measured output is fed back)"

    params: EsnParams
    #: the ridge factor used (``ridge: auto``: the one chosen on validation), for frozen_config
    readout_alpha_: float | None
    #: the refinement's iterations (cost mse_inf, external mode)
    refinement_: list[dict[str, float]]
    #: networks averaged (``members``): each readout's nonzero weights per output (networks x outputs), what
    #: frozen_config and fitted_values read (the mean readout no longer tells them apart)
    member_terms_: np.ndarray

    def __init__(
        self,
        *,
        size: int = 200,
        mode: Literal["internal", "external"] = "internal",
        connectivity: float | None = None,
        input_connectivity: float = 0.5,
        bias_connectivity: float = 0.8,
        input_scale: float = 1.0,
        bias_scale: float = 1.0,
        feedback_scale: float = 1.0,
        scale: Scale | dict[str, Any] | None = None,
        relaxation: float | tuple[float, float] = (0.0, 0.99),
        relaxation_gain: bool = True,
        tune_in: int = 20,
        settle: int = 200,
        bounds: float | None = 0.5,
        members: int = 1,
        readout: Readout | dict[str, Any] | None = None,
        refinement: Refinement | dict[str, Any] | None = None,
        weights: Weights | dict[str, Any] | None = None,
    ) -> None:
        """Parameters as in ``EsnParams`` (the spec's ``model.params``); see the class help."""
        super().__init__(**constructor_arguments(locals()))

    # ------------------------------------------------------------------ structure
    @property
    def external(self) -> bool:
        return self.params.mode == "external"

    @property
    def warmup(self) -> int:
        return self.params.tune_in if self.external else 0

    def _drive(self, u: np.ndarray, f: np.ndarray | None) -> np.ndarray:
        return u if f is None else np.hstack([u, f])

    def _set_readout(self, fit: regression.LinearFit) -> None:
        m = self.network_.size
        self.W_ = np.ascontiguousarray(fit.coef[:m].T)
        n_drive = self.network_.B.shape[1]
        self.D_ = (
            np.ascontiguousarray(fit.coef[m:].T)
            if self.params.readout.direct
            else np.zeros((fit.coef.shape[1], n_drive))
        )
        self.w0_ = np.asarray(fit.intercept, dtype=np.float64).copy()

    @property
    def selected_(self) -> list[np.ndarray]:
        """Per output: indices of the readout features (states, then drive) with nonzero weight."""
        return [np.flatnonzero(np.concatenate([self.W_[k], self.D_[k]])) for k in range(self.W_.shape[0])]

    def _readout_vector(self) -> np.ndarray:
        return np.concatenate([self.W_.ravel(), self.D_.ravel(), self.w0_])

    def _set_readout_vector(self, vec: np.ndarray) -> None:
        nw, nd = self.W_.size, self.D_.size
        self.W_ = vec[:nw].reshape(self.W_.shape).copy()
        self.D_ = vec[nw : nw + nd].reshape(self.D_.shape).copy()
        self.w0_ = vec[nw + nd :].copy()

    def _uses_validation(self) -> bool:
        """Does the readout solver look at the validation rows (FOS stopping, ridge factor search)?"""
        r = self.params.readout
        return r.solver == "fos" or (r.solver == "ridge" and r.ridge == "auto")

    def _solve_readout(self, train: Moments, validation: Moments | None) -> regression.LinearFit:
        """The readout from the accumulated moments of the training (and validation) rows."""
        for m in (train, validation):
            if m is not None and not m.finite:
                raise ValueError(_NEEDS_OUTPUTS)
        r = self.params.readout
        if r.solver == "lstsq":
            return readout.lstsq(train, rcond=r.rcond)
        if r.solver == "ridge":
            if r.ridge == "auto" and validation is None:
                raise ValueError("readout.ridge: auto needs a validation split; give a number or a validation split")
            return readout.ridge(train, r.ridge, validation)
        return readout.fos(train, validation, max_terms=r.max_terms, threshold=r.threshold, patience=r.patience)

    # ------------------------------------------------------------------ fitting
    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> EchoStateNetwork:
        rng = rng if rng is not None else np.random.default_rng(0)
        members = self._members
        if members > 1:
            return self._fit_members(data, cost, rng, progress, members)
        self._prepare(data)
        self.network_ = build_network(self.params, data.n_inputs, data.n_outputs, rng)
        return self._fit_readout(data, cost, progress)

    @property
    def _members(self) -> int:
        """Networks averaged (``members``; 1 for families built on this one without it)."""
        return int(getattr(self.params, "members", 1))

    def _fit_members(
        self: _Esn, data: TrainingData, cost: str, rng: np.random.Generator, progress: Progress, members: int
    ) -> _Esn:
        """``members`` networks, each drawn and fitted on a seed of its own (children of one SeedSequence drawn from
        ``rng``), kept as one network of their elements side by side (:func:`.network.stack_networks`) whose readout
        is the mean of theirs: y = (1/K) sum_k (W_k x_k + D_k v + w0_k). In the internal mode its output is the
        mean of the networks' outputs; in the external mode the mean is fed back to all of them."""
        root = np.random.SeedSequence([int(v) for v in rng.integers(0, 2**63, size=4)])
        fitted: list[EchoStateNetwork] = []
        for i, child in enumerate(root.spawn(members)):

            def told(stage: str, fraction: float | None, message: str, i: int = i) -> None:
                progress(stage, fraction, f"network {i + 1} of {members}: {message}")

            one = type(self)(**{**self._given, "members": 1})
            fitted.append(one.fit(data, cost, np.random.default_rng(child), told))
        self._prepare(data)
        self.network_ = stack_networks([m.network_ for m in fitted])
        self.W_ = np.hstack([m.W_ for m in fitted]) / members
        self.D_ = np.mean([m.D_ for m in fitted], axis=0)
        self.w0_ = np.mean([m.w0_ for m in fitted], axis=0)
        # what each readout chose on validation, for frozen_config: its terms (FOS) and ridge factor
        self.member_terms_ = np.array([[len(s) for s in m.selected_] for m in fitted], dtype=np.int64)
        alphas = [m.readout_alpha_ for m in fitted if m.readout_alpha_ is not None]
        self.readout_alpha_ = float(np.median(alphas)) if len(alphas) == members else None
        self.refinement_ = []
        return self

    def _prepare(self, data: TrainingData) -> None:
        self.n_inputs_ = data.n_inputs
        self.n_outputs_ = data.n_outputs
        y = data.targets("train")
        self.y_rest_ = np.nanmean(y, axis=0)
        self._bounds = data.output_bounds()
        self.clip_lo_ = np.full(self.n_outputs_, -np.inf)
        self.clip_hi_ = np.full(self.n_outputs_, np.inf)
        m = getattr(self.params, "bounds", None)  # families built on this one may not clip
        if m is not None:
            lo, hi = np.nanmin(y, axis=0), np.nanmax(y, axis=0)
            self.clip_lo_, self.clip_hi_ = lo - m * (hi - lo), hi + m * (hi - lo)

    @property
    def _clip(self) -> tuple[np.ndarray, np.ndarray]:
        lo = getattr(self, "clip_lo_", None)
        if lo is None:  # a model saved before clipping existed
            inf = np.full(self.n_outputs_, np.inf)
            return -inf, inf
        return self.clip_lo_, self.clip_hi_

    def training_drives(self, data: TrainingData) -> list[np.ndarray]:
        """Per series: the drive in training (input, plus the measured past output in external mode)."""
        return [
            np.ascontiguousarray(self._drive(s.u, _teacher_feedback(s.y) if self.external else None))
            for s in data.series
        ]

    def _splits(self, data: TrainingData) -> tuple[str, ...]:
        """The splits whose moments the readout needs."""
        return ("train", "validation") if self._uses_validation() and data.has("validation") else ("train",)

    def _fit_readout(self: _Esn, data: TrainingData, cost: str, progress: Progress) -> _Esn:
        """Readout of ``network_`` on the training split; refinement for cost mse_inf (external mode).

        The network is driven chunk by chunk and only the moments of the readout features are
        kept (memory (M + n_drive)^2, whatever the number of samples)."""
        progress("states", None, f"driving {self.network_.size} elements, accumulating the readout moments")
        moments = teacher_forced_moments(
            self.network_, data, self.training_drives(data), self.params.readout.direct, self._splits(data)
        )
        train = moments["train"]
        progress("readout", None, f"{self.params.readout.solver} readout on {train.n} samples")
        solved = self._solve_readout(train, moments.get("validation"))
        self._set_readout(solved)
        # the ridge factor used (``ridge: auto``: the one chosen on validation), for frozen_config
        alpha = solved.info.get("alpha") if self.params.readout.solver == "ridge" else None
        self.readout_alpha_ = None if alpha is None else float(alpha)
        self.refinement_ = []
        if cost == "mse_inf" and self.external:
            self._refine(data, progress)
        elif cost == "mse_inf":
            warnings.warn(
                "in the internal mode the free run equals the one-step prediction (no output feedback, "
                "thesis 5.3.2), so cost mse_inf fits the same readout as mse1",
                stacklevel=2,
            )
        return self

    def _run_args(self) -> dict[str, Any]:
        """Readout, divergence band and output clip of the external-mode runs in training."""
        lo, hi = self._bounds
        clip_lo, clip_hi = self._clip
        return dict(
            tune_in=self.params.tune_in,
            W=self.W_,
            D=self.D_,
            w0=self.w0_,
            y_rest=self.y_rest_,
            lo=lo,
            hi=hi,
            clip_lo=clip_lo,
            clip_hi=clip_hi,
        )

    def _run_starts(self, data: TrainingData) -> list[np.ndarray] | None:
        """Each series' settled start (:func:`.streaming.settled_state`) for the external-mode runs of a fit: the
        network is fixed while its readout is refined, so they are computed once; None: every run from rest."""
        if not self._settle or not self.params.tune_in:
            return None
        return [settled_state(self.network_, s.u[0], s.y[0], self._settle) for s in data.series]

    @property
    def _settle(self) -> int:
        """Samples the external mode's runs settle for before the tune-in (``settle``; 0 for networks without it)."""
        return int(getattr(self.params, "settle", 0))

    def _free_run_error(self, data: TrainingData, buffers: RunBuffers, starts: list[np.ndarray] | None) -> float:
        """Mean NMSE (fraction) over outputs of the pure free run on validation (else training) rows, each run
        from its series' state in ``starts``."""
        split = "validation" if data.has("validation") else "train"
        if not free_runs(self.network_, data, 0.0, buffers, **self._run_args(), starts=starts):
            return np.inf
        pred = data.stack(split, buffers.yhat)
        target = data.targets(split)
        return float(np.mean(np.mean((target - pred) ** 2, axis=0) / np.maximum(np.var(target, axis=0), 1e-300)))

    def _refine(self, data: TrainingData, progress: Progress) -> None:
        """Thesis 5.3.2 refinement: states of the free run (feedback = current weights) give new
        least-squares weights w~; w <- (1 - alpha) w + alpha w~; keep the weights with the lowest
        free-running validation error. If the one-step weights diverge in free run, the fed-back
        signal starts as a mixture of measured and predicted output and moves to pure prediction
        over ``ramp`` iterations (error propagation, thesis 6.3.2)."""
        r = self.params.refinement
        buffers = RunBuffers(data)  # outputs of every run, reused
        starts = self._run_starts(data)
        reused: dict[str, Moments] = {}
        best_vec = self._readout_vector()
        best_err = self._free_run_error(data, buffers, starts)
        unstable = not np.isfinite(best_err)
        self.refinement_ = [{"iteration": 0, "mix": 1.0 if unstable else 0.0, "validation_nmse": 100 * best_err}]
        mix = 1.0 if unstable else 0.0
        since_best = 0
        for it in range(1, r.max_iter + 1):
            if unstable:
                mix = max(0.0, 1.0 - it / r.ramp)
            moments = free_run_moments(
                self.network_,
                data,
                mix,
                self.params.readout.direct,
                self._splits(data),
                buffers,
                **self._run_args(),
                starts=starts,
                into=reused or None,
            )
            if moments is None:  # the run diverged
                if mix == 0.0 and not unstable:
                    break
                continue
            reused = moments
            current = self._readout_vector()
            self._set_readout(self._solve_readout(moments["train"], moments.get("validation")))
            self._set_readout_vector((1.0 - r.alpha) * current + r.alpha * self._readout_vector())
            err = self._free_run_error(data, buffers, starts)
            self.refinement_.append({"iteration": it, "mix": mix, "validation_nmse": 100 * err})
            progress("refine", it / r.max_iter, f"iteration {it}: free-run validation NMSE {100 * err:.4g} %")
            if err < best_err:
                best_err, best_vec, since_best = err, self._readout_vector(), 0
            elif mix == 0.0:
                since_best += 1
                if since_best >= r.patience:
                    break
        # without any stable iterate best_vec is still the one-step solution; evaluation reports the divergence
        self._set_readout_vector(best_vec)

    # ------------------------------------------------------------------ prediction
    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        self.check_fitted()
        u = np.ascontiguousarray(u, dtype=np.float64)
        if not self.external:
            # no feedback: the output is a static map of bounded states; clipped (eq. 6.25) because
            # the readout extrapolates linearly in the direct inputs and in states never seen
            return Simulation(np.clip(output_of(self.network_, u, self.W_, self.D_, self.w0_), *self._clip), None)
        tune = min(self.params.tune_in, u.shape[0])
        if tune > 0 and (y_measured is None or len(y_measured) < tune):
            have = 0 if y_measured is None else len(y_measured)
            raise ValueError(
                f"this external-mode network tunes in on the first {tune} measured output samples; got {have}"
            )
        Y = (
            np.zeros((0, self.n_outputs_))
            if tune == 0 or y_measured is None
            else np.ascontiguousarray(y_measured[:tune], dtype=np.float64)
        )
        lo, hi = bounds if bounds is not None else (np.full(self.n_outputs_, -np.inf), np.full(self.n_outputs_, np.inf))
        Y = Y.reshape(-1, self.n_outputs_)
        # settled: the state where the first input and measured output, held, leave the network (not zero)
        start = settled_state(self.network_, u[0], Y[0], self._settle) if len(Y) and len(u) else None
        _, y, _, div = kernels.free_run_clipped(
            *self.network_.kernel_args(),
            u,
            Y,
            tune,
            0.0,
            self.W_,
            self.D_,
            self.w0_,
            self.y_rest_,
            lo,
            hi,
            np.zeros(self.network_.size) if start is None else start,
            False,
            *self._clip,
        )
        return Simulation(y, None if div < 0 else int(div))

    def predict_one_step(self, u: np.ndarray, y_measured: np.ndarray) -> np.ndarray | None:
        if not self.external:
            return None
        v = self._drive(np.asarray(u, dtype=np.float64), _teacher_feedback(np.asarray(y_measured, dtype=np.float64)))
        return output_of(self.network_, v, self.W_, self.D_, self.w0_)

    # ------------------------------------------------------------------ reliability hooks
    def driven_system(self):
        """The network as a driven system (model space). External mode: the open loop, driven by
        the input and the fed-back output, with the readout as its closed loop (thesis 5.3.2)."""
        from dynmodel.reliability.networks import LinearFeedback, SigmoidNetwork
        from dynmodel.reliability.system import InputDomain

        self.check_fitted()
        net = self.network_
        names = [f"u{j}" for j in range(net.B_in.shape[1])]
        closed = None
        if self.external:
            names += [f"y{k}" for k in range(self.n_outputs_)]
            closed = LinearFeedback(self.W_, self.D_, self.w0_, self.params.tune_in, self.y_rest_, net.C, net.B_back)
        # model space: standard-scaled signals mostly lie within +-2
        inputs = InputDomain.from_range(names, -2 * np.ones(len(names)), 2 * np.ones(len(names)))
        return SigmoidNetwork(
            net.C,
            net.B,
            net.c0,
            net.a,
            net.g,
            inputs,
            closed,
            name="esn",
            description=f"echo state network, {net.size} elements, {self.params.mode} mode"
            + (f", {self._members} networks averaged" if self._members > 1 else ""),
        )

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        net = self.network_.sparse()  # fitted networks hold C in CSR form
        C = cast(sp.csr_matrix, net.C)
        arrays = {
            "C_indptr": C.indptr.astype(np.int64),
            "C_indices": C.indices.astype(np.int64),
            "C_data": C.data,
            "B_in": net.B_in,
            "B_back": net.B_back,
            "c0": net.c0,
            "relaxation": net.a,
            "gain": net.g,
            "W": self.W_,
            "D": self.D_,
            "w0": self.w0_,
            "y_rest": self.y_rest_,
            "clip_low": self._clip[0],
            "clip_high": self._clip[1],
        }
        attrs = {
            "size": net.size,
            "mode": self.params.mode,
            "n_inputs": self.n_inputs_,
            "n_outputs": self.n_outputs_,
            "refinement": self.refinement_,
            "readout_alpha": getattr(self, "readout_alpha_", None),
        }
        if self._members > 1:
            arrays["member_terms"] = self.member_terms_
        return arrays, attrs

    @classmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]):
        if "settle" in cls.Params.model_fields:  # a file written before ``settle``: its runs started from rest
            params = {"settle": 0, **params}
        self = cls(**params)
        m = int(attrs["size"])
        C = sp.csr_matrix((arrays["C_data"], arrays["C_indices"], arrays["C_indptr"]), shape=(m, m))
        self.network_ = Network(
            C, arrays["B_in"], arrays["B_back"].reshape(m, -1), arrays["c0"], arrays["relaxation"], arrays["gain"]
        )
        self.W_, self.D_, self.w0_ = arrays["W"], arrays["D"], arrays["w0"]
        self.y_rest_ = arrays["y_rest"]
        self.n_inputs_, self.n_outputs_ = int(attrs["n_inputs"]), int(attrs["n_outputs"])
        if "clip_low" in arrays:
            self.clip_lo_ = np.asarray(arrays["clip_low"], dtype=np.float64)
            self.clip_hi_ = np.asarray(arrays["clip_high"], dtype=np.float64)
        self.refinement_ = list(attrs.get("refinement") or [])
        alpha = attrs.get("readout_alpha")
        self.readout_alpha_ = None if alpha is None else float(alpha)
        if "member_terms" in arrays:
            self.member_terms_ = np.asarray(arrays["member_terms"], dtype=np.int64)
        return self

    def frozen_config(self) -> dict[str, Any] | None:
        """The given parameters with the readout's choice frozen: a FOS readout keeps as many terms as it chose on
        validation (``max_terms``: its states and drive terms and the constant; the network itself is fixed by
        the seed); a ridge factor chosen on validation (``ridge: auto``) becomes the number it chose. An external
        network's refinement then keeps its best iterate on the training run. None for a ridge factor chosen on
        validation by a model saved before the factor was kept. Networks averaged (``members``): each keeps as many
        terms as the most any of them chose, and the median of their ridge factors."""
        self.check_fitted()
        r = self.params.readout
        readout = dict(self._given.get("readout") or {})
        if r.solver == "ridge" and r.ridge == "auto":
            alpha = getattr(self, "readout_alpha_", None)
            if alpha is None:
                return None
            readout["ridge"] = alpha
        if r.solver == "fos" and self._members > 1:  # each network as many as the most any chose
            readout["max_terms"] = int(self.member_terms_.max()) + 1
        elif r.solver == "fos":
            readout["max_terms"] = int(max(len(s) for s in self.selected_)) + 1
        return {"params": {**self._given, "readout": readout}, "cost": None}

    def fitted_values(self) -> int:
        """The readout's nonzero weights and intercepts: the reservoir and input weights are drawn, not fitted.
        Networks averaged (``members``): the mean of their readouts' counts, the effective number of values fitted
        (the hat matrix of a mean of least-squares readouts is the mean of theirs, and so is its trace): averaging
        lowers the variance of a fit and adds no freedom to follow the data."""
        if self._members > 1:
            return int(round(float(np.mean(self.member_terms_.sum(axis=1))))) + int(np.size(self.w0_))
        return self.readout_weights()

    def readout_weights(self) -> int:
        """The readout's nonzero weights and intercepts (of every network averaged)."""
        return int(sum(len(s) for s in self.selected_) + np.size(self.w0_))

    def summary(self) -> dict[str, Any]:
        net = self.network_
        info: dict[str, Any] = {
            "elements": net.size,
            "mode": self.params.mode,
            "connections": int(np.count_nonzero(net.C)) if isinstance(net.C, np.ndarray) else int(net.C.nnz),
            "sigma(C)": round(largest_singular_value(net.C), 6),
            "rho(C)": round(spectral_radius(net.C), 6),
            "readout": self.params.readout.solver,
        }
        if self._members > 1:
            info["networks averaged"] = self._members
            info["readout weights (every network)"] = self.readout_weights()
        info["readout terms"] = [int(len(s)) for s in self.selected_]
        info["parameters"] = self.fitted_values()
        if np.isfinite(self._clip[0]).any():
            info["bounds (model space)"] = [[float(a), float(b)] for a, b in zip(*self._clip)]
        if self.external:
            info["tune_in"] = self.params.tune_in
            if self._settle:
                info["settled before the tune-in (samples)"] = self._settle
            if len(self.refinement_) > 1:
                info["refinement iterations"] = len(self.refinement_) - 1
        return info

    # ------------------------------------------------------------------ extensions (docs/plugins-extensions.md)
    @classmethod
    def extensions(cls, cause, ctx):
        from .extensions import extensions

        return extensions(cause, ctx)

    # ------------------------------------------------------------------ family: auto (docs/plugins.md)
    @classmethod
    def search_space(cls, ctx, around=None):
        from .search import search_space

        return search_space(ctx, around)
