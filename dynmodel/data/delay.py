"""The dead time of each input: how many samples pass before it acts on an output.

For an input u and an output y, an ARX model with a delay d (``na`` = 2 output lags, ``nb`` = 3 input taps
from d, and a constant),

    y[t] = c + a1 y[t-1] + a2 y[t-2] + b0 u[t-d] + b1 u[t-d-1] + b2 u[t-d-2] + e[t],

is fitted by least squares for every d in 0 .. D on the same samples (pieces with a missing sample left out:
the data loader refuses those anyway), and the delay whose one-step mean squared residual V(d) is the lowest is that pair's dead time (the criterion
of Ljung's ``delayest``). The input acts on that output when its best model leaves at most (1 - :data:`GAIN`)
of the residual of the model without it (V_AR), and it acts after that dead time when its best model also
leaves at most (1 - GAIN) of V(0); otherwise at once (0). An input's dead time is the shortest over the
outputs it acts on (its first effect on any of them), reported when it is at least :data:`MIN_DELAY`
samples: a polynomial NARX on lags 0 .. L reaches shorter ones itself.

Measured on a generated plant (tanh, a dead time of 25 samples, a first-order lag of pole 0.97, 1 % output
noise): V(25) = 0.47 V(0), and 0.60 / 0.47 / 0.47 at 22 / 23 / 24; on Silverbox, Cascaded Tanks, Bouc-Wen,
EMPS and the pneumatic seals no input has one. A smooth path of higher order than the ARX model can look
delayed: on a two-mass chain forced at the first mass, the second mass's position fits best at d = 4 (0.80
V(0)); the first mass's acts at once, so the force has no dead time (counting only the outputs where a delay
counts had reported 4).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: the longest dead time looked for (samples)
MAX_DELAY = 100
#: a dead time counts when its ARX model's one-step residuals are at most (1 - GAIN) x those without a delay
GAIN = 0.1
#: dead times shorter than this are not reported (the default lags reach them)
MIN_DELAY = 3
#: training samples (the last ones) the dead times are read on by the search and the narx default (six inputs
#: and outputs: about 1 s)
READ_ON = 50000
#: output lags and input taps of the ARX model
NA, NB = 2, 3


def _losses(u: Sequence[np.ndarray], y: Sequence[np.ndarray], D: int) -> np.ndarray:
    """V(d), d = 0 .. D: the mean squared residual of the ARX model with delay d over the samples
    t >= D + NB - 1 of every piece (finite pieces only; NaN when none is long enough), and last, V_AR: that of
    the model without the input. From the normal equations, their sums taken as dot products of shifted views
    (no regressor matrix is built: six inputs and outputs on 50000 samples take about a second, not twenty)."""
    first = D + NB - 1
    pieces = [
        (a, b)
        for a, b in zip(u, y)
        if len(a) > first + 10 * (NA + NB + 1) and np.isfinite(a).all() and np.isfinite(b).all()
    ]
    V = np.full(D + 2, np.nan)
    if not pieces:
        return V
    p, m = 1 + NA, 1 + NA + NB  # the columns without the input, and all of them
    gram = np.zeros((D + 1, m, m))  # upper triangles
    rhs = np.zeros((D + 1, m))
    tt, count = 0.0, 0
    for a, b in pieces:
        n = len(b)
        target = b[first:]
        cols = [np.ones(n - first)] + [b[first - k : n - k] for k in range(1, NA + 1)]
        taps = [a[first - s : n - s] for s in range(D + NB)]  # u[t - s], s = d + k
        gram[:, :p, :p] += np.array([[x @ z for z in cols] for x in cols])
        rhs[:, :p] += np.array([x @ target for x in cols])
        cross = np.array([[x @ z for z in taps] for x in cols])  # (p, D + NB)
        tap_rhs = np.array([z @ target for z in taps])
        for k in range(NB):
            gram[:, :p, p + k] += cross[:, k : k + D + 1].T
            rhs[:, p + k] += tap_rhs[k : k + D + 1]
            for j in range(k, NB):  # u[t-d-k] . u[t-d-j] for every d
                gram[:, p + k, p + j] += [taps[d + k] @ taps[d + j] for d in range(D + 1)]
        tt += float(target @ target)
        count += len(target)

    def residual(g: np.ndarray, r: np.ndarray) -> float:
        full = np.triu(g) + np.triu(g, 1).T
        w = np.linalg.lstsq(full, r, rcond=None)[0]
        return max(tt - float(w @ r), 0.0) / count

    for d in range(D + 1):
        V[d] = residual(gram[d], rhs[d])
    V[D + 1] = residual(gram[0, :p, :p], rhs[0, :p])
    return V


def dead_time(u: Sequence[np.ndarray], y: Sequence[np.ndarray]) -> int | None:
    """The dead time (samples) of input ``u`` on output ``y`` (pieces of the same recordings, 1-D each; a piece
    with NaN is left out): 0 when the input acts at once (no delay counts, see the module docstring); None when
    it barely acts on that output, or the pieces are too short to tell."""
    longest = max((len(a) for a in u), default=0)
    D = min(MAX_DELAY, longest // 4)
    if D < MIN_DELAY:
        return None
    cat_u, cat_y = np.concatenate(u).astype(float), np.concatenate(y).astype(float)
    with np.errstate(invalid="ignore"):
        su, sy = float(np.nanstd(cat_u)), float(np.nanstd(cat_y))
    if not (su > 0 and sy > 0):
        return None
    mu, my = float(np.nanmean(cat_u)), float(np.nanmean(cat_y))
    V = _losses(
        [(np.asarray(a, dtype=float) - mu) / su for a in u], [(np.asarray(b, dtype=float) - my) / sy for b in y], D
    )
    V, V_ar = V[:-1], V[-1]
    if not (np.isfinite(V[0]) and V[0] > 0 and np.isfinite(V_ar)):
        return None
    d = int(np.nanargmin(V))
    if V[d] > (1 - GAIN) * V_ar:
        return None  # the input barely acts on this output
    return d if V[d] <= (1 - GAIN) * V[0] else 0


def dead_times(u_pieces: Sequence[np.ndarray], y_pieces: Sequence[np.ndarray], names: Sequence[str]) -> dict[str, int]:
    """Per input (columns of ``u_pieces``, named ``names``) its dead time on the outputs (columns of
    ``y_pieces``) when it is at least :data:`MIN_DELAY` samples: the shortest over the outputs it acts on."""
    out: dict[str, int] = {}
    for j, name in enumerate(names):
        found = [
            dead_time([p[:, j] for p in u_pieces], [q[:, i] for q in y_pieces]) for i in range(y_pieces[0].shape[1])
        ]
        delays = [d for d in found if d is not None]
        if delays and min(delays) >= MIN_DELAY:
            out[name] = min(delays)
    return out
