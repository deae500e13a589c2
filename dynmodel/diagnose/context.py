"""What a detector sees: the fitted model, its free-running residual on the diagnosis splits, the
data, helpers (the model's memory, refits of patched specs) and the significance rule.

The diagnosis splits are train and validation: the test split stays held out for measuring the
gain of an extension. Residuals are e = y - y_hat (measured minus free run) on the scored samples,
in contiguous segments (a segment ends where a recording, a transient or a divergence cuts it).
Out-of-sample tests fit on the training rows and judge on the *check* rows (the validation split;
without one, the last 30 % of every segment).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..extensions import Extension, ExtensionContext, family_extensions, unique
from ..family import Progress, no_progress
from .detector import Judgement, Settings
from .fitting import Fit, Fitter

DIAGNOSIS_SPLITS = ("train", "validation")


@dataclass
class Segment:
    recording: int
    start: int  # first sample (index in the recording: t = start * sampling_time)
    stop: int
    u: np.ndarray  # (n, n_inputs) physical inputs
    y: np.ndarray  # (n, n_outputs) measured
    yhat: np.ndarray  # (n, n_outputs) free run
    check: np.ndarray  # (n,) True on validation rows

    @property
    def n(self) -> int:
        return self.stop - self.start

    @property
    def e(self) -> np.ndarray:
        return self.y - self.yhat


CHECK_FRACTION = 0.3


def segments_of(fit: Fit, splits: tuple[str, ...] = DIAGNOSIS_SPLITS) -> list[Segment]:
    """Scored ranges of ``splits``, adjacent ones merged, cut where the free run diverged; validation rows
    are marked as check rows (without a validation split, the last 30 % of every segment)."""
    rows = sorted((r, a, b, s) for s in splits for r, a, b in fit.ds.scored(s, warmup=fit.model.warmup))
    merged: list[list] = []
    for rec, a, b, split in rows:
        if merged and merged[-1][0] == rec and merged[-1][2] == a:
            merged[-1][2] = b
            merged[-1][3].append((a, b, split))
        else:
            merged.append([rec, a, b, [(a, b, split)]])
    has_validation = any(split == "validation" for *_, parts in merged for _, _, split in parts)
    out = []
    for rec, a, b, parts in merged:
        div = fit.runs[rec].diverged_at
        if div is not None:
            b = min(b, div)
        if b - a < 2:
            continue
        check = np.zeros(b - a, dtype=bool)
        if has_validation:
            for pa, pb, split in parts:
                if split == "validation":
                    check[max(pa, a) - a : max(min(pb, b) - a, 0)] = True
        else:
            check[int(round((1 - CHECK_FRACTION) * (b - a))) :] = True
        r = fit.ds.recordings[rec]
        out.append(Segment(rec, a, b, r.u[a:b], r.y[a:b], fit.runs[rec].y[a:b], check))
    return out


class Context:
    """Everything a detector may use; cheap attributes are computed lazily and cached."""

    def __init__(self, fit: Fit, settings: Settings, fitter: Fitter, progress: Progress = no_progress):
        self.fit = fit
        self.settings = settings
        self.fitter = fitter
        self.progress = progress
        self.segments = segments_of(fit)

    # ------------------------------------------------------------------ the baseline
    @property
    def model(self):
        return self.fit.model

    @property
    def spec(self):
        return self.fit.spec

    @property
    def raw(self) -> dict[str, Any]:
        return self.fit.raw

    @property
    def ds(self):
        return self.fit.ds

    @property
    def family(self) -> str:
        return self.spec.model.family

    @cached_property
    def resolved(self) -> dict[str, Any]:
        return self.spec.resolved()

    @property
    def params(self) -> dict[str, Any]:
        return self.resolved["model"]["params"]

    @property
    def input_names(self) -> list[str]:
        return list(self.ds.input_names)

    @property
    def output_names(self) -> list[str]:
        return list(self.ds.output_names)

    @property
    def sampling_time(self) -> float:
        return float(self.ds.sampling_time)

    @property
    def n(self) -> int:
        return sum(s.n for s in self.segments)

    # ------------------------------------------------------------------ per-channel series
    def residuals(self, k: int) -> list[np.ndarray]:
        return [s.e[:, k] for s in self.segments]

    def inputs(self, j: int) -> list[np.ndarray]:
        return [s.u[:, j] for s in self.segments]

    def outputs(self, k: int) -> list[np.ndarray]:
        return [s.y[:, k] for s in self.segments]

    def check_rows(self) -> np.ndarray:
        """(n,) True on the rows out-of-sample tests judge on (validation), False where they fit."""
        return np.concatenate([s.check for s in self.segments])

    def times(self) -> list[np.ndarray]:
        """Seconds since each segment's recording started."""
        return [np.arange(s.start, s.stop) * self.sampling_time for s in self.segments]

    def trend_features(self) -> np.ndarray:
        """(n, 2) slow functions of time, t and 1 - exp(-3 t / T) (T the longest recording time), that the
        dependence tests put in their base: a drift in the residual is no evidence of input dependence."""
        t = np.concatenate(self.times())
        span = max(float(t.max()) if t.size else 1.0, self.sampling_time)
        return np.column_stack([t / span, -np.expm1(-3.0 * t / span)])

    def mse(self, k: int) -> float:
        e = np.concatenate(self.residuals(k))
        return float(np.mean(e**2)) if e.size else 0.0

    def output_var(self, k: int) -> float:
        y = np.concatenate(self.outputs(k))
        return float(np.var(y)) if y.size else 0.0

    # ------------------------------------------------------------------ the rule
    def effect(self, share: float, k: int) -> float:
        """The share of the residual mean square as a fraction of the output variance."""
        return float(share * self.mse(k) / max(self.output_var(k), np.finfo(float).tiny))

    def judge(
        self, p_value: float, share: float, k: int, gates: dict[str, tuple[bool, str]] | None = None
    ) -> Judgement:
        """Significant: p < alpha, and the cause accounts for at least ``min_share`` of the residual mean
        square and for at least ``min_effect`` of the output variance, and every detector-specific gate
        (name -> (passed, what failed)) passes. The verdict carries every value and threshold."""
        s = self.settings
        effect = self.effect(share, k)
        p_value = float(p_value)
        failed = [text for ok, text in (gates or {}).values() if not ok]
        if not p_value < s.alpha:
            failed.append(f"p {_g(p_value)} >= alpha")
        if not share >= s.min_share:
            failed.append(f"share {share:.2g} < {s.min_share:g}")
        if not effect >= s.min_effect:
            failed.append(f"effect {effect:.2g} < {s.min_effect:g}")
        values = {
            "p_value": p_value,
            "alpha": s.alpha,
            "share": float(share),
            "min_share": s.min_share,
            "effect": effect,
            "min_effect": s.min_effect,
        }
        values.update({name: bool(ok) for name, (ok, _) in (gates or {}).items()})
        if failed:
            return Judgement(False, ", ".join(failed), values)
        return Judgement(True, f"p {_g(p_value)} < alpha, share {share:.2g}, effect {effect:.2g}", values)

    @property
    def max_lag(self) -> int:
        longest = max((s.n for s in self.segments), default=0)
        return int(self.settings.max_lag or max(1, min(1000, longest // 5)))

    # ------------------------------------------------------------------ helpers
    @cached_property
    def memory(self) -> int:
        """The model's memory in samples (see :func:`dynmodel.diagnose.memory.model_memory`)."""
        from .memory import model_memory

        return model_memory(self.fit, self.max_lag)

    @cached_property
    def references(self):
        """The quick references (training mean, linear ARX/OE) of this dataset (:mod:`.reference`)."""
        return self.fitter.references(self.ds)

    @cached_property
    def n_train(self) -> int:
        return int(self.ds.n_scored("train", warmup=self.model.warmup))

    def extension_context(self, evidence: dict[str, Any] | None = None) -> ExtensionContext:
        """What the families' extension hooks read (docs/plugins-extensions.md)."""
        return ExtensionContext.from_spec(
            self.resolved,
            self.input_names,
            self.output_names,
            self.sampling_time,
            written=self.raw,
            n_train=self.n_train,
            memory=self.__dict__.get("memory"),
            evidence=evidence,
            fitted=self.model.family,
        )

    def extensions(
        self, cause: str, evidence: dict[str, Any] | None = None, generic: list[Extension] | None = None
    ) -> list[Extension]:
        """``generic`` (data-side) extensions, then the families' own for ``cause`` (the spec's family first,
        then switches to other installed families), without repeats."""
        return unique(list(generic or []) + family_extensions(cause, self.extension_context(evidence)))

    def refit(self, patch: dict[str, Any], label: str = "") -> Fit:
        """Fit the spec with ``patch`` applied (cached, so a candidate measured later reuses it)."""
        from .patch import merge

        return self.fitter.fit(merge(self.raw, patch), label=label)


def _g(p: float) -> str:
    return "<1e-16" if p < 1e-16 else f"{p:.2g}"
