"""Networks of driven Lorenz systems (thesis 4.4.2): reliable dynamical models by construction.

Parallel strategy: M elements with different parameters, all driven by the input. Feed-forward:
elements in layers, the first layer driven by the input, every other element by a weighted sum
of coupling outputs x2 / r of earlier elements (eq. 4.58 / 4.59). The output is a least-squares
combination of all 3M states plus an offset (eq. 4.55). Element parameters (and, feed-forward,
the couplings) are adapted by simulated annealing on the validation NMSE.
"""

from __future__ import annotations

import threading
import warnings
from typing import Any, Literal

import numpy as np

from dynmodel import readout
from dynmodel.anneal import Schedule, anneal, run_restarts
from dynmodel.data.training import TrainingData
from dynmodel.family import Family, Progress, Simulation, constructor_arguments, no_progress

from .params import LorenzNetParams
from .search import Evaluator, initial_state, make_moves
from .streaming import outputs, readout_moments


class LorenzNet(Family):
    name = "lorenz-net"
    description = "network of driven Lorenz systems, reliable by construction (thesis 4.4.2)"
    Params = LorenzNetParams

    params: LorenzNetParams

    def __init__(
        self,
        *,
        size: int = 32,
        strategy: Literal["parallel", "feed-forward"] = "feed-forward",
        layers: int = 4,
        extra_links: int = 30,
        steps: int = 400,
        coupling_share: float = 0.5,
        t0: float = 0.1,
        t_end: float = 1e-4,
        step: float = 0.5,
        sigma_range: tuple[float, float] = (0.0, 20.0),
        r_range: tuple[float, float] = (0.0, 40.0),
        b_range: tuple[float, float] = (0.0, 10.0),
        alpha_range: tuple[float, float] = (0.8, 1.2),
        input_scale: float = 1.0,
        readout_delays: tuple[int, ...] = (),
        anneal_delays: bool = True,
        substeps: int = 4,
        time_scale: float | None = None,
        restarts: int = 1,
        workers: int = 0,
    ) -> None:
        """Parameters as in ``LorenzNetParams`` (the spec's ``model.params``); see the class help."""
        super().__init__(**constructor_arguments(locals()))

    def _dt(self, data_sampling_time: float) -> float:
        return float(self.params.time_scale or data_sampling_time)

    def _search(self, data: TrainingData, rng: np.random.Generator, report, halt: threading.Event):
        p = self.params
        evaluator = Evaluator(data, p, self.dt_)
        state = initial_state(p, data.n_inputs, rng)
        score = evaluator.score(state)
        result = anneal(
            state,
            score,
            evaluator.score,
            make_moves(p),
            Schedule(p.steps, p.t0, p.t_end),
            rng,
            on_step=report,
            stop=lambda step, best: halt.is_set(),
        )
        info = {
            "validation_nmse": 100 * result.best_score,
            "initial_validation_nmse": 100 * score,
            "accepted": result.accepted,
            "steps": len(result.history),
            "element_integrations": evaluator.element_integrations,
            "interrupted": result.interrupted or halt.is_set(),
        }
        return result.best, result.best_score, info

    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> LorenzNet:
        rng = rng if rng is not None else np.random.default_rng(0)
        p = self.params
        self.n_inputs_, self.n_outputs_ = data.n_inputs, data.n_outputs
        self.dt_ = self._dt(data.sampling_time)
        lock = threading.Lock()

        def reporter(k: int):
            def report(step, temperature, current, best, info):
                if step % 10 == 0 or step == p.steps - 1:
                    with lock:
                        progress(
                            "anneal",
                            (step + 1) / max(p.steps, 1),
                            f"run {k + 1}/{p.restarts}, T = {temperature:.3g}, best validation NMSE {100 * best:.4g} %",
                        )

            return report

        runs = run_restarts(
            lambda k, seed, halt: self._search(data, seed, reporter(k), halt), p.restarts, p.workers, rng
        )
        best = int(np.argmin([r[1] for r in runs]))
        state = runs[best][0]
        self.search_: dict[str, Any] | None = {"restarts": [r[2] for r in runs], "best_run": best}
        if any(r[2].get("interrupted") for r in runs):
            warnings.warn(
                f"the annealing was interrupted (Ctrl-C): the model keeps the best network found so far "
                f"(validation NMSE {100 * runs[best][1]:.4g} %), not the result of the full schedule",
                stacklevel=2,
            )
        if not np.isfinite(runs[best][1]):
            raise ValueError(
                "every Lorenz network diverged in the RK4 integration; raise `substeps` or lower the parameter ranges"
            )
        self.element_params_, self.C_, self.B_, self.layer_ = state.params, state.C, state.B, state.layer
        progress("readout", None, "least squares on all 3M states" + (" and their delays" if p.readout_delays else ""))
        moments = readout_moments(
            self.element_params_, self.C_, self.B_, self.dt_, p.substeps, data, delays=p.readout_delays
        )
        fit = readout.lstsq(moments["train"])
        self.W_, self.w0_ = np.ascontiguousarray(fit.coef.T), fit.intercept
        return self

    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        self.check_fitted()
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        y = outputs(
            self.element_params_,
            self.C_,
            self.B_,
            self.dt_,
            self.params.substeps,
            u,
            self.W_,
            self.w0_,
            self.params.readout_delays,
        )
        bad = np.flatnonzero(~np.isfinite(y).all(axis=1))
        return Simulation(y, int(bad[0]) if bad.size else None)

    def driven_system(self):
        """The network as a driven system in model space, for the reliability check."""
        from dynmodel.reliability.system import InputDomain

        from .system import LorenzNetworkSystem

        self.check_fitted()
        names = [f"u{j}" for j in range(self.n_inputs_)]
        # model space: the fitted data's inputs; standard-scaled signals mostly lie within +-2
        inputs = InputDomain.from_range(names, -2 * np.ones(len(names)), 2 * np.ones(len(names)))
        return LorenzNetworkSystem(self.element_params_, self.C_, self.B_, self.dt_, self.params.substeps, inputs)

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays = {
            "element_params": self.element_params_,
            "C": self.C_,
            "B": self.B_,
            "layer": self.layer_,
            "W": self.W_,
            "w0": self.w0_,
        }
        attrs = {
            "dt": self.dt_,
            "n_inputs": self.n_inputs_,
            "n_outputs": self.n_outputs_,
            "search": getattr(self, "search_", None),
            "element_params_columns": ["sigma", "r", "b", "alpha"],
        }
        return arrays, attrs

    @classmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> LorenzNet:
        self = cls(**params)
        self.element_params_, self.C_, self.B_ = arrays["element_params"], arrays["C"], arrays["B"]
        self.layer_ = arrays["layer"].astype(np.int64)
        self.W_, self.w0_ = arrays["W"], arrays["w0"]
        self.dt_ = float(attrs["dt"])
        self.n_inputs_, self.n_outputs_ = int(attrs["n_inputs"]), int(attrs["n_outputs"])
        self.search_ = attrs.get("search")
        return self

    def summary(self) -> dict[str, Any]:
        info = {
            "elements": int(self.element_params_.shape[0]),
            "strategy": self.params.strategy,
            "couplings": int(np.count_nonzero(self.C_)),
            "layers": int(self.layer_.max()) + 1,
            "integration": f"RK4, {self.params.substeps} steps per {self.dt_:g}",
        }
        search = getattr(self, "search_", None)
        if search:
            run = search["restarts"][search["best_run"]]
            info["annealing"] = (
                f"{len(search['restarts'])} run(s); best validation NMSE {run['validation_nmse']:.4g} % "
                f"(start {run['initial_validation_nmse']:.4g} %)"
            )
        return info
