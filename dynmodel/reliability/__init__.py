"""Reliability check (thesis 4.4.1, 5.3.1, 5.3.2): does a driven system forget its initial state?

from dynmodel.reliability import check, check_model, Settings
report = check_model(dynmodel.load("m.h5"))        # or check(SomeDrivenSystem(...))
report.verdict.verdict                              # 'reliable' | 'unreliable' | 'inconclusive'
"""

from __future__ import annotations

from .check import Report, Settings, check
from .system import ClosedLoop, DrivenSystem, Evidence, InputDomain, Sine, SystemParams, TestSystem


def check_model(model, settings: Settings | None = None, progress=None, source: str = "") -> Report:
    """Check a fitted model (its family must expose ``driven_system()``)."""
    from ..family import no_progress
    from .model_view import model_system

    return check(model_system(model, source), settings, progress or no_progress)


__all__ = [
    "check",
    "check_model",
    "Settings",
    "Report",
    "DrivenSystem",
    "ClosedLoop",
    "Evidence",
    "InputDomain",
    "Sine",
    "SystemParams",
    "TestSystem",
]
