"""The detector plugin contract: a detector looks at a fitted model's free-running residual, the
data and the model, and returns a :class:`Finding` (or None when it does not apply).

Detectors register under the ``dynmodel.detectors`` entry-point group; the entry-point name is
the cause id they report. A finding's ``score`` is comparable across detectors: the share of the
free-run residual's mean square the cause accounts for (1 for causes that invalidate the free run
as a whole: a diverging run, an unreliable model).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from ..extensions import Extension

if TYPE_CHECKING:
    from .context import Context


@dataclass
class Settings:
    """Thresholds of the diagnosis and sizes of its measurements."""

    alpha: float = 0.001  # per-detector significance level (13 built-in checks: family-wise about 1.3 %)
    min_share: float = 0.05  # a cause must account for at least this share of the residual mean square
    min_effect: float = 0.001  # ... and for at least this fraction of the output variance (0.1 NMSE points)
    max_lag: int | None = None  # largest lag searched for delays (default: a fifth of the data, at most 1000)
    seed: int = 0  # seed of the bootstraps (not of the model fits)
    rounds: int = 3  # diagnose, extend, refit, diagnose again ... until adequate or no gain
    seeds: int = 3  # fits per spec for families whose fit is random (uncertainty of the gain)
    bootstrap: int = 500  # block-bootstrap resamples (deterministic families)
    candidates: int = 6  # extensions measured per round (the named cause's, then one per further cause)
    reliability: bool = True  # run the reliability check on network families

    def to_json(self) -> dict[str, Any]:
        return dict(vars(self))


@dataclass
class Judgement:
    """Why a finding is or is not named: every gate with its value and threshold, and one line."""

    significant: bool
    reason: str
    gates: dict[str, Any] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return self.significant

    @classmethod
    def fixed(cls, significant: bool, reason: str, **gates: Any) -> Judgement:
        """A verdict from a detector's own criterion (no p-value / share rule)."""
        return cls(bool(significant), reason, dict(gates))

    def to_json(self) -> dict[str, Any]:
        return {"significant": self.significant, "reason": self.reason, **self.gates}


@dataclass
class Finding:
    cause: str
    score: float
    significant: bool
    summary: str
    evidence: dict[str, Any]
    extensions: list[Extension] = field(default_factory=list)
    priority: int = 50  # breaks ties between equal scores (lower first)
    reason: str = ""  # why it is (not) named: the gates and their thresholds, in one line
    gates: dict[str, Any] = field(default_factory=dict)
    applicable: bool = True  # False: the detector does not apply to this model or data (reason says why)
    generic: bool = False  # a verdict on the whole structure (inadequate-structure): ranked after specific causes
    caveat: str = ""  # a check that could not decide (e.g. inconclusive): said beside an "adequate" verdict

    @property
    def extension(self) -> Extension | None:
        return self.extensions[0] if self.extensions else None

    def to_json(self) -> dict[str, Any]:
        return {
            "cause": self.cause,
            "score": self.score,
            "significant": self.significant,
            "summary": self.summary,
            "reason": self.reason,
            "gates": self.gates,
            "generic": self.generic,
            "caveat": self.caveat,
            "evidence": self.evidence,
            "extension": self.extension.to_json() if self.extension else None,
            "alternatives": [x.to_json() for x in self.extensions[1:]],
        }


class Detector(ABC):
    """Subclass, set ``cause`` and ``description``, implement :meth:`detect`."""

    cause: ClassVar[str] = ""
    description: ClassVar[str] = ""
    priority: ClassVar[int] = 50
    #: when the detector applies (shown when :meth:`detect` returns None)
    applies: ClassVar[str] = ""
    #: a verdict on the structure as a whole, not a specific cause: named after every specific cause
    generic: ClassVar[bool] = False

    @abstractmethod
    def detect(self, ctx: Context) -> Finding | None:
        """A finding (significant or not, with its evidence), or None when the test does not apply."""

    def finding(
        self,
        ctx: Context,
        score: float,
        significant: bool | Judgement,
        summary: str,
        evidence: dict[str, Any],
        extensions: list[Extension] | None = None,
    ) -> Finding:
        """``significant``: the :meth:`Context.judge` verdict (or a plain bool, explained generically)."""
        if not isinstance(significant, Judgement):
            significant = Judgement.fixed(
                bool(significant), "named by the detector's criterion" if significant else "not significant"
            )
        return Finding(
            self.cause,
            float(score),
            significant.significant,
            summary,
            evidence,
            list(extensions or []),
            self.priority,
            significant.reason,
            significant.gates,
            True,
            self.generic,
        )


def not_applicable(cause: str, detector: Any) -> Finding:
    """The row of a check that did not apply."""
    applies = getattr(detector, "applies", "") or ""
    reason = "not applicable" + (f": {applies}" if applies else "")
    return Finding(cause, 0.0, False, reason, {}, [], getattr(detector, "priority", 50), reason, {}, False)


def rank(findings: list[Finding]) -> list[Finding]:
    """Significant findings first: specific causes by score (descending, ties by priority), then verdicts
    on the whole structure; then the rest by score; checks that did not apply last."""
    return sorted(
        findings,
        key=lambda f: (not f.significant, f.significant and f.generic, not f.applicable, -f.score, f.priority, f.cause),
    )
