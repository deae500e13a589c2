"""PNG plots a user looks at after a fit or a prediction (matplotlib, Agg backend)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def measured_vs_simulated(path: Path, t: np.ndarray, y: np.ndarray, yhat: np.ndarray, names: list[str],
                          title: str, spans: list[tuple[str, float, float]] | None = None) -> Path:
    """Measured and free-running outputs over time, with the error below; split spans shaded."""
    plt = _pyplot()
    q = y.shape[1]
    fig, axes = plt.subplots(2 * q, 1, figsize=(11, 3.2 * q + 1.5), sharex=True, squeeze=False,
                             gridspec_kw={"height_ratios": [3, 1] * q})
    colors = {"train": "#dbe9f6", "validation": "#fde8c8", "test": "#d9f0d3"}
    for k in range(q):
        ax, ax_e = axes[2 * k, 0], axes[2 * k + 1, 0]
        for label, a, b in spans or []:
            for axx in (ax, ax_e):
                axx.axvspan(a, b, color=colors.get(label, "#eeeeee"), lw=0)
            ax.text(a, 1.0, f" {label}", transform=ax.get_xaxis_transform(), va="top", fontsize=8, color="#555")
        ax.plot(t, y[:, k], lw=0.8, color="#333333", label="measured")
        ax.plot(t, yhat[:, k], lw=0.8, color="#d62728", label="free run")
        ax.set_ylabel(names[k])
        ax.legend(loc="upper right", fontsize=8)
        ax_e.plot(t, yhat[:, k] - y[:, k], lw=0.6, color="#1f77b4")
        ax_e.set_ylabel("error")
    axes[-1, 0].set_xlabel("time")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
