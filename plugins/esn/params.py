"""Parameters of the `esn` family, with defaults that work on a first try."""

from __future__ import annotations

from typing import Literal, Optional, Union

from pydantic import Field, model_validator

from dynmodel.family import FamilyParams


class Scale(FamilyParams):
    """Rescaling of the random connection matrix C."""

    by: Literal["singular", "spectral", "none"] = Field(
        "singular",
        description="singular: largest singular value (guarantees reliability when < 1, thesis 5.3.1); "
        "spectral: spectral radius (does not); none: keep C as given",
    )
    value: float = Field(0.95, gt=0, description="target largest singular value or spectral radius")


class Weights(FamilyParams):
    """Explicit network matrices (for instance the 2-element example of thesis eq. 5.28)."""

    C: list[list[float]] = Field(description="connection matrix, M x M")
    b: Optional[Union[list[float], list[list[float]]]] = Field(None, description="input weights, M or M x n_inputs")
    c0: Optional[list[float]] = Field(None, description="biases, M (default zeros)")
    b_back: Optional[Union[list[float], list[list[float]]]] = Field(
        None, description="external mode: weights of the fed-back output, M or M x n_outputs"
    )
    relaxation: Optional[list[float]] = Field(None, description="relaxation parameter per element")

    @model_validator(mode="after")
    def _shapes(self) -> Weights:
        m = len(self.C)
        if m == 0 or any(len(row) != m for row in self.C):
            raise ValueError(f"C must be square; got {m} rows of lengths {sorted({len(r) for r in self.C})}")
        for key in ("b", "c0", "b_back", "relaxation"):
            v = getattr(self, key)
            if v is not None and len(v) != m:
                raise ValueError(f"{key} has {len(v)} rows but C has {m}")
        return self


class Readout(FamilyParams):
    """Output weights: y_t = W x_t [+ D v_t] + w0 (eq. 5.19 / 5.32, with optional direct links)."""

    solver: Literal["fos", "lstsq", "ridge"] = Field(
        "fos",
        description="fos: Fast Orthogonal Search keeps only useful states (thesis 5.3.3, robust to noise); "
        "lstsq: all states by SVD least squares; ridge: all states, shrunk",
    )
    direct: bool = Field(
        True,
        description="also offer the network's drive (inputs, fed-back outputs) to the readout "
        "(direct input-output links, thesis eq. 5.6)",
    )
    max_terms: Optional[int] = Field(None, gt=0, description="fos: most states kept (default: no limit)")
    patience: int = Field(
        50,
        gt=0,
        description="fos: stop after this many terms without a lower validation error "
        "(1: at the first rise, thesis A.3)",
    )
    threshold: Optional[float] = Field(
        None, gt=0, description="fos: stop when a term reduces the error by less than this fraction"
    )
    rcond: Optional[float] = Field(
        None, gt=0, description="lstsq: relative singular-value cutoff (default eps * max(N, K))"
    )
    ridge: Union[float, Literal["auto"]] = Field(
        "auto", description="ridge factor, or auto: chosen on the validation split"
    )


class Refinement(FamilyParams):
    """Predictor-corrector refinement of the output weights on free-running error (thesis 5.3.2)."""

    alpha: float = Field(0.2, gt=0, le=1, description="update parameter: w <- (1 - alpha) w + alpha w_free")
    max_iter: int = Field(60, ge=1, description="at most this many iterations")
    patience: int = Field(6, ge=1, description="stop after this many iterations without a lower validation error")
    ramp: int = Field(
        10,
        ge=1,
        description="when the one-step model's free run diverges: iterations over which the "
        "fed-back signal moves from measured to predicted output (error propagation, 6.3.2)",
    )


class EsnParams(FamilyParams):
    size: int = Field(200, gt=0, description="number of elements M")
    mode: Literal["internal", "external"] = Field(
        "internal",
        description="internal: driven by the input only (eq. 5.41), reliable; external: the delayed output "
        "is an extra input, teacher-forced in training and fed back in free run (eq. 5.42 / 5.43)",
    )
    connectivity: Optional[float] = Field(
        None,
        ge=0,
        le=1,
        description="probability of a nonzero entry in C "
        "(default 2 / size: two connections per element, 0.01 for 200 elements)",
    )
    input_connectivity: float = Field(
        0.5,
        gt=0,
        le=1,
        description="probability of a nonzero input weight (default 0.5: with two connections per element a "
        "sparse network passes little on, so the input should reach many elements directly)",
    )
    bias_connectivity: float = Field(0.8, ge=0, le=1, description="probability of a nonzero bias")
    input_scale: float = Field(1.0, gt=0, description="std of the nonzero input weights")
    bias_scale: float = Field(1.0, ge=0, description="std of the nonzero biases")
    feedback_scale: float = Field(1.0, gt=0, description="external mode: std of the nonzero fed-back-output weights")
    scale: Optional[Scale] = Field(None, description="default: largest singular value 0.95; none for explicit weights")
    relaxation: Union[float, tuple[float, float]] = Field(
        (0.0, 0.99),
        description="relaxation a of x_t = a x_{t-1} + g tanh(...): a number, or [low, high] drawn per element "
        "(default [0, 0.99]: leaky elements with time constants from 1 to 100 samples, thesis 6.2 / 6.3: a "
        "randomly connected network scaled to sigma(C) = 0.95 has a spectral radius near 0.3 and forgets its "
        "input within a few samples, too fast for most measured systems)",
    )
    relaxation_gain: bool = Field(
        True,
        description="g = 1 - |a| (eq. 6.21, the default: every element's gain stays below 1) instead of g = 1 (eq. 6.27)",
    )
    tune_in: int = Field(
        20,
        ge=0,
        description="external mode: measured output samples fed back before running free (default 20: inside the "
        "state-initialisation windows of the standard benchmarks, 20 - 50 samples)",
    )
    settle: int = Field(
        200,
        ge=0,
        description="external mode: before the tune-in, the network is driven this many samples by the first input "
        "and the first measured output held, from rest, so that its state starts where those values hold it rather "
        "than at zero (0: from zero, as in the thesis). A 20-sample tune-in from zero left some networks on a "
        "second attractor from measured starts inside their own training data (docs/families.md)",
    )
    bounds: Optional[float] = Field(
        0.5,
        ge=0,
        description="clip the output to its training range widened by this many range widths on both sides "
        "(eq. 6.25 applied to networks: outside the training inputs a readout extrapolates without limit; in the "
        "external mode the clipped value is fed back); null: no clipping",
    )
    members: int = Field(
        1,
        ge=1,
        le=16,
        description="networks fitted, each drawn from its own seed with its own readout, and averaged: the model "
        "is one network of members x size elements (block-diagonal C) whose readout is the mean of theirs. A "
        "random network's free run varies from seed to seed by more than its validation shows; the mean of a few "
        "varies less (in external mode the mean output is fed back)",
    )
    readout: Readout = Field(default_factory=Readout)
    refinement: Refinement = Field(default_factory=Refinement)
    weights: Optional[Weights] = Field(None, description="explicit matrices instead of a random network")

    @model_validator(mode="after")
    def _resolve(self) -> EsnParams:
        if self.weights is not None and self.members > 1:
            raise ValueError("members averages networks drawn at random; explicit weights give one network")
        if self.weights is not None:
            m = len(self.weights.C)
            if "size" in self.model_fields_set and self.size != m:
                raise ValueError(f"size {self.size} disagrees with the {m} x {m} matrix in weights.C")
            self.size = m
            # explicit matrices (e.g. eq. 5.28) are plain elements unless leaky ones are asked for
            if "relaxation" not in self.model_fields_set:
                self.relaxation = 0.0
            if "relaxation_gain" not in self.model_fields_set:
                self.relaxation_gain = False
        if isinstance(self.relaxation, tuple):
            lo, hi = self.relaxation
            if not -1 < lo <= hi < 1:
                raise ValueError("relaxation range must satisfy -1 < low <= high < 1")
        elif not -1 < self.relaxation < 1:
            raise ValueError("relaxation must lie in (-1, 1)")
        if self.connectivity is None:
            self.connectivity = min(1.0, 2.0 / self.size)
        if self.scale is None:
            self.scale = Scale(by="none") if self.weights is not None else Scale()
        return self
