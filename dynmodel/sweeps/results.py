"""The results of a sweep as a table: one row per point, sortable, summarised over seeds.

Metrics are a flat mapping split -> entry, whatever the splits are called (``train``,
``validation``, ``test``, ``test:<name>``); a table column is ``<split>.<metric>``. Points are
ranked by the free-run error on the validation split (the train split when a point has no
validation split, which the ``sort`` note then says): ``nmse`` when the spec computes it, else its
first metric (``fit`` ranks high values first). Diverged points rank after every stable one, errors
last.
"""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from .grid import Point, short_names, shown

#: metrics in the order the tables show them; other numeric entries follow alphabetically
METRIC_ORDER = ("nmse", "rmse", "fit", "max", "nmse_1", "samples")
HIGHER_IS_BETTER = ("fit",)
STATUS_RANK = {"ok": 0, "diverged": 1, "error": 2}


@dataclass
class SortKey:
    split: str
    metric: str
    note: str | None = None

    @property
    def column(self) -> str:
        return f"{self.split}.{self.metric}"

    @property
    def descending(self) -> bool:
        return self.metric in HIGHER_IS_BETTER


def choose_sort(records: list[dict[str, Any]], metrics: list[str]) -> SortKey:
    """The split and metric points are ranked by (see the module docstring)."""
    metric = "nmse" if "nmse" in metrics or not metrics else metrics[0]
    ok = [r for r in records if r.get("status") == "ok"]
    if not ok or all("validation" in r["metrics"] for r in ok):
        return SortKey("validation", metric)
    return SortKey(
        "train",
        metric,
        "some points have no validation split: ranked by the train split's free-run error, on which the "
        "models were fitted (add a validation split to data.split for a fair comparison)",
    )


def score(record: dict[str, Any], key: SortKey) -> float:
    """The record's ranking value (lower is better; NaN when missing)."""
    value = _raw_score(record, key)
    if value is None:
        return math.nan
    return -value if key.descending else value


def _order(record: dict[str, Any], key: SortKey) -> tuple:
    s = score(record, key)
    return (
        STATUS_RANK.get(record.get("status", "error"), 3),
        math.isnan(s),
        s if not math.isnan(s) else 0.0,
        record["key"],
    )


def metric_columns(records: list[dict[str, Any]]) -> list[str]:
    """``split.metric`` columns in the order splits first appear and metrics are listed."""
    per_split: dict[str, set[str]] = {}
    for r in records:
        for split, entry in (r.get("metrics") or {}).items():
            names = per_split.setdefault(split, set())
            names.update(k for k, v in entry.items() if isinstance(v, (int, float)) or v is None)
    cols = []
    for split, names in per_split.items():
        names.discard("unstable_from")
        ordered = [m for m in METRIC_ORDER if m in names] + sorted(names - set(METRIC_ORDER))
        cols += [f"{split}.{m}" for m in ordered]
    return cols


@dataclass
class SweepResult:
    """A sweep's results: ``rows`` (one dict per point, the columns of results.csv), sortable with
    :meth:`sort`, convertible with :meth:`to_pandas`; ``best`` is the top-ranked stable point;
    ``summary`` the seed statistics per configuration when the grid sweeps ``seed``;
    ``best_model`` the best point's FittedModel when it was kept in memory."""

    keys: list[str]
    points: list[Point]
    records: dict[str, dict[str, Any]]
    sort_key: SortKey
    folder: Any = None
    best_model: Any = None
    notes: list[str] = field(default_factory=list)
    _order: list[str] | None = None
    #: run facts: name, spec, grid, executor, seconds, ran, resumed, interrupted, warnings, figure
    info: dict[str, Any] = field(default_factory=dict)
    #: models kept in memory (no output folder), by point key
    models: dict[str, Any] = field(default_factory=dict)

    def model(self, key: str):
        """The FittedModel of point ``key``, kept in memory or in the output folder (KeyError if not kept)."""
        if key in self.models:
            return self.models[key].to_model()
        path = (self.records.get(key) or {}).get("model")
        if path and self.folder is not None:
            from ..store import load

            return load(self.folder / path)
        raise KeyError(f"the model of {key} was not kept (keep='all' keeps every model, 'best' the best one)")

    # -- table -------------------------------------------------------------------------
    @property
    def columns(self) -> list[str]:
        seed = [] if "seed" in self.keys else ["seed"]
        tail = ["seconds", "attempts", "worker", "message", "model"]
        return ["point", "status", *self.keys, *seed, *metric_columns(list(self.records.values())), *tail]

    def _row(self, point: Point, columns: list[str] | None = None) -> dict[str, Any]:
        r = self.records.get(point.key) or {"status": "not run", "metrics": {}}
        row: dict[str, Any] = {"point": point.key, "status": r.get("status")}
        row.update(point.values)
        row.setdefault("seed", r.get("seed", point.seed))
        for col in metric_columns(list(self.records.values())) if columns is None else columns:
            split, metric = col.rsplit(".", 1)
            row[col] = ((r.get("metrics") or {}).get(split) or {}).get(metric)
        row.update(
            seconds=r.get("seconds"),
            attempts=r.get("attempts"),
            worker=r.get("worker"),
            message=r.get("message"),
            model=r.get("model"),
        )
        return row

    @property
    def rows(self) -> list[dict[str, Any]]:
        by_key = {p.key: p for p in self.points}
        order = self._order or [p.key for p in self.points]
        columns = metric_columns(list(self.records.values()))
        return [self._row(by_key[k], columns) for k in order]

    def __len__(self) -> int:
        return len(self.points)

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return iter(self.rows)

    def __getitem__(self, i: int) -> dict[str, Any]:
        return self.rows[i]

    def ranked(self) -> list[dict[str, Any]]:
        """Finished points, best first (the order of the printed table)."""
        done = [r for r in self.records.values() if r.get("status") in STATUS_RANK]
        return sorted(done, key=lambda r: _order(r, self.sort_key))

    def sort(self, by: str | None = None, descending: bool = False) -> SweepResult:
        """A copy with rows sorted by column ``by`` (missing values last), or ranked (default)."""
        if by is None:
            ranked = [r["key"] for r in self.ranked()]
            order = ranked + [p.key for p in self.points if p.key not in ranked]
        else:
            rows = self.rows
            if rows and by not in rows[0]:
                raise KeyError(f"no column '{by}'; columns: {', '.join(self.columns)}")
            present = [r for r in rows if r.get(by) is not None]
            missing = [r for r in rows if r.get(by) is None]
            present.sort(key=lambda r: _sortable(r[by]), reverse=descending)
            order = [r["point"] for r in present + missing]
        return SweepResult(
            self.keys,
            self.points,
            self.records,
            self.sort_key,
            self.folder,
            self.best_model,
            self.notes,
            order,
            self.info,
            self.models,
        )

    @property
    def best(self) -> dict[str, Any] | None:
        """The row of the best stable point (None when no point finished ok)."""
        ranked = self.ranked()
        if not ranked or ranked[0].get("status") != "ok" or math.isnan(score(ranked[0], self.sort_key)):
            return None
        by_key = {p.key: p for p in self.points}
        return self._row(by_key[ranked[0]["key"]])

    def to_pandas(self):
        """The rows as a pandas DataFrame (pandas is optional: pip install pandas)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("SweepResult.to_pandas needs pandas: pip install pandas") from None
        return pd.DataFrame(self.rows, columns=self.columns)

    to_dataframe = to_pandas

    # -- seeds -------------------------------------------------------------------------
    @property
    def summary(self) -> list[dict[str, Any]]:
        """Per configuration (the swept values without ``seed``), when the grid sweeps seeds: points,
        stable points and the median, quartiles and range of the ranking metric over the stable
        seeds; best median first."""
        if "seed" not in self.keys:
            return []
        others = [k for k in self.keys if k != "seed"]
        groups: dict[str, dict[str, Any]] = {}
        for p in self.points:
            config = {k: p.values[k] for k in others}
            g = groups.setdefault(json.dumps(config, sort_keys=True, default=str), {"config": config, "keys": []})
            g["keys"].append(p.key)
        out = []
        col = self.sort_key.column
        for g in groups.values():
            recs = [self.records[k] for k in g["keys"] if k in self.records]
            ok = [r for r in recs if r.get("status") == "ok"]
            vals = sorted(v for v in (_raw_score(r, self.sort_key) for r in ok) if v is not None)
            entry: dict[str, Any] = {
                "config": g["config"],
                "points": len(g["keys"]),
                "finished": len(recs),
                "ok": len(ok),
                "diverged": sum(r.get("status") == "diverged" for r in recs),
                "errors": sum(r.get("status") == "error" for r in recs),
                "metric": col,
            }
            if vals:
                q = statistics.quantiles(vals, n=4, method="inclusive") if len(vals) > 1 else [vals[0]] * 3
                entry.update(median=statistics.median(vals), q1=q[0], q3=q[2], min=vals[0], max=vals[-1])
            out.append(entry)
        sign = -1.0 if self.sort_key.descending else 1.0
        out.sort(key=lambda e: (e.get("median") is None, sign * e["median"] if e.get("median") is not None else 0.0))
        return out

    def seed_note(self) -> str | None:
        """Does the best configuration beat the second for every seed, or do their ranges overlap?"""
        summ = [e for e in self.summary if e.get("ok", 0) >= 2]
        if len(summ) < 2:
            return None
        a, b = summ[0], summ[1]
        short = short_names(self.keys)
        la = ", ".join(f"{short[k]}={shown(v)}" for k, v in a["config"].items())
        lb = ", ".join(f"{short[k]}={shown(v)}" for k, v in b["config"].items())
        better_everywhere = (a["min"] > b["max"]) if self.sort_key.descending else (a["max"] < b["min"])
        if better_everywhere:
            return f"every seed of the best configuration ({la}) beats every seed of the next ({lb})"
        return (
            f"the seed ranges of the best configuration ({la}) and the next ({lb}) overlap: the difference "
            "between them may be seed luck; more seeds would tell"
        )

    # -- output -------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        points = []
        for p in self.points:
            r = self.records.get(p.key)
            entry: dict[str, Any] = {"point": p.key, "values": p.values, "seed": p.seed}
            if r is None:
                entry["status"] = "not run"
            else:
                entry.update({k: v for k, v in r.items() if k not in ("key", "values")})
            points.append(entry)
        best = self.best
        return {
            "keys": self.keys,
            "sort": {"split": self.sort_key.split, "metric": self.sort_key.metric, "note": self.sort_key.note},
            "counts": self.counts(),
            "best": None if best is None else best["point"],
            "points": points,
            "summary": self.summary,
            "notes": self.notes,
        }

    def counts(self) -> dict[str, int]:
        statuses = [r.get("status") for r in self.records.values()]
        return {
            "points": len(self.points),
            "ok": statuses.count("ok"),
            "diverged": statuses.count("diverged"),
            "error": statuses.count("error"),
            "not_run": len(self.points) - len(statuses),
        }

    def to_csv(self) -> str:
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=self.columns, lineterminator="\n")
        writer.writeheader()
        for row in self.rows:
            writer.writerow({k: _cell(v) for k, v in row.items()})
        return buf.getvalue()

    def __repr__(self) -> str:
        c = self.counts()
        best = self.best
        tail = f", best {best['point']} ({self.sort_key.column} {best[self.sort_key.column]:.4g})" if best else ""
        return f"SweepResult({c['points']} points: {c['ok']} ok, {c['diverged']} diverged, {c['error']} errors{tail})"


def _raw_score(record: dict[str, Any], key: SortKey) -> float | None:
    entry = (record.get("metrics") or {}).get(key.split) or {}
    value = entry.get(key.metric)
    return None if value is None else float(value)


def _sortable(v: Any) -> tuple:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return (0, float(v), "")
    return (1, 0.0, json.dumps(v, sort_keys=True, default=str))


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)  # round-trips exactly
    if isinstance(v, (list, dict, bool)):
        return json.dumps(v)
    return v
