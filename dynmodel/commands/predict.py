"""``dynmodel predict`` and ``dynmodel inspect`` as library functions: a saved model replayed on an input
file, or summarized."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FreeRunDiverged
from ..model import FittedModel, Run
from ..prediction import PredictionInput


@dataclass
class PredictResult:
    """The free run of :func:`predict_file`: the table (``columns``, ``rows``) and what was written."""

    model: FittedModel
    inputs: PredictionInput
    run: Run
    columns: list[str]
    rows: np.ndarray
    input_path: Path
    out: Path | None
    plot_path: Path | None
    skip_tune_in: bool

    def written_line(self) -> str:
        """``N predictions written to FILE`` with what the tune-in rows hold."""
        warmup = self.model.warmup
        skipped = f" (the {warmup} tune-in rows left out)" if self.skip_tune_in and warmup else ""
        marked = f" (the first {warmup} rows are the measured tune-in, marked in column 'measured')"
        return f"{len(self.rows)} predictions written to {self.out}{skipped or (marked if warmup else '')}"

    def excursion_notes(self, margin: float = 0.05) -> list[str]:
        """An input that goes beyond the training input range by more than ``margin`` of its width, as ``fit``
        says it of a validation or test split: the model extrapolates there (a polynomial's input monomials
        grow, a readout meets states it never saw)."""
        notes = [
            f"the input '{name}' leaves the training range by {100 * excess:.0f} % of its width (sample {k}, "
            f"{self.inputs.time_name} = {self.inputs.time[k]:.6g}): the model extrapolates there"
            for name, excess, k in self.model.input_excursions(self.inputs.u, margin)
        ]
        return notes + self.output_notes(margin)

    def output_notes(self, margin: float = 0.05) -> list[str]:
        """A predicted output that goes beyond the training output range by more than ``margin`` of its width
        (after the tune-in): where it first does and how far it goes. Inside the input range this is most
        often the start: a network's state starts at rest, far from the state the data's start needs."""
        train, y = self.model.train_output, self.run.y[self.model.warmup :]
        if train is None or train.ndim != 2 or train.shape[0] == 0 or train.shape[1] != y.shape[1] or not len(y):
            return []
        lo, hi = np.nanmin(train, axis=0), np.nanmax(train, axis=0)
        width = np.maximum(hi - lo, np.finfo(float).tiny)
        notes = []
        for j, name in enumerate(self.model.output_names):
            excess = np.maximum(y[:, j] - hi[j], lo[j] - y[:, j]) / width[j]
            out = np.flatnonzero(np.nan_to_num(excess, nan=0.0) > margin)
            if not len(out):
                continue
            k = int(out[0]) + self.model.warmup
            start = (
                "; it starts there: the model's state starts from rest, far from the state the data's start needs "
                "(`dynmodel reliability-check` tells how many samples it takes to forget its start; leave them out)"
                if out[0] < 0.05 * len(y) and not self.model.warmup  # no measured tune-in sets its state
                else ""
            )
            notes.append(
                f"the predicted output '{name}' leaves the training output range by {100 * float(np.nanmax(excess)):.0f} % "
                f"of its width on {len(out)} samples, from sample {k} ({self.inputs.time_name} = "
                f"{self.inputs.time[k]:.6g}){start}"
            )
        return notes

    def problem(self) -> FreeRunDiverged | None:
        """The divergence of the free run (later predictions are NaN), or None."""
        at = self.run.diverged_at
        if at is None:
            return None
        return FreeRunDiverged(
            f"the free run diverged at sample {at} ({self.inputs.time_name} = {self.inputs.time[at]:.6g}); "
            "later predictions are NaN",
            str(self.input_path),
            "check that the input stays within the training range",
        )


def predict_file(
    model_path: str | Path,
    input_path: str | Path,
    out: str | Path | None = None,
    tune_in: str | Path | None = None,
    plot: str | Path | None = None,
    skip_tune_in: bool = False,
    force: bool = False,
) -> PredictResult:
    """``dynmodel predict``: replay the model (free run) on the input columns of ``input_path`` (the tune-in
    outputs from ``tune_in`` or the input file), write the table to ``out`` (CSV; None: not written, the
    caller prints ``rows``) and the figure to ``plot``; output paths are checked before the run."""
    from .. import prediction, store
    from ..errors import DataError
    from ..paths import check_outputs

    model_file, input_file = Path(model_path), Path(input_path)
    tune_file = Path(tune_in) if tune_in is not None else None
    out_file = Path(out) if out is not None else None
    plot_file = Path(plot) if plot is not None else None
    model = store.load(model_file)
    inp = prediction.read_inputs(model, input_file, tune_file)
    columns = prediction.header(model, inp.time_name, skip_tune_in)
    # only a table with the tune-in flag column is told apart from measured data: a file of time and outputs
    # alone may be the user's measurements (same header), so replacing it takes --force
    ours = [
        h for h in (prediction.header(model, inp.time_name, skip) for skip in (False, True)) if prediction.MEASURED in h
    ]
    check_outputs(
        [(out_file, "csv", "--out"), (plot_file, "plot", "--plot")],
        {"model": model_file, "input file": input_file, "tune-in file": tune_file},
        force,
        columns={"--out": ours},
    )
    try:
        run = model.run(inp.u, inp.y_tune)
    except DataError:
        raise
    except ValueError as exc:
        raise DataError(str(exc), str(input_file), "check the input file") from None
    rows = prediction.table(model, inp, run, skip_tune_in)
    if out_file is not None:
        prediction.write_table(out_file, columns, rows)
    if plot_file is not None:
        from ..plots import measured_vs_simulated

        y_true = inp.y_measured if inp.y_measured is not None else np.full_like(run.y, np.nan)
        measured_vs_simulated(
            plot_file,
            inp.time,
            y_true,
            run.y,
            model.output_names,
            f"{model_file.name} on {input_file.name}",
            tune_in=model.warmup,
        )
    return PredictResult(model, inp, run, columns, rows, input_file, out_file, plot_file, skip_tune_in)


@dataclass
class InspectResult:
    """A saved model's summary (:func:`dynmodel.inspection.describe`, with the search record of family
    auto) and the usefulness note of its stored metrics."""

    model: FittedModel
    summary: dict[str, Any]
    note: str | None


def inspect_model(model_path: str | Path, json_path: str | Path | None = None, force: bool = False) -> InspectResult:
    """``dynmodel inspect``: family, data, preprocessing, metrics, provenance of a model file; the summary
    is also written to ``json_path`` when given."""

    from .. import store
    from ..inspection import describe
    from ..paths import check_outputs, write_json
    from ..usefulness import assess, summary_line

    path = Path(model_path)
    json_file = Path(json_path) if json_path is not None else None
    check_outputs([(json_file, "json", "--json")], {"model": path}, force)
    model = store.load(path)
    summary = describe(model, path)
    if model.search is not None:
        # every candidate with its parameters, scores and verdict: the leaderboard's footnote sends users here
        kept = ("winner", "winner_summary", "notes", "interrupted", "budget", "seconds", "candidates")
        summary["search"] = {k: model.search.get(k) for k in kept}
    note = summary_line(assess(model), model.spec.get("spec_file") or model.provenance.get("spec_file"))
    if json_file is not None:
        write_json(json_file, summary)
    return InspectResult(model, summary, note)
