"""Read named columns from measured-data files: CSV/text, NPZ, HDF5 and MATLAB .mat.

The format is taken from the file's content (HDF5, ZIP/NPZ and MATLAB signatures; text otherwise),
the suffix only deciding where the content does not; a file whose content and suffix disagree is
read by its content with a note. Text files may be UTF-8 (with or without BOM), UTF-16 or Latin-1
(read with a note), with any common delimiter; decimal commas are read when the delimiter is not a
comma. A column selector is a name (CSV header entry, NPZ key, HDF5 dataset path, MAT variable),
optionally with a 0-based column index for 2-D arrays: ``"q[1]"``. Headerless text files
are read with ``header: false`` and either ``columns: [names...]`` or integer selectors.
"""

from __future__ import annotations

import csv
import re
import warnings
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..textfiles import DataNote, decode_text

_SELECTOR = re.compile(r"^(?P<name>.+?)\[(?P<col>\d+)\]$")
TEXT_SUFFIXES = {".csv", ".txt", ".tsv", ".dat"}
HDF5_SUFFIXES = {".h5", ".hdf5", ".hdf"}
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
#: an ISO 8601 date with a time of day (a logger's time stamp)
_DATE_TIME = re.compile(r"^\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}")


def _split_selector(sel: str | int) -> tuple[str, int | None]:
    if isinstance(sel, int):
        return str(sel), None
    m = _SELECTOR.match(sel.strip())
    if m:
        return m.group("name").strip(), int(m.group("col"))
    return sel.strip(), None


def _as_column(arr: np.ndarray, col: int | None, path: Path, name: str) -> np.ndarray:
    a = np.asarray(arr)
    if a.dtype.kind not in "biuf":
        raise DataError(f"'{name}' holds {a.dtype} values, not numbers", str(path), "select a numeric variable")
    a = np.squeeze(a.astype(np.float64))
    if col is not None:
        if a.ndim != 2:
            raise DataError(
                f"'{name}' is {a.ndim}-D, so '{name}[{col}]' cannot pick a column",
                str(path),
                f"use '{name}' without an index",
            )
        if a.shape[0] < a.shape[1]:
            a = a.T
        if col >= a.shape[1]:
            raise DataError(
                f"'{name}' has {a.shape[1]} columns, index {col} is out of range",
                str(path),
                f"use an index below {a.shape[1]}",
            )
        return a[:, col]
    if a.ndim == 0:
        raise DataError(
            f"'{name}' is a scalar, not a time series", str(path), "select a variable that holds one value per sample"
        )
    if a.ndim != 1:
        raise DataError(
            f"'{name}' has shape {a.shape}; a column must be 1-D",
            str(path),
            f"pick one column with '{name}[0]', '{name}[1]', ...",
        )
    return a


def _missing(path: Path, name: str, available: Sequence[str]) -> DataError:
    shown = ", ".join(list(available)[:20]) + (" ..." if len(available) > 20 else "")
    return DataError(f"no column '{name}'", str(path), f"use one of: {shown}")


def _sniff_delimiter(first_lines: list[str]) -> str | None:
    sample = "\n".join(first_lines)
    try:
        return csv.Sniffer().sniff(sample, delimiters=",;\t |").delimiter
    except csv.Error:
        return None if not any("," in ln for ln in first_lines) else ","


def _commented_header(raw_lines: list[str], lines: list[str], delim: str | None, path: Path) -> list[str] | None:
    """``lines`` with a header taken from the comment line right above the first data line, when that data line
    is all numbers and the comment has as many fields (``numpy.savetxt(header=...)`` writes '# t,u,y'), with a
    note; None otherwise."""
    first = lines[0]
    k = raw_lines.index(first)
    if k == 0 or not raw_lines[k - 1].lstrip().startswith("#"):
        return None

    def cells(line: str) -> list[str]:
        return line.split() if delim in (None, " ") else next(csv.reader([line], delimiter=delim or ","))

    values = [c.strip() for c in cells(first)]
    names = [c.strip() for c in cells(raw_lines[k - 1].lstrip()[1:].strip())]
    try:
        [float(v) for v in values]
    except ValueError:
        return None  # the first line is a header of its own
    if len(names) != len(values) or not all(names) or any(_is_number(n) for n in names):
        return None
    warnings.warn(
        DataNote(f"{path}: the column names are read from the comment line '# {', '.join(names)}'"), stacklevel=3
    )
    return [raw_lines[k - 1].lstrip()[1:].strip(), *lines]


def _is_units_row(cells: list[str], following: list[str]) -> bool:
    """A row of units under the header (s, mm, N): no cell of it is a number, and the next row has numbers."""
    texts = [c.strip() for c in cells if c.strip()]
    numeric = [_is_number(c.strip()) or bool(_DECIMAL_COMMA.match(c.strip())) for c in following if c.strip()]
    return (
        bool(texts)
        and not any(_is_number(c) or _DECIMAL_COMMA.match(c) for c in texts)
        and bool(numeric)
        and all(numeric)
    )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_text(
    path: Path,
    selectors: Sequence[str | int],
    header: bool = True,
    columns: Sequence[str] | None = None,
    delimiter: str | None = None,
    gaps: bool = False,
) -> dict[str, np.ndarray]:
    """Read selected columns of a delimited text file into float64 arrays (``gaps``: an empty cell is NaN
    instead of an error, for columns that need not be complete, such as measured outputs beside the inputs
    of a prediction)."""
    text, _ = decode_text(_read_bytes(path), str(path))
    raw_lines = text.lstrip("\ufeff").splitlines()
    kept = [(i + 1, ln) for i, ln in enumerate(raw_lines) if ln.strip() and not ln.lstrip().startswith("#")]
    lines = [ln for _, ln in kept]
    numbers = [i for i, _ in kept]  # each kept line's number in the file (messages name the file's lines)
    if not lines:
        raise DataError("the file is empty", str(path), "point data.path to a file with samples")
    delim = delimiter or _sniff_delimiter(lines[:20])
    if header:
        with_names = _commented_header(raw_lines, lines, delim, path)
        if with_names is not None:
            lines, numbers = with_names, [numbers[0] - 1, *numbers]
    whitespace = delim in (None, " ")
    decimal_comma = False

    def split(line: str) -> list[str]:
        if whitespace:
            return line.split()
        return next(csv.reader([line], delimiter=delim or ","))  # delim is set when not whitespace

    if header:
        names = [h.strip() for h in split(lines[0])]
        body = lines[1:]
        unnamed = [i for i, n in enumerate(names) if not n]
        if unnamed and delim == "," and body:
            first = split(body[0])
            if any(i < len(first) and first[i].strip() for i in unnamed):  # values under no name
                raise DataError(
                    f"the header names {len(names) - len(unnamed)} columns and leaves {len(unnamed)} unnamed, but "
                    "the rows hold values under the unnamed ones",
                    str(path),
                    "the file seems to use decimal commas with comma separators: export it with ';' as separator "
                    "or with decimal points",
                )
    else:
        width = len(split(lines[0]))
        names = list(columns) if columns else [str(i) for i in range(width)]
        if columns and len(columns) != width:
            raise DataError(
                f"data.columns names {len(columns)} columns but the file has {width}",
                str(path),
                f"give exactly {width} names",
            )
        body = lines
    if header and len(body) > 1 and _is_units_row(split(body[0]), split(body[1])):
        warnings.warn(
            DataNote(
                f"{path}: line {numbers[1]} ({', '.join(c.strip() for c in split(body[0]))}) holds no number: read "
                "as the columns' units and skipped"
            ),
            stacklevel=2,
        )
        body, numbers = body[1:], [numbers[0], *numbers[2:]]
    if not body:
        raise DataError("the file has a header row but no samples", str(path), "check the file")
    index: dict[str, int] = {}
    for i, nm in enumerate(names):
        index.setdefault(nm, i)
    wanted: list[tuple[str, int]] = []
    for sel in selectors:
        key = str(sel).strip()
        if key and names.count(key) > 1:
            raise DataError(
                f"the header names {names.count(key)} columns '{key}'; which one is meant is unclear",
                str(path),
                "give each column its own name",
            )
        if key not in index:
            if header and key.isdigit() and int(key) < len(names):
                wanted.append((key, int(key)))
                continue
            raise _missing(path, key, [n for n in names if n])
        wanted.append((key, index[key]))
    body_numbers = numbers[1:] if header else numbers
    out = {key: np.empty(len(body)) for key, _ in wanted}
    for row, line in enumerate(body):
        cells = split(line)
        if header and len(cells) > len(names) and any(c.strip() for c in cells[len(names) :]):
            comma = delim == "," and any(c.strip().isdigit() for c in cells)
            raise DataError(
                f"line {body_numbers[row]} has {len(cells)} fields but the header names {len(names)}",
                str(path),
                "the file seems to use decimal commas with comma separators: export it with ';' as separator or "
                "with decimal points"
                if comma
                else "fix that line (or set delimiter: in the spec)",
            )
        for key, col in wanted:
            text = cells[col].strip() if col < len(cells) else ""
            if not text and gaps:
                out[key][row] = np.nan
                continue
            if not text:
                raise DataError(
                    f"column '{key}' has no value at line {body_numbers[row]} (sample {row})",
                    str(path),
                    "fill or remove that line",
                )
            if decimal_comma:
                text = text.replace(",", ".")
            try:
                out[key][row] = float(text)
            except ValueError:
                # a comma-separated file may hold decimal commas only in quoted cells (csv unquoted them)
                if not decimal_comma and _DECIMAL_COMMA.match(text):
                    decimal_comma = True
                    warnings.warn(DataNote(f"{path}: decimal commas read as decimal points"), stacklevel=2)
                    try:
                        out[key][row] = float(text.replace(",", "."))
                        continue
                    except ValueError:
                        pass
                if _is_date_time(text):
                    raise DataError(
                        f"column '{key}' holds the date and time '{text}' at line {body_numbers[row]}; time stamps "
                        "are read as numbers (seconds, or units of data.time_unit)",
                        str(path),
                        "write the stamps as seconds since the start (pandas: (t - t[0]).dt.total_seconds()), or "
                        "leave data.time_column out and give data.sampling_time",
                    ) from None
                raise DataError(
                    f"column '{key}' holds '{text}' at line {body_numbers[row]}, which is not a number",
                    str(path),
                    "fix that cell, or set header: false if the file has no header row"
                    if header and row == 0
                    else "fix or remove that line",
                ) from None
    return out


def _is_date_time(text: str) -> bool:
    """Does ``text`` read as an ISO 8601 date with a time (``2024-01-01 00:00:00.010``, ``2024-01-01T10:00``)?"""
    if not _DATE_TIME.match(text):
        return False
    try:
        np.datetime64(text.replace(" ", "T", 1))
    except ValueError:
        return False
    return True


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise DataError(
            f"cannot read the file ({(exc.strerror or str(exc)).lower()})", str(path), "check its permissions"
        ) from None


def read_npz(path: Path, selectors: Sequence[str]) -> dict[str, np.ndarray]:
    try:
        z = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise DataError(
            f"not a readable .npz archive ({_first_sentence(exc)})",
            str(path),
            "save the arrays with numpy.savez(path, u=..., y=...)",
        ) from None
    if not hasattr(z, "files"):  # a single .npy array
        raise DataError(
            "holds a single NumPy array, not named arrays",
            str(path),
            "save the columns by name with numpy.savez(path, u=..., y=...)",
        )
    with z:
        out = {}
        for sel in selectors:
            name, col = _split_selector(sel)
            if name not in z.files:
                raise _missing(path, name, z.files)
            try:
                arr = z[name]
            except ValueError as exc:
                if "allow_pickle" in str(exc) or "Object arrays" in str(exc):
                    raise DataError(
                        f"'{name}' is an object array (pickled Python objects), which dynmodel never loads",
                        str(path),
                        f"save '{name}' as numbers, e.g. numpy.savez(path, {name}=numpy.asarray(values, dtype=float))",
                    ) from None
                raise DataError(
                    f"'{name}' cannot be read ({_first_sentence(exc)})", str(path), "save the arrays again"
                ) from None
            except (OSError, EOFError, zipfile.BadZipFile) as exc:
                raise DataError(
                    f"'{name}' cannot be read ({_first_sentence(exc)})",
                    str(path),
                    "the archive is damaged; save it again",
                ) from None
            out[str(sel)] = _as_column(arr, col, path, name)
    return out


def _first_sentence(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.split(". ")[0].rstrip(".")


def read_hdf5(path: Path, selectors: Sequence[str]) -> dict[str, np.ndarray]:
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise DataError(
            f"not a readable HDF5 file ({_first_sentence(exc)})", str(path), "the file is damaged or not HDF5"
        ) from None
    with fh:
        if fh.attrs.get("format") == "dynmodel-model":
            raise DataError(
                "is a dynmodel model file, not measured data",
                str(path),
                "point the data path at the measured data (run a model on new data with `dynmodel predict`)",
            )
        datasets: list[str] = []
        fh.visititems(lambda n, o: datasets.append(n) if isinstance(o, h5py.Dataset) else None)
        out = {}
        for sel in selectors:
            name, col = _split_selector(sel)
            key = name.strip("/")
            if key not in fh or not isinstance(fh[key], h5py.Dataset):
                raise _missing(path, name, datasets)
            out[str(sel)] = _as_column(fh[key][()], col, path, name)
    return out


def read_mat(path: Path, selectors: Sequence[str]) -> dict[str, np.ndarray]:
    import scipy.io

    try:
        mat = scipy.io.loadmat(path)
    except NotImplementedError:  # MATLAB v7.3 files are HDF5
        return read_hdf5(path, selectors)
    except Exception as exc:  # noqa: BLE001 - scipy raises many kinds for a damaged file
        raise DataError(
            f"not a readable MATLAB file ({_first_sentence(exc)})", str(path), "save it again from MATLAB"
        ) from None
    names = [k for k in mat if not k.startswith("__")]
    out = {}
    for sel in selectors:
        name, col = _split_selector(sel)
        if name not in names:
            raise _missing(path, name, names)
        out[str(sel)] = _as_column(mat[name], col, path, name)
    return out


def read_columns(
    path: Path,
    selectors: Sequence[str | int],
    *,
    header: bool = True,
    columns: Sequence[str] | None = None,
    delimiter: str | None = None,
    gaps: bool = False,
) -> dict[str, np.ndarray]:
    """Read the selected columns of ``path``; the format follows the file's content (see the module).
    ``gaps``: empty cells of a text file are NaN instead of an error."""
    if not path.exists():
        raise DataError(
            "file not found", str(path), "check data.path (relative paths resolve against the spec file's folder)"
        )
    if not path.is_file():
        raise DataError("is not a file", str(path), "point data.path to a data file")
    fmt = sniff_format(path)
    by_suffix = _suffix_format(path.suffix.lower())
    if fmt == "binary" and by_suffix in ("mat", "npz", "hdf5"):
        fmt = by_suffix  # let the format's own reader name the damage
    if fmt == "binary":
        from ..paths import describe_file

        raise DataError(
            f"cannot read {describe_file(path)} as data",
            str(path),
            "export the data as CSV, NPZ, HDF5 or MATLAB .mat",
        )
    mismatch = by_suffix is not None and fmt != by_suffix
    if mismatch:
        from ..paths import describe_file

        looks = describe_file(path)
        warnings.warn(DataNote(f"{path}: named {path.suffix} but holds {looks}; read as such"), stacklevel=2)
    try:
        if fmt == "text":
            cols = read_text(path, selectors, header=header, columns=columns, delimiter=delimiter, gaps=gaps)
        elif fmt == "npz":
            cols = read_npz(path, [str(s) for s in selectors])
        elif fmt == "hdf5":
            cols = read_hdf5(path, [str(s) for s in selectors])
        else:
            cols = read_mat(path, [str(s) for s in selectors])
    except DataError as exc:
        if not mismatch:
            raise
        raise DataError(
            f"named {path.suffix} but holds {looks}, read as such: {exc.what}", exc.where, exc.fix
        ) from None
    lengths = {k: len(v) for k, v in cols.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{k}: {n}" for k, n in lengths.items())
        raise DataError(
            f"selected columns differ in length ({detail})", str(path), "select columns recorded on the same time grid"
        )
    return cols


def _suffix_format(suffix: str) -> str | None:
    if suffix in TEXT_SUFFIXES:
        return "text"
    if suffix == ".npz":
        return "npz"
    if suffix in HDF5_SUFFIXES:
        return "hdf5"
    if suffix == ".mat":
        return "mat"
    return None


def sniff_format(path: Path) -> str:
    """The format by content: 'hdf5', 'npz', 'mat', 'text' or 'binary' (anything else)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise DataError(
            f"cannot read the file ({(exc.strerror or str(exc)).lower()})", str(path), "check its permissions"
        ) from None
    signature = b"\x89HDF\r\n\x1a\n"
    if head.startswith(b"MATLAB 7.3") or (head.startswith(b"MATLAB") and head[512:520] == signature):
        return "hdf5"
    if head.startswith(signature) or head[512:520] == signature:
        return "hdf5"
    if head.startswith(b"MATLAB"):
        return "mat"
    if head.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        return "npz" if (b".npy" in head or path.suffix.lower() == ".npz") else "binary"
    if head.startswith(b"\x93NUMPY"):
        return "npz"
    from ..textfiles import detect_encoding, looks_binary

    if detect_encoding(head) is not None or not looks_binary(head):
        return "text"
    return "binary"


def list_columns(path: Path, *, header: bool = True, delimiter: str | None = None) -> list[str]:
    """The names :func:`read_columns` accepts for ``path`` (header entries, NPZ keys, HDF5 dataset
    paths, MAT variables); an empty list when the file cannot be read."""
    try:
        fmt = sniff_format(path)
        if fmt == "text":
            text, _ = decode_text(_read_bytes(path), str(path))
            first = next(
                (ln for ln in text.lstrip("\ufeff").splitlines() if ln.strip() and not ln.lstrip().startswith("#")), ""
            )
            if not header or not first:
                return []
            delim = delimiter or _sniff_delimiter([first])
            cells = first.split() if delim in (None, " ") else next(csv.reader([first], delimiter=delim))
            return [c.strip() for c in cells]
        if fmt == "npz":
            with np.load(path, allow_pickle=False) as z:
                return list(z.files)
        if fmt == "hdf5":
            import h5py

            names: list[str] = []
            with h5py.File(path, "r") as fh:
                fh.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
            return names
        if fmt == "mat":
            import scipy.io

            return [k for k in scipy.io.loadmat(path) if not k.startswith("__")]
    except Exception:  # noqa: BLE001 - only a listing; reading reports the real problem
        return []
    return []
