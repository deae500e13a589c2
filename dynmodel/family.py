"""The contract between the engine and a model-family plugin.

A family is a class registered under the ``dynmodel.families`` entry-point group. It follows
scikit-learn habits: parameters in the constructor (validated by the family's pydantic
``Params`` model), ``fit`` returns ``self``, fitted attributes end in ``_``. All arrays the
family sees and returns are in model space (scaled, delay lines applied); the engine does the
conversion from and to physical units.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

from .data.training import TrainingData

if TYPE_CHECKING:
    from .reliability.system import DrivenSystem

#: progress callback: (stage, fraction done in [0, 1] or None, message)
Progress = Callable[[str, "float | None", str], None]


def no_progress(stage: str, fraction: float | None, message: str) -> None:
    return None


class FamilyParams(BaseModel):
    """Base for a family's parameter model: unknown parameters are rejected."""

    model_config = ConfigDict(extra="forbid")


@dataclass
class Simulation:
    """A free run: outputs (n, n_outputs), NaN from the sample where it diverged on."""

    y: np.ndarray
    diverged_at: int | None = None


class NotFittedError(RuntimeError):
    pass


class Family(ABC):
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Params: ClassVar[type[FamilyParams]] = FamilyParams
    #: what to try when a free run diverges (the fix of the one-line error)
    stability_hint: ClassVar[str] = "use cost: mse_inf"
    #: what to try when the model needs more measured outputs (``warmup``) than a protocol's
    #: initialization window allows; ``{window}`` is replaced by the window's length
    warmup_hint: ClassVar[str] = "configure the model to start from at most {window} measured outputs"
    #: does ``fit`` draw random numbers (network weights, annealing moves)? Then a result depends on the
    #: seed, and ``dynmodel diagnose`` repeats fits over seeds to measure a gain's uncertainty
    stochastic: ClassVar[bool] = True

    def __init__(self, **params: Any):
        self.params = self.Params(**params)

    def get_params(self) -> dict[str, Any]:
        return self.params.model_dump(mode="json")

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.params!r})"

    # -- fitting -------------------------------------------------------------------------
    @abstractmethod
    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> Family:
        """Fit to ``data`` minimising ``cost`` ('mse1' or 'mse_inf'); return self."""

    # -- prediction ----------------------------------------------------------------------
    @property
    def warmup(self) -> int:
        """Samples at the start of a run that use measured outputs (tune-in); 0 for pure simulators.
        Known before ``fit`` where the parameters fix it, so that a protocol's window is checked
        before a long fit (and again after it)."""
        return 0

    @abstractmethod
    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        """Free run over ``u`` (n, n_inputs) from the rest state.

        ``y_measured`` provides at least the first ``warmup`` measured outputs. When the
        output leaves ``bounds`` (lo, hi) the run stops and reports the sample.
        """

    def predict_one_step(self, u: np.ndarray, y_measured: np.ndarray) -> np.ndarray | None:
        """One-step-ahead predictions, or None where they equal the free run."""
        return None

    # -- persistence ---------------------------------------------------------------------
    @abstractmethod
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Fitted state as plain arrays and JSON-able attributes (no pickles)."""

    @classmethod
    @abstractmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> Family:
        """Rebuild a fitted model from :meth:`to_arrays` output."""

    # -- reliability -----------------------------------------------------------------------
    def driven_system(self) -> DrivenSystem | None:
        """The fitted model as a batched driven system x_t = f(x_{t-1}, v_t) in model space, for
        ``dynmodel reliability-check`` (see :mod:`dynmodel.reliability.system`); None when the
        family has no state to test."""
        return None

    def summary(self) -> dict[str, Any]:
        """A few facts for `dynmodel inspect`."""
        return {}

    def check_fitted(self) -> None:
        if not any(k.endswith("_") and not k.startswith("_") for k in vars(self)):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit() first")
