"""The diagnosis loop: fit the baseline, run every detector (and the core's adequacy reference), measure
the proposed extensions, keep the best on validation, and go another round on the extended model,
until nothing is significant (adequate), no candidate lowers the validation NMSE by at least
``MIN_GAIN`` (relative), or after ``rounds`` (default 3). A cause masked by a larger one surfaces in a
later round, once the larger one is fixed.

Candidates of a round: every extension of the named (highest-ranked) cause, then the first extension of
each further significant cause, at most ``candidates`` in all. An extension is measured by refitting the
patched spec; candidates are compared on the free-run NMSE of the validation split (train when there is
none), never on the test split's outputs, which only score the chosen models (each round's test NMSE and
the total gain are reported, never used to choose). A candidate whose free run diverges on some
recording's *input* (test recordings included: the divergence band comes from the training outputs, so
this screen uses no measured test output) ranks after every candidate that stays stable.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import registry
from ..errors import DynmodelError
from ..family import Progress, no_progress
from . import patch as patch_mod
from .adequacy import InadequateStructure
from .context import Context
from .detector import Extension, Finding, Settings, not_applicable, rank
from .fitting import Fit, Fitter
from .gain import measure_gain

MIN_GAIN = 0.01


def fitted_family(base: Any) -> str:
    """The family of the baseline model, ``auto -> narx`` when the search chose it."""
    name = base.model.family.name
    return f"auto -> {name}" if base.spec.model.family == "auto" and name != "auto" else name


@dataclass
class Candidate:
    cause: str
    extension: Extension
    fit: Fit | None = None
    error: str | None = None

    def score(self, split: str) -> float:
        return float("inf") if self.fit is None else self.fit.nmse(split)

    @property
    def diverges(self) -> bool:
        """Does the free run leave the divergence band on any recording (inputs only decide this)?"""
        return self.fit is None or any(r.diverged_at is not None for r in self.fit.runs)

    def rank(self, split: str) -> tuple[bool, float]:
        return self.diverges, self.score(split)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"cause": self.cause, **self.extension.to_json()}
        if self.fit is not None:
            out["metrics"] = self.fit.metrics
            out["fit_seconds"] = self.fit.seconds
        if self.error:
            out["error"] = self.error
        return out


@dataclass
class Round:
    index: int
    fit: Fit
    findings: list[Finding]
    memory: int | None
    candidates: list[Candidate] = field(default_factory=list)
    chosen: Candidate | None = None
    accepted: bool = False
    outcome: str = ""
    seconds: float = 0.0
    split: str = "validation"  # where the candidates were compared

    @property
    def significant(self) -> list[Finding]:
        return [f for f in self.findings if f.significant]

    @property
    def verdict(self) -> str:
        return self.significant[0].cause if self.significant else "adequate"

    def gain(self) -> dict[str, Any]:
        """What this round's chosen extension did: the comparison split's NMSE before and after (it decided),
        the test NMSE before and after (reported only)."""
        out: dict[str, Any] = {"cause": None, "extension": None, "accepted": self.accepted}
        if self.chosen is None or self.chosen.fit is None:
            return out
        after = self.chosen.fit
        out.update(
            cause=self.chosen.cause,
            extension=self.chosen.extension.summary,
            split=self.split,
            nmse_before=_finite(self.fit.nmse(self.split)),
            nmse_after=_finite(after.nmse(self.split)),
            test_nmse_before=_test(self.fit, "nmse"),
            test_nmse_after=_test(after, "nmse"),
        )
        out["relative_reduction"] = _reduction(out["test_nmse_before"], out["test_nmse_after"])
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "round": self.index,
            "verdict": self.verdict,
            "named": [f.cause for f in self.significant],
            "model_memory_samples": self.memory,
            "metrics": self.fit.metrics,
            "findings": [f.to_json() for f in self.significant],
            "checks": [
                {"cause": f.cause, "significant": f.significant, "score": f.score, "reason": f.reason, "gates": f.gates}
                for f in self.findings
            ],
            "candidates": [c.to_json() for c in self.candidates],
            "chosen": None if self.chosen is None else self.chosen.to_json(),
            "accepted": self.accepted,
            "outcome": self.outcome,
            "gain": self.gain(),
            "seconds": self.seconds,
        }


@dataclass
class Diagnosis:
    name: str
    source: str
    settings: Settings
    rounds: list[Round]
    gain: dict[str, Any] | None
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)
    reference: dict[str, Any] | None = None  # the quick references of the data (mean, linear ARX/OE)

    @property
    def baseline(self) -> Fit:
        return self.rounds[0].fit

    def extended_warning(self) -> str | None:
        """One line when the extended model it hands over is worse on the test than the baseline, or of little use
        there (what ``dynmodel fit`` of extended.yaml would say): its validation did not represent the test."""
        final = self.final
        if final is None or self.gain is None:
            return None
        from ..usefulness import assess, summary_line

        before, after = self.gain.get("test_nmse_before"), self.gain.get("test_nmse_after")
        worse = before is not None and after is not None and after > before
        line = summary_line(assess(final.model, final.ds, final.runs), "extended.yaml", final.spec.cost)
        if not worse:
            return None if line is None else f"the extended model: {line}"
        text = (
            f"the extended model validates better but is worse on the {self.gain.get('test_split') or 'test'} split "
            f"({before:.4g} % -> {after:.4g} % NMSE): its validation did not represent the test"
        )
        return f"{text}; {line}" if line else f"{text}. Fix: keep the baseline, or validate on data like the test's"

    @property
    def findings(self) -> list[Finding]:
        """The baseline's significant findings, the named cause first."""
        return self.rounds[0].significant

    @property
    def checks(self) -> list[Finding]:
        return self.rounds[0].findings

    @property
    def verdict(self) -> str:
        return self.rounds[0].verdict

    @property
    def named(self) -> list[tuple[int, str]]:
        """(round, cause) of every cause named in any round, in order."""
        return [(r.index, f.cause) for r in self.rounds for f in r.significant]

    @property
    def applied(self) -> list[Candidate]:
        """The extensions applied in turn (the first round's best even when it brought no gain)."""
        accepted = [r.chosen for r in self.rounds if r.accepted and r.chosen is not None]
        if not accepted and self.rounds[0].chosen is not None:
            return [self.rounds[0].chosen]
        return accepted

    @property
    def final(self) -> Fit | None:
        """The extended model, None when nothing was extended (adequate, or no extension fitted)."""
        applied = self.applied
        return applied[-1].fit if applied else None

    @property
    def extended_spec(self) -> dict[str, Any] | None:
        final = self.final
        return None if final is None else final.raw

    def to_json(self) -> dict[str, Any]:
        base = self.baseline
        final = self.final
        extended: dict[str, Any] = {"spec": self.extended_spec, "metrics": None if final is None else final.metrics}
        extended["extensions"] = [{"cause": c.cause, **c.extension.to_json()} for c in self.applied]
        extended["rounds"] = [r.to_json() for r in self.rounds]
        extended["named"] = [{"round": i, "cause": c} for i, c in self.named]
        return {
            "baseline": {
                "metrics": base.metrics,
                "verdict": self.verdict,
                "family": base.model.family.name,  # for family: auto, the one the search chose
                "searched": base.spec.model.family == "auto",
                "cost": base.model.spec.get("cost") or base.spec.cost,
                "model_memory_samples": self.rounds[0].memory,
                "checks": [f.to_json() for f in self.checks],
                "reference": self.reference,
                "settings": self.settings.to_json(),
                "notes": self.notes,
                "seconds": self.seconds,
            },
            "findings": [f.to_json() for f in self.findings],
            "extended": extended,
            "gain": self._gain_json(),
            "warning": self.extended_warning(),
        }

    def _gain_json(self) -> dict[str, Any]:
        gain: dict[str, Any] = (
            dict(self.gain)
            if self.gain is not None
            else {
                "test_nmse_before": _test(self.baseline, "nmse"),
                "test_nmse_after": None,
                "relative_reduction": None,
            }
        )
        gain["rounds"] = [r.gain() for r in self.rounds]
        return gain


def _test(fit: Fit, metric: str) -> float | None:
    from .gain import test_key

    m = fit.metrics.get(test_key(fit.metrics) or "test") or {}
    return m.get(metric)


def _finite(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def _reduction(before: float | None, after: float | None) -> float | None:
    if before is None or after is None or before <= 0:
        return None
    return float(1.0 - after / before)


def detect(
    fit: Fit, settings: Settings, fitter: Fitter, progress: Progress = no_progress
) -> tuple[list[Finding], int | None]:
    """Every installed detector on one fitted model; findings ranked (significant first, by score)."""
    ctx = Context(fit, settings, fitter, progress)
    if ctx.n < 50:
        raise DynmodelError(
            f"only {ctx.n} scored train/validation samples before the free run ends",
            fit.spec.source,
            "provide more data (the diagnosis needs the free-running residual)",
        )
    findings = []
    table = dict(registry.detectors())
    table.setdefault(InadequateStructure.cause, InadequateStructure)  # the core's own check, always run
    for cause, cls in table.items():
        progress("detect", None, cause)
        found = cls().detect(ctx)
        if found is None:
            found = not_applicable(cause, cls)
        found.cause = cause
        findings.append(found)
    memory = ctx.__dict__.get("memory")
    return rank(findings), memory


def _candidates(findings: list[Finding], limit: int) -> list[tuple[str, Extension]]:
    """Every extension of the named cause, then the first extension of each further significant cause
    (the ranking of two causes can be wrong; the validation split decides), at most ``limit``, no repeats."""
    significant = [f for f in findings if f.significant and f.extensions]
    if not significant:
        return []
    top, rest = significant[0], significant[1:]
    picks = [(top.cause, ext) for ext in top.extensions]
    others = [(f.cause, f.extensions[0]) for f in rest]
    # keep room for the other causes' first proposals
    room = max(1, limit - len(others))
    ordered = picks[:room] + others + picks[room:]
    out, seen = [], set()
    for cause, ext in ordered:
        key = repr(ext.patch)
        if key not in seen:
            seen.add(key)
            out.append((cause, ext))
    return out[:limit]


POOR = 50.0  # a comparison NMSE (%) from which "adequate" comes with a warning


def _weak_note(rnd: Round, split: str) -> str:
    """When nothing is significant but the model explains less than half of the output variance, say that the
    checks lacked the power to tell what is missing, and which check came closest."""
    nmse = rnd.fit.nmse(split)
    if not np.isfinite(nmse) or nmse < POOR:
        return ""
    close = [f for f in rnd.findings if f.applicable and f.score >= 0.05]
    hint = f"; closest: {close[0].cause} ({close[0].reason})" if close else ""
    return (
        f", but the model explains only {100 - nmse:.0f} % of the {split} output variance (NMSE {nmse:.3g} %): "
        f"the data give the checks too little power to name what is missing{hint}"
    )


def _caveats(rnd: Round) -> str:
    """The checks that could not decide (a finding's caveat), which the final verdict must not hide."""
    said = [f.caveat for f in rnd.findings if f.applicable and not f.significant and f.caveat]
    return "".join(f"; but {c}" for c in said)


TIE = 0.01  # candidates within 1 % of the best validation NMSE count as equal: the earliest is kept


def _best(candidates: list[Candidate], split: str) -> Candidate:
    """The candidate with the lowest comparison NMSE among those that do not diverge; within ``TIE`` of it
    the earliest (the named cause's own extensions come first)."""
    top = min(candidates, key=lambda c: c.rank(split))
    if not np.isfinite(top.score(split)):
        return top
    limit = top.score(split) * (1 + TIE)
    return next(c for c in candidates if c.diverges == top.diverges and c.score(split) <= limit)


def diagnose(
    raw: dict[str, Any], source: str, base_dir: Path, settings: Settings | None = None, progress: Progress = no_progress
) -> Diagnosis:
    """Diagnose the spec mapping ``raw`` (as loaded from ``source``, relative paths against ``base_dir``)."""
    settings = settings or Settings()
    t_start = time.perf_counter()
    fitter = Fitter(source, base_dir, progress)
    raw = patch_mod.portable(raw, base_dir)
    notes: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        current = fitter.fit(raw, label="baseline")
        notes += current.ds.excursion_notes()
        rounds: list[Round] = []
        for index in range(1, max(1, settings.rounds) + 1):
            t0 = time.perf_counter()
            findings, memory = detect(current, settings, fitter, progress)
            split = "validation" if "validation" in current.metrics else "train"
            rnd = Round(index, current, findings, memory, split=split)
            rounds.append(rnd)
            cands = _candidates(findings, settings.candidates)
            if not rnd.significant:
                rnd.outcome = "adequate: no cause is significant" + _weak_note(rnd, split)
            elif not cands:
                rnd.outcome = f"{rnd.verdict}: no extension is offered for the significant causes"
            else:
                for cause, ext in cands:
                    cand = Candidate(cause, ext)
                    try:
                        patched = patch_mod.merge(current.raw, ext.patch)
                        cand.fit = fitter.fit(patched, label=f"{cause}: {ext.summary}")
                    except DynmodelError as exc:
                        cand.error = exc.line()
                    rnd.candidates.append(cand)
                best = _best(rnd.candidates, split)
                now, new = current.nmse(split), best.score(split)
                if best.fit is None:
                    rnd.outcome = "every extension failed to fit"
                else:
                    rnd.chosen = best
                    improved = np.isfinite(new) and (not np.isfinite(now) or new < (1 - MIN_GAIN) * now)
                    rnd.outcome = f"{split} NMSE {now:.4g} % -> {new:.4g} %" + ("" if improved else " (no gain: stop)")
                    if improved:
                        rnd.accepted = True
                        current = best.fit
            rnd.seconds = time.perf_counter() - t0
            if not rnd.accepted:
                rnd.outcome += _caveats(rnd)  # the model the diagnosis ends with: what its checks could not decide
                break
        result = Diagnosis(raw.get("name", "model"), source, settings, rounds, None, 0.0, notes)
        result.reference = fitter.references(rounds[0].fit.ds).to_json()
        if result.final is not None:
            progress("gain", None, "uncertainty of the test NMSE")
            result.gain = measure_gain(fitter, rounds[0].fit, result.final, settings)
    for w in caught:
        text = str(w.message)
        if text not in notes:
            notes.append(text)
    result.seconds = time.perf_counter() - t_start
    return result
