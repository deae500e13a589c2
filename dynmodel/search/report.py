"""The search record for people: the leaderboard ``dynmodel fit`` prints and the one-line summaries."""

from __future__ import annotations

from typing import Any

LEADERBOARD_ROWS = 8


def _fmt(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


def headline(record: dict[str, Any]) -> str:
    """``search: 23 candidates of narx, esn (cross-validated in 5 blocks), 41 s; chose ...``."""
    cands = [c for c in record["candidates"] if c.get("levels")]
    families = sorted({c["family"] for c in cands})
    validated = len((record.get("layouts") or {}).get("final") or [])
    first = (
        ", the first only training"
        if record.get("mode") == "folds" and 0 < validated < (record.get("folds") or 0)
        else ""
    )
    how = {
        "folds": f"cross-validated in {record.get('folds')} blocks{first}",
        "recordings": (
            f"each of {record.get('folds')} recordings left out in turn"
            if validated in (0, record.get("folds"))
            else f"{validated} of {record.get('folds')} recordings left out in turn, those between the others"
        ),
        "tail": f"the last 1/{record.get('folds')} of the training held out",
        "phase": f"each 1/{record.get('folds')} of the excitation's period held out in turn",
    }.get(str(record.get("mode")), "validation split")
    budget = record.get("budget") or {}
    text = (
        f"search: {len(cands)} candidates of {', '.join(families) or 'no family'} ({how}), "
        f"{record.get('seconds', 0):.0f} s for a budget of {budget.get('seconds', 0):g} s"
    )
    winner = next((c for c in record["candidates"] if c["key"] == record.get("winner")), None)
    if winner is not None:
        text += f"; chose {winner['family']}: {winner['summary']}"
    return text


def leaderboard(record: dict[str, Any], limit: int = LEADERBOARD_ROWS) -> list[dict[str, Any]]:
    """Rows of the leaderboard: the measured candidates in the search's ranking (the winner first), each
    with its family, summary, validation NMSE (the level it reached), fits, fit seconds and verdict."""
    rows = []
    winner = record.get("winner")
    ordered = sorted(
        [c for c in record["candidates"] if c.get("levels")],
        key=lambda c: (
            c["key"] != winner,
            c.get("level") != "final",
            c["validation_nmse"] is None,
            c["validation_nmse"] if c["validation_nmse"] is not None else 0.0,
            c["key"],
        ),
    )
    for c in ordered[:limit]:
        level = c.get("level")
        s = (c.get("levels") or {}).get(level) or {}
        rows.append(
            {
                "key": c["key"],
                "family": c["family"],
                "summary": c["summary"],
                "validation_nmse": c["validation_nmse"],
                "level": "screened" if level == "screen" or c.get("stands_screened") else "full",
                "fits": s.get("fits", 0),
                "seconds": c.get("fit_seconds", 0.0),
                "verdict": c.get("verdict", ""),
            }
        )
    return rows


def _short(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


def table_cells(row: dict[str, Any]) -> list[str]:
    """One leaderboard row as text: the candidate's description cut at :data:`CANDIDATE_WIDTH` characters (the
    record keeps it whole), the verdict whole (why a candidate was rejected or not chosen)."""
    return [
        _short(f"{row['family']}: {row['summary']}", CANDIDATE_WIDTH),
        _fmt(row["validation_nmse"]) + ("" if row["level"] == "full" else "*"),
        str(row["fits"]),
        f"{row['seconds']:.1f}",
        row["verdict"],
    ]


#: characters of a candidate's description in the leaderboard
CANDIDATE_WIDTH = 90


TABLE_HEADERS = ["candidate", "val. NMSE %", "fits", "fit s", "verdict"]
#: the footnote of a screened score
SCREENED = "*: scored on the screening layout only (cheaper variant or part of the training data)"
