"""Extensions are JSON merge patches (RFC 7396) of the spec.

merge(target, patch): a mapping in the patch merges into the target's mapping key by key, ``null``
deletes a key, anything else (numbers, strings, lists) replaces the target's value. A patched
spec is validated again, so an extension is always a spec a user could have written.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

from ..extensions import merge
from ..spec import validate_spec

__all__ = ["merge", "portable", "apply"]


def portable(raw: dict[str, Any], base_dir: Path) -> dict[str, Any]:
    """The user's spec with data paths made absolute (so the written spec runs from any folder)."""
    from ..spec import _resolve_paths

    out = copy.deepcopy(raw)
    data = out.get("data") or {}
    test = data.get("test")
    tests = test if isinstance(test, list) else [test or {}]
    for section in [data, *tests, data.get("validation") or {}]:
        p = section.get("path") if isinstance(section, dict) else None
        if isinstance(p, (str, list, dict)):
            section["path"] = _resolve_paths(p, lambda x: _absolute(x, base_dir))
    if isinstance(data, dict) and isinstance(data.get("root"), str):
        data["root"] = str(_absolute(data["root"], base_dir))
    return out


def _absolute(p: str, base_dir: Path) -> Path:
    path = Path(p).expanduser()
    return path if path.is_absolute() else (base_dir / path).resolve()


def apply(raw: dict[str, Any], patch: dict[str, Any], source: str, base_dir: Path):
    """(patched mapping, validated spec); SpecError when the patch gives an invalid spec."""
    patched = merge(raw, patch)
    return patched, validate_spec(patched, source, base_dir)
