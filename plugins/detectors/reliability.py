"""unreliable-model: the fitted network fails the reliability check (thesis 4.4.1, 5.3.1).

An unreliable model's free run depends on its initial state, not only on the input, so its
residual says little about the data; the finding gets score 1 and the check's counterexamples as
evidence. Families without a driven-system view, and views whose state is the measured tune-in (narx: its
free runs start from measured outputs), are not checked.
"""

from __future__ import annotations

from dynmodel.diagnose.context import Context
from dynmodel.diagnose.detector import Detector, Finding, Judgement
from dynmodel.reliability import Settings, check_model


class UnreliableModel(Detector):
    cause = "unreliable-model"
    description = "the reliability check finds that the model does not forget its initial state (thesis 5.3.1)"
    priority = 1
    applies = "families with a driven-system view started from rest (networks)"

    def detect(self, ctx: Context) -> Finding | None:
        view = ctx.model.family.driven_system() if ctx.settings.reliability else None
        if view is None or view.state_is_tune_in:  # a run that starts from measured outputs is not judged here
            return None
        ctx.progress("reliability", None, "reliability check of the fitted model")
        settings = Settings(replicas=8, scan_replicas=8, levels=9, length=1000, seed=ctx.settings.seed)
        report = check_model(ctx.model, settings, None, ctx.spec.name)
        v = report.verdict
        significant = v.verdict == "unreliable"
        evidence = {
            "statistic": "reliability check (replica test, conditional Lyapunov exponents, constant-input scan)",
            "verdict": v.verdict,
            "reasons": v.reasons[:6],
            "counterexamples": v.counterexamples[:6],
            "unsettled": v.unsettled[:6],
            "settings": settings.to_json(),
        }
        summary = f"the reliability check finds the model {v.verdict}" + (
            f": {v.counterexamples[0]}" if significant and v.counterexamples else ""
        )
        verdict = Judgement.fixed(significant, f"reliability check: {v.verdict}")
        extensions = ctx.extensions(self.cause, evidence) if significant else []
        found = self.finding(ctx, 1.0 if significant else 0.0, verdict, summary, evidence, extensions)
        if v.verdict == "inconclusive":
            found.caveat = (
                f"the reliability check over {settings.length} samples was inconclusive ("
                + (v.unsettled[0] if v.unsettled else v.reasons[0] if v.reasons else "no verdict")
                + "): check the model with `dynmodel reliability-check` before trusting its free runs from other "
                "initial states"
            )
        return found
