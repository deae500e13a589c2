"""Structure optimization of a tanh network by simulated annealing (thesis 5.3.4).

The state is the network (C, input weights, biases, relaxations); the objective is the
free-running NMSE on the validation split of the network whose readout is fitted by least
squares on the training split. One evaluation runs the compiled kernel over all series into a
reused feature buffer, forms the Gram matrix of the training rows with BLAS and solves the
readout from it: nothing is allocated per step but the small K x K system.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from dynmodel import kernels
from dynmodel.data.training import TrainingData
from dynmodel.regression import fos_select_qr, qr_reduce
from dynmodel_plugins.esn.network import Network

from .params import AnnealedRnnParams


@dataclass(frozen=True)
class NetState:
    """Dense copy of the network the moves act on (M is small, tens to a few hundred)."""

    C: np.ndarray
    B_in: np.ndarray
    B_back: np.ndarray
    c0: np.ndarray
    a: np.ndarray

    @property
    def size(self) -> int:
        return self.c0.shape[0]

    def gain(self, relaxation_gain: bool) -> np.ndarray:
        return 1.0 - np.abs(self.a) if relaxation_gain else np.ones_like(self.a)

    def network(self, relaxation_gain: bool) -> Network:
        """The sparse network this state describes (the form the kernels and the fitted model use)."""
        C = sp.csr_matrix(self.C)
        C.sort_indices()
        return Network(C, self.B_in, self.B_back, self.c0, self.a, self.gain(relaxation_gain))

    def kernel_args(self, relaxation_gain: bool) -> tuple:
        return self.network(relaxation_gain).kernel_args()


def rescale(C: np.ndarray, bound: float) -> np.ndarray:
    """Scale C down to sigma(C) = bound when its largest singular value exceeds it."""
    s = float(np.linalg.norm(C, 2)) if C.any() else 0.0
    return C * (bound / s) if s > bound else C


# ------------------------------------------------------------------ moves (thesis 5.3.4)


def _pick(mask: np.ndarray, rng: np.random.Generator) -> tuple | None:
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return None
    return np.unravel_index(int(idx[rng.integers(idx.size)]), mask.shape)


def make_moves(p: AnnealedRnnParams):
    bound = p.max_singular
    step = p.step

    def add(s: NetState, rng, scale):
        ij = _pick(s.C == 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] = rng.standard_normal()
        return replace(s, C=rescale(C, bound))

    def cut(s: NetState, rng, scale):
        ij = _pick(s.C != 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] = 0.0
        return replace(s, C=C)

    def rewire(s: NetState, rng, scale):
        src, dst = _pick(s.C != 0, rng), _pick(s.C == 0, rng)
        if src is None or dst is None:
            return None
        C = s.C.copy()
        C[dst], C[src] = C[src], 0.0
        return replace(s, C=rescale(C, bound))

    def weight(s: NetState, rng, scale):
        ij = _pick(s.C != 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] += step * scale * rng.standard_normal()
        return replace(s, C=rescale(C, bound))

    def input_weight(s: NetState, rng, scale):
        B = np.hstack([s.B_in, s.B_back])
        ij = _pick(B != 0, rng)
        if ij is None:
            return None
        B = B.copy()
        B[ij] += step * scale * rng.standard_normal()
        k = s.B_in.shape[1]
        return replace(s, B_in=B[:, :k], B_back=B[:, k:])

    def bias(s: NetState, rng, scale):
        i = _pick(s.c0 != 0, rng)
        if i is None:
            return None
        c0 = s.c0.copy()
        c0[i] += step * scale * rng.standard_normal()
        return replace(s, c0=c0)

    def relaxation(s: NetState, rng, scale):
        i = int(rng.integers(s.size))
        a = s.a.copy()
        a[i] = float(np.clip(a[i] + 0.1 * step * scale * rng.standard_normal(), 0.0, 0.99))
        return replace(s, a=a)

    table = [
        ("add", add),
        ("cut", cut),
        ("rewire", rewire),
        ("weight", weight),
        ("input", input_weight),
        ("bias", bias),
        ("relaxation", relaxation),
    ]
    weights = p.moves.model_dump()
    return [(name, weights[name], fn) for name, fn in table if weights[name] > 0]


def grow(s: NetState, k: int, p: AnnealedRnnParams, rng: np.random.Generator) -> NetState:
    """Append k elements wired like the initial network (constructive growth, 6.4.5)."""
    m = s.size + k
    C = np.zeros((m, m))
    C[: s.size, : s.size] = s.C
    new = np.zeros((m, m), dtype=bool)
    new[s.size :, :] = True
    new[:, s.size :] = True
    mask = new & (rng.random((m, m)) < p.connectivity)
    C[mask] = rng.standard_normal(int(mask.sum()))

    def rows(B, std):
        extra = np.where(
            rng.random((k, B.shape[1])) < p.input_connectivity, std * rng.standard_normal((k, B.shape[1])), 0.0
        )
        return np.vstack([B, extra])

    c0 = np.concatenate(
        [s.c0, np.where(rng.random(k) < p.bias_connectivity, p.bias_scale * rng.standard_normal(k), 0.0)]
    )
    lo, hi = p.relaxation if isinstance(p.relaxation, tuple) else (p.relaxation, p.relaxation)
    a = np.concatenate([s.a, rng.uniform(lo, hi, k)])
    return NetState(rescale(C, p.max_singular), rows(s.B_in, p.input_scale), rows(s.B_back, p.feedback_scale), c0, a)


# ------------------------------------------------------------------ evaluation

GRAM_CUTOFF = 1e-14  # eigenvalues of the centred Gram matrix kept, relative to the largest


class Evaluator:
    """Validation NMSE of a network whose readout is least squares on the training rows."""

    def __init__(self, data: TrainingData, p: AnnealedRnnParams, drives: list[np.ndarray]):
        if not data.has("validation"):
            raise ValueError(
                "annealed-rnn optimizes the network on a validation split; give data.split a "
                "validation part (e.g. {train: 0.8, validation: 0.2})"
            )
        self.data, self.p, self.drives = data, p, drives
        self.external = p.mode == "external"
        self.lo, self.hi = data.output_bounds()
        self.y_rest = np.nanmean(data.targets("train"), axis=0)
        self.Yv = data.targets("validation")
        self.var_v = np.maximum(np.var(self.Yv, axis=0), 1e-300)
        self._buffers: list[np.ndarray] = []
        self.evaluations = 0

    def _features(self, state: NetState) -> list[np.ndarray]:
        nv = self.drives[0].shape[1]
        k = state.size + (nv if self.p.readout.direct else 0) + 1
        if not self._buffers or self._buffers[0].shape[1] != k:
            self._buffers = [np.empty((d.shape[0], k)) for d in self.drives]
        args = state.kernel_args(self.p.relaxation_gain)
        x0 = np.zeros(state.size)
        for d, F in zip(self.drives, self._buffers):
            kernels.drive_features(*args, d, x0, self.p.readout.direct, F)
        return self._buffers

    def readout(self, state: NetState) -> np.ndarray | None:
        """Readout weights (K, q) from the Gram matrix of the training rows (last row: intercept)."""
        F = self._features(state)
        if self.p.readout.solver == "fos":
            Ft, Yt = self.data.stack("train", F), self.data.targets("train")
            if not np.all(np.isfinite(Ft)):
                return None
            order = np.r_[Ft.shape[1] - 1, np.arange(Ft.shape[1] - 1)]  # intercept first
            R, QtY = qr_reduce(Ft[:, order], Yt)
            Fv = self.data.stack("validation", F)[:, order]
            W = np.zeros((Ft.shape[1], Yt.shape[1]))
            for q in range(Yt.shape[1]):
                path = fos_select_qr(
                    R,
                    QtY[:, q],
                    float(Yt[:, q] @ Yt[:, q]),
                    forced=(0,),
                    max_terms=self.p.readout.max_terms,
                    Pv=Fv,
                    yv=self.Yv[:, q],
                    patience=self.p.readout.patience,
                )
                W[order[path.order[: path.best]], q] = path.coef_path[path.best - 1]
            return W
        # Normal equations of the centred features: centring removes the large common-mode
        # eigenvalue of the Gram matrix, so far more of its spectrum stays above the rounding level
        # (uncentred, a 60-element leaky network kept 17 of 61 directions, centred 32).
        segs = self.data.segments["train"]
        n = sum(b - a for _, a, b in segs)
        mean = sum(F[s][a:b, :-1].sum(axis=0) for s, a, b in segs) / n
        y_mean = sum(self.data.series[s].y[a:b].sum(axis=0) for s, a, b in segs) / n
        G = np.zeros((mean.size, mean.size))
        c = np.zeros((mean.size, y_mean.size))
        for s, a, b in segs:
            Xc = F[s][a:b, :-1] - mean
            G += Xc.T @ Xc
            c += Xc.T @ (self.data.series[s].y[a:b] - y_mean)
        if not np.all(np.isfinite(G)):
            return None
        lam, V = np.linalg.eigh(G)
        keep = lam > GRAM_CUTOFF * max(lam[-1], 1e-300)
        w = V[:, keep] @ ((V[:, keep].T @ c) / lam[keep, None])
        return np.vstack([w, y_mean - mean @ w])

    def score(self, state: NetState) -> float:
        """Mean over outputs of the validation NMSE (a fraction) of the free run."""
        self.evaluations += 1
        W = self.readout(state)
        if W is None:
            return np.inf
        if not self.external:
            pred = self.data.stack("validation", self._buffers) @ W
        else:
            m, nv = state.size, self.drives[0].shape[1]
            Wx, Wd, w0 = (
                W[:m].T.copy(),
                (W[m : m + nv].T.copy() if self.p.readout.direct else np.zeros((W.shape[1], nv))),
                W[-1].copy(),
            )
            args = state.kernel_args(self.p.relaxation_gain)
            runs = []
            for s in self.data.series:
                _, yhat, _, div = kernels.free_run(
                    *args,
                    np.ascontiguousarray(s.u),
                    np.ascontiguousarray(s.y),
                    min(self.p.tune_in, s.n),
                    0.0,
                    Wx,
                    Wd,
                    w0,
                    self.y_rest,
                    self.lo,
                    self.hi,
                    np.zeros(m),
                    False,
                )
                if div >= 0:
                    return np.inf
                runs.append(yhat)
            pred = self.data.stack("validation", runs)
        err = float(np.mean(np.mean((self.Yv - pred) ** 2, axis=0) / self.var_v))
        return err if np.isfinite(err) else np.inf
