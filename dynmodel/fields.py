"""Field checks shared by the spec sections and the families' parameter models."""

from __future__ import annotations

import types
import typing
from typing import Any

from pydantic import BaseModel
from pydantic_core import PydanticCustomError


def _plain_types(annotation: Any) -> set[Any]:
    """The types an annotation admits at its top level (through Optional, Union and Annotated)."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _plain_types(typing.get_args(annotation)[0])
    if origin is typing.Union or origin is types.UnionType:
        found: set[Any] = set()
        for arg in typing.get_args(annotation):
            found |= _plain_types(arg)
        return found
    return {origin or annotation}


#: the pydantic error type of a true/false given for a number; its context names the key
NUMBER_NOT_BOOLEAN = "number_not_boolean"


def refuse_booleans(model: type[BaseModel], data: Any) -> Any:
    """Refuse true/false (YAML also reads yes/no/on/off so) for a number field: pydantic takes them as 1
    and 0, so ``degree: yes`` silently meant degree 1."""
    if not isinstance(data, dict):
        return data
    for name, field in model.model_fields.items():
        key = name if name in data else field.alias
        if key is None or key not in data or not isinstance(data[key], bool):
            continue
        kinds = _plain_types(field.annotation)
        if bool not in kinds and kinds & {int, float}:
            raise PydanticCustomError(
                NUMBER_NOT_BOOLEAN,
                "a number, not true or false (YAML reads yes/no/on/off as true/false)",
                {"key": key, "value": data[key]},
            )
    return data
