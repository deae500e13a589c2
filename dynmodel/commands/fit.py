"""``dynmodel fit`` and ``dynmodel validate`` as library functions: a spec file in, a checked, fitted,
assessed and saved model (or a checked plan) out, with nothing printed."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..errors import DynmodelError, FreeRunDiverged, Interrupted, how_interrupted
from ..family import Family, Progress, no_progress
from ..model import FittedModel, Run
from ..spec import Spec
from ..usefulness import Note


@dataclass
class FitResult:
    """What :func:`fit_and_save` did: the model (saved to ``path``), its data and free runs, the
    usefulness notes, and the files written."""

    spec: Spec
    model: FittedModel
    dataset: Dataset
    runs: list[Run]
    notes: list[Note]
    path: Path
    seconds: float
    spec_file: str
    json_path: Path | None = None
    plot_path: Path | None = None
    #: the Ctrl-C (or SIGTERM) that cut the family's annealing short; the model keeps its best network so far
    interruption: BaseException | None = None

    @property
    def family_label(self) -> str:
        """The family fitted (``auto -> narx`` when the search chose it)."""
        name = self.model.family.name
        return name if self.model.search is None else f"auto -> {name}"

    @property
    def cost(self) -> str | None:
        return self.model.spec.get("cost") or self.spec.cost

    def data_notes(self) -> list[str]:
        """What the user should know of the data behind the figures: noise added to some splits, a validation or
        test input beyond the training range (the model extrapolates there), a validation that repeats the
        training input (the search says it itself for its validation)."""
        noise = self.spec.data.noise
        notes = []
        if noise is not None and noise.std > 0:
            notes.append(
                f"noise of std {noise.std:g} x the output std was added to the {', '.join(noise.splits)} outputs; "
                "those splits are scored against the noisy outputs"
            )
        notes += [
            f"the {split} split is not scored: {m['unscored']}"
            for split, m in self.model.metrics.items()
            if m.get("unscored")
        ]
        notes += [
            f"the {split} split is scored on its {m['samples']} samples with known outputs: {m['unknown']} with NaN "
            "outputs are left out"
            for split, m in self.model.metrics.items()
            if m.get("unknown")
        ]
        notes += self.dataset.small_split_notes(self.model.warmup)
        notes += self.dataset.overlap_notes()
        notes += self.dataset.training_input_notes()
        notes += self.dataset.artifact_notes()
        notes += self.dataset.excursion_notes()
        notes += [
            note
            for split, note in self.dataset.repeat_notes().items()
            if split != "validation" or self.model.search is None
        ]
        return notes

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` payload: metrics, model file, usefulness assessment and its one line, the notes on
        the data (and the search record)."""
        cut = self.interrupted()
        payload: dict[str, Any] = {
            "metrics": self.model.metrics,
            "model": str(self.path),
            "assessment": [n.to_json() for n in self.notes],
            "warning": self.warning(),
            "notes": ([cut] if cut else []) + self.data_notes(),
            "interrupted": cut,
        }
        if self.model.search is not None:
            payload["search"] = self.model.search
        return payload

    def problem(self) -> DynmodelError | None:
        """The error a command should end with: the user interrupted the search (the safety limit is a note),
        or the free run diverged (exit 1; the model was saved all the same); None when the fit is sound."""
        from ..usefulness import stability_fix

        cut = self.interrupted()
        if cut is not None:
            error = Interrupted(cut, self.spec_file, "rerun it without interrupting to anneal the full schedule")
            error.exit_code = how_interrupted(self.interruption)[1]
            return error
        search = self.model.search
        if search is not None and search.get("interrupted") and not search.get("safety_limit"):  # a note says so
            return Interrupted(
                f"the search was {search['interrupted']}; the best model so far was saved",
                self.spec_file,
                "rerun to search the rest of the budget (the same seed gives the same search)",
            )
        bad = self.model.unstable
        if bad:
            return FreeRunDiverged(
                f"the free run diverged on the {bad['split']} split at sample {bad['sample']} "
                f"(t = {bad['time']:.6g}) of recording '{bad['recording']}'",
                self.spec_file,
                f"{stability_fix(self.model.family.stability_hint, self.spec.cost)}; the model was saved for inspection",
                sample=bad["sample"],
            )
        return None

    def interrupted(self) -> str | None:
        """The line saying that the fit was cut short (Ctrl-C or SIGTERM during an annealing) and what was kept,
        None when it ran to the end."""
        if self.interruption is None:
            return None
        how = how_interrupted(self.interruption)[0]
        return (
            f"the annealing was interrupted ({how}): kept the best network found so far, not the result of the full "
            f"schedule, written to {self.path}"
        )

    def warning(self) -> str | None:
        """One line when the model is worse than a trivial reference or ignores its input (with what to try)."""
        from ..usefulness import summary_line

        return summary_line(self.notes, self.spec_file, self.spec.cost, searched=self.model.search or False)


def fit_and_save(
    spec: str | Path,
    out: str | Path | None = None,
    json_path: str | Path | None = None,
    plot: str | Path | None = None,
    seed: int | None = None,
    force: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress = no_progress,
) -> FitResult:
    """``dynmodel fit``: load the spec file, check every output path before any work (an existing file
    that is not a previous output of its kind is replaced only with ``force``), fit (``family: auto``:
    search, with ``workers`` / ``scheduler``), assess the model's usefulness, save it to ``out`` (default:
    the spec's output), and write the ``json_path`` summary and the ``plot`` figure when given."""
    from .. import engine, store
    from ..anneal import watch_interrupts
    from ..data import load_dataset
    from ..paths import check_outputs, spec_inputs, write_json
    from ..search import search_options
    from ..spec import load_spec
    from ..usefulness import assess

    t0 = time.perf_counter()
    s = load_spec(spec)
    if seed is not None:
        s.seed = seed
    target = Path(out) if out is not None else s.output_path()
    json_file = Path(json_path) if json_path is not None else None
    plot_file = Path(plot) if plot is not None else None
    check_outputs(
        [
            (target, "model", "--out" if out is not None else "output:"),
            (json_file, "json", "--json"),
            (plot_file, "plot", "--plot"),
        ],
        spec_inputs(s, spec),
        force,
    )
    with search_options(workers=workers, scheduler=scheduler), watch_interrupts() as watch:
        progress("data", None, "loading")
        ds = load_dataset(s)
        model, runs = engine.fit_dataset(s, ds, progress)  # a Ctrl-C in an annealing keeps its best network
        model.spec["output"] = str(target.resolve())
        notes = assess(model, ds, runs)
        store.save(model, target)
    result = FitResult(s, model, ds, runs, notes, target.resolve(), time.perf_counter() - t0, str(spec))
    result.interruption = watch.interrupted
    if json_file is not None:
        write_json(json_file, result.to_json())
        result.json_path = json_file
    if plot_file is not None:
        plot_fit(plot_file, ds, runs, model, s.name)
        result.plot_path = plot_file
    return result


def plot_fit(path: Path, ds: Dataset, runs: list[Run], model: FittedModel, name: str) -> None:
    """Measured vs free-running output of the recording holding the test split (else the first), whole,
    with the splits shaded and a zoom on the first scored samples."""
    from ..plots import measured_vs_simulated

    rec = next((r for s in ds.test_splits() for r, _, _ in ds.ranges[s]), 0)
    r = ds.recordings[rec]
    t = np.arange(r.n) * ds.sampling_time
    spans = [
        (split, a * ds.sampling_time, b * ds.sampling_time)
        for split in ds.splits()
        for rr, a, b in ds.ranges[split]
        if rr == rec
    ]
    scored = [
        a
        for split in (*ds.test_splits(), "validation", "train")
        for rr, a, _ in ds.scored(split, model.warmup)
        if rr == rec
    ]
    start = scored[0] if scored else 0
    measured_vs_simulated(
        path,
        t,
        r.y,
        runs[rec].y,
        model.output_names,
        f"{name}: {r.name}"
        + (f" (recording {rec + 1} of {len(ds.recordings)}, the test's)" if len(ds.recordings) > 1 else ""),
        spans,
        zoom=(start, min(r.n, start + 400)),
        tune_in=model.warmup,
    )


@dataclass
class ValidateResult:
    """What :func:`validate_spec_file` checked: the spec, its loaded data, the split table and the plan
    (the family, unfitted, or for ``family: auto`` the lines describing the search)."""

    spec: Spec
    dataset: Dataset
    plan: Family | list[str]
    splits: list[dict[str, Any]] = field(default_factory=list)


def validate_spec_file(spec: str | Path) -> ValidateResult:
    """``dynmodel validate``: the spec's keys, files, columns, values, split sizes and the output path that
    ``fit`` would refuse, checked without fitting (one-line errors)."""
    from ..data import describe, load_dataset
    from ..engine import check_plan, preprocessor
    from ..paths import check_outputs, spec_inputs
    from ..spec import load_spec

    s = load_spec(spec)
    check_outputs([(s.output_path(), "model", "output:")], spec_inputs(s, spec))  # what `fit` would refuse
    ds = load_dataset(s)
    preprocessor(s, ds)  # derived inputs and delay lines, refused here as fit refuses them
    plan = check_plan(s, ds)
    return ValidateResult(s, ds, plan, describe(ds))
