"""Is a fitted model of any use? A useless model is never silent.

Five findings, each a :class:`Note` with what was measured and what to try:

- ``diverged``: the free run left the divergence band on some split (see :mod:`dynmodel.model`);
- ``poor``: a held-out split (validation, test, or any other non-training key such as ``test:<name>``)
  has a free-run NMSE of at least :data:`POOR_NMSE` percent, or no better than predicting the
  training mean (the trivial reference: NMSE = 100 (1 + (mean_split - mean_train)^2 / var_split) %);
- ``ignores-input``: replacing every input by its training mean changes the free run on the
  validation split (training when there is none) by less than :data:`INPUT_DEPENDENCE` of the
  measured output's variance, mean((y(u) - y(mean u))^2) / var(y): the model is (nearly) a constant
  or an autonomous oscillator, whatever it scores;
- ``quiet``: a held-out split whose measured output barely moves (its standard deviation below :data:`QUIET`
  of the training output's, per output: a rig left idle, a sensor at rest) scores its NMSE against that small
  variance, so noise alone reaches 100 %; judged on the training output's variance instead, a model within
  :data:`POOR_NMSE` there is not called poor, the split is said to tell little, and neither its input
  dependence nor its carry-over is judged on it;
- ``does-not-carry-over``: a test split's NMSE is at least :data:`CARRY_OVER_FACTOR` times the
  validation NMSE and at least :data:`CARRY_OVER_FLOOR` percent: the model was chosen on data that do not
  represent the test (other operating conditions, inputs beyond the training range, a drift), so its
  validation figure says nothing of its use there.

``dynmodel fit`` prints them as one line; ``family: auto`` and ``dynmodel diagnose`` reuse
:func:`assess` to rank or flag models.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .data.dataset import is_test
from .metrics import split_label

if TYPE_CHECKING:
    from .data.dataset import Dataset
    from .model import FittedModel, Run

#: NMSE (percent) from which a held-out result counts as useless
POOR_NMSE = 90.0
#: input dependence (fraction of the output variance) below which a model ignores its input
INPUT_DEPENDENCE = 0.01
#: a held-out split whose output standard deviation is below this fraction of the training output's (every
#: output) is judged on the training output's variance (a ``quiet`` note instead of ``poor``)
QUIET = 0.1
#: a test NMSE at least this many times the validation NMSE ...
CARRY_OVER_FACTOR = 10.0
#: ... and at least this many percent: the validation does not represent the test data
CARRY_OVER_FLOOR = 10.0


@dataclass
class Note:
    """One finding about a fitted model."""

    kind: str  # "diverged" | "poor" | "quiet" | "ignores-input" | "does-not-carry-over"
    split: str | None
    text: str  # what was measured, as a clause of a sentence
    value: float | None = None
    output: str | None = None  # the one output of a multi-output model the finding is about

    def to_json(self) -> dict[str, Any]:
        out = {"kind": self.kind, "split": self.split, "text": self.text, "value": self.value}
        if self.output is not None:
            out["output"] = self.output
        return out


def held_out_splits(metrics: Mapping[str, Any]) -> list[str]:
    """Every split key of ``metrics`` except ``train`` (``train`` alone when nothing is held out)."""
    keys = [k for k in metrics if k != "train"]
    return keys or [k for k in metrics if k == "train"]


def trivial_nmse_each(ds: Dataset, split: str, warmup: int = 0) -> np.ndarray | None:
    """NMSE (percent) of predicting the training mean on ``split``, per output."""
    rows = ds.scored(split, warmup)
    train = ds.scored("train", warmup)
    if not rows or not train:
        return None
    y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
    mean = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in train]).mean(axis=0)
    var = y.var(axis=0)
    if not np.all(var > 0):
        return None
    return 100.0 * np.mean((y - mean) ** 2, axis=0) / var


def variance_share(ds: Dataset, split: str, warmup: int = 0) -> np.ndarray | None:
    """Per output: the variance of ``split``'s scored outputs over the training outputs' (None when either is
    unknown or the training output is constant)."""
    rows, train = ds.scored(split, warmup), ds.scored("train", warmup)
    if not rows or not train:
        return None
    y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
    y_train = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in train])
    var, var_train = np.nanvar(y, axis=0), np.nanvar(y_train, axis=0)
    if not np.all(np.isfinite(var)) or not np.all(var_train > 0):
        return None
    return var / var_train


def is_quiet(share: np.ndarray | None) -> bool:
    """Does every output move less than :data:`QUIET` of the training output (its standard deviation), given
    :func:`variance_share`'s ``share``?"""
    return share is not None and bool(np.all(share < QUIET**2))


def _quiet(value: float, per: Mapping[str, Any], share: np.ndarray | None, split: str) -> Note | None:
    """A ``quiet`` note when ``split`` is quiet (:func:`is_quiet`, ``share``: :func:`variance_share`) and the
    error, measured against the training output's variance, stays below :data:`POOR_NMSE`; else None."""
    if share is None or not is_quiet(share):
        return None
    each = [entry.get("nmse") for entry in per.values()] if len(per) == len(share) > 1 else [value]
    if any(v is None for v in each):
        return None
    on_train = float(np.mean(np.asarray(each, dtype=float) * share)) if len(each) > 1 else value * float(share[0])
    if not on_train < POOR_NMSE:  # NaN too
        return None
    return Note(
        "quiet",
        split,
        f"the {split} split's output barely moves (its standard deviation is {100 * np.sqrt(share.max()):.2g} % of the "
        f"training output's), so its NMSE of {value:.3g} % measures that small motion and the noise, not the "
        f"model: measured against the training output's variance, the error is {on_train:.2g} %",
        on_train,
    )


def trivial_nmse(ds: Dataset, split: str, warmup: int = 0) -> float | None:
    """NMSE (percent, mean over outputs) of predicting the training mean on ``split``."""
    each = trivial_nmse_each(ds, split, warmup)
    return None if each is None else float(np.mean(each))


def _poor(
    value: float, ref: float | None, split: str, output: str | None = None, shown: str | None = None
) -> Note | None:
    """A ``poor`` note when ``value`` (NMSE %) reaches :data:`POOR_NMSE` or the trivial reference ``ref``
    (``shown``: the split as the user reads it, :func:`dynmodel.metrics.split_label`)."""
    if not (value >= POOR_NMSE or (ref is not None and value >= ref)):
        return None
    worse = f", no better than the training mean's {ref:.3g} %" if ref is not None and value >= ref else ""
    on = f" on output '{output}'" if output is not None else ""
    return Note("poor", split, f"its {shown or split} NMSE is {value:.3g} %{on}{worse}", float(value), output)


def _scored_and_mean_input(
    model: FittedModel, ds: Dataset, split: str | None
) -> tuple[list[tuple[int, int, int]], np.ndarray] | None:
    """The scored rows of ``split`` (default validation, else train) after the model's tune-in, and the
    training mean of every input; None when the split has no scored sample."""
    split = split or ("validation" if ds.ranges.get("validation") else "train")
    rows = ds.scored(split, model.warmup)
    if not rows:
        return None
    train_u, _ = ds.concat_inputs("train")
    return rows, train_u.mean(axis=0) if train_u.shape[0] else np.zeros(len(ds.input_names))


def _held_run(model: FittedModel, ds: Dataset, rec: int, mean_u: np.ndarray, held: dict[int, Run] | None) -> Run:
    """The free run of recording ``rec`` with every input held at ``mean_u``, from ``held`` when it has it (one
    run for :func:`input_dependence` and :func:`input_nonlinearity` together), stored there when computed."""
    if held is not None and rec in held:
        return held[rec]
    r = ds.recordings[rec]
    run = model.run(np.broadcast_to(mean_u, r.u.shape).copy(), r.y[: model.warmup] if model.warmup else None)
    if held is not None:
        held[rec] = run
    return run


def input_dependence(
    model: FittedModel,
    ds: Dataset,
    split: str | None = None,
    runs: list[Run] | None = None,
    held: dict[int, Run] | None = None,
) -> float | None:
    """mean over outputs of mean((y(u) - y(ū))^2) / var(y) on the scored samples of ``split``
    (default validation, else train), where y(ū) is the free run with every input held at its
    training mean. inf when only the held-input run diverges; None when it cannot be measured
    (the model's own run diverges there, or the split is absent)."""
    scored = _scored_and_mean_input(model, ds, split)
    if scored is None:
        return None
    rows, mean_u = scored
    warm = model.warmup
    moved, measured, varied = [], [], []
    for rec in sorted({r for r, _, _ in rows}):
        r = ds.recordings[rec]
        tune = r.y[:warm] if warm else None
        real = runs[rec] if runs is not None else model.run(r.u, tune)
        still = _held_run(model, ds, rec, mean_u, held)
        for rr, a, b in rows:
            if rr != rec:
                continue
            if real.diverged_at is not None and real.diverged_at < b:
                return None
            moved.append(still.y[a:b] if still.diverged_at is None or still.diverged_at >= b else None)
            varied.append(real.y[a:b])
            measured.append(r.y[a:b])
    held_runs = [m for m in moved if m is not None]
    if len(held_runs) < len(moved):
        return float("inf")
    y = np.concatenate(measured)
    var = y.var(axis=0)
    if not np.all(var > 0):
        return None
    diff = np.concatenate(varied) - np.concatenate(held_runs)
    return float(np.mean(np.mean(diff**2, axis=0) / var))


def input_nonlinearity(
    model: FittedModel,
    ds: Dataset,
    split: str | None = None,
    runs: list[Run] | None = None,
    held: dict[int, Run] | None = None,
) -> float | None:
    """How far the free run is from affine in its input: with y(u) the run on the input, y(ū) with every input
    held at its training mean and y(h) on the input halved about that mean (h = (u + ū) / 2, inside the range),
    mean((y(h) - (y(u) + y(ū)) / 2)^2) / mean(((y(u) - y(ū)) / 2)^2) over the scored samples of ``split``
    (default validation, else train), the worst output; 0 for a model linear (affine) in its input, from the same
    start. None when it cannot be measured (a run diverges, the split is absent, the run ignores the input)."""
    scored = _scored_and_mean_input(model, ds, split)
    if scored is None:
        return None
    rows, mean_u = scored
    warm = model.warmup
    gap, half = [], []
    for rec in sorted({r for r, _, _ in rows}):
        r = ds.recordings[rec]
        tune = r.y[:warm] if warm else None
        full = runs[rec] if runs is not None else model.run(r.u, tune)
        still = _held_run(model, ds, rec, mean_u, held)
        mid = model.run(0.5 * (r.u + mean_u), tune)
        for rr, a, b in rows:
            if rr != rec:
                continue
            if any(x.diverged_at is not None and x.diverged_at < b for x in (full, still, mid)):
                return None
            line = 0.5 * (full.y[a:b] + still.y[a:b])
            gap.append(mid.y[a:b] - line)
            half.append(0.5 * (full.y[a:b] - still.y[a:b]))
    moved = np.mean(np.concatenate(half) ** 2, axis=0)
    if not np.all(moved > 0) or not np.isfinite(moved).all():
        return None
    return float(np.max(np.mean(np.concatenate(gap) ** 2, axis=0) / moved))


def assess(
    model: FittedModel, ds: Dataset | None = None, runs: list[Run] | None = None, metrics: Mapping | None = None
) -> list[Note]:
    """The findings of the module docstring for a fitted ``model``. Without ``ds`` only the
    metrics are judged (no trivial reference, no input dependence)."""
    metrics = model.metrics if metrics is None else metrics
    notes: list[Note] = []
    bad = next(((s, m["unstable_from"]) for s, m in metrics.items() if m.get("unstable_from")), None)
    if bad is not None:
        split, where = bad
        notes.append(
            Note(
                "diverged",
                split,
                f"its free run diverges on the {split} split (sample {where['sample']} of '{where['recording']}')",
            )
        )
    for split in held_out_splits(metrics):
        value = metrics[split].get("nmse")
        if value is None:
            continue
        refs = trivial_nmse_each(ds, split, model.warmup) if ds is not None else None
        per = metrics[split].get("per_output") or {}
        shown = split_label(split, metrics[split])
        low = _quiet(value, per, variance_share(ds, split, model.warmup), split) if ds is not None else None
        if low is not None:
            notes.append(low)
            continue
        whole = _poor(value, None if refs is None else float(np.mean(refs)), split, shown=shown)
        if whole is not None or len(per) < 2:
            notes += [whole] if whole is not None else []
            continue
        # one useless output of several: the mean over outputs must not hide it
        for j, (name, entry) in enumerate(per.items()):
            v = entry.get("nmse")
            note = None if v is None else _poor(v, None if refs is None else float(refs[j]), split, name, shown)
            notes += [note] if note is not None else []
    quiet = {n.split for n in notes if n.kind == "quiet"}  # their NMSE measures the noise: no carry-over to judge
    carried = [n for n in carry_over(metrics, search_validation(model)) if n.split not in quiet]
    if ds is not None and runs is not None:
        carried = [_with_offset(n, model, ds, runs) for n in carried]
    notes += carried
    if ds is not None and bad is None:
        # on a validation split whose output barely moves (an idle input) holding the input changes nothing either
        on = "validation" if ds.ranges.get("validation") else "train"
        on = "train" if on in quiet else on
        dep = input_dependence(model, ds, on, runs=runs)
        if dep is not None and dep < INPUT_DEPENDENCE:
            notes.append(
                Note(
                    "ignores-input",
                    on,
                    f"it ignores its input (holding the input at its mean changes the free run by "
                    f"{100 * dep:.2g} % of the output variance)",
                    dep,
                )
            )
    return notes


def search_validation(model: FittedModel) -> float | None:
    """The validation NMSE the search chose a ``family: auto`` model on (held out of its fits: blocks, recordings
    or a tail when the spec has no validation split), None for any other model."""
    record = getattr(model, "search", None) or {}
    winner = next((c for c in record.get("candidates", []) if c.get("key") == record.get("winner")), None)
    value = (winner or {}).get("validation_nmse")
    return float(value) if value is not None and np.isfinite(value) else None


def carry_over(metrics: Mapping[str, Any], searched: float | None = None) -> list[Note]:
    """``does-not-carry-over`` notes: test splits (``test``, ``test:<name>``) whose NMSE is at least
    :data:`CARRY_OVER_FACTOR` x the validation NMSE and at least :data:`CARRY_OVER_FLOOR` %. Without a
    validation split, or when its samples were fitted (``fitted``: family auto's refit on every sample),
    ``searched``: the validation NMSE of the search that chose the model."""
    validation = (metrics.get("validation") or {}).get("nmse")
    what = "validation NMSE"
    fitted = bool((metrics.get("validation") or {}).get("fitted"))
    if (validation is None or not np.isfinite(validation) or fitted) and searched is not None:
        validation, what = searched, "validation NMSE in the search (held out of its fits)"
    if validation is None or not np.isfinite(validation):
        return []
    out = []
    for split, m in metrics.items():
        value = (m or {}).get("nmse")
        if not is_test(split) or value is None or not np.isfinite(value):
            continue
        if value >= CARRY_OVER_FLOOR and value >= CARRY_OVER_FACTOR * validation:
            out.append(
                Note(
                    "does-not-carry-over",
                    split,
                    f"its {split} NMSE ({value:.3g} %) is {value / max(validation, 1e-12):.0f} x its {what} "
                    f"({validation:.3g} %)",
                    float(value),
                )
            )
    return out


def _with_offset(note: Note, model: FittedModel, ds: Dataset, runs: list[Run]) -> Note:
    """A ``does-not-carry-over`` note whose test error is mostly a constant offset (its mean's square at least
    :data:`OFFSET_SHARE` of its mean square, on every output) says so: the recording's zero or operating point
    differs (a test file recorded another day with a shifted sensor: 25.5 % test NMSE, 0.053 % without the
    offset), not the dynamics."""
    rows = ds.scored(note.split or "", model.warmup)
    errors = [ds.recordings[r].y[a:b] - runs[r].y[a:b] for r, a, b in rows]
    if not errors:
        return note
    e = np.concatenate(errors)
    if not np.isfinite(e).all():
        return note
    mean, square = e.mean(axis=0), (e**2).mean(axis=0)
    if not np.all(square > 0) or not np.all(mean**2 >= OFFSET_SHARE * square):
        return note
    shown = ", ".join(f"{m:.3g}" for m in mean)
    share = 100 * float(np.min(mean**2 / square))
    text = f"{note.text}, {OFFSET} (mean error {shown}, {share:.0f} % of its mean square)"
    return Note(note.kind, note.split, text, note.value, note.output)


def _auto_available() -> bool:
    """Does this installation accept ``model: {family: auto}``?"""
    from . import registry

    if "auto" in registry.families():
        return True
    sources = list(registry.sources())
    if not sources:
        return False
    from .errors import DynmodelError
    from .spec import validate_spec

    try:
        validate_spec({"data": {"generator": sources[0]}, "model": {"family": "auto"}})
    except (DynmodelError, ValueError):
        return False
    except Exception:  # noqa: BLE001 - a hint, never a failure
        return False
    return True


def _rejected_on_test(record: Any) -> str | None:
    """When the search rejected candidates that validated better than its choice because their free run left the
    output band on a test input: what to try instead (else None)."""
    if not isinstance(record, Mapping):
        return None
    rows = record.get("candidates") or []
    chosen = next((c for c in rows if c.get("verdict") == "chosen"), None)
    score = (chosen or {}).get("validation_nmse")
    if score is None:
        return None
    better = [  # clearly better: at most half the chosen one's validation NMSE, and not poor itself
        c
        for c in rows
        if str(c.get("verdict", "")).startswith("rejected: leaves the output band on the test")
        and c.get("validation_nmse") is not None
        and c["validation_nmse"] <= 0.5 * score
        and c["validation_nmse"] < 50.0
    ]
    if not better:
        return None
    best = min(better, key=lambda c: c["validation_nmse"])
    return (
        f"{len(better)} candidate(s) that validated clearly better were rejected because their free run leaves the training "
        f"output range on the test input (best: {best.get('family')}: {best.get('summary')}, validation NMSE "
        f"{best['validation_nmse']:.3g} %): if the test truly takes the output beyond the training range, fit that "
        "one directly (its parameters are in the search record), or record training data that cover the test's range"
    )


def what_to_try(
    spec_path: str | None = None, cost: str | None = None, searched: Any = False, python: bool = False
) -> str:
    """The usual next steps for a useless model (``searched``: it came from ``family: auto`` already, true or its
    search record; ``python``: fitted with the Python API on arrays, so the steps are said as Python calls)."""
    return _with_rejected(_what_to_try(spec_path, cost, searched, python), _rejected_on_test(searched))


def _with_rejected(steps: str, rejected: str | None) -> str:
    return steps if rejected is None else f"{steps}; also, {rejected}"


def _what_to_try(spec_path: str | None, cost: str | None, searched: Any, python: bool) -> str:
    if python:
        steps = ["cost='mse_inf'"] if cost is not None and cost != "mse_inf" else []
        if searched:
            steps.append("a larger search budget (params: {budget: ...}) or more data")
        elif _auto_available():
            steps.append("the model search, dynmodel.fit({'model': {'family': 'auto'}}, data=(u, y))")
        else:
            steps.append("another family (dynmodel.registry.families())")
        steps.append("a spec file and `dynmodel diagnose` to name what the model gets wrong")
        return "try " + ", ".join(steps[:-1]) + " or " + steps[-1]
    steps = [f"`dynmodel diagnose {spec_path or 'SPEC'}` to name what the model gets wrong"]
    if cost is not None and cost != "mse_inf":
        steps.append("cost: mse_inf")
    if searched:
        steps.append("a larger search budget (model.params.budget) or more data")
    else:
        steps.append("family: auto" if _auto_available() else "another family (`dynmodel plugins`)")
    return "try " + ", ".join(steps[:-1]) + " or " + steps[-1]


#: a test error whose mean's square is at least this share of its mean square is a constant offset
OFFSET_SHARE = 0.8
#: how a test error that is a constant offset is said, and what to do then
OFFSET = "mostly a constant offset"
OFFSET_FIX = (
    "the test recording's zero or operating point differs from the training data's (a sensor offset?), not its "
    "dynamics: remove the offset from the data, or train and validate on recordings that show it"
)
#: what to try when a held-out split's output barely moves
QUIET_FIX = (
    "hold out a stretch where the input moves the output (data.split, or a validation recording of its own) to "
    "see how the model does"
)
#: what to try when the validation does not represent the test data
CARRY_OVER_FIX = (
    "validate on data like the test's (a validation split or recording that covers its operating conditions "
    "and input range), record longer, or prefer a simpler model"
)


def summary_line(
    notes: list[Note],
    spec_path: str | None = None,
    cost: str | None = None,
    searched: Any = False,
    python: bool = False,
) -> str | None:
    """One line for the user: every finding but divergence (reported as an error of its own). A model that
    validates well but does not carry over to the test is said so apart from a model of little use."""
    carry = "; ".join(n.text for n in notes if n.kind == "does-not-carry-over")
    quiet = "; ".join(n.text for n in notes if n.kind == "quiet")
    kept = [n for n in notes if n.kind not in ("does-not-carry-over", "quiet")]
    line = _useless_line(kept, spec_path, cost, searched, python)
    if quiet:
        said = f"{quiet}. Fix: {QUIET_FIX}"
        line = said if line is None else f"{line}; also, {said}"
    if not carry:
        return line
    if line is None:
        if OFFSET in carry:
            return f"this model does not carry over to the test data: {carry}. Fix: {OFFSET_FIX}"
        return (
            f"this model does not carry over to the test data: {carry}, so the validation did not represent the "
            f"test. Fix: {CARRY_OVER_FIX}"
        )
    return f"{line}; also, {carry}: " + (OFFSET_FIX if OFFSET in carry else "the validation did not represent the test")


def _useless_line(
    notes: list[Note], spec_path: str | None, cost: str | None, searched: Any, python: bool = False
) -> str | None:
    poor = [n for n in notes if n.kind == "poor"]
    parts = []
    if poor:
        scores = ", ".join(
            f"{n.value:.3g} % on {n.split}" + (f" for output '{n.output}'" if n.output else "") for n in poor
        )
        worse = any("training mean" in n.text for n in poor)
        parts.append(
            f"its free-run NMSE is {scores} ({'no better than predicting the training mean' if worse else '>= 90 %'})"
        )
    parts += [n.text for n in notes if n.kind not in ("poor", "diverged")]
    if not parts:
        return None
    return f"this model is of little use: {'; '.join(parts)}. Fix: {what_to_try(spec_path, cost, searched, python)}"


def stability_fix(hint: str, cost: str | None) -> str:
    """A family's advice for a diverging free run without the options the spec already uses
    (no 'use cost: mse_inf' when the cost is mse_inf)."""
    if cost != "mse_inf" or "cost: mse_inf" not in hint:
        return hint
    import re

    text = re.sub(r"cost: mse_inf(\s*\([^)]*\))?(,\s*|\s+or\s+)?", "", hint).strip()
    text = re.sub(r"\s+", " ", text).rstrip(", ")
    if text in ("", "use"):
        return "the free run diverges even with cost: mse_inf; try a smaller model or `dynmodel diagnose`"
    return text
