"""Read named columns from measured-data files: CSV/text, NPZ, HDF5 and MATLAB .mat.

A column selector is a name (CSV header entry, NPZ key, HDF5 dataset path, MAT variable),
optionally with a 0-based column index for 2-D arrays: ``"q[1]"``. Headerless text files
are read with ``header: false`` and either ``columns: [names...]`` or integer selectors.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError

_SELECTOR = re.compile(r"^(?P<name>.+?)\[(?P<col>\d+)\]$")
TEXT_SUFFIXES = {".csv", ".txt", ".tsv", ".dat"}


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


def read_text(
    path: Path,
    selectors: Sequence[str | int],
    header: bool = True,
    columns: Sequence[str] | None = None,
    delimiter: str | None = None,
) -> dict[str, np.ndarray]:
    """Read selected columns of a delimited text file into float64 arrays."""
    with open(path, newline="", encoding="utf-8-sig") as fh:
        lines = fh.read().splitlines()
    lines = [ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise DataError("the file is empty", str(path), "point data.path to a file with samples")
    delim = delimiter or _sniff_delimiter(lines[:20])
    whitespace = delim in (None, " ")

    def split(line: str) -> list[str]:
        if whitespace:
            return line.split()
        return next(csv.reader([line], delimiter=delim))

    if header:
        names = [h.strip() for h in split(lines[0])]
        body = lines[1:]
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
    if not body:
        raise DataError("the file has a header row but no samples", str(path), "check the file")
    index: dict[str, int] = {}
    for i, nm in enumerate(names):
        index.setdefault(nm, i)
    wanted: list[tuple[str, int]] = []
    for sel in selectors:
        key = str(sel).strip()
        if key not in index:
            if header and key.isdigit() and int(key) < len(names):
                wanted.append((key, int(key)))
                continue
            raise _missing(path, key, [n for n in names if n])
        wanted.append((key, index[key]))
    first_data_line = 2 if header else 1
    out = {key: np.empty(len(body)) for key, _ in wanted}
    for row, line in enumerate(body):
        cells = split(line)
        for key, col in wanted:
            text = cells[col].strip() if col < len(cells) else ""
            if not text:
                raise DataError(
                    f"column '{key}' has no value at line {row + first_data_line} (sample {row})",
                    str(path),
                    "fill or remove that line",
                )
            try:
                out[key][row] = float(text)
            except ValueError:
                raise DataError(
                    f"column '{key}' holds '{text}' at line {row + first_data_line}, which is not a number",
                    str(path),
                    "fix that cell, or set header: false if the file has no header row"
                    if header and row == 0
                    else "fix or remove that line",
                ) from None
    return out


def read_npz(path: Path, selectors: Sequence[str]) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        out = {}
        for sel in selectors:
            name, col = _split_selector(sel)
            if name not in z.files:
                raise _missing(path, name, z.files)
            out[str(sel)] = _as_column(z[name], col, path, name)
    return out


def read_hdf5(path: Path, selectors: Sequence[str]) -> dict[str, np.ndarray]:
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise DataError(f"not a readable HDF5 file ({exc})", str(path), "check the file") from None
    with fh:
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
    except Exception as exc:
        raise DataError(f"not a readable MATLAB file ({exc})", str(path), "check the file") from None
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
) -> dict[str, np.ndarray]:
    """Read the selected columns of ``path``; the format follows the file suffix."""
    if not path.exists():
        raise DataError(
            "file not found", str(path), "check data.path (relative paths resolve against the spec file's folder)"
        )
    if not path.is_file():
        raise DataError("is not a file", str(path), "point data.path to a data file")
    suffix = path.suffix.lower()
    if suffix in TEXT_SUFFIXES:
        cols = read_text(path, selectors, header=header, columns=columns, delimiter=delimiter)
    elif suffix == ".npz":
        cols = read_npz(path, [str(s) for s in selectors])
    elif suffix in {".h5", ".hdf5", ".hdf"}:
        cols = read_hdf5(path, [str(s) for s in selectors])
    elif suffix == ".mat":
        cols = read_mat(path, [str(s) for s in selectors])
    else:
        raise DataError(f"unsupported file type '{suffix}'", str(path), "use .csv/.txt/.tsv, .npz, .h5/.hdf5 or .mat")
    lengths = {k: len(v) for k, v in cols.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{k}: {n}" for k, n in lengths.items())
        raise DataError(
            f"selected columns differ in length ({detail})", str(path), "select columns recorded on the same time grid"
        )
    return cols
