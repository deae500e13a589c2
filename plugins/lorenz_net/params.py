"""Parameters of the `lorenz-net` family (thesis 4.4.2)."""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import Field, model_validator

from dynmodel.family import FamilyParams


class LorenzNetParams(FamilyParams):
    size: int = Field(32, gt=0, description="number of driven Lorenz elements M (3 M states)")
    strategy: Literal["parallel", "feed-forward"] = Field(
        "feed-forward",
        description="parallel: every element driven by the external input; feed-forward: elements in "
        "layers, the first driven by the input, the others by earlier elements (strictly lower-triangular C, eq. 4.59)",
    )
    layers: int = Field(4, gt=0, description="feed-forward: number of layers (thesis: 4 layers of 8)")
    extra_links: int = Field(
        30, ge=0, description="feed-forward: random forward links added to the one link per element"
    )
    steps: int = Field(400, ge=0, description="simulated-annealing steps (thesis: 400)")
    coupling_share: float = Field(
        0.5,
        ge=0,
        le=1,
        description="feed-forward: fraction of the steps that change couplings "
        "(thesis: 200 of 400); the rest change element parameters",
    )
    t0: float = Field(0.1, gt=0, description="initial temperature")
    t_end: float = Field(1e-4, gt=0, description="final temperature")
    step: float = Field(
        0.5, gt=0, description="std of the log-change of a parameter or coupling at T0; shrinks as T / T0"
    )
    sigma_range: tuple[float, float] = Field((0.0, 20.0), description="initial sigma ~ U[low, high] (thesis: U[0, 20])")
    r_range: tuple[float, float] = Field((0.0, 40.0), description="initial r ~ U[low, high] (thesis: U[0, 40])")
    b_range: tuple[float, float] = Field((0.0, 10.0), description="initial b ~ U[low, high] (thesis: U[0, 10])")
    alpha_range: tuple[float, float] = Field(
        (0.8, 1.2), description="initial alpha ~ U[low, high] (thesis: U[0.8, 1.2])"
    )
    input_scale: float = Field(
        1.0,
        gt=0,
        description="gain of the external input into the elements it drives (b_i of eq. 4.59; 1: the "
        "drive u of eq. 4.52 as given). On the thesis's Rossler task 1.5 - 2 is better (README, ablation)",
    )
    readout_delays: tuple[int, ...] = Field(
        (),
        description="delays (samples) of the element states added to the readout: y_t = W [xi_t, "
        "xi_(t-d1), ...] (empty: the thesis's readout of the 3M current states). The elements forget the "
        "Rossler drive within about one time unit; states 1 - 3 time units old (10, 20, 30 samples at 0.1) "
        "give the readout the memory a 10-time-unit horizon needs (docs/ablations.md)",
    )
    anneal_delays: bool = Field(
        True,
        description="the annealing scores candidates with the delayed readout (true) or with the readout of "
        "the current states only (false: the elements are optimized as in the thesis and the delays enter "
        "the final readout; much faster with many delays)",
    )
    substeps: int = Field(4, ge=1, description="RK4 steps per sampling interval")
    time_scale: Optional[float] = Field(
        None,
        gt=0,
        description="model time units per sample (default: the data's "
        "sampling time; the thesis samples its Lorenz systems at 0.1)",
    )
    restarts: int = Field(1, ge=1, description="independent annealing runs; the best on validation is kept")
    workers: int = Field(0, ge=0, description="threads for restarts (0: one per core, at most `restarts`)")

    @model_validator(mode="after")
    def _check(self) -> LorenzNetParams:
        if self.t_end >= self.t0:
            raise ValueError(f"t_end ({self.t_end}) must be below t0 ({self.t0})")
        for name in ("sigma_range", "r_range", "b_range", "alpha_range"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name} must satisfy 0 <= low <= high")
        if any(d <= 0 for d in self.readout_delays) or len(set(self.readout_delays)) < len(self.readout_delays):
            raise ValueError(f"readout_delays must be distinct positive sample counts, got {list(self.readout_delays)}")
        if self.strategy == "feed-forward" and self.layers > self.size:
            raise ValueError(f"{self.layers} layers need at least as many elements (size {self.size})")
        return self
