"""The progress log written when stderr is not a terminal (a cluster job's log, a CI run)."""

from __future__ import annotations

import io

from dynmodel.progress import Reporter


def _lines(calls: list[tuple[str, float | None, str]]) -> list[str]:
    stream = io.StringIO()
    report = Reporter(stream=stream, interval=3600.0, quiet_start=0.0)
    for call in calls:
        report(*call)
    return [line.split("] ", 1)[1] for line in stream.getvalue().splitlines()]


def test_a_search_stage_that_starts_after_measured_fits_is_logged_at_once():
    """A stage's fits report fractions and are logged every few seconds; the next stage's start, reported
    without a fraction, is logged at once (a diagnosis that followed the last full fit within the interval
    left the log silent for ten minutes)."""
    lines = _lines(
        [
            ("search", None, "full: 3 fits"),
            ("search", 0.6, "full: 1/3"),
            ("search", 0.8, "full: 3/3"),
            ("search", None, "moves 1: diagnose the leader: 1 fits"),
        ]
    )
    assert lines == ["search: full: 3 fits", "search: moves 1: diagnose the leader: 1 fits"]


def test_steps_without_fractions_within_the_interval_are_not_logged_each():
    """A family's frequent steps (terms added one by one) stay one line per stage within the interval."""
    lines = _lines(
        [("select", None, f"{k} terms: + u(t-{k})") for k in range(1, 20)] + [("evaluate", None, "free runs")]
    )
    assert lines == ["select: 1 terms: + u(t-1)", "evaluate: free runs"]
