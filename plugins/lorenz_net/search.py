"""Annealing of Lorenz-network parameters and couplings (thesis 4.4.2).

The objective is the validation NMSE of the network whose linear readout of all 3M states plus an
offset (eq. 4.55) is fitted by least squares on the training rows. The evaluator keeps the state
trajectories of the last evaluated network and integrates again only the elements a
move touched and those downstream of them (in the parallel strategy: one element of M).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dynmodel import readout, regression
from dynmodel.data.training import TrainingData
from dynmodel.moments import Moments, chunk_rows, split_blocks

from .elements import descendants, simulate_network
from .params import LorenzNetParams
from .streaming import delayed, readout_moments

WEIGHT_LOW, WEIGHT_HIGH = 0.5, 1.5  # couplings from [-1.5, -0.5] U [0.5, 1.5] (thesis 4.4.2)
#: trajectories cached by one evaluator (one restart) at most; above, every candidate is integrated
#: again chunk by chunk (memory bounded for any length of the recordings, M times the integration work)
CACHE_BYTES = 1 << 30


@dataclass(frozen=True)
class LorenzState:
    params: np.ndarray  # (M, 4): sigma, r, b, alpha
    C: np.ndarray  # (M, M) strictly lower triangular
    B: np.ndarray  # (M, n_inputs)
    layer: np.ndarray  # (M,) layer index of each element


def _coupling(rng: np.random.Generator) -> float:
    return float(rng.choice([-1.0, 1.0]) * rng.uniform(WEIGHT_LOW, WEIGHT_HIGH))


def initial_state(p: LorenzNetParams, n_inputs: int, rng: np.random.Generator) -> LorenzState:
    m = p.size
    params = np.column_stack(
        [
            rng.uniform(*p.sigma_range, m),
            rng.uniform(*p.r_range, m),
            rng.uniform(*p.b_range, m),
            rng.uniform(*p.alpha_range, m),
        ]
    )
    params = np.maximum(params, 1e-3)  # sigma, r, b, alpha > 0 keep every element reliable
    C = np.zeros((m, m))
    if p.strategy == "parallel":
        layer = np.zeros(m, dtype=np.int64)
    else:
        layer = np.minimum(np.arange(m) * p.layers // m, p.layers - 1)
        for i in range(m):  # one link to a previous layer for every element after the first layer
            if layer[i] > 0:
                C[i, rng.choice(np.flatnonzero(layer < layer[i]))] = _coupling(rng)
        free = [(i, j) for i in range(m) for j in range(i) if C[i, j] == 0]
        for k in rng.choice(len(free), size=min(p.extra_links, len(free)), replace=False):
            C[free[k]] = _coupling(rng)
    B = np.zeros((m, n_inputs))
    first = layer == 0
    B[first] = p.input_scale * (
        1.0 if n_inputs == 1 else np.array([[_coupling(rng) for _ in range(n_inputs)] for _ in range(int(first.sum()))])
    )
    return LorenzState(params, C, B, layer)


def make_moves(p: LorenzNetParams):
    step = p.step

    def parameter(s: LorenzState, rng, scale):
        params = s.params.copy()
        i, k = int(rng.integers(params.shape[0])), int(rng.integers(4))
        params[i, k] *= float(np.exp(step * scale * rng.standard_normal()))
        return replace(s, params=params)

    def add(s: LorenzState, rng, scale):
        m = s.C.shape[0]
        free = [(i, j) for i in range(m) for j in range(i) if s.C[i, j] == 0]
        if not free:
            return None
        C = s.C.copy()
        C[free[int(rng.integers(len(free)))]] = _coupling(rng)
        return replace(s, C=C)

    def cut(s: LorenzState, rng, scale):
        # keep at least one input for every element outside the first layer
        rows, cols = np.nonzero(s.C)
        ok = [k for k in range(len(rows)) if np.count_nonzero(s.C[rows[k]]) > 1]
        if not ok:
            return None
        k = ok[int(rng.integers(len(ok)))]
        C = s.C.copy()
        C[rows[k], cols[k]] = 0.0
        return replace(s, C=C)

    def rescale(s: LorenzState, rng, scale):
        rows, cols = np.nonzero(s.C)
        if rows.size == 0:
            return None
        k = int(rng.integers(rows.size))
        C = s.C.copy()
        C[rows[k], cols[k]] *= float(np.exp(step * scale * rng.standard_normal()))
        return replace(s, C=C)

    ranges = [p.sigma_range, p.r_range, p.b_range, p.alpha_range]

    def redraw(s: LorenzState, rng, scale):
        params = s.params.copy()
        i, k = int(rng.integers(params.shape[0])), int(rng.integers(4))
        params[i, k] = max(rng.uniform(*ranges[k]), 1e-3)
        return replace(s, params=params)

    element_moves = [("parameter", 0.5, parameter), ("redraw", 0.5, redraw)]
    if p.strategy == "parallel":
        return element_moves
    share = p.coupling_share
    return [(n, w * (1.0 - share), f) for n, w, f in element_moves] + [
        ("add", share / 3, add),
        ("cut", share / 3, cut),
        ("rescale", share / 3, rescale),
    ]


class Evaluator:
    """Validation NMSE with cached trajectories: only touched elements and their descendants are
    integrated again; the readout is least squares on the training rows (as in the final fit)."""

    def __init__(self, data: TrainingData, p: LorenzNetParams, dt: float):
        if not data.has("validation"):
            raise ValueError(
                "lorenz-net optimizes its elements on a validation split; give data.split a validation "
                "part (e.g. {train: 0.67, validation: 0.33})"
            )
        self.data, self.p, self.dt = data, p, dt
        self.delays = p.readout_delays if p.anneal_delays else ()  # the readout the candidates are scored with
        self.Yv = data.targets("validation")
        self.var_v = np.maximum(np.var(self.Yv, axis=0), 1e-300)
        self.cached: LorenzState | None = None
        self.states: list[np.ndarray] = []  # per series (n, M, 3)
        self.finite = np.ones((0, 0), dtype=bool)  # per series and element: trajectory finite
        self.evaluations = 0
        self.element_integrations = 0
        self.cache = sum(s.n for s in data.series) * 3 * p.size * 8 <= CACHE_BYTES

    def _changed(self, s: LorenzState) -> list[int]:
        old = self.cached
        if old is None or old.params.shape != s.params.shape:
            return list(range(s.params.shape[0]))
        rows = np.flatnonzero(
            np.any(old.params != s.params, axis=1) | np.any(old.C != s.C, axis=1) | np.any(old.B != s.B, axis=1)
        )
        return descendants(s.C, set(int(i) for i in rows))

    def features(self, s: LorenzState) -> list[np.ndarray]:
        """Per series: the (n, 3M) states of network ``s`` (updated in place from the cache)."""
        todo = self._changed(s)
        full = self.cached is None or self.cached.params.shape != s.params.shape
        if full:
            self.states = []
            self.finite = np.ones((len(self.data.series), s.params.shape[0]), dtype=bool)
        for k, series in enumerate(self.data.series):
            if full:
                X, _ = simulate_network(s.params, s.C, s.B, series.u, self.dt, self.p.substeps)
                self.states.append(X)
            elif todo:
                simulate_network(s.params, s.C, s.B, series.u, self.dt, self.p.substeps, out=self.states[k], only=todo)
            if todo:
                self.finite[k, todo] = np.isfinite(self.states[k][:, todo, :]).all(axis=(0, 2))
        self.element_integrations += len(todo) * len(self.data.series)
        self.cached = s
        return [delayed(X.reshape(X.shape[0], -1), self.delays) for X in self.states]

    def readout(self, F: list[np.ndarray]) -> regression.LinearFit:
        """Least-squares readout on the training rows from the square-root moments of the states (as
        the final fit), accumulated from the cached trajectories without copying them: the 3M Lorenz
        states are nearly collinear (numerical rank about 80 of 97 for 32 elements), and the normal
        equations lost that accuracy (validation NMSE 30 - 41 % instead of 24 - 28 % for random
        parallel networks)."""
        K = F[0].shape[1]
        train = Moments(K, self.data.n_outputs)
        rows = chunk_rows(K + self.data.n_outputs)
        for k, series in enumerate(self.data.series):
            for start, stop, label in split_blocks(self.data, k, rows, ("train",)):
                if label is not None:
                    train.add(F[k][start:stop], series.y[start:stop])
        return readout.lstsq(train)

    def score(self, s: LorenzState) -> float:
        self.evaluations += 1
        if not self.cache:
            return self._streamed_score(s)
        F = self.features(s)
        if not self.finite.all():  # a diverged trajectory (non-finite states) cannot be read out
            return np.inf
        fit = self.readout(F)
        sse = np.zeros(self.data.n_outputs)
        for k, a, b in self.data.segments["validation"]:  # no copy of the validation states
            sse += np.sum((self.data.series[k].y[a:b] - fit.predict(F[k][a:b])) ** 2, axis=0)
        err = float(np.mean(sse / len(self.Yv) / self.var_v))
        return err if np.isfinite(err) else np.inf

    def _streamed_score(self, s: LorenzState) -> float:
        """The same objective without the cache: the whole network integrated chunk by chunk, the
        readout from the training moments, the error from the validation moments."""
        m = readout_moments(
            s.params, s.C, s.B, self.dt, self.p.substeps, self.data, ("train", "validation"), self.delays
        )
        self.element_integrations += s.params.shape[0] * len(self.data.series)
        if not (m["train"].finite and m["validation"].finite):
            return np.inf
        fit = readout.lstsq(m["train"])
        err = float(np.mean(m["validation"].residual_ss(fit.coef, fit.intercept) / m["validation"].n / self.var_v))
        return err if np.isfinite(err) else np.inf
