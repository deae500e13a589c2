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


def readout_moments(
    params: np.ndarray, C: np.ndarray, B: np.ndarray, dt: float, substeps: int, data: TrainingData, splits=("train",)
) -> dict[str, Moments]:
    """Moments of the readout rows (all 3M states, y) of ``splits``."""
    K = 3 * params.shape[0]
    rows = chunk_rows(K + data.n_outputs)
    net = ChunkedNetwork(params, C, B, dt, substeps, rows)

    def produce(k: int, start: int, stop: int) -> np.ndarray:
        if start == 0:
            net.reset()
        return net.run(data.series[k].u[start:stop]).reshape(stop - start, K)

    return accumulate(data, produce, K, splits, rows)


def outputs(
    params: np.ndarray,
    C: np.ndarray,
    B: np.ndarray,
    dt: float,
    substeps: int,
    U: np.ndarray,
    W: np.ndarray,
    w0: np.ndarray,
) -> np.ndarray:
    """Readout ``W xi_t + w0`` (n, n_outputs) of the network driven by U from rest."""
    K = 3 * params.shape[0]
    rows = chunk_rows(K)
    net = ChunkedNetwork(params, C, B, dt, substeps, min(rows, max(len(U), 1)))
    y = np.empty((len(U), W.shape[0]))
    for start in range(0, len(U), rows):
        stop = min(start + rows, len(U))
        y[start:stop] = net.run(U[start:stop]).reshape(stop - start, K) @ W.T + w0
    return y
