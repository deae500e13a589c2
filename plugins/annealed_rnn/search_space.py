"""The `annealed-rnn` family's part in ``family: auto`` (the ``Family.search_space`` hook, docs/plugins.md).

One starting candidate: the thesis's 60-element network annealed for 400 steps (5.3.4), internal mode,
one thread (the search runs candidates side by side). Neighbours of a good one: constructive growth
(6.4.5), twice the annealing steps, and the external mode where the protocol allows a tune-in. Random:
the search fits several seeds and judges the median.
"""

from __future__ import annotations

from typing import Any

from dynmodel.search.space import Candidate, Found, SearchContext

NAME = "annealed-rnn"
#: seconds per annealing step, training sample and element, and a fixed part
_COST = 1.5e-8
_FIXED = 0.1


def _work(ctx: SearchContext, steps: int, size: int, external: bool = False) -> float:
    return _FIXED + _COST * steps * max(ctx.n_train, 1) * size * (1.5 if external else 1.0)


def _cand(ctx: SearchContext, summary: str, params: dict[str, Any], steps: int = 400, size: int = 60) -> Candidate:
    external = params.get("mode") == "external"
    return Candidate(NAME, {"workers": 1, **params}, summary, work=_work(ctx, steps, size, external), stochastic=True)


def search_space(ctx: SearchContext, around: Found | None = None) -> list[Candidate]:
    if around is None:
        return [_cand(ctx, "60 elements annealed for 400 steps (the default)", {})]
    p = {k: v for k, v in around.candidate.params.items() if k != "workers"}
    steps = int(p.get("steps", 400))
    out = [
        _cand(ctx, "constructive growth up to 200 elements (6.4.5)", {**p, "grow": True}, steps, 120),
        _cand(ctx, f"annealed for {2 * steps} steps", {**p, "steps": 2 * steps}, 2 * steps),
    ]
    if p.get("mode") != "external" and (ctx.max_warmup is None or ctx.max_warmup >= 5):
        tune = 20 if ctx.max_warmup is None else min(20, ctx.max_warmup)
        out.append(_cand(ctx, f"external mode, tune-in {tune}", {**p, "mode": "external", "tune_in": tune}, steps))
    return out
