"""Parameters of the `arx` family: the polynomial orders of A(q) y(t) = B(q) u(t - nk) + c."""

from __future__ import annotations

from pydantic import Field

from dynmodel.family import FamilyParams


class ArxParams(FamilyParams):
    na: int = Field(2, ge=0, le=100, description="output lags y(t-1) ... y(t-na): the order of A(q)")
    nb: int = Field(3, ge=1, le=100, description="input taps u(t-nk) ... u(t-nk-nb+1) per input: the order of B(q)")
    nk: int = Field(0, ge=0, le=1000, description="input delay in samples (0: the input acts in the same sample)")
    constant: bool = Field(True, description="estimate an offset c")
    ridge: float = Field(
        0.0,
        ge=0,
        description="ridge factor on the least-squares (ARX) estimate, relative to the mean squared regressor",
    )
    max_nfev: int = Field(
        200, ge=1, description="cost mse_inf (output error): at most this many free runs per output's solve"
    )
