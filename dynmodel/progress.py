"""Progress on stderr: a live line on a terminal; otherwise log lines on stage changes, on a step without a
fraction that follows one with a fraction (a search's next stage: the fits of a stage report fractions,
the start of the next one none), and every few seconds, starting once a run has lasted two seconds."""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from rich.status import Status


class Reporter:
    """Callable ``(stage, fraction, message)`` used as a family's progress callback."""

    def __init__(
        self, enabled: bool = True, stream: TextIO | None = None, interval: float = 5.0, quiet_start: float = 2.0
    ):
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.interval = interval
        self.quiet_start = quiet_start
        self._stage: str | None = None
        self._last = 0.0
        self._measured = False  # did the last call carry a fraction?
        self._status: Status | None = None
        self._start = time.monotonic()
        if self.tty:
            from rich.console import Console

            self._console = Console(file=self.stream, emoji=False)

    def __call__(self, stage: str, fraction: float | None, message: str) -> None:
        if not self.enabled:
            return
        pct = f" {100 * fraction:3.0f}%" if fraction is not None else ""
        text = f"{stage}{pct}: {message}"
        if self.tty:
            if self._status is None:
                self._status = self._console.status(text)
                self._status.start()
            else:
                self._status.update(text)
            return
        now = time.monotonic()
        if now - self._start < self.quiet_start:
            return  # short runs and early errors stay free of log noise
        new_step = fraction is None and self._measured
        self._measured = fraction is not None
        if stage != self._stage or new_step or now - self._last >= self.interval:
            elapsed = now - self._start
            print(f"[dynmodel {elapsed:7.1f}s] {text}", file=self.stream, flush=True)
            self._stage, self._last = stage, now

    def close(self) -> None:
        if self._status is not None:
            self._status.stop()
            self._status = None

    def __enter__(self) -> Reporter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
