"""User-facing errors: one line that says what is wrong, where, and how to fix it.

Exit codes follow the project conventions: 0 success, 1 a check ran and failed
(for example a diverging free run), 2 usage, spec or data error.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130  # Ctrl-C (SIGINT): 128 + 2
EXIT_TERMINATED = 143  # SIGTERM (timeout, SLURM, docker stop): 128 + 15


class DynmodelError(Exception):
    """An error caused by the user's input (spec, data, model file, options).

    ``str(err)`` is a single line: ``"<where>: <what>. Fix: <fix>"``.
    """

    exit_code = EXIT_USAGE

    def __init__(self, what: str, where: str | None = None, fix: str | None = None):
        self.what = what.rstrip(". ")
        self.where = where
        self.fix = fix
        super().__init__(self.line())

    def line(self) -> str:
        text = f"{self.where}: {self.what}" if self.where else self.what
        if self.fix:
            text += f". Fix: {self.fix.rstrip('.')}"
        return " ".join(text.split())


class SpecError(DynmodelError, ValueError):
    """Malformed YAML, unknown key, wrong type or value in a spec."""


class DataError(DynmodelError, ValueError):
    """Missing file or column, NaN/inf values, too little data for the split."""


class ModelFileError(DynmodelError):
    """Unreadable, corrupt, incomplete or newer-format model file."""


class FreeRunDiverged(DynmodelError):
    """A free-running simulation left every plausible range of the output."""

    exit_code = EXIT_CHECK_FAILED

    def __init__(self, what: str, where: str | None = None, fix: str | None = None, sample: int | None = None):
        self.sample = sample
        super().__init__(what, where, fix)


class ParameterError(DynmodelError, ValueError):
    """An unknown or invalid family parameter given in Python (a ValueError, as scikit-learn expects)."""


class OutputError(DynmodelError):
    """An output path that cannot be written, or whose file must not be replaced."""


class Interrupted(DynmodelError):
    """The user stopped the command (Ctrl-C)."""

    exit_code = EXIT_INTERRUPTED


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by ``timeout``, SLURM, ``docker stop``), raised in the main thread as a KeyboardInterrupt
    subclass so that every clean-up of a Ctrl-C runs (workers stopped, finished sweep points kept); the
    command then exits 143 (:func:`how_interrupted`)."""

    def __init__(self, message: str = "terminated (SIGTERM)"):
        super().__init__(message)


def how_interrupted(exc: BaseException | None) -> tuple[str, int]:
    """("Ctrl-C", 130) for a KeyboardInterrupt, ("SIGTERM", 143) for :class:`Terminated`."""
    if isinstance(exc, Terminated):
        return "SIGTERM", EXIT_TERMINATED
    return "Ctrl-C", EXIT_INTERRUPTED


def interruption(exc: BaseException | None) -> str:
    """ "interrupted (Ctrl-C)" or "terminated (SIGTERM)": how a record says a run was stopped."""
    how, _ = how_interrupted(exc)
    return f"{'terminated' if how == 'SIGTERM' else 'interrupted'} ({how})"


def interruption_line(exc: BaseException | None) -> str:
    """The one line a command stopped outside its own handling ends with (while it loads or parses its line)."""
    return f"error: {interruption(exc)}. Fix: rerun the command"


class ModelWarning(UserWarning):
    """A model fitted with the Python API that is of little use (worse than the training mean, ignoring its
    input, not carrying over to the test) or whose free run diverged: the line ``dynmodel fit`` prints
    (:mod:`dynmodel.usefulness`), with what to try."""
