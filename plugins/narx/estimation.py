"""Free-running estimation (cost ``mse_inf``, eq. 3.15) and free-run scoring of a split.

The weights w minimise sum_k sum_t (y_t[k] - yhat_t[k](w))^2 / (N var(y[k])) over the training
samples, where yhat is the free run of each recording from its start. The solver is scipy's
nonlinear least squares (Levenberg-Marquardt or trust region) with the exact Jacobian from the
compiled sensitivity recursion (:func:`kernels.free_run_jacobian`). If the starting model
diverges in free run, the error-propagation scheme of thesis 6.3.2 is used: the fed-back signal
is a mixture ``mix * y + (1 - mix) * yhat`` whose measured share ``mix`` drops step by step to 0,
each step starting from the previous solution.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from scipy.optimize import least_squares

from dynmodel.data.training import TrainingData

from . import kernels
from .lm import levenberg_marquardt

#: residual of a sample after a breakdown of the run (NaN), in units of the output's std
_BROKEN = 1e3


@dataclass
class Structure:
    """Everything the kernels need besides the weights and the data."""

    src: np.ndarray
    ch: np.ndarray
    lag: np.ndarray
    ptr: np.ndarray
    reg: np.ndarray
    pw: np.ndarray
    out: np.ndarray
    n_out: int
    start: int  # first predicted sample of a run (the initial past is measured before it)
    clip_lo: np.ndarray
    clip_hi: np.ndarray
    settle: int = 0  # samples of pre-roll with the first input held (initial: settled), not returned

    def __post_init__(self) -> None:
        if self.settle and self.start:
            raise ValueError("a settled free run starts from rest, not from measured outputs (start 0)")

    def settled(self, u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``u`` and ``y`` preceded by the pre-roll: ``settle`` samples of the first input, outputs unknown."""
        P = self.settle
        u_pre = np.concatenate([np.repeat(u[:1], P, axis=0), u])
        y_pre = np.concatenate([np.full((P, y.shape[1]), np.nan), y])
        return np.ascontiguousarray(u_pre), np.ascontiguousarray(y_pre)

    def without_settling(self) -> Structure:
        """The same structure run on arrays that already hold the pre-roll (:meth:`settled`)."""
        return replace(self, settle=0)

    def _after_pre_roll(self, div: int) -> int:
        """The diverged sample of a run with its pre-roll, counted from the run's first sample (0 when the
        pre-roll itself diverged), or -1."""
        return -1 if div < 0 else max(div - self.settle, 0)

    def mixture(self, mix) -> np.ndarray:
        """The measured share of the fed-back signal, one value per output."""
        return np.ascontiguousarray(np.broadcast_to(np.asarray(mix, dtype=np.float64), (self.n_out,)))

    def run(
        self,
        u: np.ndarray,
        y: np.ndarray,
        w: np.ndarray,
        mix=0.0,
        band: tuple[np.ndarray, np.ndarray] | None = None,
        clip=None,
    ):
        if self.settle and len(u):
            yhat, div = self.without_settling().run(*self.settled(u, y), w, mix, band, clip)
            return yhat[self.settle :], self._after_pre_roll(div)
        lo, hi = band if band is not None else (np.full(self.n_out, -np.inf), np.full(self.n_out, np.inf))
        clo, chi = clip if clip is not None else (self.clip_lo, self.clip_hi)
        return kernels.free_run(
            u,
            y,
            self.src,
            self.ch,
            self.lag,
            self.ptr,
            self.reg,
            self.pw,
            self.out,
            w,
            self.n_out,
            self.start,
            self.mixture(mix),
            clo,
            chi,
            lo,
            hi,
        )

    def run_jacobian(self, u: np.ndarray, y: np.ndarray, w: np.ndarray, mix, clip):
        if self.settle and len(u):
            yhat, J, div = self.without_settling().run_jacobian(*self.settled(u, y), w, mix, clip)
            return yhat[self.settle :], J[self.settle :], self._after_pre_roll(div)
        inf = np.full(self.n_out, np.inf)
        return kernels.free_run_jacobian(
            u,
            y,
            self.src,
            self.ch,
            self.lag,
            self.ptr,
            self.reg,
            self.pw,
            self.out,
            w,
            self.n_out,
            self.start,
            self.mixture(mix),
            clip[0],
            clip[1],
            -inf,
            inf,
        )


def make_structure(
    emb,
    exponents: np.ndarray,
    term_output: np.ndarray,
    n_out: int,
    start: int,
    clip: tuple[np.ndarray, np.ndarray],
    settle: int = 0,
) -> Structure:
    from .embedding import factor_lists

    src, ch, lag = emb.arrays()
    ptr, reg, pw = factor_lists(exponents)
    return Structure(
        src,
        ch,
        lag,
        ptr,
        reg,
        pw,
        np.asarray(term_output, dtype=np.int64),
        n_out,
        start,
        np.asarray(clip[0], dtype=np.float64),
        np.asarray(clip[1], dtype=np.float64),
        settle,
    )


@dataclass
class Scored:
    """Per recording: the rows of a split that are scored (t >= start, target known)."""

    rows: list[np.ndarray]
    stop: list[int]  # run each recording up to here
    var: np.ndarray  # per output, over the scored targets
    n: int

    @classmethod
    def of(cls, data: TrainingData, split: str, start: int) -> Scored:
        rows: list[list[np.ndarray]] = [[] for _ in data.series]
        for s, a, b in data.segments.get(split, []):
            a = max(a, start)
            if a < b:
                t = np.arange(a, b)
                rows[s].append(t[np.isfinite(data.series[s].y[a:b]).all(axis=1)])
        rr = [np.concatenate(r) if r else np.zeros(0, dtype=np.int64) for r in rows]
        stop = [int(r[-1]) + 1 if r.size else 0 for r in rr]
        ys = [data.series[s].y[r] for s, r in enumerate(rr) if r.size]
        Y = np.concatenate(ys) if ys else np.zeros((0, data.n_outputs))
        var = np.maximum(np.var(Y, axis=0), 1e-300) if len(Y) else np.ones(data.n_outputs)
        return cls(rr, stop, var, int(len(Y)))


def segment_view(data: TrainingData, split: str, lead: int) -> TrainingData:
    """The segments of ``split`` cut out of their recordings, each with the ``lead`` samples before
    it (measured outputs of the training split: the initial past of a free run started there, as a
    test starts from a state-initialisation window). Scoring a free run on this view costs the
    split's length instead of its recording's (Silverbox: a fifth)."""
    from dynmodel.data.training import Series

    series, segments = [], []
    for s, a, b in data.segments.get(split, []):
        a0 = max(0, a - lead)
        ser = data.series[s]
        series.append(Series(ser.u[a0:b], ser.y[a0:b]))
        segments.append((len(series) - 1, a - a0, b - a0))
    return TrainingData(
        series,
        {split: segments},
        data.input_names,
        data.output_names,
        data.sampling_time,
        data.output_offset,
        data.output_scale,
    )


def split_error(
    st: Structure, data: TrainingData, scored: Scored, w: np.ndarray, band: tuple[np.ndarray, np.ndarray]
) -> float:
    """Mean over outputs of the free-run NMSE (a fraction) on the scored rows; inf if a run diverges."""
    sq = np.zeros(st.n_out)
    for s, rows in enumerate(scored.rows):
        if not rows.size:
            continue
        ser = data.series[s]
        stop = scored.stop[s]
        yhat, div = st.run(ser.u[:stop], ser.y[:stop], w, 0.0, band)
        if div >= 0:
            return np.inf
        sq += np.sum((ser.y[rows] - yhat[rows]) ** 2, axis=0)
    return float(np.mean(sq / scored.n / scored.var)) if scored.n else np.nan


def one_output(
    n_out: int, k: int, band: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Feedback mix and band to run output ``k`` alone: the other outputs fed back measured (mix 1) and
    unbounded, output k free-running (mix 0) within ``band``."""
    mix = np.ones(n_out)
    mix[k] = 0.0
    lo = np.full(n_out, -np.inf)
    hi = np.full(n_out, np.inf)
    lo[k], hi[k] = band[0][k], band[1][k]
    return mix, (lo, hi)


def output_error(
    st: Structure,
    data: TrainingData,
    scored: Scored,
    w: np.ndarray,
    band: tuple[np.ndarray, np.ndarray],
    k: int,
) -> float:
    """Free-run NMSE (a fraction) of output ``k`` alone on the scored rows, the other outputs fed back
    measured (mix 1; ``st`` holds only output k's terms); inf when output k leaves the band."""
    mix, bounds = one_output(st.n_out, k, band)
    sq = 0.0
    for s, rows in enumerate(scored.rows):
        if not rows.size:
            continue
        ser = data.series[s]
        stop = scored.stop[s]
        yhat, div = st.run(ser.u[:stop], ser.y[:stop], w, mix, bounds)
        if div >= 0:
            return np.inf
        sq += float(np.sum((ser.y[rows, k] - yhat[rows, k]) ** 2))
    return sq / scored.n / scored.var[k] if scored.n else np.nan


def diverges(
    st: Structure, data: TrainingData, scored: Scored, w: np.ndarray, band: tuple[np.ndarray, np.ndarray], mix=0.0
) -> bool:
    """Whether a free run of any recording leaves the band before its last scored row."""
    return any(
        st.run(data.series[s].u[: scored.stop[s]], data.series[s].y[: scored.stop[s]], w, mix, band)[1] >= 0
        for s, rows in enumerate(scored.rows)
        if rows.size
    )


@dataclass
class FreeRunProblem:
    """Residuals r(w) = (yhat_t - y_t) / sqrt(N var_k) of the (mixed) free run on training rows,
    optionally with ridge rows sqrt(alpha_k / (N var_k)) w_j for the penalised terms."""

    st: Structure
    data: TrainingData
    scored: Scored
    clip: tuple[np.ndarray, np.ndarray]  # keeps residuals finite: the user's bounds or the divergence band
    penalty: np.ndarray | None = None  # per term, sqrt of the scaled ridge factor (0: not penalised)
    mix: float = 0.0
    scale: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.scale = 1.0 / np.sqrt(self.scored.n * self.scored.var)

    def series(self):
        """(scored rows, inputs, outputs) of each training recording with scored rows, up to its last one."""
        for s, rows in enumerate(self.scored.rows):
            if rows.size:
                ser = self.data.series[s]
                stop = self.scored.stop[s]
                yield rows, ser.u[:stop], ser.y[:stop]

    def residuals(self, w: np.ndarray) -> np.ndarray:
        parts = []
        for rows, u, y in self.series():
            yhat, _ = self.st.run(u, y, w, self.mix, None, self.clip)
            r = (yhat[rows] - y[rows]) * self.scale
            parts.append(np.where(np.isfinite(r), r, _BROKEN).ravel())
        if self.penalty is not None:
            parts.append(self.penalty * w)
        return np.concatenate(parts)

    def jacobian(self, w: np.ndarray) -> np.ndarray:
        parts = []
        for rows, u, y in self.series():
            _, J, _ = self.st.run_jacobian(u, y, w, self.mix, self.clip)
            # scored rows are one contiguous run in practice: a view, not a copy of the N x p matrix
            block = J[rows[0] : rows[-1] + 1] if rows[-1] - rows[0] + 1 == rows.size else J[rows]
            block *= self.scale[None, :, None]
            parts.append(block.reshape(-1, w.size))
        if self.penalty is not None:
            parts.append(np.diag(self.penalty))
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def cost(self, w: np.ndarray) -> float:
        r = self.residuals(w)
        return float(r @ r)


def refine(
    problem: FreeRunProblem,
    w0: np.ndarray,
    mixes: list[float],
    solver: Literal["lm", "trf"],
    max_nfev: int,
    tol: float,
    after_step: Callable[[float, np.ndarray, object], None] | None = None,
) -> np.ndarray:
    """Solve the free-running least-squares problem at each mixture in turn (the last one is 0)."""
    w = np.asarray(w0, dtype=np.float64).copy()
    for mix in mixes:
        problem.mix = mix
        res: Any
        if solver == "lm":
            res = levenberg_marquardt(
                problem.residuals, problem.jacobian, w, max_nfev=max_nfev, ftol=tol, xtol=tol, gtol=tol
            )
        else:
            res = least_squares(
                problem.residuals,
                w,
                jac=problem.jacobian,
                method=solver,
                x_scale="jac",
                ftol=tol,
                xtol=tol,
                gtol=tol,
                max_nfev=max_nfev,
            )
        if np.all(np.isfinite(res.x)) and res.cost <= 0.5 * problem.cost(w) * (1 + 1e-12):
            w = res.x.copy()
        if after_step is not None:
            after_step(mix, w, res)
    return w
