"""The `narx` family's part in ``family: auto`` (the ``Family.search_space`` hook, docs/plugins.md).

The family's own default already searches the embedding: lags 1 .. L_max and degrees 1 .. 3 on one Gram
matrix, the number of FOS terms chosen on the free-running validation error, the finalists re-estimated
on the free run (``cost: mse_inf``). So the starting candidates vary what the default does not:

* the default itself (the model most users want);
* the same search with a small term budget (few terms extrapolate more gently where test inputs leave the
  training range, EMPS);
* a longer memory at degree 2 (inputs 0..L, outputs 1..L with L up to 12 while the pool stays small:
  slow, smooth systems such as cascaded tanks);
* a linear model with long lags (an ARX / output-error reference the nonlinear ones must beat);
* for inputs that move like a position (``ctx.positions``), the default with their direction of motion and
  travel since the last reversal as inputs (``derived_inputs``, thesis 6.1-6.3: a Coulomb force is a
  direction times a level, a Dahl or LuGre force follows the travel since the last reversal);
* for such inputs that change sign (``ctx.signed``: a velocity), the default with their sign as an input (a
  Coulomb or LuGre force switches on it);
* where an input acts only after a dead time (``ctx.dead_times``), the default's pool on lags that start there;
* a second-order linear output-error model settled at its first input and unclipped (``initial: settled``,
  its terms chosen on validation, no output bounds, screened on the free run too): a run starts from rest at
  its first input, so its level must come from the inputs, not from measured initial outputs it could carry
  over, and it transfers to a recording at another operating condition (the pneumatic seal trained at 1, 3
  and 7 bar: every other candidate, clipped and carrying its level, failed on each left-out pressure). Started
  at the training mean instead (``initial: zeros``), the step to the first input kicked the run, and the fit
  learned to use that kick to reach a recording's level (seal 1/3/7 -> 5 bar: 12.0 % test NMSE, settled 4.4 %).

Every candidate is screened with least-squares weights (``cost: mse1``: FOS and the free-run stop,
no free-running re-estimation) and re-estimated on the free run only when it survives. Neighbours of a
good candidate (``around``) start from what its fit chose (lags L, degree d, k terms): two more lags, one
more degree, half and twice the terms, every one of 1.5 and 2 times the terms kept (screened with refined
weights: least squares says nothing of them), the output clipped at the training range (a saturating sensor),
ridge weights, and terms selected on the free-running error; each keeps the data-side extensions of the
candidate it grows from.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from dynmodel.search.space import Candidate, Found, SearchContext, data_summary

from .embedding import pool_size
from .params import GROWTH_WINDOW

NAME = "narx"
#: seconds per training sample and pool monomial of a screening fit (FOS on a Gram matrix, free-run stop)
_SCREEN_COST = 1e-7
#: seconds per training sample and squared term of the free-running re-estimation (/ 40 iterations): measured on
#: the full fits of the Silverbox and Bouc-Wen searches with the blocked-QR Levenberg-Marquardt (124 and 128 s
#: where 2.5e-8, the figure with MINPACK's QR, planned 376 s; 33 and 37 s where it planned 158 s). Per output:
#: one input, three accelerations (24000 samples, a linear model on lags 0..4), one output 0.67 s, two 3.6 s,
#: three 8.2 s, about the number of outputs times the squared terms per output (which grow with the lags of
#: every output); without the factor a three-output search planned for 300 s took 800 s)
_REFINE_COST = 8e-9


#: seconds per operation and training sample of the free-run growth (``growth_work``, :class:`.selection.GrowthWork`):
#: measured 6.3e-10 on Bouc-Wen's growth (12 000 samples, 10 to 90 terms) and 3.3e-10 on a generated Hammerstein
#: system's (3200 samples, 7 to 237 terms), the two running side by side on two cores
_GROWTH_OP_COST = 6e-10
#: the free-run growth of one fit stops at this fraction of the search's budget in planned seconds (``growth_work``):
#: Bouc-Wen's growth to 90 terms (70 kept) took 50 s; a noise-free Hammerstein system's grew on to 184 and 237 terms
#: (440 and 564 s per fold), its folds took 1095 s for a budget of 300 s and the search ran into its safety limit
GROWTH_CAP = 0.25

#: order of the high-order linear output-error candidate: up to five lightly damped modes (an eighth-order
#: resonant band-pass, 1 % output noise: 12.5 % test NMSE for the search without it, 4.6e-5 % for this model)
_OE_ORDER = 10


def _model_inputs(ctx: SearchContext) -> list[str]:
    return ctx.extension_context(NAME, {}).model_input_names


def _table(ctx: SearchContext, L: int, first_input: int = 0) -> dict[str, list[dict[str, int]]]:
    table = {u: [{"from": first_input, "to": L}] for u in _model_inputs(ctx)}
    table.update({y: [{"from": 1, "to": L}] for y in ctx.output_names})
    return table


def _regressors(ctx: SearchContext, L: int) -> int:
    return len(_model_inputs(ctx)) * (L + 1) + ctx.n_outputs * L


def _initial(ctx: SearchContext, L: int) -> dict[str, Any]:
    """``initial: zeros`` when the protocol lets a run start from fewer measured outputs than the lags."""
    return {} if ctx.allows_warmup(L) else {"initial": "zeros"}


def _work(ctx: SearchContext, pool: int, terms: int, samples: int | None = None) -> tuple[float, float]:
    """(full, screening) seconds of one fit on ``samples`` (default ctx.n_train) training samples: the terms
    are chosen and re-estimated for every output (``terms`` each), so both grow with the number of outputs."""
    n = max(ctx.n_train if samples is None else samples, 1)
    q = max(ctx.n_outputs, 1)
    screen = 0.05 + _SCREEN_COST * q * n * pool * (1 + n / 50000)
    refine = _REFINE_COST * q * n * terms * terms * 40
    return screen + refine, screen


def _max_lag(ctx: SearchContext, degree: int, pool: int, cap: int) -> int:
    L = 1
    for lag in range(cap, 0, -1):
        if pool_size(_regressors(ctx, lag), degree, True) <= pool:
            L = lag
            break
    if ctx.max_warmup is not None and ctx.max_warmup > 0:
        L = min(L, ctx.max_warmup)
    return max(L, 1)


#: the "all m terms kept" neighbours grow models of at most this many terms (their screening is refined)
KEPT_UP_TO = 40


def _candidate(
    ctx: SearchContext,
    summary: str,
    params: dict[str, Any],
    pool: int,
    terms: int,
    refined_screen: bool = False,
    **extra: Any,
) -> Candidate:
    """``refined_screen``: screened with its weights refined on the free run too (a candidate whose least-squares
    weights say nothing of it)."""
    full, screen = _work(ctx, pool, terms)
    return Candidate(
        family=NAME,
        params=params,
        summary=summary,
        cost="mse_inf",
        screen_cost=None if refined_screen else "mse1",
        work=full,
        screen_work=None if refined_screen else screen,
        stochastic=False,
        **extra,
    )


def _output_error(ctx: SearchContext, L: int = 2, every_term: bool = False) -> Candidate:
    """The linear output-error model of order ``L`` settled at its first input: the linear terms of inputs
    0..L and outputs 1..L (how many: FOS with the default patience, on the validation error; at order 2 every
    term was measured too and lost, see docs/auto.md; ``every_term``: all of them, the high-order model whose
    weights start from Steiglitz-McBride iterations, linear_start.py), weights on the free-running error (its
    screening fit too: least squares alone is the ARX model, biased in free run), no output clip (a linear
    model extrapolates in proportion)."""
    pool = pool_size(_regressors(ctx, L), 1, True)
    unbounded = {y: [None, None] for y in ctx.output_names}  # as bounds: null (kept as written: the candidate's key)
    params: dict[str, Any] = {"lags": _table(ctx, L), "degree": 1, "max_terms": pool, "initial": "settled"}
    if every_term:
        params["patience"] = None
    every = ", every term" if every_term else ""
    summary = f"linear output error settled at its first input: inputs 0..{L}, outputs 1..{L}{every}, no output clip"
    return _candidate(
        ctx, summary, {**params, "bounds": unbounded}, pool, pool, refined_screen=True, complexity=float(pool)
    )


def _own_output_error(ctx: SearchContext, L: int = 2) -> Candidate:
    """For several outputs: the linear output-error model in which each output follows its own past only,
    y_k(t) = c_k + sum_{i=1..L} a_{k,i} y_k(t-i) + sum_j sum_{m=0..L} b_{k,j,m} u_j(t-m) (a fixed structure:
    ``terms`` per output), settled at its first input, weights on the free run, no output clip. Every output
    at every lag in every equation lets least squares couple the outputs into a run that drifts: on a 6-input
    6-output joint-velocity plant (40 000 samples), the coupled linear model validated at 24.6 % NMSE with
    every term kept and refined, 62 % with FOS's terms; this one at 0.457 % (test 0.406 %)."""
    inputs = _model_inputs(ctx)
    lagged = [f"{u}[t]" if m == 0 else f"{u}[t-{m}]" for u in inputs for m in range(L + 1)]
    terms = {y: ["1", *lagged, *(f"{y}[t-{i}]" for i in range(1, L + 1))] for y in ctx.output_names}
    each = 1 + len(lagged) + L
    cand = _candidate(
        ctx,
        f"linear output error, each output on its own past: inputs 0..{L}, own output 1..{L}, no output clip",
        {"terms": terms, "initial": "settled", "bounds": {y: [None, None] for y in ctx.output_names}},
        each,
        each,
        refined_screen=True,
        complexity=float(each * ctx.n_outputs),
    )
    # the outputs' weights are refined together: measured 2.7 - 3.2 x the plan of one output's at a time (6
    # outputs, 24 000 training samples: 67 s and 154 s for orders 2 and 4, planned 21 and 57)
    return replace(cand, work=(cand.work or 0.0) * max(1.0, ctx.n_outputs / 2))


def _after_dead_times(ctx: SearchContext, pool: int, terms: int) -> Candidate:
    """The default's pool with each input's lags starting at its dead time (``ctx.dead_times``): inputs d .. d + L,
    outputs 1 .. L, the degree chosen on validation. The default's lags 0 .. L (L <= 6) never reach an input
    that acts 25 samples later (a generated plant: the NARX default 0.80 % test NMSE; the search, from this
    candidate grown, 0.00042 %)."""
    L = _max_lag(ctx, 3, 600, 6)
    delays = {u: ctx.dead_times.get(u, 0) for u in _model_inputs(ctx)}
    table: dict[str, list[dict[str, int]]] = {u: [{"from": d, "to": d + L}] for u, d in delays.items()}
    table.update({y: [{"from": 1, "to": L}] for y in ctx.output_names})
    shown = ", ".join(f"{u} {d}..{d + L}" for u, d in delays.items() if d)
    return _candidate(
        ctx,
        f"lags from the dead time: inputs {shown}, outputs 1..{L}, degree chosen on validation",
        {"lags": table, **_initial(ctx, L + max(delays.values()))},
        pool,
        terms,
    )


def starting(ctx: SearchContext) -> list[Candidate]:
    out = []
    zeros = {} if ctx.max_warmup != 0 else {"initial": "zeros"}
    pool6 = pool_size(_regressors(ctx, _max_lag(ctx, 3, 600, 6)), 3, True)
    expected_terms = min(60, max(10, ctx.n_train // 400))
    out.append(
        _candidate(ctx, "lags and degree chosen on validation (the default)", dict(zeros), pool6, expected_terms)
    )
    cap = max(4, min(15, 3 * (len(_model_inputs(ctx)) + ctx.n_outputs) + 2))
    if ctx.excursion > 0.05 or ctx.small:
        out.append(
            _candidate(
                ctx,
                f"lags and degree chosen on validation, at most {cap} terms (gentler beyond the training data)",
                {"max_terms": cap, **zeros},
                pool6,
                cap,
                complexity=float(cap),
            )
        )
    L2 = _max_lag(ctx, 2, 300, 12)
    pool2 = pool_size(_regressors(ctx, L2), 2, True)
    out.append(
        _candidate(
            ctx,
            f"degree 2, inputs 0..{L2} and outputs 1..{L2} (a longer memory)",
            {"lags": _table(ctx, L2), "degree": 2, **_initial(ctx, L2)},
            pool2,
            min(40, pool2),
        )
    )
    L1 = _max_lag(ctx, 1, 60, 20)
    pool1 = pool_size(_regressors(ctx, L1), 1, True)
    out.append(
        _candidate(
            ctx,
            f"linear: inputs 0..{L1}, outputs 1..{L1}",
            {"lags": _table(ctx, L1), "degree": 1, **_initial(ctx, L1)},
            pool1,
            pool1,
            complexity=float(pool1),
        )
    )
    out.append(_output_error(ctx))
    if ctx.n_outputs > 1:
        out.append(_own_output_error(ctx))
    pool_oe = pool_size(_regressors(ctx, _OE_ORDER), 1, True)
    if ctx.n_outputs == 1 and ctx.n_train >= 20 * pool_oe:
        out.append(_output_error(ctx, _OE_ORDER, every_term=True))
    for derived in (ctx.direction_inputs(), ctx.sign_inputs()):  # friction: what the force switches or relaxes on
        if derived:
            out.append(
                _candidate(
                    ctx,
                    "lags and degree chosen on validation" + data_summary({"derived_inputs": derived}),
                    dict(zeros),
                    pool6,
                    expected_terms,
                    data={"derived_inputs": derived},
                )
            )
    if ctx.dead_times:
        out.append(_after_dead_times(ctx, pool6, expected_terms))
    if ctx.excursion <= 0.05 and not ctx.small:
        out.append(
            _candidate(
                ctx,
                f"lags and degree chosen on validation, at most {cap} terms",
                {"max_terms": cap, **zeros},
                pool6,
                cap,
                complexity=float(cap),
            )
        )
    return out


def _chosen(fitted: Any) -> tuple[dict[str, list[int]] | None, int | None, int | None]:
    """(lag table, degree, terms per output) the fitted model chose; Nones when unknown."""
    if fitted is None or not hasattr(fitted, "embedding_"):
        return None, None, None
    table: dict[str, list[int]] = {}
    for r in fitted.embedding_.regressors:
        table.setdefault(r.name, []).append(int(r.lag))
    degree = None
    try:
        degree = int(max(int(e.sum()) for e in fitted.exponents_))
    except (AttributeError, ValueError):
        degree = None
    sel = getattr(fitted, "selection_", {}) or {}
    if sel.get("degree") is not None:
        degree = int(sel["degree"])
    terms = None
    try:
        terms = max(len(t) for t in fitted.terms_)
    except (AttributeError, ValueError):
        terms = None
    return table, degree, terms


def neighbours(ctx: SearchContext, found: Found) -> list[Candidate]:
    fixed_terms = found.candidate.params.get("terms")
    if fixed_terms:  # a fixed structure, each output on its own past (1 + m (L + 1) + L terms): two more lags only
        m = len(_model_inputs(ctx))
        order = (len(fixed_terms[ctx.output_names[0]]) - 1 - m) // (m + 1)
        return [_own_output_error(ctx, order + 2)] if ctx.n_outputs > 1 else []
    table, degree, terms = _chosen(found.fitted)
    if table is None or degree is None:
        return []
    p = dict(found.candidate.params)
    base = {k: v for k, v in p.items() if k in ("initial", "bounds", "ridge")}
    L = max(max(v) for v in table.values())
    compact = {k: [{"from": min(v), "to": max(v)}] for k, v in table.items()}
    regs = sum(len(v) for v in table.values())
    out = []

    data = found.candidate.data  # its data-side extensions (derived inputs): the lags name them
    on = data_summary(data)

    def add(
        summary: str,
        params: dict[str, Any],
        pool: int,
        k: int,
        complexity: float | None = None,
        refined_screen: bool = False,
    ) -> None:
        out.append(_candidate(ctx, summary + on, params, pool, k, refined_screen, complexity=complexity, data=data))

    k = terms or 10
    fixed = {"lags": compact, "degree": degree, **base}
    pool = pool_size(regs, degree, True)
    # more lags (the same degree), while the pool stays within 3000 monomials
    longer = {name: [{"from": min(v), "to": max(v) + 2}] for name, v in table.items()}
    pool_longer = pool_size(regs + 2 * len(table), degree, True)
    if pool_longer <= 3000 and ctx.allows_warmup(L + 2):
        add(f"degree {degree}, lags up to {L + 2} (two more)", {**fixed, "lags": longer}, pool_longer, k)
    if degree < 4 and pool_size(regs, degree + 1, True) <= 3000:
        add(
            f"degree {degree + 1} on lags up to {L}",
            {**fixed, "degree": degree + 1},
            pool_size(regs, degree + 1, True),
            k,
        )
    for m in sorted({max(2, k // 2), min(2 * k, pool)}):
        if m != k:
            add(
                f"degree {degree}, lags up to {L}, at most {m} terms (was {k})",
                {**fixed, "max_terms": m},
                pool,
                m,
                complexity=float(m),
            )
    for m in sorted({(3 * k) // 2, 2 * k}):
        # every one of m terms kept (no validation stop): the size is chosen on the refined free run, not on the
        # least-squares one that stopped the growth (EMPS, 8 terms grown: 0.084 % validation NMSE; 12 kept and
        # refined: 0.021 %). Small models only, as the free-run growth below: on Silverbox (84 terms) 126 kept
        # validated within the tie of the ridge model and took the arrow's extrapolation from 0.55 to 1.1 mV
        if k < m <= pool and k <= KEPT_UP_TO:
            add(
                f"degree {degree}, lags up to {L}, all {m} terms kept (was {k})",
                {**fixed, "max_terms": m, "patience": None},
                pool,
                m,
                complexity=float(m),
                refined_screen=True,  # least squares: 0.119 %, refined: 0.021 %
            )
    if p.get("bounds") != 0.0:
        add(
            f"degree {degree}, lags up to {L}, output clipped at the training range (a saturating output)",
            {**fixed, "bounds": 0.0},
            pool,
            k,
        )
    if p.get("ridge") is None:
        add(
            f"degree {degree}, lags up to {L}, ridge weights (factor chosen on validation)",
            {**fixed, "ridge": "auto"},
            pool,
            k,
        )
    if k <= 40:
        # the growth starts from the linear model that validates best (up to every linear term), and re-estimates
        # every term on the free run at each step: a 2x2 system on lags 0..14 took 26 s per fit, planned 0.54 s
        started = max(k, min(regs + 1, pool))
        window = min(ctx.n_train, GROWTH_WINDOW)
        grow, _ = _work(ctx, pool, started, window)
        whole, _ = _work(ctx, pool, k)
        # the growth's plan is its expected size (it stops near the terms it starts from), its bound a count of
        # operations worth GROWTH_CAP of the budget: a growth that runs on stops there, the same on any machine
        cap = GROWTH_CAP * ctx.budget
        work = round(cap / (_GROWTH_OP_COST * max(window, 1)) / 1e6, 3)
        out.append(
            Candidate(
                family=NAME,
                params={**fixed, "selection": "free_run", "growth_window": GROWTH_WINDOW, "growth_work": work},
                summary=f"degree {degree}, lags up to {L}, terms selected on the free-running error{on}",
                cost="mse_inf",
                data=data,
                # every growth step re-estimates the weights on the free run (on the growth window), then once
                # more on the whole training split
                work=min(max(2.0, k / 2) * grow, cap) + (whole if ctx.n_train > GROWTH_WINDOW else 0.0),
                stochastic=False,
            )
        )
    return out


def full_work(ctx: SearchContext, found: Found) -> float | None:
    """The full fit's seconds from the screening fit's size: the pool of the lags and degree it chose and the terms
    it kept (a starting candidate guesses its terms: the longer memory at degree 2 guessed 40 on three recordings
    of 50k samples, its screening fits kept about 170 and each full fold took minutes). None for the free-run
    selection, whose estimate counts its growth, and when the fit was not kept."""
    if found.candidate.params.get("selection") == "free_run":
        return None
    table, degree, terms = _chosen(found.fitted)
    if table is None or degree is None or terms is None:
        return None
    full, _ = _work(ctx, pool_size(sum(len(v) for v in table.values()), degree, True), terms)
    return full


def search_space(ctx: SearchContext, around: Found | None = None) -> list[Candidate]:
    if around is None:
        return starting(ctx)
    return neighbours(ctx, around)
