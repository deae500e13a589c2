"""Signals given in Python: arrays, pandas Series and DataFrames, and lists of them (recordings).

pandas is optional: it is imported only when an object comes from it. Every signal becomes a
float64 array (n, channels); a Series or DataFrame also gives the channel names.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .data.dataset import Recording
from .errors import DataError


def is_pandas(obj: Any) -> bool:
    return type(obj).__module__.split(".")[0] == "pandas"


def is_recording_list(obj: Any) -> bool:
    """A list or tuple of signals (arrays or pandas objects), i.e. several recordings; a list of
    numbers is one signal."""
    return (
        isinstance(obj, (list, tuple)) and len(obj) > 0 and all(isinstance(x, np.ndarray) or is_pandas(x) for x in obj)
    )


def matrix(obj: Any, what: str = "signal") -> tuple[np.ndarray, list[str] | None]:
    """A signal as a float64 array (n, channels) (a copy) and its channel names when pandas gives them."""
    names = None
    if is_pandas(obj):
        if getattr(obj, "ndim", 1) == 1:
            names = [str(obj.name)] if obj.name is not None else None
        else:
            names = [str(c) for c in obj.columns]
        obj = obj.to_numpy(dtype=np.float64)
    try:
        a = np.array(obj, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DataError(
            f"the {what} is not numeric ({exc})", what, "pass numbers: an array, Series or DataFrame"
        ) from None
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise DataError(
            f"the {what} has shape {a.shape}", what, "pass one sample per row: an array (n,) or (n, channels)"
        )
    return a, names


def select(obj: Any, names: Sequence[str], what: str) -> Any:
    """The named columns of a DataFrame (or a dict of columns); other objects unchanged."""
    if is_pandas(obj) and getattr(obj, "ndim", 1) == 2:
        missing = [n for n in names if n not in obj.columns]
        if missing:
            raise DataError(
                f"the DataFrame has no column '{missing[0]}'",
                what,
                f"its columns are {[str(c) for c in obj.columns]}; name the {what} columns that exist",
            )
        return obj[list(names)]
    return obj


def default_names(prefix: str, k: int) -> list[str]:
    return [prefix] if k == 1 else [f"{prefix}{j}" for j in range(k)]


def _check_finite(a: np.ndarray, names: list[str], where: str) -> None:
    bad = ~np.isfinite(a)
    if bad.any():
        row, col = (int(i[0]) for i in np.nonzero(bad))
        raise DataError(
            f"'{names[col]}' has {'NaN' if np.isnan(a[row, col]) else 'inf'} at sample {row} "
            f"({int(bad[:, col].sum())} non-finite value(s))",
            where,
            "remove, interpolate or fill those samples before fitting",
        )


def recordings(
    u: Any,
    y: Any,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    label: str = "arrays",
) -> tuple[list[Recording], list[str], list[str]]:
    """Recordings from inputs ``u`` and outputs ``y`` (one signal each, or equally long lists of
    signals), with the input and output names: given ones first, then pandas names, then ``u`` /
    ``y`` (``u0``, ``u1``, ... for several channels)."""
    us = list(u) if is_recording_list(u) else [u]
    ys = list(y) if is_recording_list(y) else [y]
    if len(us) != len(ys):
        raise DataError(
            f"{len(us)} input recording(s) but {len(ys)} output recording(s)",
            label,
            "pass one output signal per input signal",
        )
    recs: list[Recording] = []
    ins, outs = list(input_names or []), list(output_names or [])
    for i, (ui, yi) in enumerate(zip(us, ys)):
        ua, un = matrix(ui, "input")
        ya, yn = matrix(yi, "output")
        if ua.shape[0] != ya.shape[0]:
            raise DataError(
                f"recording {i}: the input has {ua.shape[0]} samples, the output {ya.shape[0]}",
                label,
                "give inputs and outputs of the same length",
            )
        ins = ins or un or default_names("u", ua.shape[1])
        outs = outs or yn or default_names("y", ya.shape[1])
        for arr, names, what in ((ua, ins, "input"), (ya, outs, "output")):
            if arr.shape[1] != len(names):
                raise DataError(
                    f"recording {i}: {arr.shape[1]} {what} column(s) for the {len(names)} name(s) {names}",
                    label,
                    f"give every recording the same {what} columns",
                )
        name = label if len(us) == 1 else f"{label}[{i}]"
        _check_finite(np.hstack([ua, ya]), ins + outs, name)
        recs.append(Recording(name, ua, ya))
    if set(ins) & set(outs):
        raise DataError(
            f"'{sorted(set(ins) & set(outs))[0]}' names both an input and an output",
            label,
            "give distinct input_names and output_names",
        )
    return recs, ins, outs


def like_input(u: Any, y: np.ndarray, names: Sequence[str]) -> Any:
    """Predictions ``y`` (n, outputs) as a DataFrame indexed like ``u`` when ``u`` is a pandas object."""
    if not is_pandas(u):
        return y
    import pandas as pd

    return pd.DataFrame(y, index=u.index, columns=list(names))
