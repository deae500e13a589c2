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


def measured_vs_simulated(
    path: Path,
    t: np.ndarray,
    y: np.ndarray,
    yhat: np.ndarray,
    names: list[str],
    title: str,
    spans: list[tuple[str, float, float]] | None = None,
    zoom: tuple[int, int] | None = None,
    tune_in: int = 0,
) -> Path:
    """Measured and free-running output over the whole recording (splits shaded, tune-in greyed),
    a zoom on ``zoom`` samples, and the error below. The y-range follows the measured output, so
    a diverging or untuned stretch does not hide the rest."""
    plt = _pyplot()
    q = y.shape[1]
    n = len(t)
    if zoom is None:
        zoom = (min(tune_in, max(n - 1, 0)), min(n, tune_in + 500))
    fig, axes = plt.subplots(
        3 * q, 1, figsize=(11, 6.5 * q), squeeze=False, gridspec_kw={"height_ratios": [2.2, 2.2, 1] * q}
    )
    for k in range(q):
        full, near, err = axes[3 * k, 0], axes[3 * k + 1, 0], axes[3 * k + 2, 0]
        lim = _limits(y[:, k]) if np.isfinite(y[:, k]).any() else _limits(yhat[:, k])
        for label, a, b in spans or []:
            for ax in (full, err):
                ax.axvspan(a, b, color=_SPLIT_COLORS.get(label.split(":")[0], "#eeeeee"), lw=0)
            full.text(a, 1.0, f" {label}", transform=full.get_xaxis_transform(), va="top", fontsize=8, color="#555")
        if tune_in:
            for ax in (full, err):
                ax.axvspan(t[0], t[min(tune_in, n - 1)], color="#bbbbbb", alpha=0.5, lw=0)
        measured = bool(np.isfinite(y[:, k]).any())  # predict on inputs alone has no measured output
        if measured:
            full.plot(t, y[:, k], lw=0.6, color="#333333", label="measured")
        full.plot(t, yhat[:, k], lw=0.6, color="#d62728", label="free run")
        full.set_ylabel(names[k])
        full.legend(loc="upper right", fontsize=8)
        a, b = zoom
        if measured:
            near.plot(t[a:b], y[a:b, k], lw=1.0, color="#333333", label="measured")
        near.plot(t[a:b], yhat[a:b, k], lw=1.0, color="#d62728", ls="--", label="free run")
        near.set_ylabel(f"{names[k]} (zoom)")
        if not measured:
            err.set_yticks([])
            if n > 1:
                err.set_xlim(t[0], t[-1])
            err.text(
                0.5, 0.5, "no measured output: no error to show", ha="center", va="center", transform=err.transAxes
            )
            continue
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
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def recording(
    path: Path, t: np.ndarray, u: np.ndarray, y: np.ndarray, input_names: list[str], output_names: list[str], title: str
) -> Path:
    """A generated recording: inputs and outputs against time, and every output against the first
    input (for friction data: force against position, the hysteresis loops of fig. 6.2 / 6.5 / 6.8)."""
    plt = _pyplot()
    q = y.shape[1]
    fig = plt.figure(figsize=(11, 4.2 + 3.6 * q))
    grid = fig.add_gridspec(2 + q, 2, height_ratios=[1, 1] + [1.6] * q)
    ax_u = fig.add_subplot(grid[0, :])
    for j, name in enumerate(input_names):
        ax_u.plot(t, u[:, j], lw=0.7, label=name)
    ax_u.set_ylabel("input")
    ax_u.legend(loc="upper right", fontsize=8)
    ax_y = fig.add_subplot(grid[1, :], sharex=ax_u)
    for k, name in enumerate(output_names):
        ax_y.plot(t, y[:, k], lw=0.7, label=name)
    ax_y.set_ylabel("output")
    ax_y.set_xlabel("time")
    ax_y.legend(loc="upper right", fontsize=8)
    n = len(t)
    zoom = slice(0, min(n, max(200, n // 10)))
    for k, name in enumerate(output_names):
        whole = fig.add_subplot(grid[2 + k, 0])
        whole.plot(u[:, 0], y[:, k], lw=0.4, color="#1f77b4")
        whole.set_xlabel(input_names[0])
        whole.set_ylabel(name)
        whole.set_title(f"{name} against {input_names[0]}", fontsize=9)
        near = fig.add_subplot(grid[2 + k, 1])
        near.plot(u[zoom, 0], y[zoom, k], lw=0.6, color="#d62728")
        near.set_xlabel(input_names[0])
        near.set_title(f"the first {zoom.stop} samples", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def tracking_error(
    path: Path,
    t: np.ndarray,
    reference: np.ndarray,
    error: np.ndarray,
    error_perfect: np.ndarray,
    switch: float,
    skip: float,
    title: str,
    window: float = 5.0,
) -> Path:
    """Thesis fig. 6.25: reference and position in a window before and after the switch, the tracking
    error over the whole run, and the error after the switch for the model and the perfect model."""
    plt = _pyplot()
    fig = plt.figure(figsize=(11, 9))
    grid = fig.add_gridspec(3, 2, height_ratios=[1.2, 1, 1])
    end = float(t[-1] + (t[1] - t[0])) if len(t) > 1 else float(t[-1])  # the run's duration
    windows = [(0.6 * switch, "P-control"), (switch + 0.6 * (end - switch), "P-control + feed-forward")]
    position = reference + error
    for col, (a, label) in enumerate(windows):
        ax = fig.add_subplot(grid[0, col])
        sel = (t >= a) & (t <= a + window)
        ax.plot(t[sel], reference[sel], lw=1.0, color="#333333", label="reference")
        ax.plot(t[sel], position[sel], lw=1.0, ls="--", color="#d62728", label="position")
        ax.set_title(f"{label}, t in [{a:g}, {a + window:g}]", fontsize=9)
        ax.legend(loc="upper right", fontsize=8)
    ax = fig.add_subplot(grid[1, :])
    ax.plot(t, error, lw=0.5, color="#1f77b4")
    ax.axvline(switch, color="#555555", ls=":")
    for a, b in [(0, skip), (switch, switch + skip)]:
        ax.axvspan(a, b, color="#dddddd", lw=0)
    ax.set_ylabel("tracking error P - P_r")
    ax.text(switch, 1.0, " feed-forward on", transform=ax.get_xaxis_transform(), va="top", fontsize=8)
    ax = fig.add_subplot(grid[2, :])
    after = t >= switch
    ax.plot(t[after], error[after], lw=0.5, color="#1f77b4", label="model")
    ax.plot(t[after], error_perfect[after], lw=0.5, color="#2ca02c", label="perfect model")
    ax.axvspan(switch, switch + skip, color="#dddddd", lw=0)
    ax.set_ylabel("error after the switch")
    ax.set_xlabel("time (s)")
    ax.legend(loc="upper right", fontsize=8)
    scored = error[t >= switch + skip]
    if scored.size and np.isfinite(scored).all():
        span = 1.2 * float(np.max(np.abs(scored))) or 1.0
        ax.set_ylim(-span, span)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
