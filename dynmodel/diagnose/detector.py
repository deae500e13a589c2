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

if TYPE_CHECKING:
    from .context import Context


@dataclass
class Settings:
    """Thresholds of the diagnosis and sizes of its measurements."""

    alpha: float = 0.001  # per-detector significance level (9 built-in detectors: family-wise about 1 %)
    min_share: float = 0.05  # a cause must account for at least this share of the residual mean square
    min_effect: float = 0.001  # ... and for at least this fraction of the output variance (0.1 NMSE points)
    max_lag: int | None = None  # largest lag searched for delays (default: a fifth of the data, at most 1000)
    seed: int = 0  # seed of the bootstraps (not of the model fits)
    rounds: int = 1
    seeds: int = 3  # fits per spec for families whose fit is random (uncertainty of the gain)
    bootstrap: int = 500  # block-bootstrap resamples (deterministic families)
    candidates: int = 4  # extensions measured per round
    reliability: bool = True  # run the reliability check on network families

    def to_json(self) -> dict[str, Any]:
        return dict(vars(self))


@dataclass
class Extension:
    """A proposed change of the spec, as a JSON merge patch (RFC 7396), with a one-line summary."""

    summary: str
    patch: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return {"summary": self.summary, "patch": self.patch}


@dataclass
class Finding:
    cause: str
    score: float
    significant: bool
    summary: str
    evidence: dict[str, Any]
    extensions: list[Extension] = field(default_factory=list)
    priority: int = 50  # breaks ties between equal scores (lower first)

    @property
    def extension(self) -> Extension | None:
        return self.extensions[0] if self.extensions else None

    def to_json(self) -> dict[str, Any]:
        return {
            "cause": self.cause,
            "score": self.score,
            "significant": self.significant,
            "summary": self.summary,
            "evidence": self.evidence,
            "extension": self.extension.to_json() if self.extension else None,
            "alternatives": [x.to_json() for x in self.extensions[1:]],
        }


class Detector(ABC):
    """Subclass, set ``cause`` and ``description``, implement :meth:`detect`."""

    cause: ClassVar[str] = ""
    description: ClassVar[str] = ""
    priority: ClassVar[int] = 50

    @abstractmethod
    def detect(self, ctx: Context) -> Finding | None:
        """A finding (significant or not, with its evidence), or None when the test does not apply."""

    def finding(
        self,
        ctx: Context,
        score: float,
        significant: bool,
        summary: str,
        evidence: dict[str, Any],
        extensions: list[Extension] | None = None,
    ) -> Finding:
        return Finding(
            self.cause, float(score), bool(significant), summary, evidence, list(extensions or []), self.priority
        )


def rank(findings: list[Finding]) -> list[Finding]:
    """Significant findings first, then by score (descending), ties by priority."""
    return sorted(findings, key=lambda f: (not f.significant, -f.score, f.priority, f.cause))
