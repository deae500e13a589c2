"""How the `annealed-rnn` family extends itself for a diagnosed cause (the ``Family.extensions`` hook,
docs/plugins-extensions.md): the internal mode for a diverging free run, a smaller bound on the largest
singular value of C for an unreliable network (thesis 5.3.1), slower elements for memory, constructive
growth (6.4.5) for capacity. It offers no switch from other families (annealing is slow)."""

from __future__ import annotations

from dynmodel.extensions import Extension, ExtensionContext, params_patch

NAME = "annealed-rnn"


def extensions(cause: str, ctx: ExtensionContext) -> list[Extension]:
    if ctx.family != NAME:
        return []
    p = ctx.params
    if cause == "free-run-instability" and p.get("mode") == "external":
        return [
            Extension(
                "internal mode: a reliable network driven by the input only (thesis 5.3.2)",
                params_patch(mode="internal"),
            )
        ]
    if cause == "unreliable-model":
        return [
            Extension(
                "keep the largest singular value of C at 0.9 and the relaxation below 0.5",
                params_patch(max_singular=0.9, initial_singular=0.85, relaxation=[0.0, 0.5]),
            )
        ]
    relaxation = p.get("relaxation", [0.0, 0.9])
    high = max(relaxation) if isinstance(relaxation, (list, tuple)) else float(relaxation)
    if cause in ("insufficient-memory", "missing-dynamics") and high < 0.99:
        return [
            Extension(
                "slower elements: relaxation drawn from [0.5, 0.99] (eq. 6.21)",
                params_patch(relaxation=[0.5, 0.99], relaxation_gain=True),
            )
        ]
    if cause in ("static-nonlinearity", "output-nonlinearity", "inadequate-structure", "unmodeled-oscillation"):
        if not p.get("grow", False):
            return [
                Extension(
                    "constructive growth: add elements while validation improves (6.4.5)", params_patch(grow=True)
                )
            ]
    return []
