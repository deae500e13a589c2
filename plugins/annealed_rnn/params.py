"""Parameters of the `annealed-rnn` family (thesis 5.3.4, 6.2.3, 6.3.2, 6.4.5)."""

from __future__ import annotations

from typing import Any, Literal, Union

from pydantic import Field, model_validator

from dynmodel.family import FamilyParams
from dynmodel_plugins.esn.params import EsnParams, Readout, Refinement


def esn_declaration(name: str) -> Any:
    """The `esn` family's declaration of a network parameter that both families share (default,
    bounds, description): one home, so a change there applies to both."""
    return EsnParams.model_fields[name]


#: the parameters annealed-rnn declares through :func:`esn_declaration`; ``input_connectivity`` and
#: ``tune_in`` keep annealed-rnn's own defaults (0.1, 100: the annealing's figures were measured with
#: them), which differ from esn's since esn's defaults were revised (issue 14)
SHARED_WITH_ESN = (
    "mode",
    "bias_connectivity",
    "input_scale",
    "bias_scale",
    "feedback_scale",
    "refinement",
)


class Moves(FamilyParams):
    """Relative frequencies of the structure changes of thesis 5.3.4 (0 disables a move)."""

    add: float = Field(1.0, ge=0, description="a zero entry of C becomes N(0, 1)")
    cut: float = Field(1.0, ge=0, description="a nonzero entry of C becomes zero")
    rewire: float = Field(1.0, ge=0, description="a zero and a nonzero entry of C swap places")
    weight: float = Field(2.0, ge=0, description="a nonzero entry of C changes by N(0, (T/T0)^2)")
    input: float = Field(1.0, ge=0, description="a nonzero input weight changes by N(0, (T/T0)^2)")
    bias: float = Field(1.0, ge=0, description="a nonzero bias changes by N(0, (T/T0)^2)")
    relaxation: float = Field(
        1.0, ge=0, description="a relaxation parameter changes by N(0, (0.1 T/T0)^2), kept in [0, 0.99]"
    )

    @model_validator(mode="after")
    def _some(self) -> Moves:
        if sum(self.model_dump().values()) <= 0:
            raise ValueError("at least one move needs a positive weight")
        return self


class AnnealedRnnParams(FamilyParams):
    size: int = Field(60, gt=0, description="elements M at the start")
    steps: int = Field(400, ge=0, description="simulated-annealing steps per stage (thesis: 400)")
    mode: Literal["internal", "external"] = esn_declaration("mode")
    connectivity: float = Field(
        0.06, gt=0, le=1, description="initial probability of a nonzero entry of C (thesis 5.3.4: 0.06 for 60 elements)"
    )
    input_connectivity: float = Field(0.1, gt=0, le=1, description="probability of a nonzero input weight")
    bias_connectivity: float = esn_declaration("bias_connectivity")
    input_scale: float = esn_declaration("input_scale")
    bias_scale: float = esn_declaration("bias_scale")
    feedback_scale: float = esn_declaration("feedback_scale")
    initial_singular: float = Field(
        0.9, gt=0, lt=1, description="largest singular value of the initial C (thesis 5.3.4: 0.9)"
    )
    max_singular: float = Field(
        0.95, gt=0, lt=1, description="after every move C is rescaled to this value when sigma(C) exceeds it"
    )
    relaxation: Union[float, tuple[float, float]] = Field(
        (0.0, 0.9),
        description="initial relaxation a of x_t = a x_{t-1} + g tanh(...): a number, or [low, high] drawn per "
        "element (eq. 6.21: a in [0, 1))",
    )
    relaxation_gain: bool = Field(
        True,
        description="g = 1 - |a| (eq. 6.21: every element's gain stays below 1) instead "
        "of g = 1 (eq. 6.27 / 6.38); check reliability with `dynmodel "
        "reliability-check`",
    )
    step: float = Field(
        1.0,
        gt=0,
        description="std of a weight change at the initial temperature; it shrinks as T / T0 "
        "(thesis 5.3.4: variance (T / T0)^2)",
    )
    t0: float = Field(0.1, gt=0, description="initial temperature (scale of accepted relative NMSE increases)")
    t_end: float = Field(1e-4, gt=0, description="final temperature; cooling T <- a T reaches it after `steps` steps")
    moves: Moves = Field(default_factory=Moves)
    grow: bool = Field(
        False, description="constructive growth (6.4.5): add elements when the validation NMSE stops improving"
    )
    grow_by: int = Field(5, gt=0, description="elements added per growth stage")
    max_size: int = Field(200, gt=0, description="growth never exceeds this many elements")
    patience: int = Field(100, gt=0, description="steps without a new best validation NMSE that end a growth stage")
    restarts: int = Field(1, ge=1, description="independent annealing runs; the best on validation is kept")
    workers: int = Field(0, ge=0, description="threads for restarts (0: one per core, at most `restarts`)")
    tune_in: int = Field(100, ge=0, description="external mode: measured output samples fed back before running free")
    readout: Readout = Field(
        default_factory=lambda: Readout(solver="lstsq", direct=False),
        description="readout of every candidate and of the final network",
    )
    refinement: Refinement = esn_declaration("refinement")

    @model_validator(mode="after")
    def _check(self) -> AnnealedRnnParams:
        if self.t_end >= self.t0:
            raise ValueError(f"t_end ({self.t_end}) must be below t0 ({self.t0})")
        if self.initial_singular > self.max_singular:
            raise ValueError("initial_singular must not exceed max_singular")
        if self.max_size < self.size:
            raise ValueError(f"max_size ({self.max_size}) is below size ({self.size})")
        if isinstance(self.relaxation, tuple):
            lo, hi = self.relaxation
            if not 0 <= lo <= hi < 1:
                raise ValueError("relaxation range must satisfy 0 <= low <= high < 1")
        elif not 0 <= self.relaxation < 1:
            raise ValueError("relaxation must lie in [0, 1)")
        return self
