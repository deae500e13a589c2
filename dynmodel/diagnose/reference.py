"""Quick references a model must beat before a diagnosis may call it adequate: the training mean, and a
linear ARX / OE model estimated on the free-running error. Family-free: plain least squares and a
Gauss-Newton refinement in numpy / scipy.

Linear model, per output k, in training-standardised units:

    y_t = sum_{i=1..na} a_i y_{t-i} + sum_j sum_{l=0..nb-1} b_{jl} u_{j,t-l} + c          (ARX)

fitted by least squares on the training rows (measured past outputs, one step ahead), for the orders
(na, nb) = (1, 2), (2, 3), (3, 4), (4, 5), (6, 7), (8, 9). The free run feeds its own outputs back
from the sample ``na`` of every recording on (the first samples are the measured ones, the warm-up of a
polynomial NARX model with measured initial conditions). The best order on the free-running error of the
validation split (the training split with a final-prediction-error penalty when there is none) is then
refined on the free-running error of the training rows (output error, OE: scipy's least_squares with a
trust region, the denominator kept stable), and whichever of ARX and OE runs better on that split is the
reference. Free runs that leave the training range widened by ten range widths count as diverged
(infinite NMSE).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import optimize, signal

from ..data.dataset import Dataset

ORDERS = ((1, 2), (2, 3), (3, 4), (4, 5), (6, 7), (8, 9))
BAND = 10.0  # range widths beyond the training output range that count as divergence
MAX_EVALS = 15  # evaluations of the OE refinement (each with a finite-difference Jacobian: p free runs)


@dataclass
class Linear:
    """One linear model per output: a (na,), b (n_inputs, nb), c."""

    na: int
    nb: int
    coef: list[tuple[np.ndarray, np.ndarray, float]]
    method: str = "ARX (least squares)"
    nmse: dict[str, float] = field(default_factory=dict)
    runs: list[np.ndarray] = field(default_factory=list)  # per recording (n, n_outputs), physical units

    @property
    def warmup(self) -> int:
        return max(self.na, self.nb - 1)

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": "linear",
            "method": self.method,
            "output_order": self.na,
            "input_order": self.nb,
            "output_lags": [1, self.na],
            "input_lags": [0, self.nb - 1],
            "nmse": {k: (None if not np.isfinite(v) else float(v)) for k, v in self.nmse.items()},
        }


@dataclass
class References:
    mean_nmse: dict[str, float]
    linear: Linear | None
    seconds: float = 0.0

    def to_json(self) -> dict[str, Any]:
        return {
            "mean": {"kind": "training mean", "nmse": self.mean_nmse},
            "linear": None if self.linear is None else self.linear.to_json(),
            "seconds": self.seconds,
        }


class _Data:
    """Standardised recordings and the rows of each split."""

    def __init__(self, ds: Dataset):
        self.ds = ds
        train = ds.scored("train")
        u = np.concatenate([ds.recordings[r].u[a:b] for r, a, b in train])
        y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in train])
        self.u_mu, self.u_sd = u.mean(axis=0), np.where(u.std(axis=0) > 0, u.std(axis=0), 1.0)
        self.y_mu, self.y_sd = y.mean(axis=0), np.where(y.std(axis=0) > 0, y.std(axis=0), 1.0)
        self.u = [(r.u - self.u_mu) / self.u_sd for r in ds.recordings]
        self.y = [(r.y - self.y_mu) / self.y_sd for r in ds.recordings]
        ys = (y - self.y_mu) / self.y_sd
        lo, hi = ys.min(axis=0), ys.max(axis=0)
        width = np.maximum(hi - lo, 1e-12)
        self.lo, self.hi = lo - BAND * width, hi + BAND * width
        self.train = train


def _regressors(u: np.ndarray, y: np.ndarray, k: int, na: int, nb: int, rows: np.ndarray) -> np.ndarray:
    cols = [y[rows - i, k] for i in range(1, na + 1)]
    for j in range(u.shape[1]):
        cols += [u[rows - lag, j] for lag in range(nb)]
    cols.append(np.ones(len(rows)))
    return np.column_stack(cols)


def _fit_arx(d: _Data, na: int, nb: int) -> Linear | None:
    m = max(na, nb - 1)
    coef = []
    for k in range(d.y[0].shape[1]):
        X, t = [], []
        for r, a, b in d.train:
            rows = np.arange(max(a, m), b)
            if rows.size:
                X.append(_regressors(d.u[r], d.y[r], k, na, nb, rows))
                t.append(d.y[r][rows, k])
        if not X:
            return None
        A, target = np.vstack(X), np.concatenate(t)
        if A.shape[0] <= 2 * A.shape[1]:
            return None
        theta, *_ = np.linalg.lstsq(A, target, rcond=None)
        coef.append((theta[:na], theta[na:-1].reshape(-1, nb), float(theta[-1])))
    return Linear(na, nb, coef)


def _stable(a: np.ndarray) -> np.ndarray:
    """Denominator coefficients with every root reflected into the unit circle (radius at most 0.999)."""
    if a.size == 0:
        return a
    roots = np.roots(np.r_[1.0, -a])
    big = np.abs(roots) >= 1.0
    if not big.any():
        return a
    roots[big] = 0.999 / np.conj(roots[big])
    return -np.real(np.poly(roots))[1:]


def _simulate(u: np.ndarray, y: np.ndarray, k: int, a: np.ndarray, b: np.ndarray, c: float, m: int, lo, hi):
    """Free run of output k over one recording (standardised), measured for t < m; NaN after divergence."""
    n = len(u)
    out = np.empty(n)
    out[:m] = y[:m, k]
    if n <= m:
        return out
    x = np.full(n, c)
    for j in range(u.shape[1]):
        x += signal.lfilter(b[j], [1.0], u[:, j])
    den = np.r_[1.0, -a]
    past = y[:m, k][::-1][: len(a)]
    zi = signal.lfiltic([1.0], den, past) if len(a) else np.zeros(0)
    if len(a):
        out[m:] = signal.lfilter([1.0], den, x[m:], zi=zi)[0]
    else:
        out[m:] = x[m:]
    bad = ~np.isfinite(out) | (out < lo[k]) | (out > hi[k])
    if bad.any():
        out[int(np.argmax(bad)) :] = np.nan
    return out


def _runs(d: _Data, lin: Linear) -> list[np.ndarray]:
    """Free runs of every recording, physical units."""
    out = []
    for u, y in zip(d.u, d.y):
        cols = [_simulate(u, y, k, a, b, c, lin.warmup, d.lo, d.hi) for k, (a, b, c) in enumerate(lin.coef)]
        out.append(np.column_stack(cols) * d.y_sd + d.y_mu)
    return out


def _nmse(ds: Dataset, runs: list[np.ndarray], split: str, warmup: int) -> float:
    rows = ds.scored(split, warmup=warmup)
    if not rows:
        return float("nan")
    y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
    yh = np.concatenate([runs[r][a:b] for r, a, b in rows])
    if not np.isfinite(yh).all():
        return float("inf")
    var = np.maximum(y.var(axis=0), np.finfo(float).tiny)
    return float(np.mean(100.0 * ((y - yh) ** 2).mean(axis=0) / var))


def _refine_output(d: _Data, k: int, a0: np.ndarray, b0: np.ndarray, c0: float, m: int):
    """Output-error refinement of output k's coefficients on the training rows' free run; None on failure."""
    na = len(a0)
    ni, nb = b0.shape

    def unpack(theta: np.ndarray):
        return _stable(theta[:na]), theta[na : na + ni * nb].reshape(ni, nb), float(theta[-1])

    def residual(theta: np.ndarray) -> np.ndarray:
        a, b, c = unpack(theta)
        res = []
        for r, start, stop in d.train:
            sim = _simulate(d.u[r][:stop], d.y[r][:stop], k, a, b, c, m, d.lo, d.hi)
            e = d.y[r][max(start, m) : stop, k] - sim[max(start, m) : stop]
            res.append(np.nan_to_num(e, nan=1e3))
        return np.concatenate(res)

    theta0 = np.r_[_stable(a0), b0.ravel(), c0]
    try:
        sol = optimize.least_squares(residual, theta0, method="trf", max_nfev=MAX_EVALS)
    except (ValueError, np.linalg.LinAlgError):
        return None
    return unpack(sol.x) if np.isfinite(sol.x).all() else None


def _refine(d: _Data, lin: Linear) -> Linear | None:
    """Output-error refinement of every output's coefficients."""
    coef = []
    for k, (a0, b0, c0) in enumerate(lin.coef):
        out = _refine_output(d, k, a0, b0, c0, lin.warmup)
        if out is None:
            return None
        coef.append(out)
    return Linear(lin.na, lin.nb, coef, "OE (free-running error)")


def references(ds: Dataset) -> References:
    """The training mean and the linear ARX / OE reference on the dataset's splits."""
    import time

    t0 = time.perf_counter()
    d = _Data(ds)
    splits = ds.splits()
    mean_nmse = {}
    for split in splits:
        rows = ds.scored(split)
        y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
        var = np.maximum(y.var(axis=0), np.finfo(float).tiny)
        mean_nmse[split] = float(np.mean(100.0 * ((y - d.y_mu) ** 2).mean(axis=0) / var))
    select = "validation" if "validation" in splits else "train"
    n_train = sum(b - a for _, a, b in d.train)
    best: tuple[float, Linear] | None = None
    for na, nb in ORDERS:
        lin = _fit_arx(d, na, nb)
        if lin is None:
            continue
        runs = _runs(d, lin)
        score = _nmse(ds, runs, select, lin.warmup)
        if select == "train":  # final prediction error: penalise the parameters
            p = na + nb * d.u[0].shape[1] + 1
            score *= (n_train + p) / max(n_train - p, 1)
        if np.isfinite(score) and (best is None or score < best[0]):
            best = (score, lin)
    if best is None:
        return References(mean_nmse, None, time.perf_counter() - t0)
    arx = best[1]
    candidates = [arx]
    oe = _refine(d, arx)
    if oe is not None:
        candidates.append(oe)
    scored = []
    for lin in candidates:
        lin.runs = _runs(d, lin)
        lin.nmse = {s: _nmse(ds, lin.runs, s, lin.warmup) for s in splits}
        scored.append((lin.nmse.get(select, np.inf), lin.method != "ARX (least squares)", lin))
    chosen = min(scored, key=lambda x: (x[0], x[1]))[2]
    return References(mean_nmse, chosen, time.perf_counter() - t0)


def linear_envelope(ds: Dataset) -> dict[str, tuple[list[float], list[float]]] | None:
    """Per split, the range (low, high per output) of the linear reference's free run, for the search's
    linear-system band (:mod:`dynmodel.search.checks`); None without a reference. Reads the outputs of the
    training and validation splits only: the reference is estimated and chosen there, and a recording whose
    start lies in neither (a test recording of its own) is run from rest, its past outputs at the training mean."""
    fit_splits = [s for s in ("train", "validation") if ds.ranges.get(s)]
    lin = references(replace(ds, ranges={s: ds.ranges[s] for s in fit_splits})).linear
    if lin is None:
        return None
    d = _Data(ds)
    measured = {r for s in fit_splits for r, a, _ in ds.ranges[s] if a == 0}
    out: dict[str, tuple[list[float], list[float]]] = {}
    runs = []
    for i, (u, y) in enumerate(zip(d.u, d.y)):
        start = y if i in measured else np.zeros_like(y)
        cols = [_simulate(u, start, k, a, b, c, lin.warmup, d.lo, d.hi) for k, (a, b, c) in enumerate(lin.coef)]
        runs.append(np.column_stack(cols) * d.y_sd + d.y_mu)
    for split in ds.splits():
        rows = ds.scored(split, warmup=lin.warmup)
        if not rows:
            continue
        run = np.concatenate([runs[r][a:b] for r, a, b in rows])
        if run.size and np.isfinite(run).all():  # a diverging reference vouches for nothing
            out[split] = (run.min(axis=0).tolist(), run.max(axis=0).tolist())
    return out
