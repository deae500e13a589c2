"""The commands of the CLI as library functions: each does the whole job of one ``dynmodel`` command
(check the output paths before any work, run it, write its files) and returns a result object that the
CLI only prints. Usable from Python without typer or rich::

    from dynmodel.commands import fit_and_save
    result = fit_and_save("specs/quickstart.yaml", out="m.h5", json_path="m.json")
    result.model.metrics["test"]["nmse"], result.warning(), result.problem()
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .catalog import PluginGroup, Recording, generate_recording, installed_plugins, schema_text
    from .control import ControlResult, run_control
    from .diagnose import DiagnoseResult, diagnose_spec_file
    from .fit import FitResult, ValidateResult, fit_and_save, plot_fit, validate_spec_file
    from .options import parse_params, parse_sine
    from .predict import InspectResult, PredictResult, inspect_model, predict_file
    from .reliability import ReliabilityResult, check_reliability
    from .sweep import run_sweep

#: where each name lives (imported on first use: a command loads only what it runs)
_HOMES = {
    "catalog": ("PluginGroup", "Recording", "generate_recording", "installed_plugins", "schema_text"),
    "control": ("ControlResult", "run_control"),
    "diagnose": ("DiagnoseResult", "diagnose_spec_file"),
    "fit": ("FitResult", "ValidateResult", "fit_and_save", "plot_fit", "validate_spec_file"),
    "options": ("parse_params", "parse_sine"),
    "predict": ("InspectResult", "PredictResult", "inspect_model", "predict_file"),
    "reliability": ("ReliabilityResult", "check_reliability"),
    "sweep": ("run_sweep",),
}
_MODULE_OF = {name: module for module, names in _HOMES.items() for name in names}


def __getattr__(name: str) -> Any:
    if name not in _MODULE_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_MODULE_OF[name]}", __name__), name)


__all__ = [
    "fit_and_save",
    "FitResult",
    "validate_spec_file",
    "ValidateResult",
    "plot_fit",
    "predict_file",
    "PredictResult",
    "inspect_model",
    "InspectResult",
    "check_reliability",
    "run_sweep",
    "ReliabilityResult",
    "diagnose_spec_file",
    "DiagnoseResult",
    "run_control",
    "ControlResult",
    "generate_recording",
    "Recording",
    "schema_text",
    "installed_plugins",
    "PluginGroup",
    "parse_params",
    "parse_sine",
]
