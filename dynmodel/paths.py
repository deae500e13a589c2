"""Output paths checked before any work: never destroy a user's file, never fail after a long run.

:func:`check_output` answers, before a command reads or fits anything, whether it may write a file
(or a report folder) at a path:

- the folder exists or can be created, and files can be created in it (probed with a temporary file,
  so read-only mounts, ``/proc`` and permissions are all caught, also for root);
- the path is not a folder (a report folder is), no part of its folder is a file, its name fits the
  file system;
- it is not the same file as any input the command reads (data, spec, model, tune-in file), with or
  without ``--force``;
- an existing file is replaced only when it is a previous output of the same kind (a dynmodel model,
  a CSV with a header the command writes, a JSON summary, a matplotlib figure, a diagnosis report
  folder); anything else needs ``force``, and a model never replaces anything but a model. A CSV
  without ``columns`` (``dynmodel generate``, whose output looks like measured data) is never taken
  for a previous output.

Every refusal is an :class:`~dynmodel.errors.OutputError`: one line, exit code 2.
"""

from __future__ import annotations

import errno
import json
import os
import re
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

from .errors import OutputError

if TYPE_CHECKING:
    from .spec import Spec

#: the kinds of output a command writes
KINDS = ("model", "csv", "json", "plot", "report", "yaml")
#: figure formats matplotlib writes (the format follows the suffix)
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff", ".webp")
#: keys by which a JSON file is recognized as a summary dynmodel wrote (fit, inspect, diagnose,
#: reliability-check, control, schema)
JSON_KEYS = frozenset({"metrics", "model", "baseline", "verdict", "test_system", "properties", "$defs"})
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_DESCRIPTION = {
    "model": "a model file",
    "csv": "a CSV file",
    "json": "a JSON summary",
    "plot": "a plot",
    "report": "a report folder",
    "yaml": "a YAML spec",
}

PathLike = Union[str, os.PathLike]
Inputs = Union[Iterable[PathLike], Mapping[str, Union[PathLike, Iterable[PathLike], None]]]


# ---------------------------------------------------------------- what a file looks like


def describe_file(path: Path) -> str:
    """A few words on what an existing file looks like (for messages): 'an HDF5 file', 'text
    starting with "t,u,y"', 'a ZIP archive', ..."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        return f"an unreadable file ({exc.strerror})"
    return describe_bytes(head)


def describe_bytes(head: bytes) -> str:
    """What the first bytes of a file look like."""
    if not head:
        return "an empty file"
    if head.startswith(_HDF5_SIGNATURE) or head[512:520] == _HDF5_SIGNATURE:
        return "an HDF5 file"
    if head.startswith(b"PK\x03\x04") or head.startswith(b"PK\x05\x06"):
        if b"[Content_Types].xml" in head or b"xl/" in head:
            return "an Excel workbook (.xlsx, a ZIP archive)"
        if b".npy" in head:
            return "a NumPy .npz archive"
        return "a ZIP archive"
    if head.startswith(b"\x93NUMPY"):
        return "a NumPy .npy array"
    if head.startswith(b"MATLAB"):
        return "a MATLAB .mat file"
    if head.startswith(b"\x89PNG"):
        return "a PNG image"
    if head.startswith(b"%PDF"):
        return "a PDF document"
    if head.startswith(b"\x1f\x8b"):
        return "a gzip-compressed file"
    if head.startswith(b"\xd0\xcf\x11\xe0"):
        return "an old Excel/Office document (.xls)"
    if head.startswith((b"\xff\xfe", b"\xfe\xff")) or head[1:200:2].count(0) > 50 or head[0:200:2].count(0) > 50:
        return "UTF-16 text"
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    printable = sum(ch.isprintable() or ch in "\r\n\t" for ch in text)
    if printable < 0.9 * len(text):
        return "a binary file"
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if len(first) > 40:
        first = first[:37] + "..."
    return f'text starting with "{first}"'


def _is_model(path: Path) -> bool:
    try:
        import h5py

        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == "dynmodel-model"
    except Exception:  # noqa: BLE001 - anything unreadable is not a model
        return False


def _csv_header(path: Path) -> list[str] | None:
    try:
        with open(path, "rb") as fh:
            head = fh.read(8192)
    except OSError:
        return None
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        return None
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return [c.strip() for c in line.split(",")]
    return None


def _is_dynmodel_json(path: Path) -> bool:
    try:
        if path.stat().st_size > 200_000_000:
            return False
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(value, dict) and bool(JSON_KEYS & set(value))


def _is_figure(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return False
    return b"atplotlib" in head


def _is_report(folder: Path) -> bool:
    """An empty folder, or one holding a diagnosis report (index.md starting '# Diagnosis of')."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return False
    if not entries:
        return True
    index = folder / "index.md"
    try:
        with open(index, encoding="utf-8") as fh:
            return fh.readline().startswith("# Diagnosis of")
    except (OSError, UnicodeDecodeError):
        return False


def is_previous_output(path: Path, kind: str, columns: Sequence[str] | Sequence[Sequence[str]] | None = None) -> bool:
    """Is the existing ``path`` an output of ``kind`` that dynmodel wrote before (and may replace)?"""
    if kind == "model":
        return _is_model(path)
    if kind == "csv":
        if not columns:
            return False
        options = columns if isinstance(columns[0], (list, tuple)) else [columns]
        found = _csv_header(path)
        return any(found == [str(c) for c in option] for option in options)
    if kind == "json":
        return _is_dynmodel_json(path)
    if kind == "plot":
        return _is_figure(path)
    if kind == "report":
        return path.is_dir() and _is_report(path)
    if kind == "yaml":
        try:
            return path.read_text(encoding="utf-8").startswith("# written by dynmodel")
        except (OSError, UnicodeDecodeError):
            return False
    raise ValueError(f"unknown output kind {kind!r}; use one of {KINDS}")


# ---------------------------------------------------------------- inputs


def _flatten_inputs(inputs: Inputs | None) -> list[tuple[str, Path]]:
    out: list[tuple[str, Path]] = []
    if inputs is None:
        return out
    if isinstance(inputs, Mapping):
        for role, value in inputs.items():
            if value is None:
                continue
            if isinstance(value, (str, os.PathLike)):
                out.append((str(role), Path(value)))
            else:
                out.extend((str(role), Path(v)) for v in value if v is not None)
    else:
        out.extend(("input file", Path(v)) for v in inputs if v is not None)
    return out


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    try:
        return a.resolve() == b.resolve()
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def spec_inputs(spec: Spec, spec_path: PathLike | None = None) -> dict[str, list[Path]]:
    """The files a spec makes a command read: the spec itself and every data path (main source,
    separate validation / test sources, and any other section holding a ``path``)."""
    roles: dict[str, list[Path]] = {}
    if spec_path is not None:
        roles["spec"] = [Path(spec_path)]
    data = spec.resolved().get("data") or {}
    found: list[Path] = []

    def paths_of(p: Any) -> None:
        """A ``path`` value: a file, a list of files, or ``{input: file, output: file}`` (or lists of these)."""
        if isinstance(p, str):
            found.append(Path(p))
        elif isinstance(p, list):
            for item in p:
                paths_of(item)
        elif isinstance(p, dict):
            for value in p.values():
                paths_of(value)

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            paths_of(node.get("path"))
            root = node.get("root") if node.get("benchmark") else None
            if isinstance(root, str) and Path(root).is_dir():  # a benchmark reads the files of its folder
                found.extend(f for f in sorted(Path(root).rglob("*"))[:5000] if f.is_file())
            for key, value in node.items():
                if key != "path":
                    walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(data)
    if found:
        roles["data file"] = found
    return roles


# ---------------------------------------------------------------- the check


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe(folder: Path) -> OSError | None:
    """Create and remove a temporary file in ``folder``; the error if that is impossible."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=".dynmodel-probe-", dir=folder)
    except OSError as exc:
        return exc
    os.close(fd)
    try:
        os.unlink(tmp)
    except OSError:
        pass
    return None


def _reason(exc: OSError) -> str:
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.EROFS:
        return "read-only file system"
    if exc.errno == errno.ENOSPC:
        return "no space left on the device"
    return (exc.strerror or str(exc)).lower()


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def check_output(
    path: PathLike,
    kind: str,
    inputs: Inputs | None = None,
    force: bool = False,
    *,
    option: str | None = None,
    columns: Sequence[str] | Sequence[Sequence[str]] | None = None,
) -> Path:
    """Raise :class:`OutputError` unless ``path`` can take an output of ``kind`` (see the module
    docstring); returns the path. ``inputs``: the files the command reads, as paths or as a mapping
    role -> path(s) (the role names them in the message). ``option``: the command-line option or
    spec key that gave the path (``--out``), named in the fix. ``columns``: for ``csv``, the header
    about to be written, or a list of such headers (a file with one of them is a previous output)."""
    if kind not in KINDS:
        raise ValueError(f"unknown output kind {kind!r}; use one of {KINDS}")
    p = Path(path).expanduser()
    where = str(p)
    opt = option or "the output option"
    what = _DESCRIPTION[kind]

    for role, source in _flatten_inputs(inputs):
        if _same_file(p, source):
            raise OutputError(
                f"this is the {role} the command reads; writing {what} there would destroy it",
                where,
                f"give {opt} another file name (e.g. {_suggest(p, kind)})",
            )

    name_max = _name_max(_nearest_existing(p.parent) if not p.parent.exists() else p.parent)
    for part in p.parts:
        if len(os.fsencode(part)) > name_max:
            raise OutputError(
                f"the name '{part[:24]}...' has {len(os.fsencode(part))} bytes; the file system allows {name_max}",
                where,
                f"choose a shorter name with {opt}",
            )
    if kind == "model" and len(os.fsencode(p.name)) + 24 > name_max:
        raise OutputError(
            f"the file name has {len(os.fsencode(p.name))} bytes; a model file needs room for its temporary "
            f"name within the file system's {name_max}",
            where,
            f"choose a shorter name with {opt}",
        )

    if kind == "plot" and p.suffix.lower() not in PLOT_SUFFIXES:
        raise OutputError(
            f"a plot's format follows its suffix, and '{p.suffix or '(none)'}' is not a figure format",
            where,
            f"end the name with .png (or {', '.join(s for s in PLOT_SUFFIXES[1:4])})",
        )

    if p.is_dir():
        if kind != "report":
            raise OutputError(
                f"is a folder; {what} needs a file name",
                where,
                f"give {opt} a file inside it, e.g. {p / _DEFAULT_NAME[kind]}",
            )
        if not _is_report(p) and not force:
            raise OutputError(
                "the folder exists and holds files that are not a diagnosis report",
                where,
                f"give {opt} a new or empty folder, or add --force to write the report into it",
            )
        folder = p
    else:
        if p.exists() or p.is_symlink():
            if kind == "report":
                raise OutputError("is a file; the report needs a folder", where, f"give {opt} a folder name")
            if not p.exists():  # a dangling symbolic link
                raise OutputError(
                    "is a symbolic link to a missing file", where, f"remove the link or give {opt} another name"
                )
            if not os.access(p, os.W_OK):
                raise OutputError(
                    "the existing file is read-only", where, f"give {opt} another name, or make the file writable"
                )
            if not is_previous_output(p, kind, columns):
                looks = describe_file(p)
                if kind == "model":
                    raise OutputError(
                        f"exists and is {looks}, not a dynmodel model; a model replaces only a model",
                        where,
                        f"give {opt} another name, e.g. {_suggest(p, kind)} (delete the file first if it really "
                        "should go)",
                    )
                if not force:
                    raise OutputError(
                        f"exists and is {looks}; this command replaces a CSV file only when asked to"
                        if kind == "csv" and not columns
                        else f"exists and is {looks}, not {what} dynmodel wrote",
                        where,
                        f"give {opt} another name, or add --force to replace it",
                    )
        parent = p.parent
        ancestor = _nearest_existing(parent)
        if not ancestor.is_dir():
            raise OutputError(
                f"'{ancestor}' is a file, so no folder can be made there", where, f"give {opt} a path in a folder"
            )
        folder = ancestor
    problem = _probe(folder)
    if problem is not None:
        raise OutputError(
            f"cannot create files in '{folder}' ({_reason(problem)})",
            where,
            f"give {opt} a path in a folder you can write to",
        )
    return p


def check_outputs(
    outputs: Sequence[tuple[PathLike | None, str, str]],
    inputs: Inputs | None = None,
    force: bool = False,
    columns: Mapping[str, Sequence[str] | Sequence[Sequence[str]]] | None = None,
) -> None:
    """:func:`check_output` for several outputs ``(path or None, kind, option)``, which must also
    differ from one another."""
    given = [(Path(p).expanduser(), kind, opt) for p, kind, opt in outputs if p is not None]
    for i, (p, kind, opt) in enumerate(given):
        for q, _, other in given[:i]:
            if _same_file(p, q):
                raise OutputError(
                    f"{other} and {opt} name the same file; one would overwrite the other",
                    str(p),
                    f"give {opt} another name",
                )
        for q, other_kind, other in given:
            if other_kind == "report" and q != p and _inside(p, q):  # the report writes its own files there
                raise OutputError(
                    f"{opt} lies inside the report folder of {other}, whose files the report writes (index.md, "
                    "extended.yaml, figures)",
                    str(p),
                    f"give {opt} a path outside {q}",
                )
        check_output(p, kind, inputs, force, option=opt, columns=(columns or {}).get(opt))


def _inside(path: Path, folder: Path) -> bool:
    """Is ``path`` within ``folder`` (both resolved, symbolic links followed)?"""
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


def _suggest(p: Path, kind: str) -> str:
    stem = p.stem or "output"
    suffix = {"model": ".h5", "csv": ".csv", "json": ".json", "plot": ".png", "report": "-report", "yaml": ".yaml"}
    name = f"{stem}{suffix[kind]}"
    if name == p.name:
        name = f"{stem}-new{suffix[kind]}"
    return str(p.with_name(name)) if str(p.parent) not in ("", ".") else name


_DEFAULT_NAME = {
    "model": "model.h5",
    "csv": "predictions.csv",
    "json": "summary.json",
    "plot": "plot.png",
    "report": "report",
    "yaml": "spec.yaml",
}
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


def safe_name(name: str, limit: int = 80) -> str:
    """``name`` as a portable file or folder name: letters, digits and ``._+-`` (other runs become
    ``-``), at most ``limit`` characters, never empty or hidden."""
    cleaned = _UNSAFE.sub("-", name).strip("-.") or "model"
    if len(cleaned) > limit:
        cleaned = cleaned[:limit].rstrip("-.")
    return cleaned


def umask() -> int:
    """The process's umask (read by setting it and setting it back): new outputs get 0666 (folders 0777) minus
    it, not the private 0600 of a temporary file."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path: PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and a rename, so an interrupted
    write never leaves half a file; the file gets the user's umask."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name[:100]}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.chmod(tmp, 0o666 & ~umask())
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def write_json(path: PathLike, payload: Any, allow_nan: bool = True) -> Path:
    """``payload`` as indented JSON, written as :func:`write_text` writes (temporary file, rename)."""
    return write_text(path, json.dumps(payload, indent=2, allow_nan=allow_nan) + "\n")
