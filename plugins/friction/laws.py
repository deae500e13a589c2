"""Friction laws of thesis 6.1: parameters, validation and their packing for the kernels.

Units are SI throughout: position in m, velocity in m/s, force in N, stiffness in N/m, damping in
N s/m. The defaults describe a small sliding table (a few kg, Coulomb force 20 N, break-away after
micrometres of pre-sliding) and are the plant of the control experiment (6.4).

* ``dahl``  dz/dt = v - sigma |v| z / F_c, F = sigma z (+ viscous v)                       (eq. 6.8)
* ``lugre`` dz/dt = v - sigma0 |v| z / g(v), F = sigma0 z + sigma1(v) dz/dt + sigma2 v     (eq. 6.10)
  with g(v) = F_c + (F_s - F_c) exp(-|v / v_s|^delta) (eq. 6.11, delta = 2) and Olsson's
  velocity-dependent damping sigma1(v) = sigma1 exp(-(v / v_d)^2) (eq. 6.12)
* ``gms``   M elements; sticking: dF_i/dt = k_i v; slipping: dF_i/dt = C (sign(v) - F_i / (nu_i g(v)));
  F = sum F_i + sigma2 v (eq. 6.13 - 6.16)

Eq. 6.13 as printed, dF_i/dt = sign(v) C (1 - F_i / (nu_i g(v))), attracts F_i to +nu_i g(v) for
either sign of v, and for v < 0 that fixed point is repelling. The law implemented here is the
symmetric one, attraction towards sign(v) nu_i g(v) at the rate C / (nu_i g(v)); both agree for
v > 0. An element sticks when the velocity goes through zero and slips when |F_i| reaches
nu_i g(v) while it is loaded in the direction of motion (eq. 6.15); while it is unloaded its force
is kept within the (possibly shrinking) limit nu_i g(v) without a switch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal, Optional, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, model_validator

#: law ids inside the kernels
DAHL, LUGRE, GMS = 0, 1, 2


class _LawBase(BaseModel):
    model_config = ConfigDict(extra="forbid")

    viscous: float = Field(0.0, description="viscous coefficient sigma2 (N s/m) of the term sigma2 v")

    @model_validator(mode="after")
    def _viscous(self):
        if self.viscous < 0:
            raise ValueError(
                f"viscous = {self.viscous:g} is negative: a negative damping feeds energy into the "
                "motion; use a value >= 0"
            )
        return self


class _Stribeck(_LawBase):
    coulomb: float = Field(20.0, description="Coulomb force F_c (N)")
    static: float = Field(22.0, description="break-away (static) force F_s (N)")
    stribeck_velocity: float = Field(0.002, description="Stribeck velocity v_s (m/s)")
    stribeck_exponent: float = Field(
        2.0, description="exponent delta of g(v) = F_c + (F_s - F_c) exp(-|v/v_s|^delta) (eq. 6.5; 2: eq. 6.11)"
    )

    @model_validator(mode="after")
    def _stribeck(self):
        for key in ("coulomb", "static", "stribeck_velocity", "stribeck_exponent"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{key} = {getattr(self, key):g} must be positive")
        return self

    def g(self, v: np.ndarray | float) -> np.ndarray:
        """Stribeck curve g(v) (eq. 6.11), the steady-state dry friction at velocity v."""
        v = np.asarray(v, dtype=np.float64)
        return self.coulomb + (self.static - self.coulomb) * np.exp(
            -(np.abs(v / self.stribeck_velocity) ** self.stribeck_exponent)
        )


class DahlFields(_LawBase):
    """Dahl's model (eq. 6.6 - 6.9): steady state F = F_c sign(v)."""

    sigma: float = Field(1e7, description="stiffness of the asperities sigma (N/m): the initial slope dF/dx")
    coulomb: float = Field(20.0, description="Coulomb force F_c (N)")

    @model_validator(mode="after")
    def _positive(self):
        for key in ("sigma", "coulomb"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{key} = {getattr(self, key):g} must be positive")
        return self

    def g(self, v):
        return np.full_like(np.asarray(v, dtype=np.float64), self.coulomb)


class LuGreFields(_Stribeck):
    """The LuGre model (eq. 6.10 - 6.12): steady state F = g(v) sign(v) + sigma2 v."""

    sigma0: float = Field(1e7, description="bristle stiffness sigma0 (N/m)")
    sigma1: float = Field(2e3, description="micro-viscous damping sigma1 (N s/m)")
    damping: Literal["standard", "olsson"] = Field(
        "standard", description="standard: constant sigma1 (eq. 6.10); olsson: sigma1 exp(-(v/v_d)^2) (eq. 6.12)"
    )
    damping_velocity: float = Field(0.01, description="v_d of Olsson's damping (m/s)")

    @model_validator(mode="after")
    def _lugre(self):
        if not self.sigma0 > 0:
            raise ValueError(f"sigma0 = {self.sigma0:g} must be positive")
        if self.sigma1 < 0:
            raise ValueError(
                f"sigma1 = {self.sigma1:g} is negative: a negative damping feeds energy into the "
                "contact; use a value >= 0"
            )
        if not self.damping_velocity > 0:
            raise ValueError(f"damping_velocity = {self.damping_velocity:g} must be positive")
        return self


class GmsFields(_Stribeck):
    """Generalized Maxwell-slip model (eq. 6.13 - 6.16): M block-springs in parallel."""

    elements: int = Field(10, ge=1, le=1000, description="number of elements M")
    stiffness: Optional[list[float]] = Field(
        None,
        description="k_i (N/m), one per element; default: element i breaks away after a displacement "
        "nu_i F_s / k_i spread geometrically over `presliding`",
    )
    fractions: Optional[list[float]] = Field(
        None, description="nu_i, one per element, summing to 1 (eq. 6.14); default: 1 / M each"
    )
    presliding: tuple[float, float] = Field(
        (2e-7, 2e-5), description="default stiffness: break-away displacements of the first and last element (m)"
    )
    attraction: float = Field(
        5e3, description="C (N/s): a slipping element approaches sign(v) nu_i g(v) at the rate C / (nu_i g(v))"
    )

    @model_validator(mode="after")
    def _gms(self):
        m = self.elements
        if self.fractions is not None:
            if len(self.fractions) != m:
                raise ValueError(
                    f"fractions has {len(self.fractions)} values but elements is {m}; give one nu_i per element"
                )
            if any(not f > 0 for f in self.fractions):
                raise ValueError("every fraction nu_i must be positive")
            total = float(np.sum(self.fractions))
            if abs(total - 1.0) > 1e-9:
                raise ValueError(f"the fractions nu_i add up to {total:.6g}; they must sum to 1 (eq. 6.14)")
        if self.stiffness is not None:
            if len(self.stiffness) != m:
                raise ValueError(
                    f"stiffness has {len(self.stiffness)} values but elements is {m}; give one k_i per element"
                )
            if any(not k > 0 for k in self.stiffness):
                raise ValueError("every stiffness k_i must be positive (N/m)")
        lo, hi = self.presliding
        if not 0 < lo <= hi:
            raise ValueError(f"presliding = [{lo:g}, {hi:g}] must satisfy 0 < first <= last (m)")
        if not self.attraction > 0:
            raise ValueError(f"attraction = {self.attraction:g} must be positive (N/s)")
        return self

    def nu(self) -> np.ndarray:
        return (
            np.full(self.elements, 1.0 / self.elements) if self.fractions is None else np.asarray(self.fractions, float)
        )

    def k(self) -> np.ndarray:
        if self.stiffness is not None:
            return np.asarray(self.stiffness, dtype=np.float64)
        lo, hi = self.presliding
        delta = np.geomspace(lo, hi, self.elements)
        return self.nu() * self.static / delta


class DahlLaw(DahlFields):
    type: Literal["dahl"] = "dahl"


class LuGreLaw(LuGreFields):
    type: Literal["lugre"] = "lugre"


class GmsLaw(GmsFields):
    type: Literal["gms"] = "gms"


AnyLaw = Union[DahlFields, LuGreFields, GmsFields]


def _law_tag(value) -> str | None:
    if isinstance(value, dict):
        return value.get("type", "gms")
    return getattr(value, "type", None)


#: a law chosen by ``type`` (default gms)
Law = Annotated[
    Union[Annotated[DahlLaw, Tag("dahl")], Annotated[LuGreLaw, Tag("lugre")], Annotated[GmsLaw, Tag("gms")]],
    Discriminator(_law_tag, custom_error_type="law_type", custom_error_message="type must be dahl, lugre or gms"),
]


@dataclass(frozen=True)
class PackedLaw:
    """A law as plain arrays for the numba kernels.

    ``p``: [sigma0, sigma1, sigma2, F_c, F_s, v_s, delta, v_d (0: constant sigma1), C];
    ``k``, ``nu``: element stiffness and fractions (GMS; length 1 otherwise).
    """

    kind: int
    p: np.ndarray
    k: np.ndarray
    nu: np.ndarray

    @property
    def n_states(self) -> int:
        return self.k.shape[0] if self.kind == GMS else 1


def pack(law: AnyLaw) -> PackedLaw:
    one = np.ones(1)
    if isinstance(law, DahlFields):
        p = np.array([law.sigma, 0.0, law.viscous, law.coulomb, law.coulomb, 1.0, 2.0, 0.0, 0.0])
        return PackedLaw(DAHL, p, one, one)
    if isinstance(law, LuGreFields):
        vd = law.damping_velocity if law.damping == "olsson" else 0.0
        p = np.array(
            [
                law.sigma0,
                law.sigma1,
                law.viscous,
                law.coulomb,
                law.static,
                law.stribeck_velocity,
                law.stribeck_exponent,
                vd,
                0.0,
            ]
        )
        return PackedLaw(LUGRE, p, one, one)
    p = np.array(
        [
            0.0,
            0.0,
            law.viscous,
            law.coulomb,
            law.static,
            law.stribeck_velocity,
            law.stribeck_exponent,
            0.0,
            law.attraction,
        ]
    )
    return PackedLaw(GMS, p, np.ascontiguousarray(law.k()), np.ascontiguousarray(law.nu()))


def initial_stiffness(law: AnyLaw) -> float:
    """dF/dx at the start of a motion from the virgin state: sigma, sigma0 (+ nothing else), or sum k_i."""
    if isinstance(law, DahlFields):
        return law.sigma
    if isinstance(law, LuGreFields):
        return law.sigma0
    return float(np.sum(law.k()))


def steady_force(law: AnyLaw, v: float) -> float:
    """Sliding force at constant velocity v: F_c sign(v) (Dahl), g(v) sign(v) + sigma2 v (LuGre, GMS)."""
    return float(np.sign(v) * law.g(v) + law.viscous * v)
