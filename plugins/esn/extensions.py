"""How the `esn` family extends itself for a diagnosed cause (the ``Family.extensions`` hook,
docs/plugins-extensions.md). A network takes every model input through its input weights and direct
readout links, so new channels need no parameter (the base ``include_inputs`` returns {}).

Moves: leaky elements (eq. 6.21) for memory, a larger network or stronger input weights for
nonlinearity and oscillations, the internal mode and a rescaled connection matrix for stability and
reliability (thesis 5.3.1, 5.3.2). (No longer readout selection for structure-stopped-early: the FOS readout
already runs 50 terms past its best.) Sizes are read from the resolved
parameters (the family's own default when unset), never assumed. When another family is diagnosed with
a dynamical cause a polynomial cannot follow (direction dependence, an output nonlinearity), the esn
family offers to replace it by a leaky echo state network of its default size.
"""

from __future__ import annotations

from typing import Any

from dynmodel.extensions import Extension, ExtensionContext, params_patch, switch_family

NAME = "esn"
LEAKY = {"relaxation": [0.5, 0.99], "relaxation_gain": True}


def _size(ctx: ExtensionContext) -> int:
    from .params import EsnParams

    return int(ctx.params.get("size") or EsnParams().size)


def _leaky(relaxation: Any) -> bool:
    if isinstance(relaxation, (list, tuple)):
        return max(relaxation) >= 0.5
    return float(relaxation or 0.0) >= 0.5


def larger(ctx: ExtensionContext) -> Extension:
    size = _size(ctx)
    return Extension(f"a larger network ({2 * size} elements, was {size})", params_patch(size=2 * size))


def stronger_input(ctx: ExtensionContext) -> Extension:
    scale = float(ctx.params.get("input_scale", 1.0))
    return Extension(
        f"input weights twice as strong (input_scale {2 * scale:g}): the elements work further into their "
        "nonlinear range",
        params_patch(input_scale=2 * scale),
    )


def leaky(ctx: ExtensionContext) -> list[Extension]:
    if _leaky(ctx.params.get("relaxation", 0.0)):
        return []
    return [
        Extension(
            "leaky elements with relaxation drawn from [0.5, 0.99] (eq. 6.21): slower internal memory",
            params_patch(**LEAKY),
        )
    ]


def internal(ctx: ExtensionContext) -> list[Extension]:
    if ctx.params.get("mode") != "external":
        return []
    return [
        Extension(
            "internal mode: a reliable network driven by the input only (thesis 5.3.2)", params_patch(mode="internal")
        )
    ]


def extensions(cause: str, ctx: ExtensionContext) -> list[Extension]:
    if ctx.family != NAME:
        return _switch(cause, ctx)
    if ctx.params.get("weights") is not None:
        return []  # explicit matrices: nothing to grow
    if cause == "free-run-instability":
        return internal(ctx)
    if cause == "unreliable-model":
        scale = ctx.params.get("scale") or {}
        contraction = scale.get("by") == "singular" and float(scale.get("value", 1.0)) < 1.0
        out = []
        if not contraction:
            out.append(
                Extension(
                    "rescale C to a largest singular value of 0.95 (reliable by eq. 4.51)",
                    params_patch(scale={"by": "singular", "value": 0.95}),
                )
            )
        if ctx.params.get("mode") == "external":
            out.append(
                Extension(
                    "internal mode with C rescaled to a largest singular value of 0.95",
                    params_patch(mode="internal", scale={"by": "singular", "value": 0.95}),
                )
            )
        return out
    if cause == "static-nonlinearity":
        return [stronger_input(ctx), larger(ctx)]
    if cause == "output-nonlinearity":
        return [larger(ctx), stronger_input(ctx)]
    if cause in ("insufficient-memory", "missing-dynamics"):
        return leaky(ctx) + [larger(ctx)]
    if cause == "unmodeled-oscillation":
        return [larger(ctx)]
    if cause == "inadequate-structure":
        return leaky(ctx) + [larger(ctx)]
    return []


def _switch(cause: str, ctx: ExtensionContext) -> list[Extension]:
    if cause not in ("direction-dependence", "output-nonlinearity"):
        return []
    from .params import EsnParams

    size = EsnParams().size
    return [
        Extension(
            f"a dynamical family: a leaky echo state network ({size} elements, eq. 6.21) driven by the input",
            switch_family(ctx, NAME, {"relaxation": [0.0, 0.9], "relaxation_gain": True}, cost="mse1"),
        )
    ]
