"""Lorenz networks run over long recordings chunk by chunk, states never stored whole.

The network is integrated over a chunk of samples at a time, every element from the states it
reached at the end of the previous chunk (:func:`~.elements.simulate_network` with ``x0``), which
gives exactly the states of one long run; the readout needs only their moments
(:mod:`dynmodel.moments`), the prediction only their weighted sum.
"""

from __future__ import annotations

import numpy as np

from dynmodel.data.training import TrainingData
from dynmodel.moments import Moments, accumulate, chunk_rows

from .elements import simulate_network


class ChunkedNetwork:
    """States of a network over consecutive chunks of an input, in a reused (rows, M, 3) buffer."""

    def __init__(self, params: np.ndarray, C: np.ndarray, B: np.ndarray, dt: float, substeps: int, rows: int):
        self.params, self.C, self.B, self.dt, self.substeps = params, C, B, dt, substeps
        M = params.shape[0]
        self.buffer = np.empty((rows, M, 3))
        self.state = np.zeros((M, 3))

    def reset(self) -> None:
        self.state[:] = 0.0

    def run(self, U: np.ndarray) -> np.ndarray:
        """States (n, M, 3) of the next n samples (a view into the buffer)."""
        X = self.buffer[: U.shape[0]]
        if U.shape[0]:
            simulate_network(
                self.params, self.C, self.B, np.ascontiguousarray(U), self.dt, self.substeps, X, None, self.state.copy()
            )
            self.state[:] = X[-1]
        return X


class DelayLine:
    """Readout rows ``[xi_t, xi_(t-d1), xi_(t-d2), ...]`` of consecutive chunks of states xi (n, K); the
    states before the first sample are those of the network at rest (zeros)."""

    def __init__(self, K: int, delays: tuple[int, ...]):
        self.K, self.delays = K, tuple(int(d) for d in delays)
        self.depth = max(self.delays, default=0)
        self.history = np.zeros((self.depth, K))

    @property
    def width(self) -> int:
        return self.K * (1 + len(self.delays))

    def reset(self) -> None:
        self.history[:] = 0.0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if not self.delays:
            return X
        n, D = X.shape[0], self.depth
        H = np.vstack([self.history, X])
        F = np.empty((n, self.width))
        F[:, : self.K] = X
        for j, d in enumerate(self.delays, start=1):
            F[:, j * self.K : (j + 1) * self.K] = H[D - d : D - d + n]
        self.history[:] = H[len(H) - D :]
        return F


def delayed(X: np.ndarray, delays: tuple[int, ...]) -> np.ndarray:
    """Readout rows of one whole recording's states X (n, K) (see :class:`DelayLine`)."""
    return DelayLine(X.shape[1], delays)(X)


def readout_moments(
    params: np.ndarray,
    C: np.ndarray,
    B: np.ndarray,
    dt: float,
    substeps: int,
    data: TrainingData,
    splits=("train",),
    delays: tuple[int, ...] = (),
) -> dict[str, Moments]:
    """Moments of the readout rows (all 3M states and their ``delays``, y) of ``splits``."""
    K = 3 * params.shape[0]
    line = DelayLine(K, delays)
    rows = chunk_rows(line.width + data.n_outputs)
    net = ChunkedNetwork(params, C, B, dt, substeps, rows)

    def produce(k: int, start: int, stop: int) -> np.ndarray:
        if start == 0:
            net.reset()
            line.reset()
        return line(net.run(data.series[k].u[start:stop]).reshape(stop - start, K))

    return accumulate(data, produce, line.width, splits, rows)


def outputs(
    params: np.ndarray,
    C: np.ndarray,
    B: np.ndarray,
    dt: float,
    substeps: int,
    U: np.ndarray,
    W: np.ndarray,
    w0: np.ndarray,
    delays: tuple[int, ...] = (),
) -> np.ndarray:
    """Readout ``W [xi_t, xi_(t-d1), ...] + w0`` (n, n_outputs) of the network driven by U from rest."""
    K = 3 * params.shape[0]
    line = DelayLine(K, delays)
    rows = chunk_rows(line.width)
    net = ChunkedNetwork(params, C, B, dt, substeps, min(rows, max(len(U), 1)))
    y = np.empty((len(U), W.shape[0]))
    for start in range(0, len(U), rows):
        stop = min(start + rows, len(U))
        y[start:stop] = line(net.run(U[start:stop]).reshape(stop - start, K)) @ W.T + w0
    return y
