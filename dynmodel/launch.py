"""The ``dynmodel`` console entry point.

A Ctrl-C while the command line's modules load (typer, rich: the first quarter second) ends with one line and
exit 130, as it does once a command runs (:func:`dynmodel.cli.handled`), not with a traceback. ``import dynmodel``
before it is kept light for the same reason (its API names load on first use).
"""

from __future__ import annotations

import sys

from .errors import how_interrupted, interruption_line


def main() -> None:
    """Load the command line and run it."""
    try:
        from .cli import main as run

        run()  # a command's own handling catches what comes later (dynmodel.cli.handled)
    except KeyboardInterrupt as exc:
        print(interruption_line(exc), file=sys.stderr)
        raise SystemExit(how_interrupted(exc)[1]) from None
