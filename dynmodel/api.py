"""The Python API on arrays: ``Family.fit(u, y)`` and ``dynmodel.fit(spec, data=...)``.

Both paths build the same :class:`~dynmodel.data.Dataset` as ``dynmodel fit`` does from files (splits,
transient, noise: :func:`~dynmodel.data.load_dataset` with the recordings in memory) and fit with
:func:`dynmodel.engine.fit_family` (preprocessing fitted on the training split, the family's
model-space fit, evaluation of every split). A model fitted on arrays therefore equals the model
``dynmodel fit`` gives for the same samples written to a file, bit for bit.

The model file of such a model holds the resolved spec with ``data.path: <arrays>``: the samples
are not in a file, and the input and output names, sampling time and preprocessing are recorded.
"""

from __future__ import annotations

import numbers
import types
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from pydantic import Field, ValidationError

from . import engine
from .columns import index_step, is_pandas, is_recording_list, recordings, select
from .data.dataset import SOURCE_KEYS, Dataset, LoadedSource, load_dataset
from .errors import DataError, ModelWarning, ParameterError, SpecError
from .family import Family, Progress, no_progress
from .metrics import COSTS
from .model import FittedModel, Run
from .spec import IN_MEMORY, DataCommon, EvaluationSpec, Spec, parse_yaml, validate_spec, validation_summary


class ArrayData(DataCommon):
    """The ``data`` section of a fit on arrays: the spec's preprocessing keys and the channel names."""

    input: list[str] = Field(min_length=1)
    output: list[str] = Field(min_length=1)
    sampling_time: float = Field(1.0, gt=0)


@dataclass
class ArraySpec:
    """What the engine reads from a spec, for a family object fitted on arrays (no plugin lookup, so a
    family class that is not registered fits too)."""

    family: Family
    data: ArrayData
    cost: str
    seed: int
    evaluation: EvaluationSpec
    source: str = IN_MEMORY
    #: splits given as separate recordings ("validation")
    separate: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.family.name or type(self.family).__name__

    @property
    def model(self) -> SimpleNamespace:
        return SimpleNamespace(family=self.family.name or type(self.family).__name__, params=self.family.params)

    def resolve_path(self, p: str) -> Path:
        raise DataError("a fit on arrays reads no file", p, "pass the samples to fit()")

    def resolved(self) -> dict[str, Any]:
        data = {"path": IN_MEMORY, **self.data.model_dump(mode="json")}
        data.update({s: {"path": IN_MEMORY} for s in self.separate})
        return {
            "name": self.name,
            "data": data,
            "model": {"family": self.model.family, "params": self.family.params.model_dump(mode="json")},
            "cost": self.cost,
            "evaluation": self.evaluation.model_dump(mode="json"),
            "seed": self.seed,
            "output": None,
        }


def progress_reporter(progress: Progress | bool | None):
    from contextlib import nullcontext

    from .progress import Reporter

    if progress is True:
        return Reporter()
    if progress not in (None, False) and not callable(progress):
        raise ParameterError(
            f"progress={progress!r} is neither True nor a callable",
            "fit",
            "pass progress=True (a live line on stderr), a function (stage, fraction, message), or None",
        )
    return nullcontext(progress or no_progress)


def fit_arrays(
    family: Family,
    u: Any,
    y: Any,
    *,
    validation: float | tuple[Any, Any] | None = 0.2,
    cost: str | None = None,
    seed: int = 0,
    sampling_time: float | None = None,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    transient: int = 0,
    scaling: str = "standard",
    delay_lines: Sequence[int] = (),
    delay_form: str = "copy",
    derived_inputs: Sequence[Mapping[str, Any]] = (),
    detrend: Sequence[Any] = (),
    spikes: str = "replace",
    progress: Progress | bool | None = None,
) -> FittedModel:
    """Fit ``family`` on recordings given in Python (see ``Family.fit``); returns the FittedModel, which
    is also ``family.model_``."""
    recs, ins, outs = recordings(u, y, input_names, output_names)
    if sampling_time is None:  # the step of a time-stamped pandas index, else one unit per sample
        first = u[0] if is_recording_list(u) else u
        sampling_time = index_step(first) or 1.0
    sources: dict[str, LoadedSource] = {}
    if validation is None:
        split: dict[str, float] = {"train": 1.0}
    elif isinstance(validation, (int, float)) and not isinstance(validation, bool):
        if not 0 < validation < 1:
            raise ParameterError(
                f"validation={validation} is not a fraction in (0, 1)",
                "fit",
                "hold out e.g. validation=0.2, pass (u_val, y_val), or None",
            )
        split = {"train": 1.0 - float(validation), "validation": float(validation)}
    elif isinstance(validation, (tuple, list)) and len(validation) == 2:
        named = input_names is None and output_names is None  # names from the data: found by name again
        vrecs, _, _ = recordings(validation[0], validation[1], ins, outs, "validation", columns=named)
        sources["validation"] = (vrecs, float(sampling_time), ins, outs)
        split = {"train": 1.0}
    else:
        raise ParameterError(
            f"validation={type(validation).__name__} is neither a fraction nor (inputs, outputs)",
            "fit",
            "pass validation=0.2, validation=(u_val, y_val) or validation=None",
        )
    if cost is None:  # as a spec without cost: the family's own default
        cost = getattr(family, "default_cost", "mse1")
    if cost not in COSTS:
        raise ParameterError(f"unknown cost '{cost}'", "fit", "use cost='mse1' (one-step) or cost='mse_inf' (free run)")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ParameterError(f"seed={seed!r} is not an integer >= 0", "fit", "pass e.g. seed=0")
    try:
        data = ArrayData(
            input=ins,
            output=outs,
            sampling_time=sampling_time,
            split=split,
            transient=transient,
            scaling=scaling,
            delay_lines=list(delay_lines),
            delay_form=delay_form,
            derived_inputs=list(derived_inputs),
            detrend=list(detrend),
            spikes=spikes,
        )
    except ValidationError as exc:
        raise ParameterError(validation_summary(exc), "fit", "see help(Family.fit)") from None
    sources["data"] = (recs, float(data.sampling_time), ins, outs)
    spec = ArraySpec(family, data, cost, int(seed), EvaluationSpec(), separate=tuple(s for s in sources if s != "data"))
    ds = load_dataset(spec, sources)
    warn_data_notes(ds)
    with progress_reporter(progress) as report:
        model, runs = engine.fit_family(family, spec, ds, report)
    warn_if_useless(model, ds, runs)
    return model


def warn_data_notes(ds: Dataset) -> None:
    """What was found in the measured outputs and done about it (spikes replaced, a clipped sensor), as
    :class:`~dynmodel.textfiles.DataNote` warnings: a notebook sees what ``dynmodel fit`` prints as notes."""
    from .textfiles import DataNote

    for note in ds.artifact_notes():
        warnings.warn(DataNote(note[0].upper() + note[1:]), stacklevel=_caller_level())


def warn_if_useless(model: FittedModel, ds: Dataset, runs: list[Run]) -> None:
    """A model fitted in Python is never silently useless: the findings of :func:`dynmodel.usefulness.assess`
    go to ``model.assessment``, and the line ``dynmodel fit`` would print (a diverged free run included) is
    issued as a :class:`~dynmodel.errors.ModelWarning`."""
    from .usefulness import assess, stability_fix, summary_line

    notes = assess(model, ds, runs)
    model.assessment = notes
    cost = model.spec.get("cost")
    lines = [f"{n.text}: {stability_fix(model.family.stability_hint, cost)}" for n in notes if n.kind == "diverged"]
    line = summary_line(notes, cost=cost, searched=model.search or False, python=True)
    if line:
        lines.append(line)
    for text in lines:
        warnings.warn(text[0].upper() + text[1:], ModelWarning, stacklevel=_caller_level())


def _caller_level() -> int:
    """The ``stacklevel`` of the first frame outside dynmodel and its plugins: a warning points at the user's
    line (``model.fit(u, y)``), not at the package's internals."""
    import os
    import sys

    import dynmodel_plugins

    packages = (sys.modules["dynmodel"], dynmodel_plugins)
    ours = tuple(str(Path(str(p.__file__)).resolve().parent) + os.sep for p in packages)
    frame: types.FrameType | None = sys._getframe(1)
    level = 1
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(ours):
        frame, level = frame.f_back, level + 1
    return level


# ---------------------------------------------------------------------------- dynmodel.fit(spec, data=...)


def _as_split_sources(data: Any) -> dict[str, Any]:
    """``data=`` as {"data": main recordings, "validation": ..., "test": ...} (still unconverted)."""
    if isinstance(data, Mapping) and not is_pandas(data):
        unknown = [k for k in data if k not in ("train", "validation", "test")]
        if unknown or "train" not in data:
            raise DataError(
                f"data= has the key(s) {sorted(data)}" if unknown else "data= has no 'train' entry",
                "data",
                "pass {'train': ..., 'validation': ..., 'test': ...} (validation and test optional)",
            )
        return {"data" if k == "train" else k: v for k, v in data.items()}
    return {"data": data}


def _pairs(obj: Any, ins: list[str] | None, outs: list[str] | None, where: str) -> tuple[Any, Any]:
    """(inputs, outputs) of one data= entry: ``(u, y)``, a DataFrame with the spec's columns, or a list
    of these (several recordings)."""
    items = obj if isinstance(obj, list) else [obj]
    us, ys = [], []
    for item in items:
        if is_pandas(item) and getattr(item, "ndim", 1) == 2:
            if not ins or not outs:
                raise SpecError(
                    "a DataFrame holds inputs and outputs side by side, and the spec does not say which is which",
                    "data.input / data.output",
                    "name the input and output columns in the spec's data section",
                )
            us.append(select(item, ins, where))
            ys.append(select(item, outs, where))
        elif isinstance(item, tuple) and len(item) == 2:
            us += list(item[0]) if is_recording_list(item[0]) else [item[0]]
            ys += list(item[1]) if is_recording_list(item[1]) else [item[1]]
        else:
            raise DataError(
                f"cannot read a {type(item).__name__} as a recording",
                where,
                "pass (u, y), a DataFrame with the spec's input and output columns, or a list of these",
            )
    return (us[0], ys[0]) if len(us) == 1 else (us, ys)


def fit_spec(
    spec: Spec | Mapping[str, Any] | str | Path, data: Any, progress: Progress | bool | None = None
) -> FittedModel:
    """``dynmodel.fit(spec, data=...)``: the spec's model, cost, seed, splits and preprocessing on
    recordings given in Python instead of the spec's data source.

    ``spec``: a loaded spec, a mapping or a YAML path; its data section may then omit ``path`` /
    ``generator``. ``data``: ``(u, y)``, a DataFrame with the spec's ``data.input`` and ``data.output``
    columns, a list of these (several recordings, split as the files of ``path: [...]`` are), or
    ``{"train": ..., "validation": ..., "test": ...}`` for separate recordings (as ``data.validation``
    / ``data.test`` sources are)."""
    raw, source, base = _raw_spec(spec)
    raw_data = dict(raw.get("data") or {})
    entries = _as_split_sources(data)
    for s in ("validation", "test"):
        if raw_data.get(s) and s not in entries:
            raise SpecError(
                f"the spec reads a separate {s} recording (data.{s}), and data= does not give one",
                f"{source}: data.{s}",
                f"pass data={{'train': ..., '{s}': ...}} or remove data.{s}",
            )
    spec_ins = [str(c) for c in raw_data["input"]] if raw_data.get("input") else None
    spec_outs = [str(c) for c in raw_data["output"]] if raw_data.get("output") else None
    u, y = _pairs(entries["data"], spec_ins, spec_outs, "data")
    recs, ins, outs = recordings(u, y, spec_ins, spec_outs, "arrays", columns=True)
    loaded: dict[str, tuple[list, list[str], list[str]]] = {"data": (recs, ins, outs)}
    for s in ("validation", "test"):
        if s in entries:
            su, sy = _pairs(entries[s], ins, outs, f"data.{s}")
            loaded[s] = recordings(su, sy, ins, outs, "arrays", columns=True)
    # the spec's source keys do not apply: the samples are given; separate sources come from data=
    raw_data = {k: v for k, v in raw_data.items() if k not in SOURCE_KEYS or k == "sampling_time"}
    st = float(raw_data.get("sampling_time") or 1.0)
    raw_data.update(path=IN_MEMORY, input=ins, output=outs, sampling_time=st)
    for s in ("validation", "test"):
        raw_data.pop(s, None)
    validated = validate_spec({**raw, "data": raw_data}, source, base)
    sources = {k: (r, st, i, o) for k, (r, i, o) in loaded.items()}
    ds = load_dataset(validated, sources)
    warn_data_notes(ds)
    with progress_reporter(progress) as report:
        model, runs = engine.fit_dataset(validated, ds, report)
    warn_if_useless(model, ds, runs)
    kept = ("path", "input", "output", "sampling_time")
    model.spec["data"] = {k: v for k, v in model.spec["data"].items() if k in kept or k not in SOURCE_KEYS}
    model.spec["data"]["path"] = IN_MEMORY
    for s in ("validation", "test"):
        if s in loaded:
            model.spec["data"][s] = {"path": IN_MEMORY}
    return model


def _raw_spec(spec: Spec | Mapping[str, Any] | str | Path) -> tuple[dict[str, Any], str, Path | None]:
    """A spec as a raw mapping, with its source text for messages and the folder paths resolve against."""
    if isinstance(spec, Mapping):
        return dict(spec), "<spec>", None
    if isinstance(spec, Spec):  # a loaded spec
        raw = spec.model_dump(mode="python", exclude_unset=False)
        return raw, spec.source, spec.base_dir
    path = Path(spec)
    if not path.exists():
        raise SpecError("spec file not found", str(path), "check the path")
    raw = parse_yaml(path.read_text(encoding="utf-8"), str(path))
    raw.setdefault("name", path.stem)
    return raw, str(path), path.parent
