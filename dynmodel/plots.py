"""PNG plots a user looks at after a fit or a prediction (matplotlib, Agg backend)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

_SPLIT_COLORS = {"train": "#dbe9f6", "validation": "#fde8c8", "test": "#d9f0d3"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _limits(y: np.ndarray) -> tuple[float, float] | None:
    finite = y[np.isfinite(y)]
    if finite.size == 0:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    pad = 0.25 * (hi - lo or 1.0)
    return lo - pad, hi + pad


def measured_vs_simulated(path: Path, t: np.ndarray, y: np.ndarray, yhat: np.ndarray, names: list[str],
                          title: str, spans: list[tuple[str, float, float]] | None = None,
                          zoom: tuple[int, int] | None = None, tune_in: int = 0) -> Path:
    """Measured and free-running output over the whole recording (splits shaded, tune-in greyed),
    a zoom on ``zoom`` samples, and the error below. The y-range follows the measured output, so
    a diverging or untuned stretch does not hide the rest."""
    plt = _pyplot()
    q = y.shape[1]
    n = len(t)
    if zoom is None:
        zoom = (min(tune_in, max(n - 1, 0)), min(n, tune_in + 500))
    fig, axes = plt.subplots(3 * q, 1, figsize=(11, 6.5 * q), squeeze=False,
                             gridspec_kw={"height_ratios": [2.2, 2.2, 1] * q})
    for k in range(q):
        full, near, err = axes[3 * k, 0], axes[3 * k + 1, 0], axes[3 * k + 2, 0]
        lim = _limits(y[:, k]) if np.isfinite(y[:, k]).any() else _limits(yhat[:, k])
        for label, a, b in spans or []:
            for ax in (full, err):
                ax.axvspan(a, b, color=_SPLIT_COLORS.get(label, "#eeeeee"), lw=0)
            full.text(a, 1.0, f" {label}", transform=full.get_xaxis_transform(), va="top", fontsize=8, color="#555")
        if tune_in:
            for ax in (full, err):
                ax.axvspan(t[0], t[min(tune_in, n - 1)], color="#bbbbbb", alpha=0.5, lw=0)
        full.plot(t, y[:, k], lw=0.6, color="#333333", label="measured")
        full.plot(t, yhat[:, k], lw=0.6, color="#d62728", label="free run")
        full.set_ylabel(names[k])
        full.legend(loc="upper right", fontsize=8)
        a, b = zoom
        near.plot(t[a:b], y[a:b, k], lw=1.0, color="#333333", label="measured")
        near.plot(t[a:b], yhat[a:b, k], lw=1.0, color="#d62728", ls="--", label="free run")
        near.set_ylabel(f"{names[k]} (zoom)")
        err.plot(t, yhat[:, k] - y[:, k], lw=0.5, color="#1f77b4")
        err.set_ylabel("free run - measured")
        if lim is not None:
            full.set_ylim(*lim)
            near.set_ylim(*(_limits(y[a:b, k]) or lim))
            width = lim[1] - lim[0]
            e = (yhat[:, k] - y[:, k])[tune_in:]
            e = e[np.isfinite(e)]
            if e.size:
                span = min(float(np.max(np.abs(e))) * 1.1, width) or 1.0
                err.set_ylim(-span, span)
    axes[-1, 0].set_xlabel("time")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
