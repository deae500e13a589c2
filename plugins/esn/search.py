"""The `esn` family's part in ``family: auto`` (the ``Family.search_space`` hook, docs/plugins.md).

Starting candidates: the default internal network (leaky elements, input to half of them, the output
clipped), a twice larger one, and, where the protocol lets a run start from measured outputs, the
external mode with a tune-in inside that window (fed back, it models smooth, well-excited outputs best,
thesis 5.3.2, and can diverge elsewhere: the search's band checks catch that), and, where the only input
moves like a position, the larger network with its direction of motion, travel since the last reversal and
input delay lines (the friction network of thesis 6.2-6.4). Every candidate is random:
the search fits several seeds and judges the median. Neighbours of a good network: three networks of other
seeds averaged (``members: 3``: one network's free run varies from seed to seed more than its validation
shows, the mean of three less), twice the elements,
weaker and stronger input weights, slower leaky elements, a ridge readout over all states, the
external mode for an internal network, and, for an internal network on data without delay lines, input
delay lines in difference form u(t) - u(t - d) at d = 1, 2, 5, 10, 25, 50, 100 samples (at most a fiftieth of
the training samples): an external memory of the input's recent displacements, what pre-sliding friction
and other hysteresis need (thesis 6.2.3; a data-side extension, the data section patched); and, for inputs
that move like a position (``SearchContext.positions``), their direction of motion and travel since the last
reversal as inputs, alone and with the delay lines (thesis 6.1-6.3: friction depends on them). Every
neighbour keeps the data patch of the network it grows from: the friction network grown into one of twice
the elements is still the friction network.
"""

from __future__ import annotations

from typing import Any

from dynmodel.search.space import Candidate, Found, SearchContext, data_summary

NAME = "esn"
#: seconds per training sample and element of a fit (streamed drive, FOS readout), and a fixed part
_COST = 1.2e-7
_FIXED = 0.1
#: the shortest tune-in worth an external network
_MIN_TUNE_IN = 5
#: networks averaged in the neighbour that averages (``members``): seeds part ways on the test inputs more than
#: their validation shows (docs/auto.md), and the mean of three varies less than any one
_MEMBERS = 3
#: delays (samples) of the input delay lines offered around an internal network
_DELAYS = (1, 2, 5, 10, 25, 50, 100)


def _work(ctx: SearchContext, size: int, external: bool = False, members: int = 1) -> float:
    n = max(ctx.n_train, 1)
    return members * (_FIXED + _COST * n * size * (1.5 if external else 1.0) + 2e-6 * size * size)


def _cand(
    ctx: SearchContext,
    summary: str,
    params: dict[str, Any],
    size: int,
    external: bool = False,
    data: dict[str, Any] | None = None,
) -> Candidate:
    return Candidate(
        family=NAME,
        params=params,
        summary=summary,
        data=data or {},
        work=_work(ctx, size, external, int(params.get("members", 1))),
        stochastic=True,
    )


def _tune_in(ctx: SearchContext) -> int | None:
    """The tune-in of an external network under the protocol (None: not allowed)."""
    if ctx.max_warmup is None:
        return 20
    if ctx.max_warmup < _MIN_TUNE_IN:
        return None
    return int(min(20, ctx.max_warmup))


def starting(ctx: SearchContext) -> list[Candidate]:
    out = [_cand(ctx, "internal, 200 leaky elements (the default)", {}, 200)]
    tune = _tune_in(ctx)
    if tune is not None:
        out.append(
            _cand(
                ctx,
                f"external (the output fed back), 200 elements, tune-in {tune}",
                {"mode": "external", "tune_in": tune},
                200,
                external=True,
            )
        )
    big = 400 if ctx.n_train >= 2000 else 100
    out.append(_cand(ctx, f"internal, {big} leaky elements", {"size": big}, big))
    out += _direction_starts(ctx, big)
    return out


def neighbours(ctx: SearchContext, found: Found) -> list[Candidate]:
    p = dict(found.candidate.params)
    size = int(p.get("size", 200))
    external = p.get("mode") == "external"
    members = int(p.get("members", 1))
    mode = "external" if external else "internal"
    if members > 1:
        mode += f" ({members} networks averaged)"
    # every neighbour keeps the network's data patch (derived inputs, delay lines): a friction network grown
    # without its direction features is another model, not a larger one
    data = found.candidate.data
    on = data_summary(data)
    out = []
    if members == 1:
        out.append(
            _cand(
                ctx,
                f"{found.candidate.summary}; {_MEMBERS} networks of other seeds averaged (members {_MEMBERS})",
                {**p, "members": _MEMBERS},
                size,
                external,
                data=data,
            )
        )
    if size * 2 <= 1600 and ctx.n_train >= 10 * size:
        out.append(_cand(ctx, f"{mode}, {2 * size} elements{on}", {**p, "size": 2 * size}, 2 * size, external, data))
    scale = float(p.get("input_scale", 1.0))
    for factor in (0.5, 2.0):
        out.append(
            _cand(
                ctx,
                f"{mode}, {size} elements, input weights x{factor:g} (input_scale {scale * factor:g}){on}",
                {**p, "input_scale": scale * factor},
                size,
                external,
                data,
            )
        )
    out.append(
        _cand(
            ctx,
            f"{mode}, {size} elements, slower leaky elements (relaxation 0.5 .. 0.995){on}",
            {**p, "relaxation": [0.5, 0.995]},
            size,
            external,
            data,
        )
    )
    out.append(
        _cand(
            ctx,
            f"{mode}, {size} elements, ridge readout over every state{on}",
            {**p, "readout": {**(p.get("readout") or {}), "solver": "ridge"}},
            size,
            external,
            data,
        )
    )
    # delay lines are offered to an internal network on data without any yet
    delays = [] if external or data else _offered_delays(ctx)
    if delays:
        out.append(
            _cand(
                ctx,
                f"{mode}, {size} elements, input delay lines u(t) - u(t - d), d = {', '.join(map(str, delays))}",
                p,
                size,
                data={"delay_lines": delays, "delay_form": "difference"},
            )
        )
    if not external:
        out += _direction_neighbours(ctx, found, p, size, delays)
    tune = _tune_in(ctx)
    if not external and tune is not None:
        out.append(
            _cand(
                ctx,
                f"external, {size} elements, tune-in {tune}{on}",
                {**p, "mode": "external", "tune_in": tune},
                size,
                True,
                data,
            )
        )
    return out


def _offered_delays(ctx: SearchContext) -> list[int]:
    """The input delay lines offered to an internal network: :data:`_DELAYS` up to a fiftieth of the training
    samples, none when fewer than two fit or the spec has delay lines of its own."""
    delays = [d for d in _DELAYS if d <= ctx.n_train // 50]
    return [] if len(delays) < 2 or ctx.data.get("delay_lines") else delays


def _with_directions(
    ctx: SearchContext, p: dict[str, Any], size: int, data: dict[str, Any], derived: list, delays: list[int]
) -> Candidate:
    """An internal network ``p`` of ``size`` elements with the direction features ``derived`` added to its data
    patch ``data``, and the input delay lines ``delays`` (none: [])."""
    what = f"internal, {size} elements, direction and travel since the last reversal of {', '.join(ctx.positions)}"
    what += " as inputs"
    patch = {**data, "derived_inputs": derived}
    if delays:
        what += f", and input delay lines u(t) - u(t - d), d = {', '.join(map(str, delays))}"
        patch.update(delay_lines=delays, delay_form="difference")
    return _cand(ctx, what, p, size, data=patch)


def _direction_starts(ctx: SearchContext, size: int) -> list[Candidate]:
    """Where the only input moves like a position (a force from a position: the cross-prediction of thesis
    6.2-6.4): a starting network of ``size`` elements with the direction features and the delay lines of
    friction, which a network without them can validate too poorly to be grown into (the sliding friction plant
    of 6.3: 34 % validation NMSE without, under 5 % with). Not beside other inputs (a seal's pressure): there it
    took the place of a NARX candidate among the two the search grows, and never won."""
    derived = ctx.direction_inputs()
    if not derived or ctx.n_inputs != 1:
        return []
    return [_with_directions(ctx, {"size": size}, size, {}, derived, _offered_delays(ctx))]


def _direction_neighbours(
    ctx: SearchContext, found: Found, p: dict[str, Any], size: int, delays: list[int]
) -> list[Candidate]:
    """For an internal network and inputs that move like a position: their direction of motion and travel since
    the last reversal as inputs (``derived_inputs``, thesis 6.1-6.3: what a friction force or a hysteresis loop
    depends on beyond the delay lines' last 100 samples, e.g. a slow creep in one direction), kept with the
    network's delay lines, and with the new ones (``delays``, [] when none are offered)."""
    data = found.candidate.data
    derived = ctx.direction_inputs()
    if not derived or "derived_inputs" in data:
        return []
    out = [_with_directions(ctx, p, size, data, derived, [])]
    if delays:
        out.append(_with_directions(ctx, p, size, {}, derived, delays))
    return out


def search_space(ctx: SearchContext, around: Found | None = None) -> list[Candidate]:
    return starting(ctx) if around is None else neighbours(ctx, around)
