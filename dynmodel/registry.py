"""Plugin discovery through ``importlib.metadata`` entry points.

Built-in families and data generators register themselves exactly as a third-party
package would, in ``pyproject.toml``::

    [project.entry-points."dynmodel.families"]
    esn = "dynmodel_plugins.esn:EchoStateNetwork"

The core never imports a plugin by name; it only asks this module.
"""

from __future__ import annotations

import difflib
from functools import cache
from importlib.metadata import entry_points
from typing import Any

from .errors import DynmodelError

FAMILIES = "dynmodel.families"
SOURCES = "dynmodel.sources"
SYSTEMS = "dynmodel.systems"
DETECTORS = "dynmodel.detectors"

_KIND = {FAMILIES: "model family", SOURCES: "data generator", SYSTEMS: "test system", DETECTORS: "diagnosis detector"}


@cache
def _load_group(group: str) -> dict[str, Any]:
    loaded: dict[str, Any] = {}
    for ep in sorted(entry_points(group=group), key=lambda e: e.name):
        if ep.name in loaded:
            continue
        try:
            obj = ep.load()
        except Exception as exc:  # a broken third-party plugin must not break the tool
            raise DynmodelError(
                f"the {_KIND[group]} plugin '{ep.name}' ({ep.value}) failed to import: {exc}",
                fix="reinstall or uninstall the package that provides it",
            ) from exc
        if getattr(obj, "name", ep.name) != ep.name:
            obj.name = ep.name
        loaded[ep.name] = obj
    return loaded


def families() -> dict[str, Any]:
    """Installed model families, by id."""
    return dict(_load_group(FAMILIES))


def _is_benchmark(obj: Any) -> bool:
    return getattr(obj, "kind", None) == "benchmark"


def sources() -> dict[str, Any]:
    """Installed data generators, by id (the ``dynmodel.sources`` entries that are not benchmarks)."""
    return {k: v for k, v in _load_group(SOURCES).items() if not _is_benchmark(v)}


def benchmarks() -> dict[str, Any]:
    """Installed benchmark sources (``dynmodel.sources`` entries with ``kind = "benchmark"``), by id."""
    return {k: v for k, v in _load_group(SOURCES).items() if _is_benchmark(v)}


def systems() -> dict[str, Any]:
    """Installed built-in test systems for the reliability check, by id."""
    return dict(_load_group(SYSTEMS))


def detectors() -> dict[str, Any]:
    """Installed diagnosis detectors (``dynmodel diagnose``), by id."""
    return dict(_load_group(DETECTORS))


def unknown_name_message(kind: str, name: str, known: list[str]) -> tuple[str, str]:
    """(what, fix) texts for an unknown plugin name, with a close match when there is one."""
    what = f"unknown {kind} '{name}'"
    close = difflib.get_close_matches(name, known, n=1)
    fix = f"use one of: {', '.join(known) or '(none installed)'}"
    if close:
        fix = f"did you mean '{close[0]}'? Known: {', '.join(known)}"
    return what, fix


def _lookup(table: dict[str, Any], kind: str, name: str, where: str) -> Any:
    if name not in table:
        what, fix = unknown_name_message(kind, name, sorted(table))
        raise DynmodelError(what, where, fix)
    return table[name]


def family(name: str) -> Any:
    return _lookup(families(), "family", name, "model.family")


def source(name: str) -> Any:
    return _lookup(sources(), "generator", name, "data.generator")


def benchmark(name: str) -> Any:
    return _lookup(benchmarks(), "benchmark", name, "data.benchmark")


def system(name: str) -> Any:
    return _lookup(systems(), "test system", name, "--system")
