"""The search space of ``family: auto``: what a family is told about the data, and what it answers.

A family takes part in the search by implementing one class method of the plugin contract
(docs/plugins.md, "Taking part in family: auto")::

    @classmethod
    def search_space(cls, ctx: SearchContext, around: Found | None = None) -> list[Candidate]

* ``around=None``: the family's *starting* candidates for these data, most promising first;
* ``around=found`` (a fitted candidate of this family that did well): its *neighbours*, the ways to grow
  it (more capacity, other regularisation, other seeds of the same idea), most promising first.

Both are cheap (no fitting): the search measures the candidates. A family that does not implement the
hook (the base class returns ``[]``) takes no part. Nothing in this module names a family.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from typing import Any

from ..extensions import ExtensionContext, merge_patches

#: an input that moves like a position changes sign when this fraction of its training samples lies beyond its
#: deadband on each side of zero
SIGNED = 0.1
#: seconds of a fit on the reference machine, when a candidate gives no estimate: per training sample
DEFAULT_WORK_PER_SAMPLE = 2e-4


@dataclass(frozen=True)
class SearchContext:
    """What a family's ``search_space`` hook may read about the data and the protocol.

    ``max_warmup``: measured outputs a free run may take at the start of a validation or test recording
    (the protocol's initialization window, or ``None`` when the spec declares none: then the search's
    checks run from rest); 0 when no measured output may be used at all (every sample scored).
    ``excursion``: how far the validation and test inputs go beyond the training input range, as a
    fraction of its width (0 when they stay inside): a model will extrapolate there.
    ``small``: a held-out validation split cannot rank the candidates (the data are too short for one, or its
    output barely moves); the search cross-validates in blocks (prefer few, robust candidates).
    """

    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    sampling_time: float
    n_train: int  # scored training samples
    n_validation: int  # scored validation samples (0: none)
    data: dict[str, Any]  # the spec's resolved data section
    max_warmup: int | None = None
    excursion: float = 0.0
    small: bool = False
    seeds: int = 3
    cost: str | None = None  # a cost the user wrote (every candidate then uses it), else None
    budget: float = 300.0
    #: inputs that move like a position (:func:`dynmodel.data.derived.position_like`) and the deadband of their
    #: reversals: direction and travel-since-reversal features of them mean something (friction, hysteresis)
    positions: dict[str, float] = field(default_factory=dict)
    #: inputs that act on an output only after a dead time (:func:`dynmodel.data.delay.dead_times`), in samples:
    #: lags that start there reach the input's effect without a longer embedding
    dead_times: dict[str, int] = field(default_factory=dict)
    #: the :attr:`positions` that change sign (at least :data:`SIGNED` of the training samples beyond their
    #: deadband on each side of zero): a velocity, whose sign a Coulomb or LuGre force switches on
    signed: tuple[str, ...] = ()

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    @property
    def n_outputs(self) -> int:
        return len(self.output_names)

    def direction_inputs(self) -> list[dict[str, Any]]:
        """``derived_inputs`` items for every input that moves like a position (:attr:`positions`): its direction
        of motion and travel since the last reversal, with its deadband (thesis 6.1-6.3: what a friction force
        or a hysteresis loop depends on); [] when no input does, or the spec derives inputs of its own."""
        if self.data.get("derived_inputs"):
            return []
        return [
            {kind: name, "deadband": deadband}
            for name, deadband in self.positions.items()
            for kind in ("direction", "since_reversal")
        ]

    def sign_inputs(self) -> list[dict[str, Any]]:
        """``derived_inputs`` items for every input that moves smoothly and changes sign (:attr:`signed`): its
        sign, with its reversal deadband; [] when none does, or the spec derives inputs of its own."""
        if self.data.get("derived_inputs"):
            return []
        return [{"sign": name, "deadband": self.positions[name]} for name in self.signed]

    def allows_warmup(self, samples: int) -> bool:
        """May a run start from ``samples`` measured outputs under the protocol?"""
        return self.max_warmup is None or samples <= self.max_warmup

    def extension_context(self, family: str, params: dict[str, Any], cost: str = "mse1") -> ExtensionContext:
        """An :class:`~dynmodel.extensions.ExtensionContext` for ``family`` with ``params`` on these data (to
        reuse the extension helpers, e.g. :func:`dynmodel.extensions.with_inputs`)."""
        return ExtensionContext(
            family=family,
            params=dict(params),
            written_params=dict(params),
            cost=cost,
            input_names=self.input_names,
            output_names=self.output_names,
            sampling_time=self.sampling_time,
            data=dict(self.data),
            n_train=self.n_train,
        )


@dataclass(frozen=True)
class Candidate:
    """One configuration to measure: a family, its ``model.params`` and the spec keys around them.

    ``cost``: None for the family's ``default_cost``. ``data``: a merge patch of the spec's data section
    (delay lines, derived inputs; lists replace). ``screen``: a merge patch of ``params`` used where the
    search scores candidates cheaply first (e.g. least-squares weights instead of a free-run
    re-estimation); ``screen_cost`` likewise for the cost. ``work``: estimated seconds of one fit on
    ``ctx.n_train`` training samples on one core of an ordinary machine (the search plans its budget
    with it; None: a default per sample); ``screen_work`` the same for the screening variant. ``complexity``: a size (e.g. the number of parameters) used to
    prefer the simpler of two candidates that validate alike; None: judged from the fitted model.
    ``stochastic``: None for the family's ``stochastic`` flag (several seeds are fitted when True)."""

    family: str
    params: dict[str, Any]
    summary: str
    cost: str | None = None
    data: dict[str, Any] = field(default_factory=dict)
    screen: dict[str, Any] = field(default_factory=dict)
    screen_cost: str | None = None
    work: float | None = None
    screen_work: float | None = None
    complexity: float | None = None
    stochastic: bool | None = None

    def patch(self, screening: bool = False) -> dict[str, Any]:
        """The merge patch that turns a spec into this candidate (full fit, or the screening variant)."""
        params = merge_patches(self.params, self.screen) if screening and self.screen else dict(self.params)
        out: dict[str, Any] = {"model": {"family": self.family, "params": params}}
        cost = self.screen_cost if screening and self.screen_cost else self.cost
        if cost is not None:
            out["cost"] = cost
        if self.data:
            out["data"] = dict(self.data)
        return out

    @property
    def identity(self) -> str:
        """Canonical JSON of what defines the candidate (not its summary or estimates)."""
        return json.dumps(
            {"family": self.family, "params": self.params, "cost": self.cost, "data": self.data},
            sort_keys=True,
            default=str,
        )

    @property
    def key(self) -> str:
        """A short stable name: ``<family>-<hash>``."""
        return f"{self.family}-{hashlib.sha256(self.identity.encode()).hexdigest()[:8]}"

    def with_cost(self, cost: str | None) -> Candidate:
        return self if cost is None else replace(self, cost=cost, screen_cost=None)

    def to_json(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "family": self.family,
            "summary": self.summary,
            "params": self.params,
            "cost": self.cost,
            "data": self.data,
            "screen": self.screen or None,
            "screen_cost": self.screen_cost,
            "work": self.work,
            "screen_work": self.screen_work,
            "complexity": self.complexity,
        }


@dataclass
class Found:
    """A measured candidate handed back to its family's hook to grow it: the candidate, its fitted family
    instance (model space; ``fitted.model_`` is the FittedModel in physical units; None when the fit was
    not kept), its metrics (split -> entry, as ``FittedModel.metrics``) and the search's score (validation
    free-run NMSE, %, lower is better)."""

    candidate: Candidate
    fitted: Any
    metrics: dict[str, Any]
    score: float


def data_summary(data: dict[str, Any]) -> str:
    """A candidate summary's note of its data-side extensions (a data patch: derived inputs, input delay
    lines), e.g. ", with the direction and travel since the last reversal of x as inputs and input delay
    lines"; "" for none. Families that grow a candidate keep its patch and say so with this note."""
    derived = data.get("derived_inputs") or []
    moving = sorted({str(v) for item in derived for k, v in item.items() if k in ("direction", "since_reversal")})
    signs = sorted({str(item["sign"]) for item in derived if "sign" in item})
    parts = [f"direction and travel since the last reversal of {', '.join(moving)} as inputs"] if moving else []
    parts += [f"sign of {', '.join(signs)} as an input"] if signs else []
    if len(derived) > 2 * len(moving) + len(signs):
        parts.append("derived inputs")
    if data.get("delay_lines"):
        parts.append("input delay lines")
    return f", with the {' and '.join(parts)}" if parts else ""


def candidates_of(family_cls: Any, ctx: SearchContext, around: Found | None = None) -> list[Candidate]:
    """The hook's answer, only well-formed candidates of this family, without repeats; [] when the family
    does not take part or its hook fails (a broken plugin must not stop the search)."""
    hook = getattr(family_cls, "search_space", None)
    if hook is None:
        return []
    try:
        found = hook(ctx, around) if around is not None else hook(ctx)
    except Exception as exc:  # noqa: BLE001 - reported by the caller through the warning
        import warnings

        warnings.warn(f"family '{family_cls.name}': its search_space hook failed ({exc}); skipped", stacklevel=2)
        return []
    out, seen = [], set()
    for cand in found or []:
        if not isinstance(cand, Candidate) or cand.family != family_cls.name:
            continue
        if cand.identity in seen:
            continue
        seen.add(cand.identity)
        out.append(cand.with_cost(ctx.cost))
    return out


def estimated_work(cand: Candidate, ctx: SearchContext, n_train: int | None = None, screening: bool = False) -> float:
    """Seconds of one fit of ``cand`` (its screening variant when ``screening``) on ``n_train`` training
    samples (default ``ctx.n_train``): the candidate's estimate scaled linearly with the samples."""
    n = ctx.n_train if n_train is None else n_train
    base = cand.screen_work if screening and cand.screen_work is not None else cand.work
    if base is None:
        base = DEFAULT_WORK_PER_SAMPLE * max(ctx.n_train, 1)
    return float(base) * n / max(ctx.n_train, 1)
