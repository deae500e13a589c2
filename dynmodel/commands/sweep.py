"""``dynmodel sweep`` as a library function: a spec fitted at every point of a grid, the results folder
and the JSON summary written."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..family import Progress, no_progress
from ..sweeps.results import SweepResult


def run_sweep(
    spec: str | Path,
    grid: str | Path,
    out: str | Path | None = None,
    keep: str = "best",
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    json_path: str | Path | None = None,
    force: bool = False,
    progress: Progress = no_progress,
) -> SweepResult:
    """``dynmodel sweep``: :func:`dynmodel.sweeps.sweep` into the folder ``out`` (default ``<name>-sweep``
    next to the spec), with ``json_path`` checked before any work and written at the end. Ctrl-C raises
    the KeyboardInterrupt with ``folder`` set (and ``result``: the points finished so far)."""

    from ..paths import check_outputs, write_json
    from ..sweeps import run as sweeps

    folder = Path(out) if out is not None else sweeps.default_out(spec)
    from ..errors import DynmodelError
    from ..paths import spec_inputs
    from ..spec import load_spec

    inputs: dict[str, list[Path]] = {"spec": [Path(spec)], "grid": [Path(grid)]}
    try:  # the data files the spec reads are inputs too (the sweep checks the spec itself below)
        inputs.update({k: v for k, v in spec_inputs(load_spec(spec)).items() if k != "spec"})
    except DynmodelError:
        pass
    check_outputs([(json_path, "json", "--json")], inputs, force)
    try:
        result = sweeps.sweep(
            spec,
            grid,
            out=folder,
            keep=keep,  # type: ignore[arg-type]  # a str from the command line: sweep() checks it
            resume=resume,
            workers=workers,
            scheduler=scheduler,
            progress=progress,
        )
    except KeyboardInterrupt as exc:
        interrupted: Any = exc
        interrupted.folder = folder
        raise
    if json_path is not None:
        write_json(json_path, result.to_json())
    return result
