"""``dynmodel generate``, ``schema`` and ``plugins`` as library functions: generated recordings, the spec's
JSON Schema and the installed plugins."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .options import parse_params


@dataclass
class Recording:
    """A generated recording written as CSV: time, inputs, outputs (``columns``)."""

    generator: str
    path: Path
    columns: list[str]
    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    seed: int
    plot_path: Path | None = None

    @property
    def n(self) -> int:
        return len(self.t)


def generate_recording(
    generator: str,
    out: str | Path,
    n: int = 10000,
    seed: int = 0,
    params: Mapping[str, Any] | Sequence[str] = (),
    plot: str | Path | None = None,
    force: bool = False,
) -> Recording:
    """``dynmodel generate``: ``n`` samples of a registered generator (``params``: a mapping or ``key=value``
    items) written to the CSV ``out`` (replaced only when it is a CSV, or with ``force``), and a figure of the
    signals and of every output against the first input to ``plot``."""
    from .. import registry
    from ..errors import DataError, SpecError
    from ..paths import check_outputs
    from ..spec import validation_summary

    gen = registry.source(generator)
    columns = ["t", *gen.input_names, *gen.output_names]
    out_file = Path(out)
    plot_file = Path(plot) if plot is not None else None
    check_outputs([(out_file, "csv", "--out"), (plot_file, "plot", "--plot")], None, force)  # replaces a CSV
    values = parse_params(params, example="a0=0.7")
    try:
        validated = gen.Params.model_validate(values)
    except ValueError as exc:
        raise SpecError(
            f"invalid parameter ({validation_summary(exc)})",
            "--param",
            f"see the '{generator}' entry of `dynmodel schema`",
        ) from None
    u, y = gen.generate(validated, n, np.random.default_rng(seed))
    t = np.arange(n) * gen.sampling_time(validated)
    bad = np.flatnonzero(~np.isfinite(np.column_stack([u, y])).all(axis=1))
    if bad.size:  # written, no model could use it: say so instead
        raise DataError(
            f"the generated recording holds NaN or inf from sample {int(bad[0])} on (the parameters make the system "
            "diverge or overflow)",
            "--param",
            f"use parameters in the range of the '{generator}' entry of `dynmodel schema` (finite, physical values)",
        )
    out_file.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(out_file, np.column_stack([t, u, y]), delimiter=",", header=",".join(columns), comments="", fmt="%.12g")
    result = Recording(generator, out_file, columns, t, u, y, seed)
    if plot_file is not None:
        from ..plots import recording

        recording(plot_file, t, u, y, list(gen.input_names), list(gen.output_names), f"{generator} (seed {seed})")
        result.plot_path = plot_file
    return result


def schema_text(out: str | Path | None = None, force: bool = False) -> str:
    """``dynmodel schema``: the spec's JSON Schema (every installed family's and generator's parameters)
    as indented JSON, also written to ``out`` when given."""
    import json

    from ..paths import check_outputs, write_text
    from ..spec import spec_json_schema

    check_outputs([(out, "json", "--out")], None, force)
    text = json.dumps(spec_json_schema(), indent=2)
    if out is not None:
        write_text(out, text + "\n")
    return text


@dataclass
class PluginGroup:
    """The installed plugins of one kind: ``(name, description, entry point)`` rows."""

    title: str
    group: str
    rows: list[tuple[str, str, str]] = field(default_factory=list)


def installed_plugins() -> list[PluginGroup]:
    """``dynmodel plugins``: model families, data generators, benchmark sources, reliability test systems
    and diagnose's detectors, each with the entry point that provides it."""
    from importlib.metadata import entry_points

    from .. import registry

    groups = []
    for group, loaded, title in [
        (registry.FAMILIES, registry.families(), "model families"),
        (registry.SOURCES, registry.sources(), "data generators"),
        (registry.SOURCES, registry.benchmarks(), "benchmark sources (data: {benchmark: NAME, root: DIR})"),
        (registry.SYSTEMS, registry.systems(), "test systems for reliability-check --system"),
        (registry.DETECTORS, registry.detectors(), "detectors of dynmodel diagnose"),
    ]:
        eps = {ep.name: ep.value for ep in entry_points(group=group)}
        rows = [(name, getattr(obj, "description", ""), eps.get(name, "")) for name, obj in loaded.items()]
        groups.append(PluginGroup(title, group, rows))
    return groups
