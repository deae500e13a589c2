"""Parameters of the `narx` family, with defaults that work on a first try.

Lags are written per data column (model input names, including delay-line copies such as
``u@80``, and output names): a list of integers and ranges, a range being
``{from: 0, to: 18, step: 2}`` with both ends included (thesis eq. 3.5 / 6.24 / 6.26).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
from pydantic import ConfigDict, Field, ValidationError, field_validator, model_serializer, model_validator

from dynmodel.family import FamilyParams

#: selection free_run: training samples family auto grows the model on (``growth_window``)
GROWTH_WINDOW = 12000
#: initial: settled: samples of pre-roll with the first input held, from rest, before a free run's first sample
#: (a pole at 0.97 has decayed to 0.2 % by then; a slower model starts partly settled, and is fitted so)
SETTLE_SAMPLES = 200


class LagRange(FamilyParams):
    """Lags from ``from`` to ``to`` (both included) in steps of ``step``."""

    start: int = Field(alias="from", ge=0, description="first lag")
    stop: int = Field(alias="to", ge=0, description="last lag (included)")
    step: int = Field(1, gt=0, description="distance between lags")

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    @model_serializer
    def _dump(self) -> dict[str, int]:
        return {"from": self.start, "to": self.stop, "step": self.step}

    @model_validator(mode="after")
    def _ordered(self) -> LagRange:
        if self.stop < self.start:
            raise ValueError(f"from {self.start} to {self.stop} is empty (to < from)")
        return self

    def values(self) -> list[int]:
        return list(range(self.start, self.stop + 1, self.step))


LagItem = Union[int, LagRange]


def expand_lags(items: list[LagItem]) -> list[int]:
    """Sorted unique lags of a list of integers and ranges."""
    out: set[int] = set()
    for item in items:
        out.update(item.values() if isinstance(item, LagRange) else [int(item)])
    return sorted(out)


class FreeRunRefinement(FamilyParams):
    """`cost: mse_inf`: the selected weights re-estimated on free-running error (eq. 3.15)."""

    solver: Literal["lm", "trf"] = Field(
        "lm",
        description="lm: More's trust-region Levenberg-Marquardt (MINPACK lmder's method, its QR done by LAPACK "
        "in row blocks, plugins/narx/lm.py); trf: scipy.optimize.least_squares' trust region reflective; "
        "both use the exact Jacobian of the free run from the sensitivity recursion",
    )
    max_nfev: int = Field(200, ge=1, description="at most this many free runs per solve")
    tol: float = Field(1e-10, gt=0, description="relative tolerance on the cost, the step and the gradient")
    ramp: int = Field(
        5,
        ge=1,
        description="when the least-squares model diverges in free run: solves over which the "
        "fed-back signal moves from measured to predicted output (error propagation, "
        "thesis 6.3.2)",
    )


class NarxFamilyParams(FamilyParams):
    lags: Optional[dict[str, list[LagItem]]] = Field(
        None,
        description="regressors per data column: {name: [lags]}, a lag being an integer or {from, to, step} "
        "(ends included); inputs may use lag 0, outputs start at 1. null (default): every input 0 .. L, every "
        "output 1 .. L, with L chosen on the free-running validation error among 1 .. L_max, L_max the largest "
        "of 6 .. 1 whose pool holds at most 600 monomials (6 for one input and one output at degree 3); where the "
        "training data show an input acting only after a dead time d >= 3, the same tables with that input at "
        "d .. d + L compete too",
    )
    degree: Optional[int] = Field(
        None,
        ge=1,
        le=10,
        description="largest total degree of the monomials in the pool (eq. 3.10 / 3.11); null (default): 1, 2 "
        "or 3 (3 as the thesis's friction models: cubic stiffness, odd nonlinearities), chosen together with the "
        "default lags on the free-running validation error",
    )
    constant: bool = Field(True, description="offer a constant term (always selected first)")
    input_terms: Literal["any", "linear"] = Field(
        "any",
        description="which monomials of the inputs the pool holds: any: every monomial up to the degree; linear: "
        "the inputs enter only as linear terms of their own, y[t] = f(y[t-1], ...) + sum_k b_k u[t-k] with f a "
        "polynomial of the past outputs: the structure of a force-driven mechanical system (m y'' + g(y, y') = u, "
        "Silverbox's Duffing oscillator, a positioning axis with friction), whose free run responds in proportion "
        "to an input beyond the training range instead of through its cube",
    )
    terms: Optional[Union[list[str], dict[str, list[str]]]] = Field(
        None,
        description="a fixed structure instead of FOS: monomials such as 'y[t-1]^2 * u[t]' and '1' for the "
        "constant; one list for every output, or {output: [...]}. Lags not in 'lags' are added",
    )
    initial_weights: Optional[Union[list[float], dict[str, list[float]]]] = Field(
        None,
        description="with 'terms' and cost mse_inf: start the free-running estimation from these weights (one per "
        "term, in the order of 'terms'; {output: [...]} per output) instead of from least squares: a warm start, e.g. "
        "from a model fitted on fewer samples. The weights act on the scaled data (model space, as dynmodel inspect "
        "prints them), so they hold for the scaling they were fitted with. family: auto uses them to fit its chosen "
        "model again on every sample from the weights it validated",
    )
    selection: Literal["one_step", "free_run"] = Field(
        "one_step",
        description="one_step: Fast Orthogonal Search on the one-step error (thesis A.2.2); free_run (needs "
        "cost: mse_inf): forward selection on the linearised free-running error, every step re-estimating the weights "
        "on the free run (robust to noisy outputs)",
    )
    free_run_start: Literal["linear", "constant"] = Field(
        "linear",
        description="selection free_run: the model the growth starts from: linear: the constant and the linear "
        "terms (an ARX model) that validate best in free run, with least-squares weights re-estimated on the free "
        "run; constant: the constant alone (its free run is constant, so no fed-back term can be told apart from "
        "it and the growth often stops there)",
    )
    growth_window: Optional[int] = Field(
        None,
        ge=100,
        description="selection free_run: grow the model on at most this many training samples (the last of each "
        "training segment, in proportion to its length), then re-estimate the chosen terms' weights on the whole "
        "training split starting from the grown ones, kept when they validate no worse. On a long record the "
        "free-run sensitivities of a lightly damped model build up along the run, the growth stops early and the "
        "weights stall (Bouc-Wen, 32 768 samples: 1.08 % validation NMSE grown on all of it, 0.078 % grown on the "
        "last 12 000). null (default): grow on all of it. family: auto uses 12 000 (GROWTH_WINDOW), its test-input "
        "band check guarding the larger models against extrapolation (the seal fitted at 1-5 bar: 0.0069 % "
        "validation NMSE grown on 12 000 samples, but the run diverges at 7 bar where the one grown on all stays "
        "bounded)",
    )
    growth_work: Optional[float] = Field(
        None,
        gt=0,
        description="selection free_run: stop growing once the growth has done this many million operations per "
        "training sample it grows on (counted, not timed: a Levenberg-Marquardt Jacobian of m terms counts "
        "m (m + P + 1) per output, a free run m, a step's screening of a pool of C monomials C (m + P + 1), P the "
        "largest output lag; 3 to 6e-10 s per operation and sample). The model that validated best so far is "
        "kept, and the same data give the same model on any machine. null (default): no limit. family: auto sets "
        "it from its budget (a growth to 237 terms on 3200 samples counted 517 and took 564 s; Bouc-Wen's to 90 "
        "terms on 12 000 samples 5.8 and 50 s)",
    )
    max_terms: Optional[int] = Field(None, gt=0, description="at most this many terms per output (the constant counts)")
    threshold: Optional[float] = Field(
        None,
        gt=0,
        lt=1,
        description="stop when the next term reduces the squared error by less than this fraction "
        "of the target's energy y'y",
    )
    stop_on: Literal["free_run", "one_step"] = Field(
        "free_run",
        description="selection one_step: the validation error that chooses the number of FOS terms: free_run: "
        "of the model's free run on the validation split (what the model is for: a structure that is good one "
        "step ahead need not be in free run, thesis 3.1.4; a model without an input term cannot win); one_step: "
        "of the one-step predictions (thesis A.3)",
    )
    patience: Optional[int] = Field(
        20,
        ge=1,
        description="stop after this many terms without a lower validation error and keep the best size (1: the "
        "first rise, thesis A.3; along the FOS order the free-running error is far from monotone: a term can "
        "destabilise the free run until a later one compensates, so the default looks 20 terms further); null: "
        "do not use the validation split",
    )
    drop_unstable: bool = Field(
        True,
        description="one_step: if the selected polynomial's free run leaves the divergence band on the training or "
        "validation data, drop terms from the end of the FOS order until it does not (a smaller model is often the "
        "stable one, thesis 3.1.4); false: keep the selection as it is",
    )
    weights: Literal["lstsq", "recursion"] = Field(
        "lstsq",
        description="weights of the selected terms: least squares on the data, or FOS's recursion (eq. A.14 / A.15)",
    )
    ridge: Optional[Union[float, Literal["auto"]]] = Field(
        None,
        description="ridge factor k for the selected terms (stabilization, thesis 6.3.2): a number >= 0, or auto: "
        "the factor with the lowest free-running validation error",
    )
    bounds: Optional[Union[Annotated[float, Field(ge=0)], dict[str, tuple[Optional[float], Optional[float]]]]] = Field(
        0.5,
        description="clip the free-running output (eq. 6.25): a number m clips every output to the range of its "
        "measured training and validation outputs widened by m x the training range on both sides (default 0.5: a "
        "model driven outside its training inputs stays within plausible outputs instead of diverging); {output: "
        "[L, U]} gives bounds in the data's units (null: that side unbounded); null: no clipping",
    )
    clip_while_choosing: bool = Field(
        False,
        description="choose terms and weights on the clipped free run, the clip being part of the model (thesis "
        "6.3.2, eq. 6.25 used in estimation). Default false: the clip only guards inputs the data never showed, "
        "and a model that needs it on its own training or validation data counts as diverged",
    )
    start: Literal["drop", "zeros"] = Field(
        "drop",
        description="training patterns at a recording's start (thesis 3.1.1): drop those whose regressors reach "
        "before the first sample, or fill the missing past with zeros",
    )
    initial: Literal["measured", "zeros", "settled"] = Field(
        "measured",
        description="free run: measured: the first L samples (L = the largest lag) are the measured outputs "
        "and the prediction starts at sample L; zeros: every value before the first sample is 0 (model space: "
        "the training mean); settled: the run starts from rest at its first input (that input held for "
        f"{SETTLE_SAMPLES} samples before the first, from zeros), with no kick where the input does not start "
        "at its mean",
    )
    max_pool: int = Field(
        3000, ge=1, description="refuse pools with more monomials than this (memory and time grow with its square)"
    )
    refinement: FreeRunRefinement = Field(default_factory=FreeRunRefinement)

    @field_validator("lags", mode="before")
    @classmethod
    def _lags(cls, v: Any):
        """Read every lag here, so that a mistake gets one clear message (not one per union branch)."""
        if v is None:
            return v
        if not isinstance(v, dict):
            raise ValueError("write lags per column, e.g. {u: [0, 1, 2], y: [1, 2]}")
        out: dict[str, list[LagItem]] = {}
        for name, items in v.items():
            items = items if isinstance(items, list) else [items]
            parsed: list[LagItem] = []
            for item in items:
                if isinstance(item, (int, np.integer)) and not isinstance(item, bool):
                    if item < 0:
                        raise ValueError(f"{name}: lag {item} is negative; lags count samples into the past (>= 0)")
                    parsed.append(int(item))
                elif isinstance(item, (dict, LagRange)):
                    try:
                        parsed.append(item if isinstance(item, LagRange) else LagRange.model_validate(item))
                    except ValidationError as exc:
                        from dynmodel.spec import validation_summary

                        raise ValueError(
                            f"{name}: lag range {item}: {validation_summary(exc)}; "
                            "write {from: 0, to: 18, step: 2} (ends included)"
                        ) from None
                else:
                    raise ValueError(
                        f"{name}: {item!r} is not a lag; write an integer >= 0 or a range {{from: 0, to: 18, step: 2}}"
                    )
            out[str(name)] = parsed
        if not any(expand_lags(items) for items in out.values()):
            raise ValueError("give at least one lag, e.g. {u: [0, 1], y: [1]}")
        return out

    @field_validator("bounds")
    @classmethod
    def _bounds(cls, v):
        if isinstance(v, dict):
            for name, (lo, hi) in v.items():
                if lo is not None and hi is not None and not lo < hi:
                    raise ValueError(f"bounds of '{name}': the lower bound {lo} must lie below the upper bound {hi}")
        return v

    @field_validator("ridge")
    @classmethod
    def _ridge(cls, v):
        if isinstance(v, float) and v < 0:
            raise ValueError("the ridge factor must be >= 0 (or auto)")
        return v

    @model_validator(mode="after")
    def _initial_weights(self) -> NarxFamilyParams:
        """One finite starting weight per given term, written as the terms are (one list, or per output)."""
        w = self.initial_weights
        if w is None:
            return self
        if self.terms is None:
            raise ValueError("initial_weights start the estimation of given terms: give 'terms' too")
        t = self.terms
        pairs: list[tuple[str | None, list[str], list[float]]]
        if isinstance(w, dict) and isinstance(t, dict):
            if set(w) != set(t):
                raise ValueError(f"initial_weights name the outputs {sorted(w)}; terms name {sorted(t)}")
            pairs = [(k, t[k], w[k]) for k in t]
        elif isinstance(w, list) and isinstance(t, list):
            pairs = [(None, t, w)]
        else:
            raise ValueError("write initial_weights as terms are written: one list, or {output: [...]} per output")
        for name, terms, weights in pairs:
            where = f" of '{name}'" if name is not None else ""
            if len(weights) != len(terms):
                raise ValueError(
                    f"initial_weights{where}: {len(weights)} weights for {len(terms)} terms; give one per term"
                )
            if not all(np.isfinite(weights)):
                raise ValueError(f"initial_weights{where}: every weight must be finite")
        return self

    @property
    def max_degree(self) -> int:
        """The pool's degree, or the largest one the search tries (``degree: null``)."""
        return self.degree if self.degree is not None else 3

    def lag_table(self) -> Optional[dict[str, list[int]]]:
        """Lags per column, expanded and sorted (None: the default embedding)."""
        if self.lags is None:
            return None
        return {name: expand_lags(items) for name, items in self.lags.items()}
