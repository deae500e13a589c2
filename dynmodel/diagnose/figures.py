"""PNG figures of a diagnosis (matplotlib, Agg backend): what the free run gets wrong, the residual's
statistics with their bounds, and the extended model against the baseline."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from ..data.derived import time_function
from ..plots import _SPLIT_COLORS, _limits, _pyplot
from .context import segments_of
from .correlation import ar_coefficients, ar_filter, autocorr, bartlett_sd, crosscorr, sidak_z
from .fitting import Fit
from .spectrum import welch

Z99 = float(stats.norm.isf(0.005))
DPI = 80


def _main_recording(fit: Fit) -> int:
    return next((r for r, _, _ in fit.ds.ranges.get("test", [])), 0)


def worst_windows(e: np.ndarray, width: int, count: int = 3) -> list[tuple[int, int]]:
    """Start and stop of the ``count`` non-overlapping windows of ``width`` samples with the largest mean e^2."""
    e2 = np.nan_to_num(e**2, nan=np.nanmax(e**2) if np.isfinite(e).any() else 0.0)
    if len(e2) <= width:
        return [(0, len(e2))]
    score = np.convolve(e2, np.ones(width) / width, mode="valid")
    out: list[tuple[int, int]] = []
    for _ in range(count):
        i = int(np.argmax(score))
        if score[i] <= 0 or not np.isfinite(score[i]):
            break
        out.append((i, i + width))
        score[max(0, i - width) : i + width] = -np.inf
    return out


def overview(path: Path, fit: Fit, title: str) -> list[tuple[float, float]]:
    """Measured vs free run over the test recording, splits shaded, the worst windows marked; residual below."""
    plt = _pyplot()
    rec = _main_recording(fit)
    r = fit.ds.recordings[rec]
    st = fit.ds.sampling_time
    t = np.arange(r.n) * st
    yhat = fit.runs[rec].y
    q = r.y.shape[1]
    warm = fit.model.warmup
    e = (r.y - yhat)[:, 0].copy()
    e[:warm] = 0.0
    width = max(20, r.n // 50)
    windows = worst_windows(e, width)
    fig, axes = plt.subplots(
        2 * q, 1, figsize=(11, 5.2 * q), squeeze=False, sharex=True, gridspec_kw={"height_ratios": [2.2, 1] * q}
    )
    for k in range(q):
        top, bottom = axes[2 * k, 0], axes[2 * k + 1, 0]
        for split in fit.ds.splits():
            for rr, a, b in fit.ds.ranges[split]:
                if rr == rec:
                    for ax in (top, bottom):
                        ax.axvspan(a * st, b * st, color=_SPLIT_COLORS.get(split, "#eee"), lw=0)
                    top.text(a * st, 1.0, f" {split}", transform=top.get_xaxis_transform(), va="top", fontsize=8)
        top.plot(t, r.y[:, k], lw=0.6, color="#333333", label="measured")
        top.plot(t, yhat[:, k], lw=0.6, color="#d62728", label="free run")
        for i, (a, b) in enumerate(windows):
            for ax in (top, bottom):
                ax.axvspan(a * st, b * st, fill=False, edgecolor="#9467bd", lw=1.2, ls="--")
            top.text(a * st, 0.02, f" worst {i + 1}", transform=top.get_xaxis_transform(), fontsize=7, color="#9467bd")
        lim = _limits(r.y[:, k])
        if lim:
            top.set_ylim(*lim)
        top.set_ylabel(fit.model.output_names[k])
        top.legend(loc="upper right", fontsize=8)
        bottom.plot(t, r.y[:, k] - yhat[:, k], lw=0.5, color="#1f77b4")
        bottom.set_ylabel("measured - free run")
        ek = r.y[warm:, k] - yhat[warm:, k]
        ek = ek[np.isfinite(ek)]
        if ek.size:
            span = float(np.max(np.abs(ek))) * 1.1 or 1.0
            bottom.set_ylim(-span, span)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return [(a * st, b * st) for a, b in windows]


def residual(path: Path, fit: Fit, drift: dict[str, Any] | None, title: str) -> None:
    """Residual of every scored split over time, its moving average, and the fitted drift if one was found."""
    plt = _pyplot()
    segs = segments_of(fit, ("train", "validation", "test"))
    st = fit.ds.sampling_time
    fig, ax = plt.subplots(figsize=(11, 3.6))
    n = sum(s.n for s in segs)
    w = max(5, n // 60)
    for i, s in enumerate(segs):
        t = np.arange(s.start, s.stop) * st
        e = s.e[:, 0]
        ax.plot(t, e, lw=0.4, color="#9ecae1", label="residual" if i == 0 else None)
        if s.n > w:
            m = np.convolve(e, np.ones(w) / w, mode="valid")
            ax.plot(
                t[w // 2 : w // 2 + len(m)],
                m,
                lw=1.4,
                color="#08519c",
                label=f"moving mean ({w} samples)" if i == 0 else None,
            )
        if drift:
            d = sum(c * time_function(fn, t) for c, fn in zip(drift["coefficients"], drift["terms"]))
            ax.plot(
                t,
                d - d.mean() + e.mean(),
                lw=1.4,
                color="#d62728",
                ls="--",
                label="fitted drift (sensor-drift)" if i == 0 else None,
            )
    ax.axhline(0.0, color="#555", lw=0.6)
    ax.set_xlabel("time since the recording's start (s)")
    ax.set_ylabel(f"{fit.model.output_names[0]}: measured - free run")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def correlations(
    path: Path, fit: Fit, max_lag: int, alpha: float, delay: dict[str, Any] | None, memory: int | None
) -> None:
    """Residual autocorrelation with its 99 % white-noise bounds; prewhitened residual-input
    cross-correlation with the per-lag 99 % and the family-wise (Sidak) bounds."""
    plt = _pyplot()
    segs = segments_of(fit)
    e = [s.e[:, 0] for s in segs]
    names = fit.model.input_names
    fig, axes = plt.subplots(1 + len(names), 1, figsize=(11, 3.0 * (1 + len(names))), squeeze=False)
    n = sum(len(x) for x in e)
    short = min(max_lag, 200)
    r = autocorr(e, short)
    ax = axes[0, 0]
    ax.vlines(np.arange(short + 1), 0, r, color="#1f77b4", lw=0.8)
    ax.axhspan(-Z99 / np.sqrt(n), Z99 / np.sqrt(n), color="#fdd0a2", alpha=0.6, label="99 % bounds (white noise)")
    ax.set_ylabel("autocorrelation")
    ax.set_xlabel("lag (samples)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("free-run residual", fontsize=10)
    for j, name in enumerate(names):
        u = [s.u[:, j] for s in segs]
        phi = ar_coefficients(u)
        uw, ew = ar_filter(u, phi), ar_filter(e, phi)
        c = crosscorr(ew, uw, max_lag)
        sd = bartlett_sd(ew, uw, max_lag)
        lags = np.arange(max_lag + 1)
        ax = axes[1 + j, 0]
        ax.vlines(lags, 0, np.nan_to_num(c), color="#1f77b4", lw=0.6)
        ax.fill_between(lags, -Z99 * sd, Z99 * sd, color="#fdd0a2", alpha=0.6, label="99 % bounds per lag")
        zf = sidak_z(alpha, max(1, max_lag - (memory or 0)))
        ax.plot(lags, zf * sd, color="#e6550d", lw=0.8, ls="--", label=f"family-wise bound (alpha {alpha:g})")
        ax.plot(lags, -zf * sd, color="#e6550d", lw=0.8, ls="--")
        if memory is not None:
            ax.axvspan(0, memory, color="#dddddd", alpha=0.6, label=f"model memory ({memory} samples)")
        if delay and delay.get("input") == name:
            k = delay["lag_samples"]
            ax.annotate(
                f"lag {k} ({delay['lag_seconds']:.4g} s)",
                (k, c[k]),
                xytext=(10, 10),
                textcoords="offset points",
                fontsize=8,
                color="#d62728",
                arrowprops={"arrowstyle": "->", "color": "#d62728"},
            )
        ax.set_ylabel(f"corr(e_t, {name}_t-k)")
        ax.set_xlabel(f"lag k (samples; prewhitened by AR({len(phi)}) of {name})")
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def spectrum(path: Path, fit: Fit, alpha: float, peak: dict[str, Any] | None) -> None:
    """Welch spectrum of the residual, its running-median background and the Bonferroni threshold."""
    plt = _pyplot()
    segs = segments_of(fit)
    spec = welch([s.e[:, 0] for s in segs])
    fig, ax = plt.subplots(figsize=(11, 3.6))
    if spec is not None:
        st = fit.ds.sampling_time
        f = spec.freq / st
        m = max(1, int(spec.testable.sum()))
        thr = stats.f.isf(alpha / m, spec.dof, spec.background_dof) * spec.background
        ax.semilogy(f[1:], spec.power[1:], lw=0.8, color="#1f77b4", label="residual (Welch)")
        ax.semilogy(f[1:], spec.background[1:], lw=1.0, color="#555", label="background (running median)")
        ax.semilogy(f[1:], thr[1:], lw=0.8, color="#e6550d", ls="--", label=f"threshold (alpha {alpha:g}, Bonferroni)")
        if peak:
            ax.axvline(peak["frequency_hz"], color="#d62728", lw=0.8, ls=":")
            ax.text(
                peak["frequency_hz"],
                0.95,
                f" {peak['frequency_hz']:.4g} Hz",
                transform=ax.get_xaxis_transform(),
                color="#d62728",
                fontsize=8,
                va="top",
            )
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("power density")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_title("spectrum of the free-run residual", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def loops(path: Path, fit: Fit, curve: dict[str, Any] | None) -> None:
    """Output against each input, measured and free run (hysteresis loops), and the residual against
    the input level (with the static-nonlinearity curve when one was found)."""
    plt = _pyplot()
    segs = segments_of(fit)
    names = fit.model.input_names
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 4.0 * len(names)), squeeze=False)
    y = np.concatenate([s.y[:, 0] for s in segs])
    yhat = np.concatenate([s.yhat[:, 0] for s in segs])
    sel = slice(None) if len(y) <= 4000 else slice(0, 4000)
    for j, name in enumerate(names):
        u = np.concatenate([s.u[:, j] for s in segs])
        ax = axes[j, 0]
        ax.plot(u[sel], y[sel], lw=0.4, color="#333333", label="measured", marker=".", ms=1.5)
        ax.plot(u[sel], yhat[sel], lw=0.4, color="#d62728", label="free run", marker=".", ms=1.5, alpha=0.7)
        ax.set_xlabel(name)
        ax.set_ylabel(fit.model.output_names[0])
        ax.legend(loc="upper left", fontsize=8)
        ax.set_title("output against input (first 4000 diagnosis samples)", fontsize=9)
        ax = axes[j, 1]
        ax.plot(u, y - yhat, ".", ms=1.0, color="#1f77b4", alpha=0.4)
        if curve and curve.get("input") == name:
            ax.plot(
                curve["curve"]["level"],
                np.asarray(curve["curve"]["residual"]) + float(np.mean(y - yhat)),
                color="#d62728",
                lw=1.5,
                label="static-nonlinearity fit",
            )
            ax.legend(loc="upper left", fontsize=8)
        ax.set_xlabel(f"{name} level")
        ax.set_ylabel("residual")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def before_after(path: Path, base: Fit, final: Fit, gain: dict[str, Any]) -> None:
    """The test split's worst window of the baseline with the extended model, and the test NMSE bars."""
    plt = _pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 3.8), gridspec_kw={"width_ratios": [3, 1]})
    rows = base.ds.scored(gain.get("test_split") or "test", warmup=max(base.model.warmup, final.model.warmup))
    st = base.ds.sampling_time
    if rows:
        rec, a, b = max(rows, key=lambda r: r[2] - r[1])
        r = base.ds.recordings[rec]
        e = r.y[a:b, 0] - base.runs[rec].y[a:b, 0]
        width = max(50, min(600, (b - a) // 8))
        ((w0, w1),) = worst_windows(e, width, 1) or [(0, min(width, b - a))]
        t = np.arange(a + w0, a + w1) * st
        ax.plot(t, r.y[a + w0 : a + w1, 0], color="#333333", lw=1.0, label="measured")
        ax.plot(t, base.runs[rec].y[a + w0 : a + w1, 0], color="#d62728", lw=1.0, ls="--", label="baseline")
        ax.plot(t, final.runs[rec].y[a + w0 : a + w1, 0], color="#2ca02c", lw=1.0, label="extended")
        lim = _limits(
            np.concatenate(
                [r.y[a + w0 : a + w1, 0], base.runs[rec].y[a + w0 : a + w1, 0], final.runs[rec].y[a + w0 : a + w1, 0]]
            )
        )
        if lim:
            ax.set_ylim(*lim)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(base.model.output_names[0])
        ax.legend(loc="upper right", fontsize=8)
        ax.set_title("test split: the baseline's worst window", fontsize=9)
    before, after = gain.get("test_nmse_before"), gain.get("test_nmse_after")
    unc = gain.get("uncertainty") or {}
    err = [(unc.get(k) or {}).get("std") for k in ("test_nmse_before", "test_nmse_after")]
    vals = [before if before is not None else np.nan, after if after is not None else np.nan]
    bx.bar([0, 1], vals, color=["#d62728", "#2ca02c"], yerr=[e if e is not None else 0.0 for e in err], capsize=4)
    bx.set_xticks([0, 1], ["baseline" + (" (diverged)" if before is None else ""), "extended"])
    bx.set_ylabel("test NMSE (%)")
    if all(v is not None and v > 0 for v in vals) and max(vals) / min(vals) > 30:
        bx.set_yscale("log")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
