"""Human-readable tables of a reliability report (rich, stdout)."""

from __future__ import annotations

import numpy as np
from rich.console import Console
from rich.table import Table

from .check import Report
from .verdict import describe_level

_STYLE = {"reliable": "bold green", "unreliable": "bold red", "inconclusive": "bold yellow"}
MAX_LEVEL_ROWS = 8
_RANK = {"converged": 0, "slow": 1, "close": 2, "apart": 3, "diverged": 4}


def _by_base(signals):
    """Signals grouped by what they are (the starts / phases of one input together), in order."""
    groups: dict[str, list] = {}
    for s in signals:
        groups.setdefault(s.base, []).append(s)
    return list(groups.items())


def _g(v: float | None, digits: int = 3) -> str:
    if v is None:
        return "-"
    if not np.isfinite(v):
        return str(v)
    return f"{v:.{digits}g}"


def _header(r: Report) -> str:
    s = r.system
    rng = ", ".join(f"{n} in [{lo:.4g}, {hi:.4g}]" for n, lo, hi in zip(s["inputs"], s["input_low"], s["input_high"]))
    kind = f"flow sampled every {r.sampling_time:g}" if r.continuous else "map"
    return (
        f"[bold]{s['name']}[/]: {s['description']}\n"
        f"{s['state_dim']} state variables ({kind}); {rng}\n"
        f"{r.settings.replicas} replicas x {len(r.signals)} test inputs x {r.length} steps; "
        f"{len(r.levels)} constant inputs x {r.settings.scan_replicas} replicas; seed {r.settings.seed}; "
        f"{r.timing.get('total', 0.0):.1f} s"
    )


def render(r: Report, console: Console) -> None:
    console.print(_header(r))
    unit = "time unit" if r.continuous else "step"
    per = 1.0 / r.sampling_time if r.continuous else 1.0
    if r.evidence or r.closed_loop:
        t = Table(title="algebraic evidence (eq. 4.51, 5.24)", title_justify="left")
        for c in ("quantity", "value", "implies", "why"):
            t.add_column(c, justify="right" if c == "value" else "left")
        for e in r.evidence + r.closed_loop:
            t.add_row(e.name, _g(e.value, 4), e.implies, e.statement)
        console.print(t)

    t = Table(
        title=f"replica test (def. 4.4): {r.settings.replicas} initial states per input; distance: largest "
        f"between them at the end; settled: all within {r.tolerance:.3g}",
        title_justify="left",
    )
    t.add_column("input (x starts)")
    t.add_column("distance", justify="right")
    t.add_column("settled after", justify="right")
    t.add_column(f"CLE/{unit}", justify="right")
    t.add_column("status")
    for base, group in _by_base(r.signals):
        dist = max(s.final_distance for s in group)
        afters = [s.converged_after for s in group if s.converged_after is not None]
        after = "-"
        if len(afters) == len(group):
            after = f"{max(afters)} ({max(afters) * r.sampling_time:.4g})" if r.continuous else str(max(afters))
        lams = [r.exponents[s.name].largest * per for s in group if s.name in r.exponents]
        worst = max(group, key=lambda s: _RANK[s.status])
        count = sum(s.status == worst.status for s in group)
        status = worst.status if worst.status != "slow" else f"slow (~{worst.steps_needed} steps)"
        if len(group) > 1:
            status += f" ({count}/{len(group)})"
        style = {"apart": "red", "diverged": "red", "slow": "yellow", "close": "yellow"}.get(worst.status, "")
        label = base if len(group) == 1 else f"{base} x{len(group)}"
        t.add_row(
            label, _g(dist), str(after), _g(max(lams)) if lams else "-", f"[{style}]{status}[/]" if style else status
        )
    console.print(t)
    for f in r.families:
        console.print(
            f"same tail, different start phase (fig. 5.5): final states {_g(f.final_distance)} apart -> {f.status}"
        )

    bad = sorted(
        [lv for lv in r.levels if lv.status != "fixed point"],
        key=lambda lv: (not np.all(lv.input == 0), -len(lv.attractors), -lv.responses),
    )
    t = Table(
        title=f"constant-input scan (eq. 4.39): {r.settings.scan_replicas} initial states per level",
        title_justify="left",
    )
    t.add_column("responses", justify="right")
    t.add_column("what the replicas reach")
    shown = bad[:MAX_LEVEL_ROWS]
    for lv in shown:
        style = "yellow" if lv.status == "not settled" else "red"
        t.add_row(f"[{style}]{lv.responses}[/]", describe_level(lv, r.input_names))
    good = len(r.levels) - len(bad)
    if good:
        fps = [lv for lv in r.levels if lv.status == "fixed point"]
        t.add_row(
            "1",
            f"{good} of {len(r.levels)} levels settle on one fixed point "
            f"(e.g. {describe_level(fps[0], r.input_names)})",
        )
    if len(bad) > len(shown):
        t.add_row("...", f"{len(bad) - len(shown)} more levels without a single fixed point (see --json)")
    console.print(t)

    if r.closed_loop or r.tune_in is not None:
        console.print(
            "[bold]external mode[/]: the closed loop (output fed back) is not reliable by construction "
            "(5.3.2); the verdict is for the open loop driven by input and output."
        )
        if r.tune_in is not None:
            ti = r.tune_in
            if ti.required is None:
                console.print(f"tune-in: [red]{ti.note}[/]")
            else:
                ok = ti.required <= ti.configured
                console.print(
                    f"tune-in: free runs from {ti.replicas} initial states agree within {ti.tolerance:g} "
                    f"of the output range once tuned in on [bold]{ti.required}[/] measured samples; "
                    f"the model uses {ti.configured} "
                    + ("[green](enough)[/]" if ok else "[red](too few: raise tune_in)[/]")
                )
    for note in r.notes:
        console.print(f"note: {note}", markup=False)

    v = r.verdict
    console.print(f"verdict: [{_STYLE[v.verdict]}]{v.verdict.upper()}[/]")
    for reason in v.reasons:
        console.print(f"  - {reason}", markup=False)
    if v.verdict == "inconclusive" and r.length_needed:
        console.print(f"rerun with --length {r.length_needed} (or more) to let the slow tests settle")
    if r.washout is not None and v.verdict == "reliable":
        extra = f" ({r.washout * r.sampling_time:.4g} time units)" if r.continuous else ""
        console.print(
            f"washout: discard the first {r.washout} samples{extra} of a run (replicas agree within "
            f"{r.tolerance:.3g} after that on every test input)"
        )
