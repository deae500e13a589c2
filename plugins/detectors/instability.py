"""free-run-instability: the free run diverges, or grows far beyond anything seen in training.

Divergence is the engine's own criterion (the run leaves the training output range widened by ten
range widths); the evidence names the recording, sample and time. Without divergence, the run
*grows* when it goes more than half a range width beyond the range of the measured output (every
split: where the system itself never went); the score is then the share of the squared error made on
those out-of-range samples. Third, the run *loses track* when it predicts the validation split
(train without one) with at most a tenth of the output variance explained (NMSE >= 90 %) while the
one-step prediction is at least ten times better: the feedback accumulates errors the model does not
make one step ahead (thesis 3.1.4, 6.3.2); the score is then 1 - NMSE_1 / NMSE. Free runs cover
every split here: stability is a property of the model, and the thesis (6.3.2) judges it by running
through the whole record.
"""

from __future__ import annotations

import numpy as np

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Detector, Finding, Judgement

from ._extend import free_running_cost


def stabilizers(ctx: Context, evidence: dict) -> list:
    """Free-run stabilisation (thesis 6.3.2): free-running estimation with error propagation, then the
    family's own (terms chosen on the free-running error, bounds, ridge, internal mode, ...)."""
    generic = free_running_cost(ctx, "error propagation when the least-squares model diverges, thesis 6.3.2")
    return ctx.extensions("free-run-instability", evidence, generic)


GROWTH = 0.5  # range widths beyond the measured output range
LOST = 90.0  # free-run NMSE (%) of a run that has lost track
AMPLIFICATION = 10.0  # ... while the one-step NMSE is at least this many times smaller


class FreeRunInstability(Detector):
    cause = "free-run-instability"
    description = "the free run diverges or grows beyond the training range (thesis 3.1.4, 6.3.2)"
    priority = 0

    def detect(self, ctx: Context) -> Finding | None:
        fit = ctx.fit
        st = ctx.sampling_time
        for split in ("train", "validation", "test"):
            rows = fit.ds.scored(split, warmup=fit.model.warmup)
            for rec, a, b in rows:
                k = fit.runs[rec].diverged_at
                if k is not None and k < b:
                    name = fit.ds.recordings[rec].name
                    evidence = {
                        "statistic": "divergence of the free run (left the training output range widened by "
                        "10 range widths)",
                        "diverged": True,
                        "split": split,
                        "recording": name,
                        "sample": int(k),
                        "time": float(k * st),
                        "window": [float(k * st), float(k * st)],
                    }
                    return self.finding(
                        ctx,
                        1.0,
                        Judgement.fixed(True, f"diverges ({split} split)"),
                        f"the free run diverges at sample {k} (t = {k * st:.6g} s) of '{name}' ({split} split)",
                        evidence,
                        stabilizers(ctx, evidence),
                    )
        measured = np.concatenate(
            [
                fit.ds.recordings[r].y[a:b]
                for s in ("train", "validation", "test")
                for r, a, b in fit.ds.scored(s, warmup=fit.model.warmup)
            ]
        )
        lo, hi = measured.min(axis=0), measured.max(axis=0)
        width = np.maximum(hi - lo, np.finfo(float).tiny)
        worst, where, total, outside = 0.0, None, 0.0, 0.0
        for split in ("train", "validation", "test"):
            for rec, a, b in fit.ds.scored(split, warmup=fit.model.warmup):
                yhat = fit.runs[rec].y[a:b]
                e2 = (fit.ds.recordings[rec].y[a:b] - yhat) ** 2
                excess = np.maximum(yhat - hi, lo - yhat) / width
                total += float(e2.sum())
                out = excess > GROWTH
                outside += float(e2[out].sum())
                if excess.size and excess.max() > worst:
                    i = int(np.argmax(excess.max(axis=1)))
                    worst, where = float(excess.max()), (split, rec, a + i)
        score = outside / total if total > 0 else 0.0
        significant = worst > GROWTH
        lost = self._lost_track(ctx)
        if lost is not None and not significant:
            return lost
        evidence = {
            "statistic": "largest excursion of the free run beyond the measured output range, in range widths",
            "excursion": worst,
            "threshold": GROWTH,
            "diverged": False,
            "share_out_of_range": score,
        }
        if where is not None:
            split, rec, k = where
            evidence.update(
                split=split,
                recording=fit.ds.recordings[rec].name,
                sample=int(k),
                time=float(k * st),
                window=[float(k * st), float(k * st)],
            )
        summary = (
            f"the free run grows to {worst:.2g} range widths beyond the measured output range "
            f"(sample {where[2]}, {where[0]} split)"
            if significant and where
            else f"the free run stays within {max(worst, 0.0):.2g} range widths of the measured output range"
        )
        return self.finding(
            ctx,
            score if significant else 0.0,
            Judgement.fixed(
                significant,
                f"grows {worst:.2g} > {GROWTH:g} range widths beyond the measured range"
                if significant
                else f"no divergence, growth {max(worst, 0.0):.2g} <= {GROWTH:g} ranges, tracks",
            ),
            summary,
            evidence,
            stabilizers(ctx, evidence) if significant else [],
        )

    def _lost_track(self, ctx: Context) -> Finding | None:
        metrics = ctx.model.metrics
        split = "validation" if "validation" in metrics else "train"
        m = metrics.get(split) or {}
        free, one = m.get("nmse"), m.get("nmse_1")
        if free is None or one is None or free < LOST or one * AMPLIFICATION > free:
            return None
        score = 1.0 - one / free
        evidence = {
            "statistic": "free-run NMSE against one-step NMSE (error accumulation in the feedback)",
            "diverged": False,
            "split": split,
            "nmse_free_run": free,
            "nmse_one_step": one,
            "threshold_nmse": LOST,
            "threshold_ratio": AMPLIFICATION,
            "amplification": free / max(one, 1e-300),
        }
        summary = (
            f"the free run loses track: {split} NMSE {free:.4g} % in free run against {one:.4g} % one step "
            f"ahead ({free / max(one, 1e-300):.3g} x): the feedback accumulates errors"
        )
        why = f"lost track: NMSE {free:.3g} % >= {LOST:g} %, {free / max(one, 1e-300):.3g} x one-step"
        return self.finding(ctx, score, Judgement.fixed(True, why), summary, evidence, stabilizers(ctx, evidence))
