"""Tanh networks run over long recordings without storing their states (memory O(M^2), not O(N M)).

* :func:`teacher_forced_moments` - the readout moments of the training (and validation) rows,
  the network driven chunk by chunk by the input (internal mode) or by the input and the measured
  past output (external mode, teacher forcing).
* :func:`free_run_moments` - the same for the external-mode free run (the refinement of thesis
  5.3.2), the network fed back its own output.
* :func:`free_runs` - free-run outputs of every series into reused :class:`RunBuffers`.
* :func:`output_of` - the readout output of a driven network, states never stored.
"""

from __future__ import annotations

import numpy as np

from dynmodel import kernels
from dynmodel.data.training import TrainingData
from dynmodel.moments import Moments, accumulate, chunk_rows

from .network import Network


class RunBuffers:
    """Per series, the outputs ``yhat`` and fed-back values ``fb`` (n, n_outputs) of an external-mode
    run, allocated once and reused by every run of a fit (refinement iterations, annealing steps)."""

    def __init__(self, data: TrainingData):
        self.yhat = [np.empty((s.n, data.n_outputs)) for s in data.series]
        self.fb = [np.empty((s.n, data.n_outputs)) for s in data.series]


class _Diverged(Exception):
    pass


def feature_width(net: Network, n_drive: int, direct: bool) -> int:
    """K: the states, plus the drive when it feeds the readout directly."""
    return net.size + (n_drive if direct else 0)


def settled_state(net: Network, u0: np.ndarray, y0: np.ndarray, steps: int) -> np.ndarray:
    """The state after ``steps`` samples of the drive ``[u0, y0]`` held (the first input and, fed back, the first
    measured output), from rest: where a network tuned in on a system at rest at those values starts (the
    external mode's ``settle``). Rest (zeros) for ``steps`` = 0 or an unknown first output."""
    x = np.zeros(net.size)
    v = np.concatenate([np.ravel(u0), np.ravel(y0)]).astype(np.float64)
    if steps <= 0 or not np.isfinite(v).all():
        return x
    F = np.empty((steps, net.size))
    kernels.drive_chunk(*net.kernel_args(), np.ascontiguousarray(np.broadcast_to(v, (steps, v.size))), x, False, F)
    return x


def teacher_forced_moments(
    net: Network, data: TrainingData, drives: list[np.ndarray], direct: bool, splits: tuple[str, ...]
) -> dict[str, Moments]:
    """Moments of the readout rows ``[x_t, v_t (direct)], y_t`` of ``splits``, the network driven by
    ``drives`` (per series, (n, n_drive)) from rest."""
    args = net.kernel_args()
    K = feature_width(net, drives[0].shape[1], direct)
    rows = chunk_rows(K + data.n_outputs)
    buffer = np.empty((rows, K))
    x = np.zeros(net.size)

    def produce(k: int, start: int, stop: int) -> np.ndarray:
        if start == 0:
            x[:] = 0.0
        F = buffer[: stop - start]
        kernels.drive_chunk(*args, drives[k][start:stop], x, direct, F)
        return F

    return accumulate(data, produce, K, splits, rows)


def free_run_moments(
    net: Network,
    data: TrainingData,
    mix: float,
    direct: bool,
    splits: tuple[str, ...],
    buffers: RunBuffers,
    *,
    tune_in: int,
    W: np.ndarray,
    D: np.ndarray,
    w0: np.ndarray,
    y_rest: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    clip_lo: np.ndarray,
    clip_hi: np.ndarray,
    starts: list[np.ndarray] | None = None,
    into: dict[str, Moments] | None = None,
) -> dict[str, Moments] | None:
    """Moments of the readout rows ``[x_t, u_t, f_t (direct)], y_t`` of the external-mode run with
    feedback ``f_t`` (``mix``: share of the measured output, :func:`dynmodel.kernels.free_run_clipped`;
    the output clipped to [clip_lo, clip_hi] is the one fed back); None when a run leaves [lo, hi]. Each run
    starts from its series' state in ``starts`` (:func:`settled_state`; None: from rest). ``into``: moments to
    reset and reuse (see :func:`dynmodel.moments.accumulate`)."""
    args = net.kernel_args()
    m, n_in, q = net.size, data.n_inputs, data.n_outputs
    K = m + (n_in + q if direct else 0)
    rows = chunk_rows(K + q)
    buffer = np.empty((rows, K))
    x = np.zeros(m)

    def produce(k: int, start: int, stop: int) -> np.ndarray:
        s, yhat, fb = data.series[k], buffers.yhat[k], buffers.fb[k]
        if start == 0:
            x[:] = 0.0 if starts is None else starts[k]
        F = buffer[: stop - start]
        u, y = np.ascontiguousarray(s.u), np.ascontiguousarray(s.y)
        div = kernels.free_run_span(
            *args,
            u,
            y,
            min(tune_in, s.n),
            mix,
            W,
            D,
            w0,
            y_rest,
            lo,
            hi,
            clip_lo,
            clip_hi,
            x,
            start,
            stop,
            yhat,
            fb,
            F[:, :m],
        )
        if div >= 0:
            raise _Diverged
        if direct:
            F[:, m : m + n_in] = u[start:stop]
            F[:, m + n_in :] = fb[start:stop]
        return F

    try:
        return accumulate(data, produce, K, splits, rows, into=into)
    except _Diverged:
        return None


def free_runs(
    net: Network,
    data: TrainingData,
    mix: float,
    buffers: RunBuffers,
    *,
    tune_in: int,
    W: np.ndarray,
    D: np.ndarray,
    w0: np.ndarray,
    y_rest: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    clip_lo: np.ndarray,
    clip_hi: np.ndarray,
    starts: list[np.ndarray] | None = None,
) -> bool:
    """External-mode runs of every series, outputs (clipped to [clip_lo, clip_hi], as fed back) in
    ``buffers.yhat``, each from its series' state in ``starts`` (:func:`settled_state`; None: from rest). False
    when a run leaves [lo, hi] (its later outputs are NaN)."""
    args = net.kernel_args()
    x = np.zeros(net.size)
    no_states = np.empty((0, net.size))
    for k, (s, yhat, fb) in enumerate(zip(data.series, buffers.yhat, buffers.fb)):
        x[:] = 0.0 if starts is None else starts[k]
        u, y = np.ascontiguousarray(s.u), np.ascontiguousarray(s.y)
        div = kernels.free_run_span(
            *args,
            u,
            y,
            min(tune_in, s.n),
            mix,
            W,
            D,
            w0,
            y_rest,
            lo,
            hi,
            clip_lo,
            clip_hi,
            x,
            0,
            s.n,
            yhat,
            fb,
            no_states,
        )
        if div >= 0:
            return False
    return True


def output_of(net: Network, V: np.ndarray, W: np.ndarray, D: np.ndarray, w0: np.ndarray) -> np.ndarray:
    """``W x_t + D v_t + w0`` (n, n_outputs) of the network driven by V (n, n_drive) from rest."""
    V = np.ascontiguousarray(V, dtype=np.float64)
    out = np.empty((V.shape[0], W.shape[0]))
    kernels.drive_output(*net.kernel_args(), V, np.zeros(net.size), W, D[:, : V.shape[1]], w0, out)
    return out
