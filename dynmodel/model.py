"""A fitted model in physical units: family + preprocessing + metadata, and its evaluation."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .columns import by_name, default_names, is_pandas, is_recording_list, like_input, matrix, recordings, select
from .data.dataset import Dataset
from .data.finite import non_finite
from .data.preprocess import Preprocessor
from .errors import DataError
from .family import Family
from .metrics import DEFAULT_METRICS, METRICS, nmse


def _named_columns(frame, names: list[str], what: str = "input"):
    """The model's channels of a DataFrame when it names them all (any order); a DataError when a DataFrame
    that names its columns lacks one of the model's channels named in fitting (never a silent match by
    position); else the frame as given (a Series, default column positions, or a model fitted on unnamed
    arrays)."""
    if getattr(frame, "ndim", 1) == 2 and all(n in frame.columns for n in names):
        return select(frame, names, "columns")
    if names == default_names("u" if what == "input" else "y", len(names)):
        return frame
    return by_name(frame, names, what, what)


def _each_named(signals, names: list[str], what: str = "input"):
    """:func:`_named_columns` of a signal or of every signal of a list of recordings."""
    if is_recording_list(signals):
        return [_named_columns(s, names, what) if is_pandas(s) else s for s in signals]
    return _named_columns(signals, names, what) if is_pandas(signals) else signals


@dataclass
class Run:
    """A free run of one recording in physical units."""

    y: np.ndarray
    diverged_at: int | None


def band_check(
    y: np.ndarray, bounds: tuple[np.ndarray, np.ndarray] | None, diverged_at: int | None = None, start: int = 0
) -> tuple[np.ndarray, int | None]:
    """The model-space run ``y`` with NaN from the first sample at or after ``start`` (the end of a
    tune-in, whose outputs are no prediction) outside ``bounds`` (lo, hi) or non-finite, and that
    sample (the earlier of it and ``diverged_at``); None when the run stays inside."""
    if y.ndim == 1:
        y = y[:, None]
    bad = ~np.isfinite(y)
    if bounds is not None:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
        with np.errstate(invalid="ignore"):
            bad |= (y < lo) | (y > hi)
    bad[:start] = False
    rows = np.flatnonzero(bad.any(axis=1))
    first = int(rows[0]) if rows.size else None
    if diverged_at is not None and (first is None or diverged_at < first):
        first = int(diverged_at)
    if first is not None:
        y = y.copy()
        y[first:] = np.nan
    return y, first


@dataclass
class FittedModel:
    family: Family
    preprocessor: Preprocessor
    bounds: tuple[np.ndarray, np.ndarray]  # model-space divergence band
    spec: dict[str, Any]
    metrics: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    train_input: np.ndarray | None = None  # raw training inputs (for reliability checks)
    train_input_lengths: np.ndarray | None = None
    train_output: np.ndarray | None = None  # measured training outputs (tune-in of external-mode checks)
    search: dict[str, Any] | None = None  # family: auto: the search that chose this model (docs/auto.md)
    #: what :func:`dynmodel.usefulness.assess` found after a fit in Python (None: not assessed, e.g. loaded)
    assessment: list[Any] | None = None

    def __post_init__(self) -> None:
        self.family.model_ = self  # the family's predict / score / dynmodel.save work in physical units

    @property
    def input_names(self) -> list[str]:
        return self.preprocessor.input_names

    @property
    def output_names(self) -> list[str]:
        return self.preprocessor.output_names

    @property
    def sampling_time(self) -> float:
        return self.preprocessor.sampling_time

    @property
    def warmup(self) -> int:
        """Measured output samples the model needs at the start of a run (tune-in)."""
        return self.family.warmup

    @property
    def washout(self) -> int:
        """Samples after a recording's start that training and scoring left out (the spec's
        ``data.transient``): a network's state is still forgetting its rest state there, so its
        output is no prediction and is not held to the divergence band."""
        data = self.spec.get("data") or {}
        try:
            return max(int(data.get("transient") or 0), 0)
        except (TypeError, ValueError):
            return 0

    def _inputs(self, u: np.ndarray | Mapping[str, np.ndarray]) -> np.ndarray:
        if is_pandas(u):
            u = matrix(_named_columns(u, self.input_names), "input")[0]
        if isinstance(u, Mapping):
            missing = [n for n in self.input_names if n not in u]
            if missing:
                raise DataError(
                    f"input '{missing[0]}' is missing",
                    "predict",
                    f"give every input the model needs: {self.input_names}",
                )
            u = np.column_stack([np.asarray(u[n], dtype=np.float64) for n in self.input_names])
        if is_recording_list(u):
            raise DataError(
                f"got a list of {len(u)} recordings", "predict", "predict one recording at a time (score takes a list)"
            )
        u = matrix(u, "input")[0]
        if u.shape[1] != len(self.input_names):
            raise DataError(
                f"expected {len(self.input_names)} input column(s) {self.input_names}, got {u.shape[1]}",
                "predict",
                "pass an array (n,) or (n, inputs) with the model's inputs in its order",
            )
        problem = non_finite(u, self.input_names)
        if problem is not None:
            raise DataError(f"input {problem}", "predict", "fill or remove those samples")
        return u

    def run(self, u, y_measured: np.ndarray | None = None) -> Run:
        """Free run from the rest state over the whole input; NaN after a divergence.

        Every family's run is held to the divergence band here, whether or not the family feeds
        its output back: a run that leaves the training output range widened by
        ``DIVERGENCE_MARGIN`` range widths (or turns non-finite) after the tune-in and the
        :attr:`washout` diverged at that sample."""
        um = self.preprocessor.inputs(self._inputs(u))
        ym = None if y_measured is None else self.preprocessor.outputs(self._outputs(y_measured))
        sim = self.family.simulate(um, ym, self.bounds)
        start = max(self.warmup if y_measured is not None else 0, self.washout)
        y, diverged_at = band_check(np.asarray(sim.y, dtype=np.float64), self.bounds, sim.diverged_at, start)
        return Run(self.preprocessor.physical_outputs(y), diverged_at)

    def _outputs(self, y) -> np.ndarray:
        return matrix(_named_columns(y, self.output_names, "output"), "output")[0] if is_pandas(y) else y

    def predict(self, u, y_tune: np.ndarray | None = None) -> np.ndarray:
        """Free-running prediction (n, n_outputs) in physical units; a DataFrame indexed like ``u``
        when ``u`` is a pandas DataFrame or Series.

        ``y_tune``: measured outputs, at least the first :attr:`warmup` samples (external mode).

        A free run that diverges (NaN from that sample on) and an input beyond the training range by more than
        5 % of its width are said as a :class:`~dynmodel.errors.ModelWarning`, as ``dynmodel predict`` says them.
        """
        um = self._inputs(u)  # converted and checked once, for the run and the warnings
        try:
            run = self.run(um, y_tune)
        except DataError:
            raise
        except ValueError as exc:  # the family's own refusal (a tune-in it needs and lacks): the same error class
            fix = f"pass y_tune with the first {self.warmup} measured outputs" if self.warmup else "check the input"
            raise DataError(str(exc), "predict", fix) from None
        self._warn_about(run, um)
        return like_input(u, run.y, self.output_names)

    def input_excursions(self, u: np.ndarray, margin: float = 0.05) -> list[tuple[str, float, int]]:
        """(input, excess, sample) for every input of ``u`` (n, inputs) that goes beyond the training input range
        by more than ``margin`` of its width, at the sample where it goes farthest; [] without training inputs."""
        from .data.dataset import beyond_range

        train = self.train_input
        if train is None or train.ndim != 2 or not train.shape[0] or train.shape[1] != u.shape[1]:
            return []
        ranges = beyond_range(u, train.min(axis=0), train.max(axis=0))
        return [(name, e, k) for name, (e, k) in zip(self.input_names, ranges) if e > margin]

    def _warn_about(self, run: Run, u: np.ndarray, margin: float = 0.05) -> None:
        import warnings

        from .api import _caller_level
        from .errors import ModelWarning

        texts = [
            f"the input '{name}' leaves the training range by {100 * excess:.0f} % of its width (sample {k}): the "
            "model extrapolates there"
            for name, excess, k in self.input_excursions(u, margin)
        ]
        if run.diverged_at is not None:
            texts.append(
                f"the free run diverged at sample {run.diverged_at}; the predictions are NaN from there on. Fix: keep "
                "the input within the training range, or refit on data that covers it"
            )
        for text in texts:
            warnings.warn(text[0].upper() + text[1:], ModelWarning, stacklevel=_caller_level())

    def predict_one_step(self, u, y_measured: np.ndarray) -> np.ndarray | None:
        um = self.preprocessor.inputs(self._inputs(u))
        pred = self.family.predict_one_step(um, self.preprocessor.outputs(self._outputs(y_measured)))
        return None if pred is None else like_input(u, self.preprocessor.physical_outputs(pred), self.output_names)

    def score(self, u, y) -> float:
        """R^2 of the free run, scikit-learn's regressor score (higher is better, 1 perfect, 0 the level
        of the output's mean): 1 - NMSE / 100 averaged over outputs (eq. 5.48), over every sample after
        the first :attr:`warmup` ones, which the run takes from ``y`` as its tune-in. ``u`` and ``y``
        may be lists of recordings (pooled, as a split is). A free run that diverges scores -inf."""
        u, y = _each_named(u, self.input_names), _each_named(y, self.output_names, "output")
        recs, _, _ = recordings(u, y, self.input_names, self.output_names, "score")
        warm = self.warmup
        measured, predicted = [], []
        for rec in recs:
            if rec.n <= warm:
                raise DataError(
                    f"'{rec.name}' has {rec.n} samples, and the model takes its first {warm} as the tune-in",
                    "score",
                    "score on longer recordings",
                )
            run = self.run(rec.u, rec.y[:warm] if warm else None)
            if run.diverged_at is not None:
                return float("-inf")
            measured.append(rec.y[warm:])
            predicted.append(run.y[warm:])
        y = np.concatenate(measured)
        flat = [name for name, v in zip(self.output_names, y.var(axis=0)) if not v > 0]
        if flat:  # R^2 divides by the output's variance
            raise DataError(
                f"the measured output '{flat[0]}' is constant after the tune-in, so R^2 is undefined",
                "score",
                "score on data where the output moves (or compare predict's output with it directly)",
            )
        return float(1.0 - np.mean(nmse(y, np.concatenate(predicted))) / 100.0)

    @property
    def unstable(self) -> dict[str, Any] | None:
        """The first split whose free run diverged, with where it happened, else None."""
        for split, m in self.metrics.items():
            if m.get("unstable_from"):
                return {"split": split, **m["unstable_from"]}
        return None


def _run_or_unknown(model: FittedModel, u: np.ndarray, tune: np.ndarray | None) -> Run:
    """The free run of a recording; all NaN when its tune-in outputs are unknown (a test set whose outputs are
    held back, NaN): a model that starts from measured outputs cannot run there, and nothing is scored."""
    if tune is not None and not np.isfinite(tune).all():
        return Run(np.full((len(u), len(model.output_names)), np.nan), None)
    return model.run(u, tune)


def _score(
    entry: dict[str, Any], y: np.ndarray, yhat: np.ndarray, metrics: Sequence[str], names: Sequence[str]
) -> None:
    """The metrics of the free run ``yhat`` against ``y`` into ``entry`` (per output too for several)."""
    values = {m: METRICS[m](y, yhat) for m in metrics}
    for m, v in values.items():
        entry[m] = float(np.max(v)) if m == "max" else (float(np.min(v)) if m == "fit" else float(np.mean(v)))
    if len(names) > 1:
        entry["per_output"] = {name: {m: float(values[m][i]) for m in metrics} for i, name in enumerate(names)}


def evaluate(
    model: FittedModel, ds: Dataset, metrics: Sequence[str] = DEFAULT_METRICS, one_step: bool = True
) -> tuple[dict[str, Any], list[Run]]:
    """Free-run every recording from its first sample to its end and score each split."""
    warm = model.warmup
    runs = [_run_or_unknown(model, r.u, r.y[:warm] if warm else None) for r in ds.recordings]
    one: list[np.ndarray] | None = None
    if one_step:
        # one step ahead needs the measured outputs: none for a recording whose outputs are unknown (NaN)
        preds = [
            model.predict_one_step(r.u, r.y) if np.isfinite(r.y[: max(warm, 1)]).all() else np.full(r.y.shape, np.nan)
            for r in ds.recordings
        ]
        one = [p for p in preds if p is not None]
        if len(one) < len(preds):
            one = None
    out: dict[str, Any] = {}
    st = ds.sampling_time
    for split in ds.splits():
        rows = ds.scored(split, warmup=warm)
        entry: dict[str, Any] = {"samples": int(sum(b - a for _, a, b in rows))}
        unstable = None
        for rec, _a, b in rows:
            k = runs[rec].diverged_at
            if k is not None and k < b:
                unstable = {"recording": ds.recordings[rec].name, "sample": int(k), "time": float(k * st)}
                break
        y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
        known = np.isfinite(y).all(axis=1) if rows else np.ones(0, dtype=bool)
        if not unstable and known.any() and not known.all():  # outputs missing in places: scored where known
            yhat = np.concatenate([runs[r].y[a:b] for r, a, b in rows])
            keep = known & np.isfinite(yhat).all(axis=1)
            if keep.any():
                entry["unknown"] = int((~known).sum())
                entry["samples"] = int(keep.sum())
                y = y[keep]
                _score(entry, y, yhat[keep], metrics, model.output_names)
                if one is not None:
                    y1 = np.concatenate([one[r][a:b] for r, a, b in rows])[keep]
                    fine = np.isfinite(y1).all(axis=1)
                    entry["nmse_1"] = float(np.mean(nmse(y[fine], y1[fine]))) if fine.any() else None
                out[split] = entry
                continue
        if not unstable and rows and not np.isfinite(y).all():  # a test set whose outputs are unknown (NaN)
            entry.update({m: None for m in metrics})
            entry["unscored"] = "the measured outputs are unknown (NaN)" + (
                f"; the model starts from {warm} measured outputs, so it was not run there (predict it from "
                "rest with a model that needs none, or give the first outputs)"
                if warm and all(not np.isfinite(runs[r].y).any() for r, _, _ in rows)
                else ""
            )
            if one is not None:
                entry["nmse_1"] = None
            out[split] = entry
            continue
        if unstable:
            entry.update({m: None for m in metrics})
            entry["unstable_from"] = unstable
        else:
            _score(entry, y, np.concatenate([runs[r].y[a:b] for r, a, b in rows]), metrics, model.output_names)
        if one is not None:
            y1 = np.concatenate([one[r][a:b] for r, a, b in rows])
            entry["nmse_1"] = float(np.mean(nmse(y, y1)))
        out[split] = entry
    return out, runs
