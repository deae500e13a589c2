"""Combine the evidence into ``reliable`` / ``unreliable`` / ``inconclusive``.

* A numerical *counterexample* proves unreliability (definition 4.4 quantifies over every input
  and every pair of initial states): replicas that end apart under some test input, a final
  state that depends on the phase the drive started at (fig. 5.5), a positive conditional
  Lyapunov exponent, a constant input without a single stable fixed point (eq. 4.39), a state
  that diverges.
* An algebraic proof (a contraction, eq. 4.51) proves reliability; a counterexample against it
  points at a numerical problem and makes the verdict inconclusive.
* rho > 1 with zero biases proves unreliability (eq. 5.24).
* Without proof either way: reliable when every test converged and every constant level has one
  fixed point, inconclusive when something did not settle within the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .attractors import LevelResult
from .lyapunov import Exponents
from .replicas import FamilyResult, SignalResult
from .system import Evidence


@dataclass
class Verdict:
    verdict: str
    reasons: list[str]
    counterexamples: list[str]
    unsettled: list[str]


def _fmt_vec(v: np.ndarray, digits: int = 3, limit: int = 4) -> str:
    v = np.atleast_1d(v)
    v = np.where(np.abs(v) < 1e-9 * (1.0 + np.abs(v).max()), 0.0, v)  # settled to within rounding of zero
    body = ", ".join(f"{x:.{digits}g}" for x in v[:limit])
    if len(v) > limit:
        body += f", ... ({len(v)} values, norm {np.linalg.norm(v):.3g})"
    return f"({body})" if len(v) > 1 else body


def describe_level(level: LevelResult, names: list[str]) -> str:
    """'u = 0: fixed point (0, 0); 2-cycle (0.864, -0.694) <-> (-0.864, 0.694) in 2 phases'."""
    inp = ", ".join(f"{n} = {x:.4g}" for n, x in zip(names, level.input))
    if level.status == "not settled" and all(a.kind != "non-periodic" for a in level.attractors):
        pts = np.concatenate([a.points for a in level.attractors])
        return (
            f"{inp}: {level.responses} end states within {level.spread:.3g} of each other near "
            f"{_fmt_vec(pts[0])}, still converging (rerun with --length)"
        )
    parts = []
    for a in level.attractors:
        if a.kind == "fixed point":
            parts.append(
                f"fixed point {_fmt_vec(a.points[0])}" + (f" ({a.replicas} replicas)" if level.responses > 1 else "")
            )
        elif a.kind == "cycle":
            path = " -> ".join(_fmt_vec(p) for p in a.points[:4]) + (" -> ..." if len(a.points) > 4 else "")
            parts.append(
                f"{a.period}-cycle {path} in {a.phases} phase{'s' if a.phases > 1 else ''} ({a.replicas} replicas)"
            )
        else:
            lam = "" if a.lyapunov is None or not np.isfinite(a.lyapunov) else f", largest CLE {a.lyapunov:.3g}/step"
            parts.append(f"{a.label} motion{lam} ({a.replicas} replicas, {a.phases} different)")
    if level.status == "diverged":
        parts.append("the state diverged")
    return f"{inp}: " + "; ".join(parts)


def _summary(items: list[str], total: int, what: str) -> str:
    if len(items) == 1:
        return items[0]
    return f"{len(items)} of {total} {what}, e.g. {items[0]}"


def decide(
    evidence: list[Evidence],
    signals: list[SignalResult],
    families: list[FamilyResult],
    exps: dict[str, Exponents],
    levels: list[LevelResult],
    input_names: list[str],
    tol: float,
    unit: str = "step",
    per_unit: float = 1.0,
) -> Verdict:
    """The verdict, a few summary reasons, and every counterexample / unsettled item."""
    unsettled: list[str] = []
    by_name = {s.name: s for s in signals}
    # counterexamples by category; the first item of each list is its most telling example
    apart = sorted(
        [s for s in signals if s.status == "apart"],
        key=lambda s: (s.kind != "declared", s.kind != "training", -s.final_distance),
    )
    apart_txt = [f"replicas end {s.final_distance:.3g} apart under {s.name}" for s in apart]
    diverged = [f"the state diverged at step {s.diverged_at} under {s.name}" for s in signals if s.status == "diverged"]
    for s in signals:
        if s.status == "slow":
            unsettled.append(
                f"still converging under {s.name} (distance {s.final_distance:.3g}): rerun with "
                f"--length {s.steps_needed} or more"
            )
        elif s.status == "close":
            unsettled.append(
                f"replicas end {s.final_distance:.3g} apart (above the tolerance {tol:.3g}, not "
                f"shrinking) under {s.name}"
            )
    phase = [
        f"the final state depends on the phase the drive started at: {len(f.members)} phases of the same "
        f"input end {f.final_distance:.3g} apart after an identical tail (fig. 5.5)"
        for f in families
        if f.status == "apart"
    ]
    for f in families:
        if f.status in ("slow", "close") and all(by_name[m].status == "converged" for m in f.members):
            unsettled.append(
                f"the {len(f.members)} phases of the same input (fig. 5.5) end {f.final_distance:.3g} "
                f"apart after their common tail and still approach each other: rerun with --length "
                f"{f.length_needed} or more"
                if f.status == "slow"
                else f"the {len(f.members)} phases of the same input (fig. 5.5) end {f.final_distance:.3g} "
                "apart after their common tail"
            )
    positive: list[tuple[float, str]] = []
    for name, e in exps.items():
        if e.sign() == "positive":
            item = f"positive conditional Lyapunov exponent {e.largest * per_unit:.3g} per {unit} under {name}"
            if by_name.get(name) is not None and by_name[name].status == "converged":
                unsettled.append(item + " although the replicas converged")
            else:
                positive.append((e.largest, item))
    positive.sort(key=lambda t: -t[0])
    bad_levels = [lv for lv in levels if lv.status in ("several responses", "no fixed point", "diverged")]
    bad_levels.sort(key=lambda lv: (not np.all(lv.input == 0), -len(lv.attractors)))
    level_txt = [f"constant input {describe_level(lv, input_names)}" for lv in bad_levels]
    for lv in levels:
        if lv.status == "not settled":
            unsettled.append(f"constant input not settled: {describe_level(lv, input_names)}")
    counter = level_txt + apart_txt + phase + [t for _, t in positive] + diverged
    summary = []
    if level_txt:
        summary.append(_summary(level_txt, len(levels), "constant inputs lack a single stable fixed point (eq. 4.39)"))
    if apart_txt:
        summary.append(_summary(apart_txt, len(signals), "test inputs leave the replicas apart"))
    summary += phase
    if positive:
        summary.append(_summary([t for _, t in positive], len(exps), "test inputs give a positive exponent"))
    if diverged:
        summary.append(_summary(diverged, len(signals), "test inputs make the state diverge"))
    proof_rel = [e for e in evidence if e.implies == "reliable"]
    proof_unrel = [e for e in evidence if e.implies == "unreliable"]
    if counter and proof_rel:
        return Verdict(
            "inconclusive",
            [
                f"numerical counterexamples contradict {proof_rel[0].name} = {proof_rel[0].value:.4g} "
                f"({proof_rel[0].statement}); suspect a numerical problem"
            ]
            + summary,
            counter,
            unsettled,
        )
    if counter:
        return Verdict("unreliable", summary, counter, unsettled)
    if proof_unrel:
        return Verdict(
            "unreliable", [f"{e.name} = {e.value:.4g}: {e.statement}" for e in proof_unrel], counter, unsettled
        )
    if proof_rel:
        reasons = [f"{e.name} = {e.value:.4g}: {e.statement}" for e in proof_rel]
        reasons.append(
            "the numerical tests agree"
            if not unsettled
            else f"the numerical tests find no counterexample ({len(unsettled)} slow to settle)"
        )
        return Verdict("reliable", reasons, counter, unsettled)
    if unsettled:
        return Verdict(
            "inconclusive",
            [f"no counterexample, but {len(unsettled)} test(s) did not settle, e.g. {unsettled[0]}"],
            counter,
            unsettled,
        )
    return Verdict(
        "reliable",
        [
            f"replicas converged under all {len(signals)} test inputs and each of the "
            f"{len(levels)} constant inputs has a single stable fixed point (no algebraic "
            "proof: reliable on the tested inputs)"
        ],
        counter,
        unsettled,
    )
