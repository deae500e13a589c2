"""Text files as lab software writes them: UTF-8 with or without a byte-order mark, UTF-16 (Excel's
"Unicode text"), and 8-bit Latin-1 exports, told apart from binary files before anything is parsed."""

from __future__ import annotations

import codecs
import warnings
from pathlib import Path

from .errors import DataError


class DataNote(UserWarning):
    """Something the user should know about how a file was read (shown as a warning line)."""


def detect_encoding(raw: bytes) -> str | None:
    """The encoding of ``raw`` by its byte-order mark or its NUL bytes: 'utf-8-sig', 'utf-32',
    'utf-16', 'utf-16-le', 'utf-16-be'; None when neither tells (then UTF-8, else Latin-1)."""
    if raw.startswith(codecs.BOM_UTF8):
        return "utf-8-sig"
    if raw.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        return "utf-32"
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "utf-16"
    sample = raw[:4000]
    if len(sample) >= 4:
        even_nul = sample[0::2].count(0) / len(sample[0::2])
        odd_nul = sample[1::2].count(0) / len(sample[1::2])
        if odd_nul > 0.4 and even_nul < 0.05:
            return "utf-16-le"
        if even_nul > 0.4 and odd_nul < 0.05:
            return "utf-16-be"
    return None


def looks_binary(raw: bytes) -> bool:
    """NUL bytes or many control characters in the first 4 kB (after ruling out UTF-16/32)."""
    sample = raw[:4096]
    if not sample:
        return False
    if b"\0" in sample:
        return True
    control = sum(1 for b in sample if b < 32 and b not in (9, 10, 12, 13))
    return control > 0.02 * len(sample)


def decode_text(raw: bytes, where: str) -> tuple[str, str]:
    """``raw`` as text and the encoding used. Bytes that are not UTF-8 are read as Latin-1 with a
    :class:`DataNote`; binary content raises DataError."""
    encoding = detect_encoding(raw)
    if encoding is not None:
        try:
            return raw.decode(encoding), encoding
        except UnicodeDecodeError:
            raise DataError(
                f"starts like {encoding.upper()} text but does not decode as it", where, "save the file as UTF-8"
            ) from None
    if looks_binary(raw):
        from .paths import describe_bytes

        raise DataError(
            f"is not a text file: it looks like {describe_bytes(raw[:4096])}",
            where,
            "export the data as CSV, or give the file the suffix of its format (.npz, .h5, .mat)",
        )
    try:
        return raw.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        warnings.warn(
            DataNote(f"{where}: not valid UTF-8, read as Latin-1 (check accented column names; save as UTF-8)"),
            stacklevel=2,
        )
        return raw.decode("latin-1"), "latin-1"


def read_text_file(path: str | Path, what: str = "file") -> str:
    """The text of ``path`` in whatever encoding :func:`decode_text` finds; one-line errors."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except IsADirectoryError:
        raise DataError("is a folder, not a file", str(p), f"give the {what} file") from None
    except FileNotFoundError:
        raise DataError(f"{what} not found", str(p), "check the path") from None
    except OSError as exc:
        raise DataError(
            f"cannot read the {what} ({(exc.strerror or str(exc)).lower()})", str(p), "check its permissions"
        ) from None
    return decode_text(raw, str(p))[0]
