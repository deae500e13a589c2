"""``dynmodel diagnose``: show what a model's free run gets wrong, name the cause, extend the model and
measure the gain on held-out data.

    from dynmodel.diagnose import diagnose, Settings
    result = diagnose(raw_spec_mapping, "spec.yaml", Path("."))
    result.verdict            # the named cause, or 'adequate'
    result.to_json()          # {"baseline", "findings", "extended", "gain"}

Detectors are plugins (entry-point group ``dynmodel.detectors``), see :mod:`.detector`.
"""

from __future__ import annotations

from .detector import Detector, Extension, Finding, Judgement, Settings, rank
from .runner import Diagnosis, diagnose

__all__ = ["diagnose", "Diagnosis", "Detector", "Extension", "Finding", "Judgement", "Settings", "rank"]
