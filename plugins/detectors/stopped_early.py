"""structure-stopped-early: the model's structure selection stopped while more terms clearly do better.

Applies when the model's family offers a longer selection for this cause (its ``extensions`` hook: a
polynomial NARX model takes more terms, a network's readout keeps selecting); the detector refits the
first two proposals (the diagnosis' cache reuses the fits when they become candidates). Statistic: the
paired reduction of the free-run squared error on the validation split (train when there is none),
d_t = sum_k (e_k^2 - e'_k^2) / var(y_k), tested one-sided by a signed-rank test on contiguous batch means
(:func:`dynmodel.diagnose.bootstrap.batch_means_test`). Named by the common rule (p, share, effect) and a
clear margin: the longer selection must remove at least ``MARGIN`` (10 %) of the free-run mean square.
Score: 1 - MSE_longer / MSE. A refit that diverges is no evidence.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dynmodel.diagnose.bootstrap import batch_means_test
from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Detector, Finding
from dynmodel.errors import DynmodelError

MARGIN = 0.10
REFITS = 2


class StructureStoppedEarly(Detector):
    cause = "structure-stopped-early"
    description = "the structure selection stopped while a refit with more terms is clearly better on held-out data"
    priority = 8
    applies = "families that offer a longer selection (their extensions hook) and a finite free run"

    def detect(self, ctx: Context) -> Finding | None:
        proposals = ctx.extensions(self.cause, {})
        if not proposals:
            return None
        split = "validation" if "validation" in ctx.model.metrics else "train"
        y, y0 = ctx.fit.residual(split)
        if y.size == 0 or not np.isfinite(y0).all():
            return None  # a diverging model: free-run-instability's case
        var = np.maximum(np.var(y, axis=0), np.finfo(float).tiny)
        tried: list[dict[str, Any]] = []
        for ext in proposals[:REFITS]:
            ctx.progress(self.cause, None, ext.summary)
            try:
                other = ctx.refit(ext.patch, label=f"{self.cause}: {ext.summary}")
            except DynmodelError as exc:
                tried.append({"extension": ext.summary, "error": exc.line()})
                continue
            common = max(ctx.fit.model.warmup, other.model.warmup)  # both scored on the same samples
            y, y0 = ctx.fit.residual(split, common)
            _, y1 = other.residual(split, common)
            if not np.isfinite(y1).all() or not np.isfinite(y0).all():
                tried.append({"extension": ext.summary, "nmse": None, "diverged": True})
                continue
            e0 = (((y - y0) ** 2) / var).sum(axis=1)
            e1 = (((y - y1) ** 2) / var).sum(axis=1)
            share = float(1.0 - e1.mean() / max(e0.mean(), np.finfo(float).tiny))
            tried.append({"extension": ext.summary, "nmse": other.nmse(split), "share": share, "_e": (e0, e1, ext)})
        usable = [t for t in tried if "_e" in t]
        evidence: dict[str, Any] = {
            "statistic": f"paired reduction of the free-run squared error on the {split} split by a refit with a "
            "longer selection, batch-means signed-rank test",
            "split": split,
            "nmse": ctx.fit.nmse(split),
            "margin": MARGIN,
            "alpha": ctx.settings.alpha,
        }
        if not usable:
            evidence["refits"] = tried
            return self.finding(ctx, 0.0, False, "no longer selection could be refitted", evidence)
        best = max(usable, key=lambda t: t["share"])
        e0, e1, ext = best["_e"]
        t, p, batches = batch_means_test(e0 - e1)
        share = best["share"]
        k = int(np.argmax(((y - y0) ** 2).mean(axis=0) / var))
        verdict = ctx.judge(
            p, share, k, {"margin": (share >= MARGIN, f"gain {100 * share:.1f} % < {100 * MARGIN:g} %")}
        )
        evidence.update(
            refits=[{key: v for key, v in x.items() if key != "_e"} for x in tried],
            best=ext.summary,
            nmse_longer=best["nmse"],
            p_value=p,
            t=t,
            batches=batches,
            share=share,
        )
        summary = (
            f"a longer selection ({ext.summary}) lowers the {split} free-run NMSE from {ctx.fit.nmse(split):.4g} % "
            f"to {best['nmse']:.4g} % ({100 * share:.1f} %, p = {p:.2g})"
        )
        ordered = [ext] + [x for x in proposals if x is not ext]
        return self.finding(ctx, share, verdict, summary, evidence, ordered)
