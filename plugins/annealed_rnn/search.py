"""Structure optimization of a tanh network by simulated annealing (thesis 5.3.4).

The state is the network (:class:`~dynmodel_plugins.esn.network.Network` with a dense C: the
connections, input weights, biases, relaxations); the objective is the free-running NMSE on the
validation split of the network whose readout is fitted by least squares on the training split.
One evaluation drives the network chunk by chunk into a reused buffer while accumulating the
centred Gram matrix of the training rows (:class:`dynmodel.moments.GramMoments`), solves the
readout from it and scores the validation rows as the run continues (internal mode) or in a free
run into reused output buffers (external mode): memory and allocations per step do not grow with
the length of the recordings.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from dynmodel import kernels, readout
from dynmodel.data.training import TrainingData
from dynmodel.moments import GramMoments, Moments, accumulate, chunk_rows, split_blocks
from dynmodel_plugins.esn.network import Network, element_gain
from dynmodel_plugins.esn.streaming import RunBuffers

from .params import AnnealedRnnParams


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

    def add(s: Network, rng, scale):
        ij = _pick(s.C == 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] = rng.standard_normal()
        return replace(s, C=rescale(C, bound))

    def cut(s: Network, rng, scale):
        ij = _pick(s.C != 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] = 0.0
        return replace(s, C=C)

    def rewire(s: Network, rng, scale):
        src, dst = _pick(s.C != 0, rng), _pick(s.C == 0, rng)
        if src is None or dst is None:
            return None
        C = s.C.copy()
        C[dst], C[src] = C[src], 0.0
        return replace(s, C=rescale(C, bound))

    def weight(s: Network, rng, scale):
        ij = _pick(s.C != 0, rng)
        if ij is None:
            return None
        C = s.C.copy()
        C[ij] += step * scale * rng.standard_normal()
        return replace(s, C=rescale(C, bound))

    def input_weight(s: Network, rng, scale):
        B = np.hstack([s.B_in, s.B_back])
        ij = _pick(B != 0, rng)
        if ij is None:
            return None
        B = B.copy()
        B[ij] += step * scale * rng.standard_normal()
        k = s.B_in.shape[1]
        return replace(s, B_in=B[:, :k], B_back=B[:, k:])

    def bias(s: Network, rng, scale):
        i = _pick(s.c0 != 0, rng)
        if i is None:
            return None
        c0 = s.c0.copy()
        c0[i] += step * scale * rng.standard_normal()
        return replace(s, c0=c0)

    def relaxation(s: Network, rng, scale):
        i = int(rng.integers(s.size))
        a = s.a.copy()
        a[i] = float(np.clip(a[i] + 0.1 * step * scale * rng.standard_normal(), 0.0, 0.99))
        return replace(s, a=a, g=element_gain(a, p.relaxation_gain))

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


def grow(s: Network, k: int, p: AnnealedRnnParams, rng: np.random.Generator) -> Network:
    """Append k elements wired like the initial network (constructive growth, 6.4.5); C dense."""
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
    return Network(
        rescale(C, p.max_singular),
        rows(s.B_in, p.input_scale),
        rows(s.B_back, p.feedback_scale),
        c0,
        a,
        element_gain(a, p.relaxation_gain),
    )


# ------------------------------------------------------------------ evaluation

GRAM_CUTOFF = 1e-14  # eigenvalues of the centred Gram matrix kept, relative to the largest


class Evaluator:
    """Validation NMSE of a network whose readout is least squares (or FOS) on the training rows.

    Buffers (a chunk of features, the outputs of the external-mode runs) are allocated once and
    reused by every candidate."""

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
        inf = np.full(data.n_outputs, np.inf)
        self._no_clip = (-inf, inf)  # annealed-rnn does not clip its output (no `bounds` parameter)
        self.Yv = data.targets("validation")
        self.var_v = np.maximum(np.var(self.Yv, axis=0), 1e-300)
        self.n_drive = drives[0].shape[1]
        self.fos = p.readout.solver == "fos"
        self._rows = 0
        self._features = np.empty((0, 0))
        self._outputs = np.empty((0, data.n_outputs))
        self._runs = RunBuffers(data) if self.external else None
        self._no_states = np.empty((0, 0))
        self._rest = np.zeros(0)
        self._gram = GramMoments(0, data.n_outputs)
        self._sqrt: dict[str, Moments] = {}
        self.evaluations = 0

    def _width(self, state: Network) -> int:
        return state.size + (self.n_drive if self.p.readout.direct else 0)

    def _buffers(self, state: Network) -> None:
        """(Re)allocate the chunk buffers when the network size changes (growth)."""
        K = self._width(state)
        if self._features.shape[1] != K:
            self._rows = chunk_rows(K + self.data.n_outputs)
            self._features = np.empty((self._rows, K))
            self._outputs = np.empty((self._rows, self.data.n_outputs))
            self._no_states = np.empty((0, state.size))
            self._rest = np.zeros(state.size)
            self._gram = GramMoments(K, self.data.n_outputs)
            self._sqrt = {name: Moments(K, self.data.n_outputs) for name in ("train", "validation")}

    def _moments(self, state: Network, args: tuple, splits: tuple[str, ...], into: dict) -> dict:
        """Moments of the teacher-forced (or internal-mode) readout rows of ``splits``, into the
        evaluator's reused moments."""
        x = self._rest.copy()
        direct = self.p.readout.direct

        def produce(k: int, start: int, stop: int) -> np.ndarray:
            if start == 0:
                x[:] = 0.0
            F = self._features[: stop - start]
            kernels.drive_chunk(*args, self.drives[k][start:stop], x, direct, F)
            return F

        return accumulate(self.data, produce, self._width(state), splits, self._rows, into=into)

    def _training_gram(self, state: Network, args: tuple) -> tuple[GramMoments, list]:
        """Centred Gram moments of the training rows, the network driven up to the last of them in
        each series. Also returns, per series, where the validation pass resumes: the states at the
        starts of the validation blocks driven already and the state at the end of the drive."""
        data, direct = self.data, self.p.readout.direct
        gram = self._gram
        gram.reset()
        x = self._rest.copy()
        resume = []
        for k, series in enumerate(data.series):
            x[:] = 0.0
            ends = [b for s, _, b in data.segments["train"] if s == k]
            stop1 = max(ends, default=0)
            checkpoints = {}
            for start, stop, label in split_blocks(data, k, self._rows, ("train", "validation")):
                if start >= stop1:
                    break
                if label == "validation":
                    checkpoints[start] = x.copy()
                F = self._features[: stop - start]
                kernels.drive_chunk(*args, self.drives[k][start:stop], x, direct, F)
                if label == "train":
                    gram.add(F, series.y[start:stop])
            resume.append((stop1, x.copy(), checkpoints))
        return gram, resume

    def readout(self, state: Network) -> np.ndarray | None:
        """Readout weights (K + 1, q) from the training rows (last row: intercept); None when the
        features are not finite."""
        self._buffers(state)
        return self._readout(state, state.kernel_args())[0]

    def _readout(self, state: Network, args: tuple) -> tuple[np.ndarray | None, Moments | list | None]:
        """The weights, and what scores the validation rows: their moments (FOS) or where the
        validation pass resumes (least squares)."""
        if self.fos:
            m = self._moments(state, args, ("train", "validation"), self._sqrt)
            if not (m["train"].finite and m["validation"].finite):
                return None, None
            p = self.p.readout
            fit = readout.fos(
                m["train"], m["validation"], max_terms=p.max_terms, patience=p.patience, weights="recursion"
            )
            return np.vstack([fit.coef, fit.intercept]), m["validation"]
        if self.external:  # the free run scores: drive up to the last training row only
            g = self._moments(state, args, ("train",), {"train": self._gram})["train"]
            resume = None
        else:
            g, resume = self._training_gram(state, args)
        if not g.finite or not np.all(np.isfinite(g.G)):
            return None, None
        # Normal equations of the centred features: centring removes the large common-mode
        # eigenvalue of the Gram matrix, so far more of its spectrum stays above the rounding level
        # (uncentred, a 60-element leaky network kept 17 of 61 directions, centred 32).
        K = g.n_features
        lam, V = np.linalg.eigh(g.G[:K, :K])
        keep = lam > GRAM_CUTOFF * max(lam[-1], 1e-300)
        w = V[:, keep] @ ((V[:, keep].T @ g.G[:K, K:]) / lam[keep, None])
        return np.vstack([w, g.mean[K:] - g.mean[:K] @ w]), resume

    def score(self, state: Network) -> float:
        """Mean over outputs of the validation NMSE (a fraction) of the free run."""
        self.evaluations += 1
        self._buffers(state)
        args = state.kernel_args()
        W, scorer = self._readout(state, args)
        if W is None:
            return np.inf
        if self.external:
            sse = self._free_run_sse(state, args, W)
        elif isinstance(scorer, Moments):  # FOS: the validation moments give the error
            sse = scorer.residual_ss(W[:-1], W[-1])
        else:
            sse = self._internal_sse(state, args, W, scorer)
        if sse is None:
            return np.inf
        err = float(np.mean(sse / len(self.Yv) / self.var_v))
        return err if np.isfinite(err) else np.inf

    def _split_readout(self, state: Network, W: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """W (K + 1, q) as the kernels' readout: state weights (q, M), drive weights (q, n_drive), offset."""
        m, nv = state.size, self.n_drive
        Wx, w0 = np.ascontiguousarray(W[:m].T), W[-1].copy()
        Wd = np.ascontiguousarray(W[m : m + nv].T) if self.p.readout.direct else np.zeros((W.shape[1], nv))
        return Wx, Wd, w0

    def _internal_sse(self, state: Network, args: tuple, W: np.ndarray, resume: list) -> np.ndarray:
        """Sum of squared validation errors per output: the run continues from where the training
        drive stopped (validation blocks met before it restart from their saved states), its
        output computed on the fly; states are never stored."""
        Wx, Wd, w0 = self._split_readout(state, W)
        sse = np.zeros(self.data.n_outputs)
        for k, series in enumerate(self.data.series):
            stop1, x, checkpoints = resume[k]
            for start, stop, label in split_blocks(self.data, k, self._rows, ("train", "validation")):
                if start < stop1 and label != "validation":
                    continue
                state_x = checkpoints[start].copy() if start < stop1 else x
                out = self._outputs[: stop - start]
                kernels.drive_output(*args, self.drives[k][start:stop], state_x, Wx, Wd, w0, out)
                if label == "validation":
                    sse += np.sum((series.y[start:stop] - out) ** 2, axis=0)
        return sse

    def _free_run_sse(self, state: Network, args: tuple, W: np.ndarray) -> np.ndarray | None:
        """Sum of squared validation errors per output of the external-mode free run (None: it diverged)."""
        Wx, Wd, w0 = self._split_readout(state, W)
        x = self._rest.copy()
        runs = self._runs
        assert runs is not None
        for s, yhat, fb in zip(self.data.series, runs.yhat, runs.fb):
            x[:] = 0.0
            div = kernels.free_run_span(
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
                self._no_clip[0],
                self._no_clip[1],
                x,
                0,
                s.n,
                yhat,
                fb,
                self._no_states,
            )
            if div >= 0:
                return None
        return np.sum((self.Yv - self.data.stack("validation", runs.yhat)) ** 2, axis=0)
