"""Recurrent networks whose structure is adapted to the data by simulated annealing
(thesis 5.3.4; friction models of 6.2.3, 6.3.2 and 6.4.5).

Starting from a sparse random network, structure changes (add, cut, rewire a connection; change a
connection, input weight, bias or relaxation) are accepted by the annealing rule of eq. 5.57 on
the free-running validation NMSE, the readout being least squares on the training split for
every candidate. With ``grow: true`` elements are added whenever the validation NMSE stops
improving, until that no longer helps (6.4.5). Restarts run in parallel threads; the best network
on validation is kept. The fitted network is an ordinary tanh network, so simulation, one-step
prediction, persistence and the reliability hooks are those of the `esn` family.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from dynmodel.anneal import Schedule, anneal, run_restarts
from dynmodel.data.training import TrainingData
from dynmodel.family import Family, Progress, constructor_arguments, no_progress
from dynmodel_plugins.esn.model import EchoStateNetwork
from dynmodel_plugins.esn.network import Network, build_network
from dynmodel_plugins.esn.params import EsnParams, Readout, Refinement, Scale

from .params import AnnealedRnnParams, Moves
from .search import Evaluator, grow, make_moves


class AnnealedRnn(EchoStateNetwork):
    name = "annealed-rnn"
    description = "small recurrent network whose structure is optimized by simulated annealing (thesis 5.3.4, 6.4.5)"
    Params = AnnealedRnnParams

    params: AnnealedRnnParams  # type: ignore[assignment]

    def __init__(
        self,
        *,
        size: int = 60,
        steps: int = 400,
        mode: Literal["internal", "external"] = "internal",
        connectivity: float = 0.06,
        input_connectivity: float = 0.1,
        bias_connectivity: float = 0.8,
        input_scale: float = 1.0,
        bias_scale: float = 1.0,
        feedback_scale: float = 1.0,
        initial_singular: float = 0.9,
        max_singular: float = 0.95,
        relaxation: float | tuple[float, float] = (0.0, 0.9),
        relaxation_gain: bool = True,
        step: float = 1.0,
        t0: float = 0.1,
        t_end: float = 1e-4,
        moves: Moves | dict[str, float] | None = None,
        grow: bool = False,
        grow_by: int = 5,
        max_size: int = 200,
        patience: int = 100,
        restarts: int = 1,
        workers: int = 0,
        tune_in: int = 100,
        readout: Readout | dict[str, Any] | None = None,
        refinement: Refinement | dict[str, Any] | None = None,
    ) -> None:
        """Parameters as in ``AnnealedRnnParams`` (the spec's ``model.params``); see the class help."""
        Family.__init__(self, **constructor_arguments(locals()))

    def _initial_state(self, data: TrainingData, rng: np.random.Generator) -> Network:
        p = self.params
        esn = EsnParams(
            size=p.size,
            mode=p.mode,
            connectivity=p.connectivity,
            input_connectivity=p.input_connectivity,
            bias_connectivity=p.bias_connectivity,
            input_scale=p.input_scale,
            bias_scale=p.bias_scale,
            feedback_scale=p.feedback_scale,
            scale=Scale(by="singular", value=p.initial_singular),
            relaxation=p.relaxation,
            relaxation_gain=p.relaxation_gain,
        )
        return build_network(esn, data.n_inputs, data.n_outputs, rng).dense()  # the moves edit a dense C

    def _search(
        self, data: TrainingData, drives: list[np.ndarray], rng: np.random.Generator, report, halt: threading.Event
    ) -> tuple[Network, float, list[dict[str, Any]], bool]:
        """One annealing run, with growth stages when asked."""
        p = self.params
        evaluator = Evaluator(data, p, drives)
        moves = make_moves(p)
        state = self._initial_state(data, rng)
        score = evaluator.score(state)
        best_state, best_score = state, score
        stages: list[dict[str, Any]] = []
        interrupted = False
        while True:
            result = anneal(
                state,
                score,
                evaluator.score,
                moves,
                Schedule(p.steps, p.t0, p.t_end),
                rng,
                on_step=_stage_reporter(report, state.size),
                stop=_stage_stop(score, halt, p.patience if p.grow else None),
            )
            stages.append(
                {
                    "size": int(state.size),
                    "steps": len(result.history),
                    "accepted": result.accepted,
                    "validation_nmse": 100 * result.best_score,
                }
            )
            interrupted = result.interrupted or halt.is_set()
            improved = result.best_score < best_score
            if improved:
                best_state, best_score = result.best, result.best_score
            if interrupted or not p.grow or (len(stages) > 1 and not improved):
                break
            if best_state.size + p.grow_by > p.max_size:
                break
            state = grow(best_state, p.grow_by, p, rng)
            score = evaluator.score(state)
        return best_state, best_score, stages, interrupted

    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> AnnealedRnn:
        rng = rng if rng is not None else np.random.default_rng(0)
        p = self.params
        self._prepare(data)
        drives = self.training_drives(data)
        lock = threading.Lock()

        def reporter(k: int):
            def report(size: int, step: int, temperature: float, best: float) -> None:
                if step % 10 == 0 or step == p.steps - 1:
                    with lock:
                        progress(
                            "anneal",
                            (step + 1) / max(p.steps, 1),
                            f"run {k + 1}/{p.restarts}, {size} elements, T = {temperature:.3g}, "
                            f"best validation NMSE {100 * best:.4g} %",
                        )

            return report

        runs = run_restarts(
            lambda k, seed, halt: self._search(data, drives, seed, reporter(k), halt), p.restarts, p.workers, rng
        )
        k_best = int(np.argmin([r[1] for r in runs]))
        best, score, stages, _ = runs[k_best]
        self.search_ = {
            "restarts": [{"validation_nmse": 100 * r[1], "stages": r[2]} for r in runs],
            "best_run": k_best,
            "interrupted": any(r[3] for r in runs),
        }
        if self.search_["interrupted"]:
            warnings.warn(
                f"the annealing was interrupted (Ctrl-C): the model keeps the best network found so far "
                f"(validation NMSE {100 * score:.4g} %), not the result of the full schedule",
                stacklevel=2,
            )
        self.network_ = best.sparse()
        return self._fit_readout(data, cost, progress)

    def to_arrays(self):
        arrays, attrs = super().to_arrays()
        attrs["search"] = getattr(self, "search_", None)
        return arrays, attrs

    @classmethod
    def from_arrays(cls, params, arrays, attrs):
        self = super().from_arrays(params, arrays, attrs)
        self.search_ = attrs.get("search")
        return self

    #: the base class's (None): the annealing optimises the network on the validation split, so it cannot be
    #: fitted without one (the echo state network's hook, inherited otherwise, gives a refit that fails)
    frozen_config = Family.frozen_config

    def fitted_values(self) -> int:
        """Every stored value: the annealing chose the connections, input weights, biases and relaxations too."""
        return self.stored_values()

    def summary(self) -> dict[str, Any]:
        info = super().summary()
        search = getattr(self, "search_", None)
        if search:
            run = search["restarts"][search["best_run"]]
            info["annealing"] = (
                f"{len(search['restarts'])} run(s), best: validation NMSE "
                f"{run['validation_nmse']:.4g} %, stages {[s['size'] for s in run['stages']]}"
            )
            if search.get("interrupted"):
                info["annealing"] += " (interrupted: best network so far)"
        return info

    # ------------------------------------------------------------------ extensions (docs/plugins-extensions.md)
    @classmethod
    def extensions(cls, cause, ctx):
        from .extensions import extensions

        return extensions(cause, ctx)

    # ------------------------------------------------------------------ family: auto (docs/plugins.md)
    @classmethod
    def search_space(cls, ctx, around=None):
        from .search_space import search_space

        return search_space(ctx, around)


def _stage_reporter(
    report: Callable[[int, int, float, float], None], size: int
) -> Callable[[int, float, float, float, dict[str, Any]], None]:
    """The annealing ``on_step`` callback of one growth stage: ``report(size, step, temperature, best)``."""

    def on_step(step: int, temperature: float, current: float, best: float, info: dict[str, Any]) -> None:
        report(size, step, temperature, best)

    return on_step


def _stage_stop(score: float, halt: threading.Event, patience: int | None) -> Callable[[int, float], bool]:
    """The annealing ``stop`` callback of one growth stage, starting from ``score``: stop when ``halt`` is
    set or, with a ``patience``, when the best score has not improved for that many steps."""
    since = {"step": 0, "best": score}

    def stop(step: int, best: float) -> bool:
        if best < since["best"]:
            since.update(step=step, best=best)
        return halt.is_set() or (patience is not None and step - since["step"] >= patience)

    return stop
