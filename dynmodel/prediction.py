"""`dynmodel predict` as a library: read a model's inputs (and tune-in outputs) from files, lay out
the prediction table, write it.

The table keeps the input file's time column (its name and values) when it has one: the model
spec's ``time_column``, else a column named ``t`` or ``time`` (any case); otherwise ``t`` counts
sampling times from 0. A model that tunes in on measured outputs (:attr:`FittedModel.warmup` > 0)
is no predictor on its first samples: by default those rows hold the measured outputs it was fed
and a column ``measured`` is 1 on them (0 on the predictions), so scoring the whole file stays
honest; with ``skip_tune_in`` they are left out.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from .data.dataset import time_named
from .data.finite import check_finite
from .data.readers import list_columns, read_columns
from .errors import DataError
from .model import FittedModel, Run

MEASURED = "measured"


@dataclass
class PredictionInput:
    """What a prediction needs from the user's files."""

    u: np.ndarray  # (n, n_inputs)
    y_tune: np.ndarray | None  # the first warmup measured outputs (None without tune-in)
    y_measured: np.ndarray | None  # measured outputs over the whole input file, when it has them
    time: np.ndarray  # (n,)
    time_name: str


def time_column(model: FittedModel, path: Path) -> str | None:
    """The input file's time column: the training spec's ``time_column``, else ``t`` / ``time``."""
    names = list_columns(path)
    data = model.spec.get("data") or {}
    wanted = data.get("time_column")
    if isinstance(wanted, str) and wanted in names:
        return wanted
    return time_named(names, model.input_names + model.output_names)


def read_inputs(model: FittedModel, input_path: Path, tune_in_path: Path | None = None) -> PredictionInput:
    """The model's input columns from ``input_path``; the tune-in outputs from ``tune_in_path`` (or
    the input file); the time column. One-line DataErrors for anything missing."""
    for option, given in (("--input", input_path), ("--tune-in", tune_in_path)):
        if given is None:
            continue
        if not given.exists():
            raise DataError(f"{option} file not found", str(given), f"check the {option} path")
        from .paths import is_previous_output

        if given.is_file() and is_previous_output(given, "model"):
            raise DataError(
                "is a dynmodel model file, not data",
                str(given),
                f"give {option} the data file with the model's {'input' if option == '--input' else 'output'} "
                "columns (the model file is the first argument)",
            )
    if tune_in_path is not None and not tune_in_path.exists():
        raise DataError("tune-in file not found", str(tune_in_path), "check the --tune-in path")
    if tune_in_path is not None and not tune_in_path.is_file():
        raise DataError("is a folder, not a tune-in file", str(tune_in_path), "give --tune-in a data file")
    cols = read_columns(input_path, model.input_names, gaps=True)  # an empty cell is NaN, as in a spec's data
    u = np.column_stack([cols[n] for n in model.input_names])
    check_finite(u, model.input_names, str(input_path), "fill or remove those samples")
    try:
        measured = _outputs(model, input_path, len(u))
    except DataError:
        measured = None
    need = model.warmup
    y_tune = None
    if tune_in_path is not None and not need:
        import warnings

        warnings.warn(
            f"{tune_in_path}: this model ({model.family.name}) runs from its rest state and reads no measured "
            "outputs, so the --tune-in file is not used",
            stacklevel=2,
        )
    if need:
        source = tune_in_path or input_path
        y = _outputs(model, source, None)
        if y is None:
            outs = ", ".join(f"'{n}'" for n in model.output_names)
            raise DataError(
                f"this model tunes in on the first {need} measured samples of output column(s) {outs}, "
                f"and {source.name} has none",
                str(source),
                f"add column(s) {outs} to {input_path.name} (only the first {need} rows are read) or pass "
                "--tune-in FILE",
            )
        finite = int(np.isfinite(y[:need]).all(axis=1).sum())
        if len(y) < need or finite < need:
            raise DataError(
                f"the tune-in needs {need} finite measured output samples, found {finite}",
                str(source),
                f"provide the first {need} measured values of {model.output_names}",
            )
        if need >= len(u):  # nothing left to predict
            raise DataError(
                f"the input has {len(u)} samples, no more than the model's tune-in of {need}: nothing is left to "
                "predict",
                str(input_path),
                f"give at least {need + 1} samples",
            )
        y_tune = y[:need]
    name = time_column(model, input_path)
    if name is not None:
        t = read_columns(input_path, [name])[name]
        _check_step(model, t, name, input_path)
        return PredictionInput(u, y_tune, measured, t, name)
    return PredictionInput(u, y_tune, measured, np.arange(len(u)) * model.sampling_time, "t")


def _outputs(model: FittedModel, path: Path, n: int | None) -> np.ndarray | None:
    names = set(list_columns(path))
    if not all(o in names for o in model.output_names):
        return None
    yc = read_columns(path, model.output_names, gaps=True)  # only the tune-in rows must be complete
    y = np.column_stack([yc[o] for o in model.output_names])
    return y if n is None or len(y) == n else None


def _check_step(model: FittedModel, t: np.ndarray, name: str, path: Path) -> None:
    import warnings

    if len(t) < 2:
        return
    data = model.spec.get("data") or {}
    # the training's time unit belongs to its time column: a column found by its name (t, time_s) is in seconds
    unit = float(data.get("time_unit") or 1.0) if name == data.get("time_column") else 1.0
    step = float(np.median(np.diff(t))) * unit
    st = model.sampling_time
    if st > 0 and abs(step - st) > 0.01 * st:
        warnings.warn(
            f"{path}: the time column '{name}' steps by {step:.6g} s, the model was trained at {st:.6g} s per "
            "sample; the predictions assume the model's sampling time",
            stacklevel=2,
        )


def header(model: FittedModel, time_name: str = "t", skip_tune_in: bool = False) -> list[str]:
    """The prediction table's columns."""
    cols = [time_name, *model.output_names]
    if model.warmup and not skip_tune_in:
        cols.append(MEASURED)
    return cols


def table(model: FittedModel, inp: PredictionInput, run: Run, skip_tune_in: bool = False) -> np.ndarray:
    """Rows of the prediction table (see the module docstring for the tune-in rows)."""
    y = run.y.copy()
    warm = min(model.warmup, len(y))
    if not warm:
        return np.column_stack([inp.time, y])
    if skip_tune_in:
        return np.column_stack([inp.time[warm:], y[warm:]])
    assert inp.y_tune is not None
    y[:warm] = inp.y_tune[:warm]
    flag = np.zeros(len(y))
    flag[:warm] = 1.0
    return np.column_stack([inp.time, y, flag])


def write_table(target: Path | IO[str] | None, columns: list[str], rows: np.ndarray) -> None:
    """CSV with a header row; ``None`` writes to stdout."""
    stream = sys.stdout if target is None else target
    if isinstance(stream, Path):
        stream.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(stream, rows, delimiter=",", header=",".join(columns), comments="", fmt="%.10g")
