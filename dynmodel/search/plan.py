"""The search's budget: planned work, never the clock, decides what runs.

**The rule.** A budget of B seconds is an allowance of ``B x REFERENCE_WORKERS`` planned seconds of work
(the cores the default budget is sized for). Every task has a planned work, estimated before it runs from
the candidate's own estimate (:attr:`Candidate.work`, scaled with the training samples of its layout) and
never measured. The search runs in stages whose members are fixed before they start; a stage takes its
candidates in rank order while the planned work so far stays within its cumulative share of the allowance
(:data:`SHARES`; what a stage leaves unused passes to the next), every stage taking at least its first
candidate. Results are collected for the whole stage and sorted by candidate before anything is decided.
So the candidates, the stages and the choice depend on the spec, its seed and the budget only: the same on
one worker or twenty, on a fast machine or a loaded one. Wall time follows the planned work: more workers
finish sooner, one takes about twice as long as the plan. Two things stop a search early, and the result
then says so: Ctrl-C (the best model so far is kept) and a safety limit at :data:`HARD_LIMIT` times the
budget (plus :data:`HARD_SLACK` seconds) in wall-clock time (for estimates far off on an unusual machine or data); only these depend on time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

#: the budget in seconds is planned for this many cores working in parallel
REFERENCE_WORKERS = 2
#: cumulative shares of the allowance up to the end of each stage
SHARES = {
    "screen": 0.45,
    "grow": 0.60,
    "full": 0.88,
    "moves": 1.00,
}
#: the search stops (keeping the best so far, and saying so) after this many times the budget of wall time, plus
#: HARD_SLACK seconds (starting worker processes, compiling kernels on a first run)
HARD_LIMIT = 3.0
HARD_SLACK = 120.0
#: planned seconds of a task besides the fit itself (data views, the checks' free runs, transfers)
TASK_OVERHEAD = 0.05
#: a diagnosis of the leader (one task: its fit, then the detectors' refits, a longer selection among them) in
#: fits of the leader
DIAGNOSIS_FITS = 3.0
#: ... and per training sample (the detectors' own statistics)
DIAGNOSIS_PER_SAMPLE = 1e-4


def diagnosis_work(fit: float, n_train: int) -> float:
    """Planned seconds of a diagnosis of a model whose fit takes ``fit`` seconds on ``n_train`` training samples.
    The diagnosis runs alone, one task that keeps the other reference workers idle, so its work counts once per
    reference worker: the plan is of wall time (a stage of many tasks takes its work / REFERENCE_WORKERS)."""
    return REFERENCE_WORKERS * (DIAGNOSIS_FITS * fit + DIAGNOSIS_PER_SAMPLE * n_train)


@dataclass
class Group:
    """Tasks that are taken or left together (the seeds and folds of one candidate), with their work."""

    key: str
    tasks: list[Any]
    work: float


@dataclass
class Budget:
    seconds: float
    planned: float = 0.0
    stages: dict[str, float] = field(default_factory=dict)
    #: work left for after the stages (the model's fit on the whole training split), the last reserve asked
    reserved: float = 0.0

    @property
    def allowance(self) -> float:
        return self.seconds * REFERENCE_WORKERS

    def take(self, stage: str, groups: Sequence[Group], minimum: int = 1, reserve: float = 0.0) -> list[Group]:
        """The groups of ``stage`` that fit its cumulative share less ``reserve`` (work planned after the stage),
        in the order given (at least ``minimum``)."""
        limit = SHARES[stage] * self.allowance - reserve
        self.reserved = reserve
        taken: list[Group] = []
        for g in groups:
            if len(taken) >= minimum and self.planned + g.work > limit:
                break
            taken.append(g)
            self.planned += g.work
        self.stages[stage] = self.stages.get(stage, 0.0) + sum(g.work for g in taken)
        return taken

    def to_json(self) -> dict[str, Any]:
        return {
            "seconds": self.seconds,
            "reference_workers": REFERENCE_WORKERS,
            "allowance": self.allowance,
            "planned": self.planned,
            "stages": dict(self.stages),
            "reserved": self.reserved,
        }
