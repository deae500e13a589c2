"""``dynmodel reliability-check`` as a library function: a model file or a built-in test system checked."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DynmodelError
from ..family import Progress, no_progress
from ..reliability import Report, Settings, Sine
from .options import parse_params, parse_sine


@dataclass
class ReliabilityResult:
    """The check's report and what was checked (``{"model": FILE}`` or the test system and its params)."""

    report: Report
    source: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return {**self.source, **self.report.to_json()}


def check_reliability(
    model_path: str | Path | None = None,
    system: str | None = None,
    params: Mapping[str, Any] | Sequence[str] = (),
    settings: Settings | None = None,
    sines: Sequence[str | Sine] = (),
    json_path: str | Path | None = None,
    force: bool = False,
    progress: Progress = no_progress,
) -> ReliabilityResult:
    """``dynmodel reliability-check``: replica test, Lyapunov exponents and constant-input scan (thesis
    4.4.1, 5.3.1) of a saved model, or of the registered test system ``system`` built from ``params``
    (a mapping, or ``key=value`` items); ``sines`` are extra drives (Sine or ``AMPLITUDE:OMEGA[:OFFSET]``);
    the report is also written to ``json_path``. ``result.report.exit_code``: 0 reliable, 1 otherwise."""

    from .. import registry
    from ..errors import SpecError
    from ..paths import check_outputs, write_json
    from ..reliability import check, check_model
    from ..spec import validation_summary

    if (model_path is None) == (system is None):
        raise DynmodelError(
            "give either a model file or --system NAME"
            if model_path is None
            else "give a model file or --system, not both",
            "reliability-check",
            "e.g. dynmodel reliability-check model.h5, or dynmodel reliability-check --system duffing",
        )
    if params and system is None:
        raise DynmodelError("--param sets parameters of a --system test system", "--param", "drop it for model files")
    model_file = Path(model_path) if model_path is not None else None
    json_file = Path(json_path) if json_path is not None else None
    check_outputs([(json_file, "json", "--json")], {"model": model_file}, force)
    settings = dataclasses.replace(settings or Settings(), sines=tuple(parse_sine(x) for x in sines))
    if system is not None:
        cls = registry.system(system)
        values = parse_params(params)
        try:
            target = cls(**values)
        except ValueError as exc:  # pydantic's ValidationError is a ValueError
            raise SpecError(
                f"invalid parameter ({validation_summary(exc)})",
                "--param",
                f"'{system}' takes {', '.join(cls.Params.model_fields)}",
            ) from None
        report = check(target, settings, progress)
        source: dict[str, Any] = {"test_system": system, "params": target.params.model_dump(mode="json")}
    else:
        from .. import store

        assert model_file is not None  # exactly one of MODEL and --system (checked above)
        progress("load", None, str(model_file))
        model = store.load(model_file)
        report = check_model(model, settings, progress, str(model_file))
        source = {"model": str(model_file)}
    result = ReliabilityResult(report, source)
    if json_file is not None:
        write_json(json_file, result.to_json())
    return result
