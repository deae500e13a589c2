"""Time stamps: check a recording's sampling, or interpolate it onto a uniform grid.

Rigs that log on an event loop (e.g. the pneumatic seal friction data) give non-uniform time
stamps; discrete-time models need a uniform grid. With ``resample: h`` every selected column is
interpolated linearly at t_0 + k h, k = 0 .. floor((t_end - t_0) / h).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import DataError

#: stamps count as uniform when every step is within this fraction of the median step
UNIFORM_TOLERANCE = 0.01
#: recordings count as sampled alike when their steps agree to this fraction
SAME_STEP = 1e-4
#: gaps longer than this many grid steps are reported when bridged by interpolation
GAP_WARNING = 5


def check_stamps(t: np.ndarray, where: str) -> np.ndarray:
    """The steps of finite, strictly increasing time stamps (DataError otherwise)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2:
        raise DataError("the time column needs at least two samples", where, "check data.time_column")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"the time column is not finite at sample {int(bad[0])}", where, "fix or remove that row")
    dt = np.diff(t)
    back = np.flatnonzero(dt <= 0)
    if back.size:
        k = int(back[0])
        step = float(np.median(dt[dt > 0])) if (dt > 0).any() else 0.0
        resets = np.flatnonzero(dt < -RESET * step)  # the clock starts again: another run follows
        fix = (
            "the clock restarts there (runs logged one after the other): make each run a recording of its own with "
            f"data.segments: {_segments_around(resets, len(t))} (or data.path: a list of files)"
            if k in resets
            else "sort the rows by time and remove repeated stamps"
        )
        raise DataError(f"the time stamps do not increase at sample {k + 1} ({t[k]:g} then {t[k + 1]:g})", where, fix)
    return dt


#: a step back by more than this many sampling steps is a clock that restarts (a new run), not a row out of order
RESET = 10


def _segments_around(gaps: np.ndarray, n: int) -> str:
    """The data.segments that leave out the steps ``gaps`` (a gap after sample g splits at g + 1)."""
    cuts = [0, *(int(g) + 1 for g in gaps), n]
    shown = [f"[{a}, {b}]" for a, b in zip(cuts[:-1], cuts[1:]) if b - a > 1]
    return "[" + ", ".join(shown[:4]) + (", ..." if len(shown) > 4 else "") + "]"


def uniform(t: np.ndarray, data: np.ndarray, step: float | None, where: str) -> tuple[np.ndarray, float]:
    """(data on a uniform grid, its step in seconds) from time stamps ``t`` in seconds.

    ``step=None``: the stamps must already be uniform (every step within 1 % of the median); the data
    is returned as is and the step is the mean one, (t_end - t_0) / (n - 1), which rounding of the
    stamps disturbs least. Otherwise every column is interpolated linearly onto the grid."""
    dt = check_stamps(t, where)
    if step is None:
        med = float(np.median(dt))
        worst = float(np.max(np.abs(dt - med)))
        if worst > UNIFORM_TOLERANCE * med:
            gaps = np.flatnonzero(dt > GAP_WARNING * med)
            if gaps.size:  # missing samples: interpolation would invent the signals there
                g = int(gaps[np.argmax(dt[gaps])])
                raise DataError(
                    f"the time stamps jump by {dt[g]:.6g} s after t = {t[g]:.6g} s (sample {g}; median step "
                    f"{med:.6g} s{f', {gaps.size} such gaps' if gaps.size > 1 else ''}): samples are missing there",
                    where,
                    "cut the file at the gap into recordings of their own (data.segments: "
                    f"{_segments_around(gaps, len(t))}), or add 'resample: {med:.6g}' to bridge it by linear "
                    "interpolation",
                )
            mean = float((t[-1] - t[0]) / (len(t) - 1))  # rounded stamps (1 ms on a 3.3 ms period) skew the median
            raise DataError(
                f"the time stamps are not uniform (steps from {dt.min():.6g} to {dt.max():.6g} s, median {med:.6g} s, "
                f"mean {mean:.6g} s)",
                where,
                f"add 'resample: {mean:.6g}' to interpolate onto a uniform grid",
            )
        return data, float((t[-1] - t[0]) / (len(t) - 1))
    t0 = float(t[0])
    k = int(np.floor((float(t[-1]) - t0) / step + 1e-9)) + 1
    if k < 2:
        raise DataError(
            f"the recording spans {t[-1] - t0:g} s, less than two resampling steps of {step:g} s",
            where,
            "use a smaller resample step",
        )
    grid = t0 + step * np.arange(k)
    out = np.column_stack([np.interp(grid, t, data[:, j]) for j in range(data.shape[1])])
    gaps = np.flatnonzero(dt > GAP_WARNING * step)
    if gaps.size:
        g = int(gaps[np.argmax(dt[gaps])])
        warnings.warn(
            f"{where}: {gaps.size} gap(s) longer than {GAP_WARNING} resampling steps were bridged by linear "
            f"interpolation (largest {dt[g]:.6g} s after t = {t[g] - t0:.6g} s)",
            stacklevel=2,
        )
    return out, float(step)
