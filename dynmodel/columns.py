"""Signals given in Python: arrays, pandas Series and DataFrames, and lists of them (recordings).

pandas is optional: it is imported only when an object comes from it. Every signal becomes a
float64 array (n, channels); a Series or DataFrame also gives the channel names.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .data.dataset import Recording
from .data.finite import check_finite
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
            kinds = [(names[0] if names else what, obj.dtype)]
        else:
            names = [str(c) for c in obj.columns]
            kinds = list(zip(names, obj.dtypes))
        for name, dtype in kinds:  # name the channel that is not a number
            kind = getattr(dtype, "kind", "O")
            if kind in "mM":
                raise DataError(
                    f"the {what} column '{name}' holds dates or durations ({dtype}), not samples of a signal",
                    what,
                    "drop it (a time column belongs in the index, or in sampling_time)",
                )
            if kind not in "biuf":
                try:
                    np.asarray(obj[name] if getattr(obj, "ndim", 1) == 2 else obj, dtype=np.float64)
                except (TypeError, ValueError) as exc:
                    raise DataError(
                        f"the {what} column '{name}' is not numeric ({exc})", what, "convert it to numbers or drop it"
                    ) from None
        obj = obj.to_numpy(dtype=np.float64)
    if np.iscomplexobj(obj):
        raise DataError(
            f"the {what} is complex", what, "pass real samples (e.g. the real part, or magnitude and phase as channels)"
        )
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


def index_step(obj: Any, where: str = "arrays") -> float | None:
    """The sampling time (s) of a pandas object indexed by time stamps or durations: the step of its index
    when uniform (a DataError when it is not); None for anything else."""
    index = getattr(obj, "index", None) if is_pandas(obj) else None
    if index is None or getattr(index, "dtype", None) is None or index.dtype.kind not in "mM" or len(index) < 2:
        return None
    steps = np.diff(index.to_numpy()) / np.timedelta64(1, "s")  # seconds, whatever the index's unit
    if steps.min() <= 0 or steps.max() - steps.min() > 1e-6 * steps.mean():
        raise DataError(
            f"the time index steps from {steps.min():.6g} s to {steps.max():.6g} s, not uniformly",
            where,
            "resample to a uniform step first (e.g. frame.resample('10ms').mean().interpolate()), or pass "
            "sampling_time= to take the samples as equally spaced",
        )
    return float(steps.mean())


def default_names(prefix: str, k: int) -> list[str]:
    return [prefix] if k == 1 else [f"{prefix}{j}" for j in range(k)]


def names_columns(obj: Any) -> bool:
    """Does ``obj`` name its channels: a DataFrame whose columns are not pandas' default positions
    (0, 1, ...)? Its columns are then matched by name, never by position."""
    return (
        is_pandas(obj)
        and getattr(obj, "ndim", 1) == 2
        and not all(isinstance(c, (int, np.integer)) for c in obj.columns)
    )


def by_name(obj: Any, names: Sequence[str], what: str, where: str) -> Any:
    """The channels ``names`` of a DataFrame that names its columns (:func:`names_columns`), in that
    order; a DataError naming the missing ones when it lacks any (never a silent match by position);
    other objects unchanged."""
    if not names_columns(obj):
        return obj
    missing = [n for n in names if n not in obj.columns]
    if missing:
        raise DataError(
            f"the {what} DataFrame has the columns {[str(c) for c in obj.columns]}, not {missing}",
            where,
            f"give it the {what} columns {list(names)} (any order; rename with DataFrame.rename), "
            "or pass an array to match channels by position",
        )
    return obj[list(names)]


def recordings(
    u: Any,
    y: Any,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    label: str = "arrays",
    columns: bool = False,
) -> tuple[list[Recording], list[str], list[str]]:
    """Recordings from inputs ``u`` and outputs ``y`` (one signal each, or equally long lists of
    signals), with the input and output names: given ones first, then pandas names, then ``u`` /
    ``y`` (``u0``, ``u1``, ... for several channels).

    DataFrames that name their columns are matched by name: against the names of the first recording
    that gave them, and against given names when ``columns`` (names of a spec, which are column
    names); given names otherwise rename the channels by position."""
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
    match_ins, match_outs = columns and bool(ins), columns and bool(outs)
    for i, (ui, yi) in enumerate(zip(us, ys)):
        name = label if len(us) == 1 else f"{label}[{i}]"
        if match_ins:
            ui = by_name(ui, ins, "input", name)
        if match_outs:
            yi = by_name(yi, outs, "output", name)
        if is_pandas(ui) and is_pandas(yi) and not ui.index.equals(yi.index):
            raise DataError(
                f"the input and output of recording {i} have different indexes (first {ui.index[0]!r} and "
                f"{yi.index[0]!r}); samples are paired by position, so they must be the same times",
                name,
                "align them first (e.g. frame = pd.concat([u, y], axis=1).dropna()), or pass arrays",
            )
        ua, un = matrix(ui, "input")
        ya, yn = matrix(yi, "output")
        match_ins = match_ins or (not ins and names_columns(ui))
        match_outs = match_outs or (not outs and names_columns(yi))
        if ua.shape[0] != ya.shape[0]:
            raise DataError(
                f"recording {i}: the input has {ua.shape[0]} samples, the output {ya.shape[0]}",
                label,
                "give inputs and outputs of the same length",
            )
        ins = ins or un or _unused_names("u", "input", ua.shape[1], outs or yn or [])
        outs = outs or yn or _unused_names("y", "output", ya.shape[1], ins)
        for arr, names, what in ((ua, ins, "input"), (ya, outs, "output")):
            if arr.shape[1] != len(names):
                raise DataError(
                    f"recording {i}: {arr.shape[1]} {what} column(s) for the {len(names)} name(s) {names}",
                    label,
                    f"give every recording the same {what} columns",
                )
        check_finite(np.hstack([ua, ya]), ins + outs, name)
        recs.append(Recording(name, ua, ya))
    if set(ins) & set(outs):
        raise DataError(
            f"'{sorted(set(ins) & set(outs))[0]}' names both an input and an output",
            label,
            "rename one (Series.rename, DataFrame.rename) or give distinct input_names and output_names",
        )
    return recs, ins, outs


def _unused_names(prefix: str, other: str, k: int, taken: Sequence[str]) -> list[str]:
    """The default names of ``k`` unnamed channels (``u`` or ``y``), or ``input`` / ``output`` when the
    other side's names already hold them (an input Series named ``y`` beside an unnamed output)."""
    names = default_names(prefix, k)
    return default_names(other, k) if set(names) & set(taken) else names


def like_input(u: Any, y: np.ndarray, names: Sequence[str]) -> Any:
    """Predictions ``y`` (n, outputs) as a DataFrame indexed like ``u`` when ``u`` is a pandas object."""
    if not is_pandas(u):
        return y
    import pandas as pd

    return pd.DataFrame(y, index=u.index, columns=list(names))
