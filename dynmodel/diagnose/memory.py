"""The memory of a fitted model, measured by perturbing its input (any family).

Impulses of 1 % of the input's standard deviation (smaller when the perturbed run leaves the
divergence band) are added to one input channel at times spaced ``S`` samples apart, and the free
run on the perturbed input is compared with the unperturbed one. The
mean absolute response D(h) at h samples after the impulses gives the memory: the largest h with
D(h) >= 1 % of max D. It is measured per input channel on the first diagnosis recording; the
largest over channels is returned (at most ``max_lag``).
"""

from __future__ import annotations

import numpy as np

from .fitting import Fit

LEVEL = 0.01
AMPLITUDE = 0.01
RETRIES = 3


def impulse_response(fit: Fit, j: int, spacing: int, count: int = 6) -> np.ndarray | None:
    """Mean |y_perturbed - y| (n_outputs summed, in output stds) at lags 0..spacing-1 of input channel j."""
    model = fit.model
    rec = next((r for s in ("train", "validation") for r, _, _ in fit.ds.scored(s)), 0)
    r = fit.ds.recordings[rec]
    warm = model.warmup
    start = warm + 10
    n = min(r.n, start + count * spacing)
    count = (n - start) // spacing
    if count < 1:
        return None
    u = r.u[:n].copy()
    y_tune = r.y[:warm] if warm else None
    base = model.run(u, y_tune).y
    amp = AMPLITUDE * max(float(np.std(r.u[:, j])), 1e-12)
    times = start + spacing * np.arange(count)
    scale = np.maximum(np.std(r.y, axis=0), 1e-12)
    for _ in range(RETRIES + 1):
        up = u.copy()
        up[times, j] += amp
        diff = np.abs(model.run(up, y_tune).y - base) / scale
        if np.isfinite(diff).all():
            break
        amp /= 10.0
    if not np.isfinite(diff).all():
        diff = np.nan_to_num(diff, nan=1e6, posinf=1e6)
    d = diff.sum(axis=1)
    stack = np.stack([d[t : t + spacing] for t in times])
    return stack.mean(axis=0)


def model_memory(fit: Fit, max_lag: int) -> int:
    """Largest lag (samples) at which an input impulse still moves the output by >= 1 % of its peak effect."""
    spacing = int(max(max_lag, 20))
    memory = 0
    for j in range(len(fit.model.input_names)):
        d = impulse_response(fit, j, spacing)
        if d is None or d.max() <= 0:
            continue
        above = np.flatnonzero(d >= LEVEL * d.max())
        memory = max(memory, int(above[-1]))
    return int(min(memory, max_lag))
