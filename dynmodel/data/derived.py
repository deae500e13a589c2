"""Derived input channels, computed from a recording and appended to the model inputs.

* time functions of t = k * sampling_time, the time since the recording's first sample:
  ``linear`` gives t, ``{saturating: tau}`` gives 1 - exp(-t / tau). Both are 0 at t = 0, so they
  model a drift that starts with the recording (thesis 6.2.2: a sensor zeroed at the start).
* ``direction``: d_t = +1 while the input moves up, -1 while it moves down. A reversal is declared
  once the input has moved back from its running extreme by more than ``deadband``, and d_t holds
  its value through standstill.
* ``since_reversal``: s_t = u_t - u_r, the input's change since the extreme u_r at which the last
  reversal started (hysteresis loops of friction are shaped by it).
* ``sign``: +1 where the input is above ``deadband``, -1 below ``-deadband``, 0 between: the sign of a
  velocity, on which a Coulomb or LuGre force switches.

Items are the JSON forms of the spec's ``derived_inputs`` (``{"time": "linear"}``,
``{"time": {"saturating": 30.0}}``, ``{"direction": "x", "deadband": 0.1}``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba
import numpy as np

from ..spec import DERIVED_KINDS


def time_function_name(fn: Any) -> str:
    """'linear' or 'saturating_<tau>' for a time function given as in the spec."""
    if fn == "linear":
        return "linear"
    return f"saturating_{float(fn['saturating']):g}"


def time_function(fn: Any, t: np.ndarray) -> np.ndarray:
    """Value of a time function (``"linear"`` or ``{"saturating": tau}``) at times ``t`` (seconds)."""
    if fn == "linear":
        return np.asarray(t, dtype=np.float64)
    return -np.expm1(-np.asarray(t, dtype=np.float64) / float(fn["saturating"]))


def time_matrix(functions: Sequence[Any], n: int, sampling_time: float) -> np.ndarray:
    """(n, len(functions)) values of the time functions at t = k * sampling_time."""
    t = np.arange(n, dtype=np.float64) * sampling_time
    if not functions:
        return np.zeros((n, 0))
    return np.column_stack([time_function(fn, t) for fn in functions])


@numba.njit(cache=True)
def _reversals(u: np.ndarray, deadband: float) -> tuple[np.ndarray, np.ndarray]:
    n = u.shape[0]
    d = np.empty(n)
    s = np.empty(n)
    if n == 0:
        return d, s
    direction = 1.0
    extreme = u[0]
    turn = u[0]
    started = False
    for t in range(n):
        x = u[t]
        if not started:
            # the first movement beyond the deadband sets the initial direction
            if x - u[0] > deadband:
                direction, started, extreme = 1.0, True, x
            elif u[0] - x > deadband:
                direction, started, extreme = -1.0, True, x
        elif direction > 0:
            if x >= extreme:
                extreme = x
            elif extreme - x > deadband:
                direction, turn, extreme = -1.0, extreme, x
        else:
            if x <= extreme:
                extreme = x
            elif x - extreme > deadband:
                direction, turn, extreme = 1.0, extreme, x
        d[t] = direction
        s[t] = x - turn
    return d, s


def reversals(u: np.ndarray, deadband: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Direction d_t (+1 / -1) and change since the last reversal s_t = u_t - u_r of a 1-D signal."""
    return _reversals(np.ascontiguousarray(u, dtype=np.float64), float(deadband))


#: an input moves like a position when it reverses less often than once per this many samples (the direction
#: of a noise-like input means nothing)
POSITION_STROKE = 20
#: the deadband of a reversal, as a fraction of the input's 1-99 % quantile span
DEADBAND_FRACTION = 0.005
#: an input held in every recording (it moves less than this fraction of its span within each) is no position
HELD_FRACTION = 0.1
#: a position moves in small steps: when the largest :data:`JUMP_SHARE` of its steps carry more than this share
#: of its whole path (sum of |u_t - u_{t-1}|), the input jumps between held values (a stepped or piecewise-constant
#: force, with or without noise or drift between the jumps) and is no position. Measured: a sampled sine 0.08,
#: the EMPS force command 0.46, a force held for 20-50 samples at random levels 1.0 (0.97 with drift)
JUMP_PATH = 0.7
#: the share of the steps (the largest) that :data:`JUMP_PATH` is measured on
JUMP_SHARE = 0.05


def position_like(pieces: Sequence[np.ndarray]) -> float | None:
    """The reversal deadband of a 1-D input given in ``pieces`` (recordings) when it moves like a position:
    fewer than one reversal per :data:`POSITION_STROKE` samples with a deadband of :data:`DEADBAND_FRACTION` of
    its 1-99 % span; None otherwise (a noise-like input, one that jumps between held values, or one held in every
    recording, as a set pressure)."""
    pieces = [np.asarray(p, dtype=np.float64) for p in pieces if len(p)]
    if not pieces:
        return None
    lo, hi = np.quantile(np.concatenate(pieces), [0.01, 0.99])
    deadband = DEADBAND_FRACTION * float(hi - lo)
    moving = max(float(np.subtract(*np.quantile(p, [0.99, 0.01]))) for p in pieces)
    if not deadband > 0 or moving < HELD_FRACTION * (hi - lo):
        return None
    steps = np.sort(np.concatenate([np.abs(np.diff(p)) for p in pieces]))
    largest = steps[len(steps) - max(1, int(JUMP_SHARE * len(steps))) :]
    if not steps.sum() > 0 or largest.sum() > JUMP_PATH * steps.sum():
        return None
    count = sum(int(np.sum(d[1:] != d[:-1])) for d in (reversals(p, deadband)[0] for p in pieces))
    n = sum(len(p) for p in pieces)
    return deadband if 0 < count and POSITION_STROKE * count <= n else None


def kind(item: dict[str, Any]) -> str:
    for key in DERIVED_KINDS:
        if key in item and item[key] is not None:
            return key
    raise ValueError(f"unknown derived input {item!r}")


def channel_name(item: dict[str, Any]) -> str:
    if item.get("name"):
        return str(item["name"])
    k = kind(item)
    if k == "time":
        return f"time_{time_function_name(item['time'])}"
    return f"{item[k]}_{k}"


def check(items: Sequence[dict[str, Any]], input_names: Sequence[str], output_names: Sequence[str] = ()) -> None:
    """ValueError naming the first item that refers to an unknown input or repeats a name (an input's, an
    output's or another derived channel's: a model term would not tell them apart)."""
    seen = set(input_names) | set(output_names)
    for i, item in enumerate(items):
        k = kind(item)
        if k != "time" and item[k] not in input_names:
            raise ValueError(
                f"derived_inputs[{i}]: '{item[k]}' is not an input column; the inputs are {list(input_names)}"
            )
        name = channel_name(item)
        if name in seen:
            raise ValueError(f"derived_inputs[{i}]: the channel name '{name}' is already taken; give another 'name'")
        seen.add(name)


def compute(
    items: Sequence[dict[str, Any]], u: np.ndarray, input_names: Sequence[str], sampling_time: float
) -> np.ndarray:
    """(n, len(items)) derived channels of one recording's physical inputs ``u`` (n, n_inputs)."""
    n = u.shape[0]
    out = np.empty((n, len(items)))
    for j, item in enumerate(items):
        k = kind(item)
        if k == "time":
            out[:, j] = time_matrix([item["time"]], n, sampling_time)[:, 0]
            continue
        x = u[:, list(input_names).index(item[k])]
        deadband = float(item.get("deadband") or 0.0)
        if k == "sign":
            out[:, j] = np.sign(x) * (np.abs(x) > deadband)
        else:
            d, s = reversals(x, deadband)
            out[:, j] = d if k == "direction" else s
    return out
