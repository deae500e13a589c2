"""What the search checks on a fitted candidate beyond its validation error, reading only **inputs**.

The *band check*: the candidate's free run on the inputs of every split (training, validation, every test
set) must stay inside the training output range widened by :data:`BAND` of its width on each side. A run
that leaves it diverges or extrapolates wildly where the data give no evidence; a run held at an output
clip set at (or beyond) that band counts as leaving it (the clip hides the divergence). Test outputs are
never read: a recording that starts inside a test split starts from the measured outputs of its
initialization window when the protocol declares one that covers the model's tune-in, and from rest (every
past output at the training mean) otherwise. That from-rest run is also what a protocol without a window
scores.

The *input dependence* (:func:`dynmodel.usefulness.input_dependence`, on the view's validation split): a
model whose free run barely moves when the input is held at its mean ignores its input.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..model import FittedModel

#: the band around the training output range, in range widths on each side
BAND = 0.5
#: a run within this fraction of the band's margin from its edge counts as having reached it (an output
#: clip at exactly the band holds a diverging run there)
EDGE = 0.02


def band(ds: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) per output: the training output range widened by BAND x its width, less the edge."""
    y = ds.concat_outputs("train")
    lo, hi = np.nanmin(y, axis=0), np.nanmax(y, axis=0)
    width = np.maximum(hi - lo, np.finfo(float).tiny)
    margin = BAND * (1.0 - EDGE) * width
    return lo - margin, hi + margin


def _fit_rows(ds: Dataset) -> set[tuple[int, int]]:
    """(recording, sample) starts that lie inside a training or validation range."""
    return {(r, a) for s in ("train", "validation") for r, a, _ in ds.ranges.get(s, [])}


def _start_outputs(ds: Dataset, split: str, rec: int, warmup: int, train_mean: np.ndarray) -> tuple[np.ndarray, str]:
    """The measured outputs a run of recording ``rec`` may start from, and how ('measured', 'window', 'rest')."""
    r = ds.recordings[rec]
    if warmup == 0:
        return np.empty((0, r.y.shape[1])), "rest"
    inside_fit = any(rr == rec and a == 0 for s in ("train", "validation") for rr, a, _ in ds.ranges.get(s, []))
    if inside_fit:
        return r.y[:warmup], "measured"
    window = (getattr(ds, "windows", {}) or {}).get(split)
    if window is not None and window >= warmup and np.isfinite(r.y[:warmup]).all():
        return r.y[:warmup], "window"
    return np.broadcast_to(train_mean, (warmup, r.y.shape[1])).copy(), "rest"


def band_checks(model: FittedModel, ds: Dataset) -> dict[str, Any]:
    """Per split: ``{"ok": bool, "start": how runs started, "sample": first sample outside the band or None,
    "recording": its name}`` plus ``"ok"`` over all splits. Runs every recording once."""
    lo, hi = band(ds)
    train_mean = np.nanmean(ds.concat_outputs("train"), axis=0)
    warm = model.warmup
    owner: dict[int, str] = {}
    for split in ds.splits():
        for rec, _, _ in ds.ranges.get(split, []):
            owner.setdefault(rec, split)
    runs: dict[int, tuple[np.ndarray, str]] = {}
    for rec, split in sorted(owner.items()):
        r = ds.recordings[rec]
        start, how = _start_outputs(ds, split, rec, warm, train_mean)
        try:
            run = model.run(r.u, start if warm else None)
            y = run.y
        except (ValueError, FloatingPointError):
            y = np.full_like(r.y, np.nan)
        runs[rec] = (y, how)
    out: dict[str, Any] = {"ok": True}
    for split in ds.splits():
        entry: dict[str, Any] = {"ok": True, "sample": None, "recording": None, "start": None}
        for rec, a, b in ds.scored(split, warm):
            y, how = runs[rec]
            entry["start"] = entry["start"] or how
            seg = y[a:b]
            bad = ~np.isfinite(seg).all(axis=1) | ((seg < lo) | (seg > hi)).any(axis=1)
            if bad.any():
                entry.update(ok=False, sample=int(a + np.argmax(bad)), recording=ds.recordings[rec].name)
                break
        out[split] = entry
        out["ok"] = out["ok"] and entry["ok"]
    return out


def failed_split(checks: dict[str, Any]) -> str | None:
    """The first split whose band check failed, as a phrase, or None."""
    for split, entry in checks.items():
        if isinstance(entry, dict) and not entry.get("ok", True):
            start = {"rest": " (run from rest)", "window": "", "measured": ""}.get(entry.get("start") or "", "")
            return f"leaves the output band on the {split} input at sample {entry['sample']}{start}"
    return None


def complexity(model: FittedModel) -> float:
    """The fitted model's size: ``summary()['parameters']`` when the family reports it, else the number of
    floating-point values in its stored arrays."""
    try:
        reported = model.family.summary().get("parameters")
    except Exception:  # noqa: BLE001 - a summary is optional
        reported = None
    if isinstance(reported, (int, float)) and reported >= 0:
        return float(reported)
    arrays, _ = model.family.to_arrays()
    return float(sum(np.size(a) for a in arrays.values() if np.issubdtype(np.asarray(a).dtype, np.floating)))
