"""The sweep figure: the ranking metric of every point against each swept key."""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Any

from .grid import short_names, shown
from .results import SweepResult


class _Axis:
    """x positions of one key's values: the numbers themselves, or 0, 1, ... for other values."""

    def __init__(self, values: list[Any]):
        self.numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        self.labels = list(dict.fromkeys(shown(v, 18) for v in values))
        positive = self.numeric and min(values) > 0
        self.log = bool(positive and len(set(values)) > 2 and max(values) / min(values) > 20)
        distinct = sorted(set(values)) if self.numeric else []
        integers = self.numeric and all(isinstance(v, int) for v in distinct)
        self.ticks = distinct if integers and len(distinct) <= 12 else None

    def x(self, value: Any) -> float:
        return float(value) if self.numeric else float(self.labels.index(shown(value, 18)))


def metric_vs_values(path: Path, result: SweepResult, title: str = "") -> Path | None:
    """One panel per swept key: each stable point's metric (log scale when positive and spread), the
    median per value as a line, diverged points as red crosses along the top. None when no point
    finished ok."""
    from ..plots import _pyplot

    col = result.sort_key.column
    rows = result.rows
    ok = [r for r in rows if r["status"] == "ok" and r.get(col) is not None]
    if not ok:
        return None
    plt = _pyplot()
    keys = result.keys
    short = short_names(keys)
    cols = min(len(keys), 3)
    nrows = math.ceil(len(keys) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.6 * nrows), squeeze=False)
    ys = [float(r[col]) for r in ok]
    log_y = min(ys) > 0 and max(ys) / min(ys) > 20
    bad = [r for r in rows if r["status"] == "diverged"]
    for i, key in enumerate(keys):
        ax = axes[i // cols, i % cols]
        axis = _Axis([p.values[key] for p in result.points])
        xs = [axis.x(r[key]) for r in ok]
        ax.scatter(xs, ys, s=18, alpha=0.7, color="#1f77b4", label="stable")
        by_x: dict[float, list[float]] = {}
        for x, y in zip(xs, ys):
            by_x.setdefault(x, []).append(y)
        if len(by_x) > 1 and key != "seed":  # seeds are not ordered: no line across them
            line = sorted((x, statistics.median(v)) for x, v in by_x.items())
            ax.plot([x for x, _ in line], [y for _, y in line], color="#ff7f0e", lw=1.5, label="median")
        if bad:
            ax.scatter(
                [axis.x(r[key]) for r in bad],
                [1.0] * len(bad),
                marker="x",
                color="#d62728",
                transform=ax.get_xaxis_transform(),
                clip_on=False,
                label="diverged",
            )
        if not axis.numeric:
            ax.set_xticks(range(len(axis.labels)))
            rotate = max(map(len, axis.labels)) > 6
            ax.set_xticklabels(
                axis.labels, rotation=30 if rotate else 0, ha="right" if rotate else "center", fontsize=8
            )
        elif axis.log:
            ax.set_xscale("log")
        if axis.ticks is not None and not axis.log:
            ax.set_xticks(axis.ticks)
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel(short[key])
        ax.set_ylabel(col)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=8)
    for j in range(len(keys), nrows * cols):
        axes[j // cols, j % cols].axis("off")
    fig.suptitle(title or f"{col} (free run) of every point", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
    return path
