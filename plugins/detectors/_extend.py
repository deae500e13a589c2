"""Data-side extensions the detectors propose for every family, as merge patches of the spec: delay lines,
derived inputs (time functions, direction of motion, travel since reversal), detrending and the cost.

New model-input channels reach the model through the family's ``include_inputs`` hook (a polynomial
NARX model adds them to its lag table; a network takes every input anyway). Model-side changes
(degree, lags, size, leaky elements, stabilisers) are the families' own: detectors ask for them with
``ctx.extensions(cause, evidence, generic)`` and name no family (docs/plugins-extensions.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from dynmodel.diagnose.context import Context
from dynmodel.extensions import Extension, with_inputs


def inputs_patch(
    ctx: Context, delay_lines: Sequence[int] = (), derived: Sequence[Mapping[str, Any]] = (), history: int = 0
) -> dict[str, Any]:
    """Delay lines and derived inputs, with ``history`` past samples of each new channel where the family
    takes a history per channel."""
    return with_inputs(ctx.extension_context(), delay_lines, derived, history)


def free_running_cost(ctx: Context, why: str = "") -> list[Extension]:
    """``cost: mse_inf`` unless the spec already uses it."""
    if ctx.spec.cost == "mse_inf":
        return []
    text = "estimate on the free-running error (cost: mse_inf" + (f"; {why})" if why else ")")
    return [Extension(text, {"cost": "mse_inf"})]


def delay_lines(ctx: Context, delays: Sequence[int], summary: str, history: int = 0) -> list[Extension]:
    patch = inputs_patch(ctx, delay_lines=delays, history=history)
    return [Extension(summary, patch)] if patch else []
