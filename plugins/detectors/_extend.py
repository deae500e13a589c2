"""How the built-in families spell the extensions the detectors propose, as merge patches of the spec.

Data-level changes (delay lines, derived inputs, detrending, the cost) work for every family: new
model-input channels reach a network through its input weights and direct readout links. A
polynomial NARX model only uses the columns its ``lags`` table names, so new channels are added
to the table (written out in full when the spec relied on the default table). Capacity changes
(degree, lags, network size, leaky elements, rescaling) are family specific; for a family not
listed here only the data-level extensions are offered.
"""

from __future__ import annotations

import math
from typing import Any

from dynmodel.data.derived import channel_name
from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Extension

NARX = "narx"
NETWORKS = ("esn", "annealed-rnn")
DEFAULT_INPUT_LAGS = [0, 1, 2]
DEFAULT_OUTPUT_LAGS = [1, 2]


def params_patch(**params: Any) -> dict[str, Any]:
    return {"model": {"params": params}}


def expand(items: list[Any]) -> list[int]:
    """Lags of a resolved narx lag list (integers and {from, to, step} ranges)."""
    out: set[int] = set()
    for item in items:
        if isinstance(item, dict):
            out.update(range(int(item["from"]), int(item["to"]) + 1, int(item.get("step", 1))))
        else:
            out.add(int(item))
    return sorted(out)


def lag_table(ctx: Context) -> dict[str, list[int]]:
    """The narx model's regressors per column, the default table written out when none is given."""
    lags = ctx.params.get("lags")
    if lags is not None:
        return {name: expand(items) for name, items in lags.items()}
    emb = getattr(ctx.model.family, "embedding_", None)
    if emb is not None:  # the default table is chosen on the data: the one the fitted model uses
        fitted: dict[str, list[int]] = {}
        for r in emb.regressors:
            fitted.setdefault(r.name, []).append(r.lag)
        return fitted
    table = {name: list(DEFAULT_INPUT_LAGS) for name in ctx.model.preprocessor.model_input_names}
    table.update({name: list(DEFAULT_OUTPUT_LAGS) for name in ctx.output_names})
    return table


def narx_degree(ctx: Context) -> int:
    """The narx model's degree: the spec's, or the one chosen on the data (``degree: null``)."""
    chosen = (getattr(ctx.model.family, "selection_", None) or {}).get("degree")
    return int(ctx.params.get("degree") or chosen or 3)


def _compact(lags: list[int]) -> list[Any]:
    """A lag list, with a long evenly spaced run written as a range."""
    if len(lags) > 4:
        step = lags[1] - lags[0]
        if step > 0 and all(b - a == step for a, b in zip(lags, lags[1:])):
            return [{"from": lags[0], "to": lags[-1], "step": step}]
    return lags


def lags_patch(ctx: Context, table: dict[str, list[int]]) -> dict[str, Any]:
    return params_patch(lags={k: _compact(sorted(set(v))) for k, v in table.items()})


def with_inputs(
    ctx: Context, delay_lines: list[int] = (), derived: list[dict[str, Any]] = (), lags: list[int] | None = None
) -> dict[str, Any]:
    """Patch adding delay lines and derived inputs; a narx model gets ``lags`` (default [0, 1, 2]) of the
    new channels in its lag table."""
    data: dict[str, Any] = {}
    new_channels: list[str] = []
    old_delays = [int(d) for d in ctx.resolved["data"].get("delay_lines") or []]
    delays = [int(d) for d in delay_lines if int(d) not in old_delays]
    if delays:
        data["delay_lines"] = sorted(old_delays + delays)
        new_channels += [f"{u}@{d}" for d in delays for u in ctx.input_names]
    old_items = [
        {k: v for k, v in item.items() if v is not None} for item in ctx.resolved["data"].get("derived_inputs") or []
    ]
    names = {channel_name(item) for item in old_items}
    items = [item for item in derived if channel_name(item) not in names]
    if items:
        data["derived_inputs"] = old_items + list(items)
        new_channels += [channel_name(item) for item in items]
    patch: dict[str, Any] = {"data": data} if data else {}
    if ctx.family == NARX and new_channels:
        table = lag_table(ctx)
        for name in new_channels:
            table[name] = list(lags if lags is not None else DEFAULT_INPUT_LAGS)
        patch = merge_patches(patch, lags_patch(ctx, table))
    return patch


def merge_patches(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    out = dict(a)
    for k, v in b.items():
        out[k] = merge_patches(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def stabilizers(ctx: Context) -> list[Extension]:
    """Free-run stabilization (thesis 6.3.2): free-running estimation with error propagation, terms selected
    on the free-running error, output bounds (eq. 6.25), ridge; for feedback networks the internal mode."""
    out: list[Extension] = []
    cost = ctx.spec.cost
    if ctx.family == NARX:
        if cost != "mse_inf":
            out.append(
                Extension(
                    "estimate on the free-running error (cost: mse_inf; error propagation when the "
                    "least-squares model diverges, thesis 6.3.2)",
                    {"cost": "mse_inf"},
                )
            )
        if ctx.params.get("selection", "one_step") == "one_step" and ctx.params.get("terms") is None:
            out.append(
                Extension(
                    "select the terms on the free-running error (selection: free_run, cost: mse_inf): a "
                    "structure chosen one step ahead need not work in free run (thesis 3.1.4)",
                    merge_patches({"cost": "mse_inf"}, params_patch(selection="free_run")),
                )
            )
        if ctx.params.get("bounds") is None:
            out.append(
                Extension(
                    "clip the free-running output to the training range widened by 10 % (eq. 6.25)",
                    params_patch(bounds=0.1),
                )
            )
        if ctx.params.get("ridge") is None and ctx.params.get("selection") != "free_run":
            out.append(
                Extension(
                    "ridge regression of the weights, factor chosen on validation (thesis 6.3.2)",
                    params_patch(ridge="auto"),
                )
            )
        degree = narx_degree(ctx)
        if degree > 2 and ctx.params.get("terms") is None:
            out.append(
                Extension(
                    f"a lower polynomial degree ({degree - 2}, was {degree}): smaller models are often the "
                    "stable ones (thesis 3.1.4)",
                    params_patch(degree=degree - 2),
                )
            )
        return out
    if cost != "mse_inf":
        out.append(Extension("estimate on the free-running error (cost: mse_inf)", {"cost": "mse_inf"}))
    if ctx.family in NETWORKS and ctx.params.get("mode") == "external":
        out.append(
            Extension(
                "internal mode: a reliable network driven by the input only (thesis 5.3.2)",
                params_patch(mode="internal"),
            )
        )
    return out


def more_memory(ctx: Context, tau: int) -> list[Extension]:
    """Memory for input history of about ``tau`` samples: output feedback (narx without output lags),
    delay lines at tau and 2 tau (thesis 6.3.2), leaky elements for networks."""
    out: list[Extension] = []
    st = ctx.sampling_time
    if ctx.family == NARX:
        table = lag_table(ctx)
        if not any(table.get(y) for y in ctx.output_names):
            for y in ctx.output_names:
                table[y] = list(DEFAULT_OUTPUT_LAGS)
            out.append(
                Extension(
                    "feed the past output back (output lags [1, 2]): a recursive model remembers the "
                    "whole input history",
                    lags_patch(ctx, table),
                )
            )
    delays = sorted({max(1, int(tau)), max(2, 2 * int(tau))})
    out.append(
        Extension(
            f"delay lines at {delays} samples ({', '.join(f'{d * st:.4g}' for d in delays)} s): external "
            "memory of the input (thesis 6.3.2)",
            with_inputs(ctx, delay_lines=delays, lags=[0]),
        )
    )
    if ctx.family in NETWORKS:
        out.append(
            Extension(
                "leaky elements with relaxation drawn from [0.5, 0.99] (eq. 6.21): slower internal memory",
                params_patch(relaxation=[0.5, 0.99], relaxation_gain=True),
            )
        )
    return out


def more_nonlinearity(ctx: Context) -> list[Extension]:
    """Capacity for a static nonlinearity: a higher polynomial degree, a more strongly driven or larger network."""
    if ctx.family == NARX:
        degree = narx_degree(ctx)
        options = []
        for d in (degree + 2, degree + 1):
            if d <= 10 and _pool_size(ctx, d) <= int(ctx.params.get("max_pool", 3000)):
                options.append(Extension(f"polynomial degree {d} (was {degree})", params_patch(degree=d)))
        return options
    if ctx.family in NETWORKS:
        scale = float(ctx.params.get("input_scale", 1.0))
        size = int(ctx.params.get("size", 100))
        return [
            Extension(
                f"input weights twice as strong (input_scale {2 * scale:g}): the elements work further into "
                "their nonlinear range",
                params_patch(input_scale=2 * scale),
            ),
            Extension(f"a larger network ({2 * size} elements)", params_patch(size=2 * size)),
        ]
    return []


def _pool_size(ctx: Context, degree: int) -> int:
    k = sum(len(v) for v in lag_table(ctx).values())
    return math.comb(k + degree, degree)


def faster_dynamics(ctx: Context, period: float) -> list[Extension]:
    """For an oscillation of ``period`` samples: short delays of the input and the output (about a
    quarter to a half period, thesis 6.3.2), or a larger network with short delay lines."""
    if ctx.family == NARX:
        table = lag_table(ctx)
        q = int(min(max(2, math.ceil(period / 2)), 12))
        for u in ctx.model.preprocessor.model_input_names:
            if u in ctx.input_names:
                table[u] = sorted(set(table.get(u, [])) | set(range(0, q + 1)))
        for y in ctx.output_names:
            table[y] = sorted(set(table.get(y, [])) | set(range(1, 5)))
        return [
            Extension(
                f"short delays: input lags 0..{q}, output lags 1..4 (about half the {period:.3g}-sample period)",
                lags_patch(ctx, table),
            )
        ]
    out = []
    short = sorted({max(1, round(period / 4)), max(1, round(period / 2))})
    out.append(
        Extension(
            f"short-delay inputs: delay lines at {short} samples (a quarter and half of the "
            f"{period:.3g}-sample period)",
            with_inputs(ctx, delay_lines=short),
        )
    )
    if ctx.family in NETWORKS:
        size = int(ctx.params.get("size", 100))
        out.append(Extension(f"a larger network ({2 * size} elements)", params_patch(size=2 * size)))
    return out


def rescale(ctx: Context) -> list[Extension]:
    """Make a network reliable again: largest singular value 0.95 (eq. 4.51, thesis 5.3.1)."""
    if ctx.family == "esn":
        ext = [
            Extension(
                "rescale C to a largest singular value of 0.95 (reliable by eq. 4.51)",
                params_patch(scale={"by": "singular", "value": 0.95}),
            )
        ]
        if ctx.params.get("mode") == "external":
            ext.append(
                Extension(
                    "internal mode with C rescaled to a largest singular value of 0.95",
                    params_patch(mode="internal", scale={"by": "singular", "value": 0.95}),
                )
            )
        return ext
    if ctx.family == "annealed-rnn":
        return [
            Extension(
                "keep the largest singular value of C at 0.9 and the relaxation below 0.5",
                params_patch(max_singular=0.9, initial_singular=0.85, relaxation=[0.0, 0.5]),
            )
        ]
    return []
