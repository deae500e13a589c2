"""The terminal view of a diagnosis: per round, every check with the gates that name it or not (p against
alpha, share against min_share, effect against min_effect, detector-specific gates), the extension chosen
and its gain, then the total gain on the test split."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .gain import test_key
from .runner import Diagnosis, Round, fitted_family


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _p(g: dict[str, Any]) -> str:
    p = g.get("p_value")
    if p is None:
        return "-"
    return "<1e-16" if p < 1e-16 else f"{p:.2g}"


def checks_table(rnd: Round, title: str) -> Table:
    table = Table(title=title, title_justify="left")
    columns: tuple[tuple[str, dict[str, Any]], ...] = (
        ("cause", {}),
        ("named", {}),
        ("score", {"justify": "right"}),
        ("p", {"justify": "right"}),
        ("effect", {"justify": "right"}),
        ("why (not) named", {"overflow": "fold"}),
    )
    for col, kw in columns:
        table.add_column(col, **kw)
    for f in rnd.findings:
        g = f.gates
        table.add_row(
            f.cause,
            "yes" if f.significant else "",
            f"{f.score:.3g}",
            _p(g),
            "-" if g.get("effect") is None else f"{g['effect']:.2g}",
            escape(f.reason or ""),
        )
    return table


def print_diagnosis(result: Diagnosis, out: Console, metrics_table) -> None:
    base = result.baseline
    s = result.settings
    out.print(
        f"[bold]{result.name}[/]: {fitted_family(base)} (cost {base.model.spec.get('cost') or base.spec.cost}) "
        "diagnosed in "
        f"{result.seconds:.1f} s, {len(result.rounds)} round(s); model memory {result.rounds[0].memory} samples"
    )
    out.print(metrics_table(base.metrics, "baseline free run"))
    ref = (result.reference or {}).get("linear")
    if ref:
        nmse = ", ".join(f"{k} {_fmt(v)} %" for k, v in ref["nmse"].items())
        out.print(
            f"adequacy reference: linear {ref['method']} (output lags 1..{ref['output_order']}, input lags "
            f"0..{ref['input_order'] - 1}): NMSE {nmse}",
            markup=False,
        )
    out.print(
        f"a cause is named when p < alpha {s.alpha:g}, share >= min_share {s.min_share:g} (of the residual's mean "
        f"square) and effect >= min_effect {s.min_effect:g} (of the output variance), and its own gates pass",
        markup=False,
    )
    for rnd in result.rounds:
        split = rnd.split
        nm = rnd.fit.nmse(split)
        title = (
            f"round {rnd.index}: checks of the {'baseline' if rnd.index == 1 else 'extended model'} "
            f"({split} NMSE {_fmt(nm)} %), named first, by score"
        )
        out.print(checks_table(rnd, title))
        for i, f in enumerate(rnd.significant, 1):
            out.print(f"  {i}. [bold]{f.cause}[/]: {escape(f.summary)}")
        if rnd.chosen is not None and rnd.chosen.fit is not None:
            round_gain = rnd.gain()
            test = (
                f"; test NMSE {_fmt(round_gain['test_nmse_before'])} -> {_fmt(round_gain['test_nmse_after'])} %"
                if round_gain.get("test_nmse_before") is not None or round_gain.get("test_nmse_after") is not None
                else ""
            )
            verdict = "applied" if rnd.accepted else "not applied"
            out.print(
                f"round {rnd.index}: {len(rnd.candidates)} extension(s) measured; best for {rnd.chosen.cause}: "
                f"{escape(rnd.chosen.extension.summary)} ({verdict}): {escape(rnd.outcome)}{test}"
            )
        else:
            out.print(f"round {rnd.index}: {escape(rnd.outcome)}")
    if not result.findings and len(result.rounds) == 1:
        out.print(
            "[green]adequate[/]: no cause is significant, no reference does significantly better; nothing to extend"
        )
        return
    named: list[tuple[int, str]] = []
    for i, c in result.named:
        if c not in [n for _, n in named]:
            named.append((i, c))
    if result.findings:
        out.print(f"named cause: [bold]{result.findings[0].cause}[/]")
    out.print("causes named: " + ", ".join(f"{c} (round {i})" for i, c in named))
    g = result.gain
    if g:
        before = g.get("test_nmse_before")
        after = g.get("test_nmse_after")
        red = g.get("relative_reduction")
        unc: dict[str, Any] = g.get("uncertainty") or {}
        if "per_output" in unc:
            unc = unc["per_output"][0]
        rr = unc.get("relative_reduction") or {}
        spread = f" ± {100 * rr['std']:.1f} %" if rr.get("std") is not None else ""

        def shown(v, diverged):
            return "diverged" if diverged else f"{_fmt(v)} %"

        rmse = ""
        tb, ta = (
            (base.metrics.get(test_key(base.metrics) or "test") or {}).get("rmse"),
            ((result.final.metrics if result.final else {}).get(test_key(base.metrics) or "test") or {}).get("rmse"),
        )
        if tb and ta:
            rmse = f"; test RMSE {_fmt(tb)} -> {_fmt(ta)} ({tb / ta:.3g} x lower)"
        out.print(
            f"total: test NMSE {shown(before, g.get('baseline_diverged_on_test'))} -> "
            f"{shown(after, g.get('extended_diverged_on_test'))}"
            + (f" (reduction {100 * red:.1f} %{spread})" if red is not None else "")
            + f"; test MAX {_fmt(g.get('test_max_before'))} -> {_fmt(g.get('test_max_after'))}"
            + rmse
        )
