"""Command-line style settings read into values: ``key=value`` parameters and ``AMPLITUDE:OMEGA[:OFFSET]``
sine drives (the CLI's ``--param`` and ``--sine``; the library functions accept these or the values)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ..errors import SpecError
from ..reliability import Sine


def parse_params(items: Mapping[str, Any] | Sequence[str], example: str = "a=3.5") -> dict[str, Any]:
    """The values of repeated ``key=value`` items, each value read as YAML (a mapping is taken as is)."""
    from ..spec import read_yaml

    if isinstance(items, Mapping):
        return dict(items)
    values: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise SpecError(f"'{item}' is not key=value", "--param", f"write e.g. --param {example}")
        key, raw = item.split("=", 1)
        try:
            values[key.strip()] = read_yaml(raw, "--param")
        except SpecError:
            raise SpecError(
                f"cannot read the value of '{item}'",
                "--param",
                f"write the value as YAML, e.g. --param {example} or --param C=[[0.3,2],[-0.5,-1.9]]",
            ) from None
    return values


def parse_sine(text: str | Sine) -> Sine:
    """``AMPLITUDE:OMEGA[:OFFSET]`` as a :class:`~dynmodel.reliability.Sine` (a Sine is taken as is)."""
    if isinstance(text, Sine):
        return text
    parts = text.split(":")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        nums = [float(p) for p in parts]
    except ValueError:
        raise SpecError(f"'{text}' is not AMPLITUDE:OMEGA[:OFFSET]", "--sine", "write e.g. --sine 27:1.4") from None
    return Sine(nums[0], nums[1], nums[2] if len(nums) == 3 else None)
