"""How the `narx` family extends itself for a diagnosed cause (the ``Family.extensions`` hook,
docs/plugins-extensions.md), and how it takes new input channels (``Family.include_inputs``).

Capacity moves stay inside the monomial pool limit (``max_pool``): a higher degree (static or output
nonlinearity, thesis 3.1), more lags (missing dynamics; spread as ranges when the full lag list would
overflow the pool), output feedback (a recursive model remembers the whole input history), short delays
for an oscillation (about a quarter to half its period, thesis 6.3.2), more terms (a selection that
stopped early), and the stabilisers of thesis 3.1.4 / 6.3.2 (terms selected on the free-running error,
bounds, eq. 6.25, ridge regression, a lower degree). When another family is diagnosed, narx offers to
replace it by a polynomial on the lags of the diagnosis' linear reference, estimated on the free-running
error.
"""

from __future__ import annotations

import math
from typing import Any

from dynmodel.extensions import Extension, ExtensionContext, merge_patches, params_patch, switch_family

from .embedding import default_lag_table, pool_size

#: output lags of a proposal that feeds the past output back into a model without feedback
FEEDBACK_LAGS = (1, 2)

NAME = "narx"
MAX_ORDER = 40  # at most this many lags per column from a lag-order proposal


def expand(items: list[Any]) -> list[int]:
    """Lags of a resolved lag list (integers and {from, to, step} ranges)."""
    out: set[int] = set()
    for item in items:
        if isinstance(item, dict):
            out.update(range(int(item["from"]), int(item["to"]) + 1, int(item.get("step", 1))))
        else:
            out.add(int(item))
    return sorted(out)


def lag_table(ctx: ExtensionContext) -> dict[str, list[int]]:
    """Regressor lags per column; the family's default table written out when the spec gives none."""
    lags = ctx.params.get("lags")
    if lags is not None:
        return {name: expand(items) for name, items in lags.items()}
    emb = getattr(ctx.fitted, "embedding_", None)
    if emb is not None:  # lags chosen on the data (lags: null): the table the fitted model uses
        fitted: dict[str, list[int]] = {}
        for r in emb.regressors:
            fitted.setdefault(r.name, []).append(r.lag)
        return fitted
    return default_lag_table(
        list(ctx.model_input_names),
        list(ctx.output_names),
        _degree(ctx),
        bool(ctx.params.get("constant", True)),
        _linear_inputs(ctx),
    )


def _degree(ctx: ExtensionContext) -> int:
    """The polynomial degree: the spec's, or the one chosen on the data (``degree: null``: the fitted
    model's, else the largest the default search tries)."""
    chosen = (getattr(ctx.fitted, "selection_", None) or {}).get("degree")
    return int(ctx.params.get("degree") or chosen or 3)


def _compact(lags: list[int]) -> list[Any]:
    """A lag list, a long evenly spaced run written as a range."""
    lags = sorted(set(lags))
    if len(lags) > 4:
        step = lags[1] - lags[0]
        if step > 0 and all(b - a == step for a, b in zip(lags, lags[1:])):
            return [{"from": lags[0], "to": lags[-1], "step": step}]
    return lags


def lags_patch(table: dict[str, list[int]]) -> dict[str, Any]:
    return params_patch(lags={k: _compact(v) for k, v in table.items() if v})


def _linear_inputs(ctx: ExtensionContext) -> bool:
    """Do the inputs enter only as linear terms (``input_terms: linear``)?"""
    return ctx.params.get("input_terms") == "linear"


def _pool(ctx: ExtensionContext, table: dict[str, list[int]], degree: int | None = None) -> int:
    degree = _degree(ctx) if degree is None else degree
    inputs = set(ctx.model_input_names) | set(ctx.input_names)
    linear = sum(len(v) for k, v in table.items() if k in inputs) if _linear_inputs(ctx) else 0
    return pool_size(sum(len(v) for v in table.values()), degree, bool(ctx.params.get("constant", True)), linear)


def _fits(ctx: ExtensionContext, table: dict[str, list[int]], degree: int | None = None) -> bool:
    return _pool(ctx, table, degree) <= int(ctx.params.get("max_pool", 3000))


def _free_params(ctx: ExtensionContext) -> bool:
    """May the family choose the terms (no fixed ``terms`` list)?"""
    return ctx.params.get("terms") is None


def _terms_fitted(ctx: ExtensionContext) -> int | None:
    fitted = ctx.fitted
    if fitted is None or not hasattr(fitted, "terms_"):
        return None
    try:
        return max(len(t) for t in fitted.terms_)
    except (AttributeError, ValueError):
        return None


def _spread(first: int, order: int, room) -> list[int] | None:
    """Lags first..order, thinned (every 2nd, 4th, ...) until ``room(lags)`` accepts them."""
    step = 1
    while step <= max(order, 1):
        lags = list(range(first, order + 1, step))
        if lags and lags[-1] != order:
            lags.append(order)
        if room(lags):
            return lags
        step *= 2
    return None


# ---------------------------------------------------------------------------------------- per cause
def _stabilizers(ctx: ExtensionContext) -> list[Extension]:
    p = ctx.params
    out = []
    if p.get("selection", "one_step") == "one_step" and _free_params(ctx):
        out.append(
            Extension(
                "select the terms on the free-running error (selection: free_run, cost: mse_inf): a structure "
                "chosen one step ahead need not work in free run (thesis 3.1.4)",
                merge_patches({"cost": "mse_inf"}, params_patch(selection="free_run")),
            )
        )
    if p.get("bounds") is None:
        out.append(
            Extension(
                "clip the free-running output to the training range widened by 10 % (eq. 6.25)",
                params_patch(bounds=0.1),
            )
        )
    if p.get("ridge") is None and p.get("selection") != "free_run":
        out.append(
            Extension(
                "ridge regression of the weights, factor chosen on validation (thesis 6.3.2)",
                params_patch(ridge="auto"),
            )
        )
    degree = _degree(ctx)
    if degree > 2 and _free_params(ctx):
        out.append(
            Extension(
                f"a lower polynomial degree ({degree - 2}, was {degree}): smaller models are often the stable ones "
                "(thesis 3.1.4)",
                params_patch(degree=degree - 2),
            )
        )
    return out


def _higher_degree(ctx: ExtensionContext, steps: tuple[int, ...]) -> list[Extension]:
    degree = _degree(ctx)
    table = lag_table(ctx)
    out = []
    for d in (degree + s for s in steps):
        if d <= 10 and _fits(ctx, table, d):
            out.append(Extension(f"polynomial degree {d} (was {degree})", params_patch(degree=d)))
    return out


def _input_monomials(ctx: ExtensionContext) -> list[Extension]:
    """Inputs that entered only linearly (``input_terms: linear``) in every monomial of the degree."""
    if not _linear_inputs(ctx) or not _free_params(ctx):
        return []
    table = lag_table(ctx)
    degree = _degree(ctx)
    if pool_size(sum(len(v) for v in table.values()), degree, bool(ctx.params.get("constant", True))) > int(
        ctx.params.get("max_pool", 3000)
    ):
        return []
    return [
        Extension(
            f"the inputs in every monomial of degree {degree} (input_terms: any, was linear): a static "
            "nonlinearity of the input",
            params_patch(input_terms="any"),
        )
    ]


def _output_terms(ctx: ExtensionContext) -> list[Extension]:
    """Degree + 1 with one more output lag: output-dependent terms (a stiffness or a saturation acting on
    the output needs the output's own history in the monomials)."""
    degree = _degree(ctx)
    table = lag_table(ctx)
    outputs = [y for y in ctx.output_names if table.get(y)]
    if not outputs or degree + 1 > 10:
        return []
    for y in outputs:
        table[y] = sorted(set(table[y]) | {max(table[y]) + 1})
    if not _fits(ctx, table, degree + 1):
        return []
    lags = {y: table[y] for y in outputs}
    return [
        Extension(
            f"output-dependent terms: polynomial degree {degree + 1} (was {degree}) with output lags {lags}",
            merge_patches(lags_patch(table), params_patch(degree=degree + 1)),
        )
    ]


def _output_feedback(ctx: ExtensionContext, why: str) -> list[Extension]:
    table = lag_table(ctx)
    if any(table.get(y) for y in ctx.output_names):
        return []
    for y in ctx.output_names:
        table[y] = list(FEEDBACK_LAGS)
    if not _fits(ctx, table):
        return []
    lags = list(FEEDBACK_LAGS)
    return [Extension(f"feed the past output back (output lags {lags}): {why}", lags_patch(table))]


def _more_lags(ctx: ExtensionContext, order: int, why: str) -> list[Extension]:
    """Input lags 0..order and output lags 1..order (spread when the full lists overflow the pool)."""
    order = int(min(max(order, 1), MAX_ORDER))
    table = lag_table(ctx)
    inputs = [u for u in ctx.input_names if u in table] or list(ctx.input_names)
    outputs = list(ctx.output_names)

    def room(lags: list[int]) -> bool:
        trial = dict(table)
        for u in inputs:
            trial[u] = sorted(set(table.get(u, [])) | set([0] + lags))
        for y in outputs:
            trial[y] = sorted(set(table.get(y, [])) | {x for x in lags if x >= 1})
        return _fits(ctx, trial)

    lags = _spread(1, order, room)
    if lags is None:
        return []
    before = {k: list(v) for k, v in table.items()}
    for u in inputs:
        table[u] = sorted(set(table.get(u, [])) | set([0] + lags))
    for y in outputs:
        table[y] = sorted(set(table.get(y, [])) | set(lags))
    if table == before:
        return []
    shown = f"1..{order}" if len(lags) == order else f"{lags}"
    return [Extension(f"longer lags: inputs 0 and {shown}, outputs {shown} ({why})", lags_patch(table))]


def _more_terms(ctx: ExtensionContext) -> list[Extension]:
    """A longer selection. (A merge patch cannot set ``patience`` to null: null deletes the key and the
    default returns. A patience as long as the term budget lets FOS run to ``max_terms`` and keep the size
    with the lowest validation error.)"""
    p = ctx.params
    if not _free_params(ctx):
        return []
    k = _terms_fitted(ctx)
    patience = p.get("patience")
    if p.get("selection", "one_step") == "free_run":
        now = int(patience or 1)
        return [
            Extension(
                f"keep selecting: patience {now + 4} (was {now}) terms without a lower free-running validation error",
                params_patch(patience=now + 4),
            )
        ]
    target = max(2 * k, k + 6) if k else 20
    if p.get("max_terms") is not None:
        target = max(target, 2 * int(p["max_terms"]))
    target = min(target, _pool(ctx, lag_table(ctx)))
    if k is not None and target <= k:
        return []
    return [
        Extension(
            f"more terms: FOS runs on to {target} terms per output and keeps the size with the lowest validation "
            f"error (max_terms {target}, patience {target})" + (f"; the selection had stopped at {k}" if k else ""),
            params_patch(max_terms=target, patience=target, threshold=None),
        )
    ]


def _short_delays(ctx: ExtensionContext, period: float) -> list[Extension]:
    table = lag_table(ctx)
    q = int(min(max(2, math.ceil(period / 2)), 12))
    for u in ctx.input_names:
        if u in table or ctx.params.get("lags") is None:
            table[u] = sorted(set(table.get(u, [])) | set(range(0, q + 1)))
    for y in ctx.output_names:
        table[y] = sorted(set(table.get(y, [])) | set(range(1, 5)))
    if not _fits(ctx, table):
        return []
    return [
        Extension(
            f"short delays: input lags 0..{q}, output lags 1..4 (about half the {period:.3g}-sample period)",
            lags_patch(table),
        )
    ]


def _reference_lags(ctx: ExtensionContext) -> tuple[int, int] | None:
    ref = ctx.evidence.get("reference") or {}
    na, nb = ref.get("output_order"), ref.get("input_order")
    return (int(na), int(nb)) if na is not None and nb is not None else None


def _like_reference(ctx: ExtensionContext) -> list[Extension]:
    orders = _reference_lags(ctx)
    if orders is None:
        return []
    na, nb = orders
    table = lag_table(ctx)
    for u in ctx.input_names:
        table[u] = sorted(set(table.get(u, [])) | set(range(0, nb)))
    for y in ctx.output_names:
        table[y] = sorted(set(table.get(y, [])) | set(range(1, na + 1)))
    out = []
    if _fits(ctx, table):
        out.append(
            Extension(
                f"the linear reference's lags (inputs 0..{nb - 1}, outputs 1..{na}), estimated on the free-running "
                "error (cost: mse_inf)",
                merge_patches({"cost": "mse_inf"}, lags_patch(table)),
            )
        )
    return out


def extensions(cause: str, ctx: ExtensionContext) -> list[Extension]:
    """The narx family's proposals for ``cause`` (see the module docstring)."""
    if ctx.family != NAME:
        return _switch(cause, ctx)
    ev = ctx.evidence
    if cause == "free-run-instability":
        return _stabilizers(ctx)
    if cause == "noise-bias":
        if _free_params(ctx) and ctx.params.get("selection", "one_step") != "free_run":
            return [
                Extension(
                    "select the terms on the free-running error too (selection: free_run, cost: mse_inf)",
                    merge_patches({"cost": "mse_inf"}, params_patch(selection="free_run")),
                )
            ]
        return []
    if cause == "static-nonlinearity":
        return _input_monomials(ctx) + _higher_degree(ctx, (2, 1))
    if cause == "output-nonlinearity":
        out = _higher_degree(ctx, (1,))
        out += _output_terms(ctx)
        out += _higher_degree(ctx, (2,))
        out += _output_feedback(ctx, "terms in the past output can form its nonlinearity")
        return out
    if cause == "missing-dynamics":
        order = int(ev.get("order") or 2 * max(max(lag_table(ctx).get(y) or [2]) for y in ctx.output_names))
        return _more_lags(ctx, order, "the residual is predictable from older samples") + _more_terms(ctx)
    if cause == "insufficient-memory":
        return _output_feedback(ctx, "a recursive model remembers the whole input history")
    if cause == "unmodeled-oscillation":
        period = ev.get("period_samples")
        return _short_delays(ctx, float(period)) if period and math.isfinite(period) else []
    if cause == "structure-stopped-early":
        return _more_terms(ctx)
    if cause == "inadequate-structure":
        out = _like_reference(ctx)
        out += _output_feedback(ctx, "a recursive model, like the linear reference")
        if ctx.cost != "mse_inf" and not out:
            out.append(Extension("estimate on the free-running error (cost: mse_inf)", {"cost": "mse_inf"}))
        return out
    return []


def _switch(cause: str, ctx: ExtensionContext) -> list[Extension]:
    """Proposals to replace another family by a narx model: for a structure a linear reference beats."""
    if cause != "inadequate-structure":
        return []
    orders = _reference_lags(ctx)
    if orders is None:
        return []
    na, nb = orders
    lags = {u: list(range(0, nb)) for u in ctx.model_input_names}
    lags.update({y: list(range(1, na + 1)) for y in ctx.output_names})
    params = {"lags": {k: _compact(v) for k, v in lags.items()}, "degree": 2}
    if pool_size(sum(len(v) for v in lags.values()), 2, True) > 3000:
        return []
    return [
        Extension(
            f"a polynomial NARX model (degree 2) on the linear reference's lags (inputs 0..{nb - 1}, outputs "
            f"1..{na}), estimated on the free-running error",
            switch_family(ctx, NAME, params, cost="mse_inf"),
        )
    ]


def include_inputs(channels: list[str], history: int, ctx: ExtensionContext) -> dict[str, Any]:
    """New model-input channels enter the lag table with lags 0..history (the default table written out
    when the spec relied on it)."""
    table = lag_table(ctx)
    for name in channels:
        table[name] = list(range(0, int(history) + 1))
    return lags_patch(table)
