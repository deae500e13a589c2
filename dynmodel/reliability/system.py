"""What the reliability check drives: a *driven system* x_t = f(x_{t-1}, v_t) (thesis eq. 4.31 / 4.33).

A family (``Family.driven_system()``) or a built-in test system (entry-point group
``dynmodel.systems``) exposes this view. Everything is batched: ``X`` holds one state per row
(R replicas), ``V`` one drive vector per row. Continuous systems advance by one sampling interval
of a fixed-step integrator per call.

Signals the check generates live in the system's *input space* (``inputs``: names and the
training range); :meth:`DrivenSystem.drive` maps a whole input sequence to the per-step drive
(scaling, delay lines, interpolation within a sampling interval, ...).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

Implication = Literal["reliable", "unreliable", "undecided"]


@dataclass(frozen=True)
class Evidence:
    """An algebraic fact about the system and what it implies for reliability."""

    name: str
    value: float
    implies: Implication
    statement: str

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "value": self.value, "implies": self.implies, "statement": self.statement}


@dataclass
class InputDomain:
    """Channels of the input space and the range the system is meant for (the training range).

    ``mean`` / ``std`` set the white-noise test signal; ``low`` / ``high`` the constant sweep and
    the sine amplitudes.
    """

    names: list[str]
    low: np.ndarray
    high: np.ndarray
    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def from_range(cls, names: list[str], low, high) -> InputDomain:
        """A declared range: mean at the middle, std a quarter of the width."""
        lo = np.atleast_1d(np.asarray(low, dtype=np.float64))
        hi = np.atleast_1d(np.asarray(high, dtype=np.float64))
        return cls(list(names), lo, hi, 0.5 * (lo + hi), 0.25 * (hi - lo))

    @classmethod
    def from_samples(cls, names: list[str], u: np.ndarray) -> InputDomain:
        """The range and statistics of recorded inputs (n, channels)."""
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        std = u.std(axis=0)
        return cls(list(names), u.min(axis=0), u.max(axis=0), u.mean(axis=0), np.where(std > 0, std, 1.0))

    @property
    def n(self) -> int:
        return len(self.names)

    @property
    def width(self) -> np.ndarray:
        return self.high - self.low

    def concat(self, other: InputDomain) -> InputDomain:
        return InputDomain(
            self.names + other.names,
            *(np.concatenate([getattr(self, k), getattr(other, k)]) for k in ("low", "high", "mean", "std")),
        )


@dataclass(frozen=True)
class Sine:
    """u(t) = offset + amplitude * sin(omega * t + phase), t in the system's time unit.

    ``offset`` None means the middle of the input range.
    """

    amplitude: float
    omega: float
    offset: float | None = None
    phase: float = 0.0
    label: str | None = None

    def name(self) -> str:
        if self.label:
            return self.label
        off = "" if not self.offset else f"{self.offset:g} + "
        ph = f" + {self.phase:.3g}" if self.phase else ""
        return f"{off}{self.amplitude:g} sin({self.omega:g} t{ph})"


class ClosedLoop(ABC):
    """External-mode models: the output is fed back as the last ``n_outputs`` drive channels.

    The open-loop system (driven by the input and the *measured* output) is the
    :class:`DrivenSystem` that carries this object; its drive is ``[inputs, fed-back outputs]``
    in model space and :meth:`DrivenSystem.drive` must be the identity for it. In the free run
    ``f_t = yhat_{t-1}`` (``rest_output`` at t = 0); during the tune-in ``f_t = y_{t-1}``
    (thesis 5.3.2, eq. 5.42 / 5.43).
    """

    n_outputs: int
    tune_in: int
    rest_output: np.ndarray

    @abstractmethod
    def readout(self, X: np.ndarray, V: np.ndarray) -> np.ndarray:
        """Outputs (R, n_outputs) of states X (R, M) under drives V (R, d)."""

    def facts(self) -> list[Evidence]:
        """Algebraic facts about the closed loop (informative, e.g. sigma of C + b_back w^T)."""
        return []


class DrivenSystem(ABC):
    """Batched view of x_t = f(x_{t-1}, v_t) for the reliability check (definition 4.4)."""

    #: short id and one-line description (class attributes; a view may set its own)
    name: str = ""
    description: str = ""

    #: dimension M of the state
    state_dim: int
    #: channels the check generates signals for, with their range
    inputs: InputDomain
    #: time between samples (time units per step); 1 for maps
    sampling_time: float = 1.0
    #: True for flows integrated over one sampling interval per step
    continuous: bool = False
    #: default number of steps of each test run
    default_length: int = 2000
    #: the state the system starts from in normal use (e.g. zeros), or None
    rest_state: np.ndarray | None = None
    #: external-mode models: the output feedback; None otherwise
    closed_loop: ClosedLoop | None = None
    #: the state is the past outputs a run starts from, measured (NARX): the check tells whether the model forgets
    #: them; a diagnosis does not read an unreliable verdict as a fault of its residual (its runs start measured)
    state_is_tune_in: bool = False
    #: recorded inputs (n, inputs.n) in input space and segment lengths, when available
    training_input: np.ndarray | None = None
    training_lengths: np.ndarray | None = None

    # -- dynamics --------------------------------------------------------------------------
    def drive(self, u: np.ndarray) -> np.ndarray:
        """Input sequence (n, inputs.n) -> drive sequence (n, d). Identity by default."""
        return np.ascontiguousarray(u, dtype=np.float64)

    @abstractmethod
    def step(self, X: np.ndarray, V: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """x_t = f(x_{t-1}, v_t) for every row: X (R, M), V (R, d) -> (R, M).

        ``out`` (same shape as X, never X itself) may receive the result; callers always use the
        returned array, so an implementation is free to ignore it."""

    @abstractmethod
    def tangent(self, X: np.ndarray, V: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step of the state and of tangent vectors: returns (f(X, V), Df/dx(X, V) @ E).

        E has shape (R, M, k); for flows the variational equation is integrated with the state.
        """

    def fit_outputs(self, low: np.ndarray, high: np.ndarray, record: np.ndarray | None = None) -> None:
        """The model-space training output range (per output) and the training outputs (n, outputs) when the
        model file holds them, for a view whose state holds past outputs (NARX): it starts its replicas from
        states a recording can present. The default ignores them."""
        return None

    # -- where to start --------------------------------------------------------------------
    @abstractmethod
    def state_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds (low, high) of the region the state can reach (or that is worth testing)."""

    def sample_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` initial states spread over :meth:`state_box`: the rest state, corners (sign
        patterns) and uniform points."""
        lo, hi = self.state_box()
        m = self.state_dim
        out = lo + (hi - lo) * rng.random((n, m))
        k = min(n // 4, 2 ** min(m, 30) if m < 31 else n)  # distinct corners only
        if k:
            out[n - k :] = np.where(rng.random((k, m)) < 0.5, hi, lo)
        if self.rest_state is not None and n:
            out[0] = self.rest_state
        return out

    def scale(self) -> float:
        """Characteristic distance in state space (diagonal of the state box); tolerances are
        relative to it."""
        lo, hi = self.state_box()
        return float(np.linalg.norm(hi - lo))

    # -- evidence and extra signals --------------------------------------------------------
    def evidence(self) -> list[Evidence]:
        """Algebraic facts (e.g. sigma(C), rho(C) for networks, eq. 4.51 / 5.24)."""
        return []

    def signals(self) -> list[Sine]:
        """Extra test drives the system is known for (e.g. 27 sin(1.4 t) for the Duffing oscillator)."""
        return []

    def describe(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "state_dim": self.state_dim,
            "inputs": self.inputs.names,
            "input_low": self.inputs.low.tolist(),
            "input_high": self.inputs.high.tolist(),
            "sampling_time": self.sampling_time,
            "continuous": self.continuous,
            "external_mode": self.closed_loop is not None,
        }


class SystemParams(BaseModel):
    """Base of a test system's parameter model: unknown keys are rejected."""

    model_config = ConfigDict(extra="forbid")


class TestSystem(DrivenSystem):
    """A named built-in system (entry-point group ``dynmodel.systems``) built from parameters."""

    __test__ = False  # not a pytest class
    Params: ClassVar[type[SystemParams]] = SystemParams

    def __init__(self, **params: Any):
        self.params = self.Params(**params)
        self.setup()

    def setup(self) -> None:
        """Derive the arrays the dynamics needs from ``self.params``."""
