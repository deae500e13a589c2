"""The gain of an extension on the held-out test split, with its uncertainty.

* Deterministic fits (the family's ``stochastic`` flag is false for both models): a paired circular
  block bootstrap of the test residuals (:mod:`.bootstrap`).
* Random fits: both specs are refitted with ``seeds`` seeds (the spec's seed and the next ones);
  the spread of the test NMSE and of the per-seed relative reduction is reported.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import DynmodelError
from .bootstrap import paired_nmse
from .fitting import Fit, Fitter


def test_key(metrics: dict[str, Any]) -> str | None:
    """The test split the gain is measured on: ``test``, else the first named test set (``test:<name>``)."""
    if "test" in metrics:
        return "test"
    return next((k for k in metrics if k.startswith("test:")), None)


def _test_metric(fit: Fit, metric: str, key: str | None = "test") -> float | None:
    m = fit.metrics.get(key or "test") or {}
    return None if m.get(metric) is None else float(m[metric])


def _reduction(before: float | None, after: float | None) -> float | None:
    """1 - after / before; None when either diverged (no ratio of a finite and an infinite error is a gain)."""
    if after is None or before is None:
        return None
    return float(1.0 - after / before) if before > 0 else None


def _summary(values: list[float]) -> dict[str, Any]:
    a = np.asarray(values, dtype=np.float64)
    finite = a[np.isfinite(a)]
    return {
        "values": [None if not np.isfinite(v) else float(v) for v in a],
        "mean": float(finite.mean()) if finite.size else None,
        "std": float(finite.std(ddof=1)) if finite.size > 1 else None,
    }


def measure_gain(fitter: Fitter, base: Fit, final: Fit, settings) -> dict[str, Any]:
    """Test NMSE and MAX before and after, the relative reduction, and its uncertainty."""
    key = test_key(base.metrics)
    before, after = _test_metric(base, "nmse", key), _test_metric(final, "nmse", key)
    gain: dict[str, Any] = {
        "test_split": key,
        "test_nmse_before": before,
        "test_nmse_after": after,
        "relative_reduction": _reduction(before, after),
        "test_max_before": _test_metric(base, "max", key),
        "test_max_after": _test_metric(final, "max", key),
        "baseline_diverged_on_test": bool((base.metrics.get(key or "test") or {}).get("unstable_from")),
        "extended_diverged_on_test": bool((final.metrics.get(key or "test") or {}).get("unstable_from")),
    }
    named = [k for k in base.metrics if k.startswith("test:")]
    if len(named) > 1 or (named and key == "test"):  # every named test set, the first one above
        gain["per_test"] = {
            k: {
                "test_nmse_before": _test_metric(base, "nmse", k),
                "test_nmse_after": _test_metric(final, "nmse", k),
                "relative_reduction": _reduction(_test_metric(base, "nmse", k), _test_metric(final, "nmse", k)),
            }
            for k in ([key] if key == "test" else []) + named
        }
    if key is None:
        gain["note"] = "the spec has no test split; give data.split.test or data.test to measure the gain"
        return gain
    stochastic = bool(base.model.family.stochastic or final.model.family.stochastic)
    if not stochastic:
        common = max(base.model.warmup, final.model.warmup)  # both scored on the same samples
        y, y1 = base.residual(key, common)
        _, y2 = final.residual(key, common)
        if not (np.isfinite(y1).all() and np.isfinite(y2).all()):
            gain["uncertainty"] = {"method": "none: a free run diverged on the test split"}
            return gain
        rng = np.random.default_rng([settings.seed, 0x6761696E])
        per_output = [
            paired_nmse(y[:, k], y[:, k] - y1[:, k], y[:, k] - y2[:, k], rng, settings.bootstrap)
            for k in range(y.shape[1])
        ]
        gain["uncertainty"] = per_output[0] if len(per_output) == 1 else {"per_output": per_output}
        return gain
    seeds = [int(base.spec.seed) + i for i in range(max(1, settings.seeds))]
    nb, na, red = [], [], []
    for s in seeds:
        try:
            fb = base if s == base.spec.seed else fitter.fit(base.raw, seed=s, label=f"baseline, seed {s}")
            fa = final if s == final.spec.seed else fitter.fit(final.raw, seed=s, label=f"extended, seed {s}")
        except DynmodelError:
            continue
        b, a = _test_metric(fb, "nmse", key), _test_metric(fa, "nmse", key)
        nb.append(np.inf if b is None else b)
        na.append(np.inf if a is None else a)
        r = _reduction(b, a)
        red.append(np.nan if r is None else r)
    gain["uncertainty"] = {
        "method": f"refits with {len(nb)} seeds ({seeds[0]}..{seeds[-1]})",
        "seeds": seeds,
        "test_nmse_before": _summary(nb),
        "test_nmse_after": _summary(na),
        "relative_reduction": _summary(red),
    }
    return gain
