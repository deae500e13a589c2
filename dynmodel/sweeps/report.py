"""The sweep's tables for a terminal (rich): points ranked by the validation free-run error, the seed
summary per configuration, the best point and where the files are."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .grid import short_names, shown
from .results import SweepResult

LABELS = {"nmse": "NMSE %", "rmse": "RMSE", "fit": "fit %", "max": "MAX"}
#: rows of the ranked table printed on a terminal (results.csv holds every point)
MAX_ROWS = 30


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return escape(shown(v, 24))


def render(result: SweepResult, out: Console, max_rows: int = MAX_ROWS) -> None:
    info = result.info
    key = result.sort_key
    c = result.counts()
    head = f"[bold]{escape(str(info.get('name', 'sweep')))}[/]: {c['points']} points over {', '.join(result.keys)}"
    if info.get("ran"):
        head += f"; {info['ran']} fitted on {escape(str(info.get('executor')))} in {info.get('seconds', 0):.1f} s"
    if info.get("resumed"):
        head += f"; {info['resumed']} finished earlier"
    out.print(head)
    short = short_names(result.keys)
    splits = [col.rsplit(".", 1)[0] for col in _metric_columns(result) if col.endswith(f".{key.metric}")]
    name = LABELS.get(key.metric, key.metric)
    table = Table(title=f"{name} of the free run per split, ranked by {key.split} (best first)", title_justify="left")
    table.add_column("point")
    for k in result.keys:
        table.add_column(escape(short[k]), justify="right")
    if "seed" not in result.keys:
        table.add_column("seed", justify="right", style="dim")
    table.add_column("status")
    for split in splits:
        table.add_column(
            escape(split), justify="right", style="bold" if split == key.split else None, min_width=min(len(split), 10)
        )
    table.add_column("s", justify="right")
    by_key = {r["point"]: r for r in result.rows}
    ranked = result.ranked()
    for record in ranked[:max_rows]:
        row = by_key[record["key"]]
        status = {"ok": "ok", "diverged": "[yellow]diverged[/]", "error": "[red]error[/]"}[row["status"]]
        cells = [row["point"], *(_fmt(row[k]) for k in result.keys)]
        if "seed" not in result.keys:
            cells.append(str(row.get("seed")))
        cells += [status, *(_fmt(row.get(f"{split}.{key.metric}")) for split in splits)]
        cells.append("-" if row.get("seconds") is None else f"{row['seconds']:.2f}")
        table.add_row(*cells)
    out.print(table)
    if len(ranked) > max_rows:
        where = f" (all in {result.folder}/results.csv)" if result.folder else ""
        out.print(f"... {len(ranked) - max_rows} more points{where}")
    _errors(result, out)
    _seeds(result, out)
    best = result.best
    if best is not None:
        label = ", ".join(f"{short[k]}={shown(best[k])}" for k in result.keys)
        if "seed" not in result.keys:
            label += f", seed {best['seed']}"
        where = f"; model {result.folder / best['model']}" if best.get("model") and result.folder else ""
        value = _fmt(best[key.column])
        out.print(f"best: [bold]{best['point']}[/] ({escape(label)}): {key.split} {name} {value}{escape(where)}")
    else:
        out.print("[yellow]no point finished with a stable free run[/]")
    for note in result.notes:
        out.print(f"note: {escape(note)}")
    seed_note = result.seed_note()
    if seed_note:
        out.print(f"note: {escape(seed_note)}")
    elif "seed" not in result.keys and info.get("stochastic"):
        out.print(
            "note: each configuration ran with one seed; random families vary from seed to seed "
            "(add seed: {range: [0, 5]} to the grid to see the spread)"
        )
    if result.folder is not None:
        files = "results.csv, results.json" + (", sweep.png" if info.get("figure") else "")
        out.print(f"results written to {escape(str(result.folder))}/ ({files}; point specs in specs/)")


def _metric_columns(result: SweepResult) -> list[str]:
    from .results import metric_columns

    return metric_columns(list(result.records.values()))


def _errors(result: SweepResult, out: Console) -> None:
    """The distinct messages of failed and diverged points (the first few)."""
    seen: dict[str, list[str]] = {}
    for r in result.ranked():
        if r.get("status") in ("error", "diverged") and r.get("message"):
            seen.setdefault(r["message"], []).append(r["key"])
    for i, (message, keys) in enumerate(seen.items()):
        if i == 5:
            out.print(f"... {len(seen) - 5} more distinct messages in results.csv")
            break
        which = ", ".join(keys[:4]) + (f" and {len(keys) - 4} more" if len(keys) > 4 else "")
        out.print(f"{escape(which)}: {escape(message)}", soft_wrap=True)


def _seeds(result: SweepResult, out: Console) -> None:
    summary = result.summary
    if not summary or all(e["points"] < 2 for e in summary):
        return
    others = [k for k in result.keys if k != "seed"]
    short = short_names(result.keys)
    table = Table(
        title=f"over seeds: {result.sort_key.column} per configuration, best median first", title_justify="left"
    )
    for k in others:
        table.add_column(escape(short[k]), justify="right")
    for col in ("stable / seeds", "median", "quartiles", "range"):
        table.add_column(col, justify="right")
    for e in summary:
        cells = [_fmt(e["config"][k]) for k in others]
        cells.append(f"{e['ok']} / {e['points']}")
        if "median" in e:
            cells += [_fmt(e["median"]), f"{e['q1']:.3g} - {e['q3']:.3g}", f"{e['min']:.3g} - {e['max']:.3g}"]
        else:
            cells += ["-", "-", "-"]
        table.add_row(*cells)
    out.print(table)
