"""``dynmodel control`` as a library function: a saved model as the feed-forward of a P-controlled plant."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..control import Plant, Report, Settings
from ..family import Progress, no_progress
from ..model import FittedModel
from .options import parse_params


@dataclass
class ControlResult:
    """The control experiment: the model, the plant (its generator ``name``), the report (criteria per
    realization, notes, the first realization's series) and the seconds it took."""

    model: FittedModel
    model_path: Path
    name: str
    plant: Plant
    report: Report
    seconds: float

    def summary(self) -> dict[str, dict[str, dict[str, float]]]:
        """Mean and std of every criterion, for the model and the perfect model."""
        return self.report.summary()

    def to_json(self) -> dict[str, Any]:
        return {"model": str(self.model_path), **self.report.to_json()}


def run_control(
    model_path: str | Path,
    plant: str | Path | None = None,
    params: Mapping[str, Any] | Sequence[str] = (),
    settings: Settings | None = None,
    json_path: str | Path | None = None,
    plot: str | Path | None = None,
    force: bool = False,
    progress: Progress = no_progress,
) -> ControlResult:
    """``dynmodel control`` (thesis 6.4): P-control of the plant described in ``plant`` (a YAML with
    ``generator:`` and ``params:``, or a spec; default: the model's training generator), with ``params``
    overrides (dotted keys; a mapping or ``key=value`` items), the model's force added from the switch on;
    the criteria are written to ``json_path`` and the tracking error to ``plot`` when given."""

    from .. import control as ctl
    from .. import store
    from ..errors import SpecError
    from ..paths import check_outputs, write_json

    settings = settings or Settings()
    if settings.hold not in ("linear", "zero"):
        raise SpecError(
            f"--hold {settings.hold} is not linear or zero", "--hold", "use --hold linear (default) or --hold zero"
        )
    model_file = Path(model_path)
    plant_file = Path(plant) if plant is not None else None
    json_file = Path(json_path) if json_path is not None else None
    plot_file = Path(plot) if plot is not None else None
    check_outputs(
        [(json_file, "json", "--json"), (plot_file, "plot", "--plot")],
        {"model": model_file, "plant file": plant_file},
        force,
    )
    t0 = time.perf_counter()
    model = store.load(model_file)
    described = ctl.read_plant(plant_file) if plant_file is not None else None
    name, plant_params = ctl.plant_source(model, described)
    the_plant, resolved = ctl.make_plant(name, plant_params, parse_params(params))
    report = ctl.run(model, the_plant, settings, progress)
    report.plant.update({"generator": name, "params": resolved})
    result = ControlResult(model, model_file, name, the_plant, report, time.perf_counter() - t0)
    if json_file is not None:
        write_json(json_file, result.to_json())
    if plot_file is not None:
        from ..plots import tracking_error

        s, summary = report.series, result.summary()
        tracking_error(
            plot_file,
            s["t"],
            s["reference"],
            s["error_model"],
            s["error_perfect"],
            settings.switch,
            settings.skip,
            f"{model_file.name} on {name}: alpha {summary['model']['alpha']['mean']:.4g} %, "
            f"beta {summary['model']['beta']['mean']:.4g} %",
        )
    return result
