"""A small simulated-annealing optimizer shared by the families that adapt their structure
(thesis 5.3.4, 4.4.2).

Exponential cooling ``T <- a T`` from ``T0`` to ``T_end`` over the step budget. Each step picks a
move from a weighted registry and applies it to a copy of the current state; the move receives
``scale = T / T0`` so that its step variance is ``(T / T0)^2``. A better candidate is always
accepted; a worse one with probability ``exp(delta / T)``, where ``delta`` is the relative change
of the objective ``(old - new) / old`` (eq. 5.57, negative for a worse candidate). The best state
seen is kept; Ctrl-C stops the run and returns it, except in a batch (a sweep's point, a candidate of
``family: auto``, see :func:`interrupts_propagate`), where the interrupt must stop the whole batch: there
it propagates. :func:`watch_interrupts` tells a caller (``dynmodel fit``) that a run was cut short.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

S = TypeVar("S")

#: a move: (state, rng, scale) -> new state (or None when the move does not apply to this state)
Move = Callable[[S, np.random.Generator, float], "S | None"]


#: inside a batch (a sweep point, an auto-search candidate run in this process): Ctrl-C propagates
_PROPAGATE: ContextVar[bool] = ContextVar("dynmodel_anneal_propagate", default=False)
#: the watches of :func:`watch_interrupts` active in this context
_WATCHES: ContextVar[tuple[InterruptWatch, ...]] = ContextVar("dynmodel_anneal_watches", default=())


@contextmanager
def interrupts_propagate() -> Iterator[None]:
    """Inside: a Ctrl-C (KeyboardInterrupt, also SIGTERM turned into one) during an annealing is not turned
    into "keep the best state so far" but raised, so that the batch running this fit stops (a sweep does
    not record the cut-short point as finished, an auto search stops and keeps its best candidate)."""
    token = _PROPAGATE.set(True)
    try:
        yield
    finally:
        _PROPAGATE.reset(token)


def propagating() -> bool:
    """Does a Ctrl-C during an annealing propagate here (see :func:`interrupts_propagate`)?"""
    return _PROPAGATE.get()


@dataclass
class InterruptWatch:
    """What :func:`watch_interrupts` saw: ``interrupted`` is the KeyboardInterrupt (or its subclass, e.g.
    a SIGTERM) that cut an annealing short and was kept as "the best state so far", else None."""

    interrupted: BaseException | None = None


@contextmanager
def watch_interrupts() -> Iterator[InterruptWatch]:
    """Record whether an annealing in this block was cut short by Ctrl-C (and returned its best state)."""
    watch = InterruptWatch()
    token = _WATCHES.set(_WATCHES.get() + (watch,))
    try:
        yield watch
    finally:
        _WATCHES.reset(token)


def _swallowed(exc: BaseException) -> None:
    """An interrupt was turned into "return the best so far": tell the watches."""
    for watch in _WATCHES.get():
        if watch.interrupted is None:
            watch.interrupted = exc


@dataclass
class Schedule:
    steps: int = 400
    t0: float = 0.1
    t_end: float = 1e-4

    @property
    def cooling(self) -> float:
        """Factor a of T <- a T that reaches t_end after ``steps`` steps."""
        return (self.t_end / self.t0) ** (1.0 / max(self.steps - 1, 1))


@dataclass
class AnnealResult(Generic[S]):
    best: S
    best_score: float
    history: list[dict[str, Any]] = field(default_factory=list)  # one entry per step
    interrupted: bool = False

    @property
    def accepted(self) -> int:
        return sum(1 for h in self.history if h["accepted"])


def relative_improvement(old: float, new: float) -> float:
    """delta of eq. 5.57: (old - new) / old; -inf for a non-finite candidate."""
    if not math.isfinite(new):
        return -math.inf
    if old <= 0 or not math.isfinite(old):
        return math.inf if new < old else -math.inf
    return (old - new) / old


def anneal(
    state: S,
    score: float,
    objective: Callable[[S], float],
    moves: list[tuple[str, float, Move]],
    schedule: Schedule,
    rng: np.random.Generator,
    on_step: Callable[[int, float, float, float, dict[str, Any]], None] | None = None,
    stop: Callable[[int, float], bool] | None = None,
) -> AnnealResult[S]:
    """Anneal ``state`` (objective ``score``) with ``moves`` (name, weight, move).

    ``on_step(step, temperature, current_score, best_score, info)`` reports progress;
    ``stop(step, best_score)`` may end the run early (e.g. no improvement for a while).
    """
    names = [m[0] for m in moves]
    weights = np.array([m[1] for m in moves], dtype=float)
    weights = weights / weights.sum()
    best, best_score = state, score
    current, current_score = state, score
    temperature = schedule.t0
    a = schedule.cooling
    history: list[dict[str, Any]] = []
    interrupted = False
    try:
        for step in range(schedule.steps):
            k = int(rng.choice(len(moves), p=weights))
            candidate = moves[k][2](current, rng, temperature / schedule.t0)
            accepted = False
            new_score = math.nan
            if candidate is not None:
                new_score = objective(candidate)
                delta = relative_improvement(current_score, new_score)
                if delta >= 0 or (math.isfinite(delta) and rng.random() < math.exp(delta / temperature)):
                    current, current_score, accepted = candidate, new_score, True
                    if new_score < best_score:
                        best, best_score = candidate, new_score
            info = {
                "step": step,
                "move": names[k],
                "temperature": temperature,
                "score": new_score,
                "accepted": accepted,
                "best": best_score,
            }
            history.append(info)
            if on_step is not None:
                on_step(step, temperature, current_score, best_score, info)
            if stop is not None and stop(step, best_score):
                break
            temperature *= a
    except KeyboardInterrupt as exc:
        if propagating():
            raise
        interrupted = True
        _swallowed(exc)
    return AnnealResult(best, best_score, history, interrupted)


R = TypeVar("R")


def run_restarts(
    search: Callable[[int, np.random.Generator, threading.Event], R],
    restarts: int,
    workers: int,
    rng: np.random.Generator,
) -> list[R]:
    """Run ``search(k, rng_k, halt)`` for k = 0 .. restarts-1 with independent random streams,
    in up to ``workers`` threads (0: one per core); compiled kernels release the GIL. Results do
    not depend on the number of threads. Ctrl-C sets ``halt``: every run should then stop and
    return its best state so far (then the interrupt is raised again in a batch, see
    :func:`interrupts_propagate`)."""
    seeds = rng.spawn(restarts)
    halt = threading.Event()
    n = min(restarts, workers or os.cpu_count() or 1)
    if n <= 1:
        results: list[R] = []
        try:
            with watch_interrupts() as seen:
                for k in range(restarts):
                    if seen.interrupted is not None:
                        halt.set()  # the runs still to come stop at once: Ctrl-C ends the whole annealing
                    results.append(search(k, seeds[k], halt))
            return results
        except KeyboardInterrupt:
            halt.set()
            raise
    with ThreadPoolExecutor(n) as pool:
        futures = [pool.submit(search, k, seeds[k], halt) for k in range(restarts)]
        try:
            return [f.result() for f in futures]
        except KeyboardInterrupt as exc:
            halt.set()
            results = [f.result() for f in futures]
            if propagating():
                raise
            _swallowed(exc)
            return results
