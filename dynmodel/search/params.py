"""``model: {family: auto, params: {...}}``: the parameters of the model search."""

from __future__ import annotations

from typing import Any, Literal, Optional

from pydantic import ConfigDict, Field, field_validator

from ..family import FamilyParams

AUTO = "auto"
#: the default budget in seconds (planned for REFERENCE_WORKERS cores, see :mod:`.plan`)
DEFAULT_BUDGET = 300.0


class AutoParams(FamilyParams):
    """Search candidate models of every installed family and keep the one whose free run validates best."""

    model_config = ConfigDict(extra="forbid")

    budget: float = Field(
        DEFAULT_BUDGET,
        gt=0,
        le=7 * 24 * 3600,
        description="seconds the search plans for on two cores (docs/auto.md: the work is planned from "
        "estimates, so the same seed gives the same model whatever the machine or the number of workers; "
        "more workers finish sooner, one takes about twice as long)",
    )
    families: Optional[list[str]] = Field(
        None, min_length=1, description="search only these families (default: every installed one that takes part)"
    )
    seeds: int = Field(3, ge=1, le=50, description="fits per configuration of a random family (judged by the median)")
    exclude: list[Literal["data-extensions", "moves"]] = Field(
        default_factory=list,
        description="leave out parts of the search: data-extensions (delay lines, derived inputs), moves "
        "(diagnose's proposals on the leader)",
    )

    @field_validator("families")
    @classmethod
    def _known(cls, value: Optional[list[str]]) -> Optional[list[str]]:
        if value is None:
            return value
        from .. import registry

        known = registry.families()
        for name in value:
            if name == AUTO:
                raise ValueError("'auto' is the search itself; list model families, e.g. [narx, esn]")
            if name not in known:
                what, fix = registry.unknown_name_message("family", name, sorted(known))
                raise ValueError(f"{what}. {fix}")
            if not _takes_part(known[name]):
                raise ValueError(
                    f"family '{name}' declares no search space (its search_space hook), so auto cannot search it; "
                    "fit it with model: {family: " + name + "}"
                )
        return list(dict.fromkeys(value))


def _takes_part(cls: type) -> bool:
    from ..family import Family

    hook = getattr(cls, "search_space", None)
    return hook is not None and getattr(hook, "__func__", hook) is not getattr(Family.search_space, "__func__", None)


def searchable_families() -> dict[str, type]:
    """Installed families that implement the ``search_space`` hook, by id (sorted)."""
    from .. import registry

    return {name: cls for name, cls in sorted(registry.families().items()) if _takes_part(cls)}


def auto_model_spec():
    """The spec model of ``model: {family: auto, params: ...}``."""
    from pydantic import create_model

    from ..spec import ModelChoice

    tag: Any = Literal["auto"]  # typed Any: the field's type, not an annotation to check
    return create_model(
        "ModelSpec_auto",
        __base__=ModelChoice,
        __doc__="search candidate models of every family and keep the best on validation (docs/auto.md)",
        family=(tag, ...),
        params=(AutoParams, Field(default_factory=AutoParams)),
    )
