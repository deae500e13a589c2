"""inadequate-structure: the model does no better than a quick reference (thesis 7.2: a model is only worth
its complexity if it beats simple ones). Part of the core, run in every round: no diagnosis says
"adequate" before this check.

References (:mod:`.reference`): the training mean and a linear ARX / OE model on the free-running error.
On the validation split (train without one) the free-run errors are compared:

* the model is *near useless* when its free-run NMSE is at least ``NEAR_USELESS`` (90 %): it explains
  at most a tenth of the output variance (a diverging run counts as infinite). Always named.
* the linear reference *beats* the model when it lowers the free-run mean square by at least
  ``MARGIN`` (10 %) of the model's, significantly: one-sided signed-rank test on contiguous batch means
  of d_t = sum_k (e_model,k^2 - e_ref,k^2) / var(y_k) (:func:`.bootstrap.batch_means_test`), then the
  common rule (p < alpha, share >= min_share, effect >= min_effect).

Score: the share of the model's free-run mean square the better reference removes, 1 - MSE_ref / MSE_model
(0 when no reference is better). A verdict on the structure as a whole: when specific causes are named
too, they rank first (they say what is missing); its extensions are measured all the same. The evidence gives every reference's NMSE on every split (the test
split's figure is reported, never used to decide) and the reference's orders, which the families read to
propose a structure at least as rich as the reference's.
"""

from __future__ import annotations

import numpy as np

from .bootstrap import batch_means_test
from .context import Context
from .detector import Detector, Finding, Judgement

NEAR_USELESS = 90.0
MARGIN = 0.10


def _rows(ctx: Context, split: str, runs: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    ds = ctx.ds
    rows = ds.scored(split, warmup=ctx.model.warmup)
    y = np.concatenate([ds.recordings[r].y[a:b] for r, a, b in rows])
    yh = np.concatenate([runs[r][a:b] for r, a, b in rows])
    return y, yh


class InadequateStructure(Detector):
    cause = "inadequate-structure"
    description = "the model's free run is no better than a quick reference (the mean, a linear ARX/OE model)"
    priority = 2
    generic = True
    applies = "always"

    def detect(self, ctx: Context) -> Finding | None:
        refs = ctx.references
        split = "validation" if "validation" in ctx.model.metrics else "train"
        model_nmse = ctx.fit.nmse(split)
        if not np.isfinite(model_nmse):
            model_nmse = float("inf")
        lin = refs.linear
        lin_nmse = lin.nmse.get(split, np.inf) if lin is not None else np.inf
        mean_nmse = refs.mean_nmse.get(split, 100.0)
        evidence = {
            "statistic": "free-run NMSE of the model against the training mean and a linear ARX/OE reference on the "
            f"{split} split; paired batch-means signed-rank test of the squared errors",
            "split": split,
            "model_nmse": {s: ctx.fit.nmse(s) for s in ctx.ds.splits()},
            "mean_nmse": refs.mean_nmse,
            "reference": None if lin is None else lin.to_json(),
            "near_useless_threshold": NEAR_USELESS,
            "margin": MARGIN,
            "alpha": ctx.settings.alpha,
            "reference_seconds": refs.seconds,
        }
        best = min(lin_nmse, mean_nmse)
        share = float(1.0 - best / model_nmse) if np.isfinite(model_nmse) and model_nmse > 0 else 1.0
        share = max(share, 0.0)
        which = "the linear reference" if lin_nmse <= mean_nmse else "the training mean"
        ref_text = (
            f"a linear {lin.method} reference (output lags 1..{lin.na}, input lags 0..{lin.nb - 1}) reaches "
            f"{split} NMSE {lin_nmse:.4g} %"
            if lin is not None and np.isfinite(lin_nmse)
            else "no linear reference ran stably"
        )
        model_text = "diverges" if not np.isfinite(model_nmse) else f"{model_nmse:.4g} %"
        if model_nmse >= NEAR_USELESS:
            evidence.update(p_value=None, share=share)
            summary = (
                f"the model's {split} free-run NMSE is {model_text}: it explains at most a tenth of the output "
                f"variance (the training mean: {mean_nmse:.4g} %); {ref_text}"
            )
            verdict = Judgement.fixed(
                True, f"near useless: {split} NMSE {model_text} >= {NEAR_USELESS:g} %", share=share
            )
            return self.finding(ctx, share, verdict, summary, evidence, self._extensions(ctx, evidence))
        if lin is None or not np.isfinite(lin_nmse) or lin_nmse >= model_nmse:
            evidence.update(p_value=1.0, share=0.0)
            summary = (
                f"the model ({split} NMSE {model_text}) beats the references: {ref_text}, the mean {mean_nmse:.4g} %"
            )
            verdict = Judgement.fixed(False, f"beats the references ({model_text} vs {min(lin_nmse, mean_nmse):.4g} %)")
            return self.finding(ctx, 0.0, verdict, summary, evidence)
        y, y_model = _rows(ctx, split, [r.y for r in ctx.fit.runs])
        _, y_ref = _rows(ctx, split, lin.runs)
        var = np.maximum(np.var(y, axis=0), np.finfo(float).tiny)
        d = (((y - y_model) ** 2 - (y - y_ref) ** 2) / var).sum(axis=1)
        d = d[np.isfinite(d)]
        t, p, batches = batch_means_test(d) if d.size >= 20 else (0.0, 1.0, 0)
        share = float(1.0 - lin_nmse / model_nmse)
        k = int(np.argmax(((y - y_model) ** 2).mean(axis=0) / var))
        verdict = ctx.judge(
            p, share, k, {"margin": (share >= MARGIN, f"margin {100 * share:.1f} % < {100 * MARGIN:g} %")}
        )
        evidence.update(p_value=p, t=t, batches=batches, share=share)
        summary = (
            f"{ref_text} against the model's {model_text}: {which} removes {100 * share:.1f} % of the free-run mean "
            f"square (p = {p:.2g})"
        )
        extensions = self._extensions(ctx, evidence) if verdict.significant else []
        return self.finding(ctx, share, verdict, summary, evidence, extensions)

    def _extensions(self, ctx: Context, evidence: dict):
        from ..extensions import Extension

        generic = []
        if ctx.spec.cost != "mse_inf":
            generic.append(Extension("estimate on the free-running error (cost: mse_inf)", {"cost": "mse_inf"}))
        own = ctx.extensions(self.cause, evidence)
        return own[:2] + generic + own[2:]
