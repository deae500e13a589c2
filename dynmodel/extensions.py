"""Model extensions: changes of a spec, as JSON merge patches (RFC 7396) with one-line summaries, and the
context a model family reads when it offers its own (see docs/plugins-extensions.md).

Two users share this machinery: ``dynmodel diagnose`` (a detector names a cause, the families say how
to extend the model for it, the diagnosis refits and keeps what validates) and the model search of
``family: auto`` (its moves). Neither needs the other: an :class:`ExtensionContext` is built from a
fitted diagnosis as well as from a bare resolved spec, the channel names and the sampling time.

Who proposes what:

* data-side changes work for every family and are built here, generically: delay lines, derived inputs
  (time functions, direction of motion, travel since reversal), detrending, the cost;
* model-side changes come from the families through two class-level hooks of
  :class:`dynmodel.family.Family`: ``extensions(cause, ctx)`` (capacity, structure, stabilisation; a
  family may also offer a switch *to itself* when ``ctx.family`` is another family) and
  ``include_inputs(channels, history, ctx)`` (how a model of the family takes new input channels).

No family is named in this module.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from . import registry
from .data.derived import channel_name


@dataclass
class Extension:
    """A proposed change of the spec, as a JSON merge patch (RFC 7396), with a one-line summary."""

    summary: str
    patch: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return {"summary": self.summary, "patch": self.patch}


# ---------------------------------------------------------------------------------------- merge patches
def merge(target: Any, patch: Any) -> Any:
    """RFC 7396 merge of ``patch`` into a copy of ``target``: a mapping merges key by key, ``None``
    (null) deletes a key, anything else (numbers, strings, lists) replaces the target's value."""
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    out = copy.deepcopy(target) if isinstance(target, dict) else {}
    for key, value in patch.items():
        if value is None:
            out.pop(key, None)
        else:
            out[key] = merge(out.get(key), value)
    return out


def merge_patches(a: Mapping[str, Any], b: Mapping[str, Any]) -> dict[str, Any]:
    """One patch doing what ``a`` then ``b`` do (b wins where both set a value)."""
    out = dict(a)
    for k, v in b.items():
        out[k] = merge_patches(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def params_patch(**params: Any) -> dict[str, Any]:
    """``{"model": {"params": params}}``."""
    return {"model": {"params": params}}


# ---------------------------------------------------------------------------------------- the context
@dataclass(frozen=True)
class ExtensionContext:
    """What a family's hook may read. Every field but the first eight is optional: a diagnosis fills
    them from the fitted model, a model search from what it knows before fitting."""

    family: str  # the family of the spec being extended (may be another family than the hook's own)
    params: dict[str, Any]  # its parameters, resolved (every default filled in)
    written_params: dict[str, Any]  # its parameters as written in the spec (what a switch must delete)
    cost: str  # 'mse1' or 'mse_inf'
    input_names: tuple[str, ...]  # physical input channels
    output_names: tuple[str, ...]
    sampling_time: float
    data: dict[str, Any]  # the resolved data section (delay_lines, delay_form, derived_inputs, detrend, ...)
    n_train: int | None = None  # training samples (scored)
    memory: int | None = None  # the model's memory in samples (measured, or an estimate)
    evidence: dict[str, Any] = field(default_factory=dict)  # the finding's evidence (cause-specific keys)
    fitted: Any = None  # the fitted family instance (diagnosis only; None from a spec)

    @classmethod
    def from_spec(
        cls,
        resolved: Mapping[str, Any],
        input_names: Sequence[str] | None = None,
        output_names: Sequence[str] | None = None,
        sampling_time: float | None = None,
        *,
        written: Mapping[str, Any] | None = None,
        n_train: int | None = None,
        memory: int | None = None,
        evidence: Mapping[str, Any] | None = None,
        fitted: Any = None,
    ) -> ExtensionContext:
        """From a resolved spec mapping (``Spec.resolved()`` or an equivalent dict with ``model.family``,
        ``model.params``, ``cost`` and ``data``). Channel names and the sampling time default to the data
        section's ``input`` / ``output`` / ``sampling_time`` when they are given there; ``written`` is the
        spec as the user wrote it (default: the resolved one)."""
        model = resolved.get("model") or {}
        data = dict(resolved.get("data") or {})
        inputs = list(input_names if input_names is not None else data.get("input") or [])
        outputs = list(output_names if output_names is not None else data.get("output") or [])
        st = sampling_time if sampling_time is not None else data.get("sampling_time") or 1.0
        raw_model = (written if written is not None else resolved).get("model") or {}
        return cls(
            family=str(model.get("family")),
            params=dict(model.get("params") or {}),
            written_params=dict(raw_model.get("params") or {}),
            cost=str(resolved.get("cost", "mse1")),
            input_names=tuple(str(x) for x in inputs),
            output_names=tuple(str(x) for x in outputs),
            sampling_time=float(st),
            data=data,
            n_train=n_train,
            memory=memory,
            evidence=dict(evidence or {}),
            fitted=fitted,
        )

    def with_evidence(self, evidence: Mapping[str, Any]) -> ExtensionContext:
        return replace(self, evidence=dict(evidence))

    # -------------------------------------------------------------- derived facts
    @property
    def delay_lines(self) -> list[int]:
        return [int(d) for d in self.data.get("delay_lines") or []]

    @property
    def derived_inputs(self) -> list[dict[str, Any]]:
        """The spec's derived inputs in their JSON form, unset keys dropped."""
        return [{k: v for k, v in item.items() if v is not None} for item in self.data.get("derived_inputs") or []]

    def delay_name(self, name: str, delay: int) -> str:
        mark = "~" if self.data.get("delay_form") == "difference" else "@"
        return f"{name}{mark}{int(delay)}"

    @property
    def model_input_names(self) -> list[str]:
        """The channels a model sees: inputs, one block per delay line, then derived inputs (the
        preprocessor's order)."""
        names = list(self.input_names)
        for d in self.delay_lines:
            names += [self.delay_name(n, d) for n in self.input_names]
        return names + [channel_name(item) for item in self.derived_inputs]


# ---------------------------------------------------------------------------------------- proposals
def family_extensions(cause: str, ctx: ExtensionContext, switches: bool = True) -> list[Extension]:
    """Model-side extensions for ``cause``: the spec's own family first, then (``switches``) the proposals
    of the other installed families to switch to them. A family whose hook fails offers nothing."""
    table = registry.families()
    order = [ctx.family] + (sorted(n for n in table if n != ctx.family) if switches else [])
    out: list[Extension] = []
    for name in order:
        cls = table.get(name)
        hook = getattr(cls, "extensions", None)
        if hook is None:
            continue
        out += [x for x in hook(cause, ctx) or [] if isinstance(x, Extension)]
    return unique(out)


def unique(extensions: Sequence[Extension]) -> list[Extension]:
    """Extensions without repeated patches, first kept."""
    seen, out = set(), []
    for x in extensions:
        key = repr(x.patch)
        if x.patch and key not in seen:
            seen.add(key)
            out.append(x)
    return out


def include_inputs(ctx: ExtensionContext, channels: Sequence[str], history: int = 0) -> dict[str, Any]:
    """The family's patch that makes its model use the new model-input ``channels`` ({} for families
    that use every model input anyway)."""
    cls = registry.families().get(ctx.family)
    hook = getattr(cls, "include_inputs", None)
    return dict(hook(list(channels), int(history), ctx) or {}) if hook is not None else {}


def with_inputs(
    ctx: ExtensionContext,
    delay_lines: Sequence[int] = (),
    derived: Sequence[Mapping[str, Any]] = (),
    history: int = 0,
) -> dict[str, Any]:
    """Patch adding delay lines and derived inputs (data side, every family), plus what the family
    needs to use the new channels with ``history`` past samples each. {} when nothing is new."""
    data: dict[str, Any] = {}
    new_channels: list[str] = []
    old_delays = ctx.delay_lines
    delays = sorted({int(d) for d in delay_lines if int(d) > 0 and int(d) not in old_delays})
    if delays:
        data["delay_lines"] = sorted(old_delays + delays)
        new_channels += [ctx.delay_name(u, d) for d in delays for u in ctx.input_names]
    old_items = ctx.derived_inputs
    names = {channel_name(item) for item in old_items}
    items = []
    for item in derived:
        item = dict(item)
        if channel_name(item) not in names:
            names.add(channel_name(item))
            items.append(item)
    if items:
        data["derived_inputs"] = old_items + items
        new_channels += [channel_name(item) for item in items]
    if not data:
        return {}
    return merge_patches({"data": data}, include_inputs(ctx, new_channels, history))


def switch_family(ctx: ExtensionContext, family: str, params: Mapping[str, Any], **top: Any) -> dict[str, Any]:
    """Patch replacing the spec's model by ``family`` with ``params`` (the old family's written parameters
    deleted), plus top-level keys such as ``cost``."""
    new = {key: None for key in ctx.written_params}
    new.update(params)
    return {"model": {"family": family, "params": new}, **top}
