"""The one place that turns an exception into what the user reads.

Expected failures (a user's mistake, or the machine refusing: a full disk, a read-only folder, too
little memory, Ctrl-C) become a :class:`~dynmodel.errors.DynmodelError` with one line (what, where,
how to fix) and its exit code. Everything else is a bug in dynmodel and gets the "internal error"
line. Front ends (the command line, a sweep's worker) call :func:`explain` and print
:meth:`DynmodelError.line`; they never format exceptions themselves.
"""

from __future__ import annotations

import errno

from .errors import EXIT_INTERNAL, DynmodelError, Interrupted

_OS_REASONS = {
    errno.ENOSPC: ("no space left on the device", "free some space or write to another disk"),
    errno.EDQUOT: ("disk quota exceeded", "free some space or write to another disk"),
    errno.EACCES: ("permission denied", "check the file's permissions or use another path"),
    errno.EPERM: ("operation not permitted", "check the file's permissions or use another path"),
    errno.EROFS: ("read-only file system", "write to another folder"),
    errno.ENAMETOOLONG: ("file name too long", "choose a shorter name"),
    errno.EISDIR: ("is a folder, not a file", "give a file name"),
    errno.ENOTDIR: ("a part of the path is a file, not a folder", "check the path"),
    errno.ENOENT: ("no such file or folder", "check the path"),
    errno.EEXIST: ("already exists", "choose another name"),
    errno.EBUSY: ("device or resource busy", "use another path"),
    errno.EMFILE: ("too many open files", "close other programs or raise the limit (ulimit -n)"),
    errno.EIO: ("input/output error of the device", "check the disk or network share"),
}


def _os_error(exc: OSError) -> DynmodelError | None:
    reason = _OS_REASONS.get(exc.errno) if exc.errno is not None else None
    if reason is None:
        return None
    what, fix = reason
    where = exc.filename if exc.filename is not None else None
    if exc.filename2 is not None:
        where = f"{exc.filename} -> {exc.filename2}"
    return DynmodelError(f"cannot access the file: {what}", None if where is None else str(where), fix)


def explain(exc: BaseException) -> DynmodelError | None:
    """The user-facing error for ``exc``, or None when ``exc`` is a bug (internal error)."""
    if isinstance(exc, DynmodelError):
        return exc
    if isinstance(exc, KeyboardInterrupt):
        return Interrupted("interrupted (Ctrl-C)", None, "rerun the command; files are written only when it completes")
    if isinstance(exc, MemoryError):
        detail = str(exc).splitlines()[0] if str(exc) else "the system refused an allocation"
        return DynmodelError(
            f"not enough memory ({detail})", None, "use fewer samples, a smaller model or fewer workers"
        )
    if isinstance(exc, OSError):
        return _os_error(exc)
    if isinstance(exc, UnicodeDecodeError):
        return DynmodelError(
            f"a text file is not in a known encoding ({exc.encoding} failed at byte {exc.start})",
            None,
            "save the file as UTF-8",
        )
    try:
        from pydantic import ValidationError
    except ImportError:  # pragma: no cover - pydantic is a core dependency
        ValidationError = ()  # type: ignore[assignment,misc]
    if isinstance(exc, ValidationError):
        from .spec import validation_summary

        return DynmodelError(f"invalid value ({validation_summary(exc)})", None, "see `dynmodel schema`")
    return None


def internal_error_line(exc: BaseException) -> str:
    """The line for a bug: what happened and where to report it."""
    text = " ".join(str(exc).split())
    if len(text) > 300:
        text = text[:297] + "..."
    return (
        f"internal error: {type(exc).__name__}: {text} (a bug in dynmodel, not in your input: rerun with --debug "
        "for the traceback and report it)"
    )


def exit_code(exc: BaseException) -> int:
    """The exit code for ``exc``: the user error's, else EXIT_INTERNAL."""
    mapped = explain(exc)
    return EXIT_INTERNAL if mapped is None else mapped.exit_code
