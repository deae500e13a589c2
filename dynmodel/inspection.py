"""What a saved model holds, as one JSON-ready mapping (``dynmodel inspect``, ``--json``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .model import FittedModel

FACTS = ("cost", "inputs", "outputs", "delay_lines", "delay_form", "scaling", "sampling_time", "tune_in_samples")
PROVENANCE = ("dynmodel_version", "created", "seed", "training_data_sha256", "spec_file")


def describe(model: FittedModel, path: str | Path | None = None) -> dict[str, Any]:
    """File, name, family, cost, preprocessing (:data:`FACTS`), the family's own facts
    (``family.summary()``), free-run metrics and provenance of a fitted model."""
    pre = model.preprocessor
    return {
        "file": None if path is None else str(path),
        "name": model.spec.get("name"),
        "family": model.family.name,
        "cost": model.spec.get("cost"),
        "inputs": pre.input_names,
        "outputs": pre.output_names,
        "delay_lines": pre.delay_lines,
        "delay_form": pre.delay_form,
        "scaling": pre.scaling,
        "sampling_time": pre.sampling_time,
        "tune_in_samples": model.warmup,
        "model": model.family.summary(),
        "metrics": model.metrics,
        "provenance": model.provenance,
    }
