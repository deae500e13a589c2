"""The reliability check: algebraic evidence, replica test, Lyapunov exponents, constant-input scan
and (external mode) the tune-in, combined into a verdict (thesis 4.4.1, 5.3.1, 5.3.2)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..family import Progress, no_progress
from . import attractors, lyapunov, replicas, tune_in
from .signals import TestSignal, battery, constant_levels
from .system import DrivenSystem, Evidence, Sine
from .verdict import Verdict, decide

#: relative size of the random nudge of the constant scan's initial states
NUDGE = 1e-8


@dataclass
class Settings:
    """Sizes of the tests; every random draw derives from ``seed``."""

    replicas: int = 16
    scan_replicas: int = 32
    length: int | None = None
    levels: int = 21
    seed: int = 0
    tolerance: float = 1e-6  # converged: replicas closer than this fraction of the state scale
    sines: tuple[Sine, ...] = ()
    lyapunov_replicas: int = 2
    exponents: int = 1
    tune_in_max: int | None = None
    horizon: int = 200

    def to_json(self) -> dict[str, Any]:
        return {
            "replicas": self.replicas,
            "scan_replicas": self.scan_replicas,
            "length": self.length,
            "levels": self.levels,
            "seed": self.seed,
            "tolerance": self.tolerance,
            "sines": [s.name() for s in self.sines],
            "lyapunov_replicas": self.lyapunov_replicas,
            "exponents": self.exponents,
            "tune_in_max": self.tune_in_max,
            "horizon": self.horizon,
        }


@dataclass
class Report:
    system: dict[str, Any]
    settings: Settings
    length: int
    scale: float
    tolerance: float
    evidence: list[Evidence]
    signals: list[replicas.SignalResult]
    families: list[replicas.FamilyResult]
    exponents: dict[str, lyapunov.Exponents]
    levels: list[attractors.LevelResult]
    verdict: Verdict
    input_names: list[str]
    sampling_time: float
    continuous: bool
    closed_loop: list[Evidence] = field(default_factory=list)
    tune_in: tune_in.TuneInResult | None = None
    notes: list[str] = field(default_factory=list)
    timing: dict[str, float] = field(default_factory=dict)

    @property
    def washout(self) -> int | None:
        """Steps after which every converged test's replicas stayed within the tolerance."""
        vals = [s.converged_after for s in self.signals if s.converged_after is not None]
        return max(vals) if vals else None

    @property
    def length_needed(self) -> int | None:
        """The run length the slowest still-converging test asks for (None if nothing is slow)."""
        vals = [s.steps_needed for s in self.signals if s.status == "slow" and s.steps_needed]
        vals += [f.length_needed for f in self.families if f.status == "slow" and f.length_needed]
        return max(vals) if vals else None

    @property
    def exit_code(self) -> int:
        return 0 if self.verdict.verdict == "reliable" else 1

    def lyapunov_json(self, e: lyapunov.Exponents) -> dict[str, Any]:
        return lyapunov.to_json(e, self.sampling_time, self.continuous)

    def to_json(self) -> dict[str, Any]:
        """Everything as plain JSON (non-finite numbers become null; statuses say why)."""
        return _finite(self._json())

    def _json(self) -> dict[str, Any]:
        dt, cont = self.sampling_time, self.continuous
        return {
            "verdict": self.verdict.verdict,
            "reasons": self.verdict.reasons,
            "counterexamples": self.verdict.counterexamples,
            "unsettled": self.verdict.unsettled,
            "system": self.system,
            "settings": self.settings.to_json(),
            "length": self.length,
            "state_scale": self.scale,
            "tolerance": self.tolerance,
            "washout_steps": self.washout,
            "washout_time": None if self.washout is None else self.washout * dt,
            "length_needed": self.length_needed,
            "algebraic": [e.to_json() for e in self.evidence],
            "replica_test": {
                "replicas": self.settings.replicas,
                "signals": [
                    dict(
                        s.to_json(dt),
                        largest_lyapunov=(
                            self.lyapunov_json(self.exponents[s.name]) if s.name in self.exponents else None
                        ),
                    )
                    for s in self.signals
                ],
                "phase_families": [f.to_json() for f in self.families],
                "largest_final_distance": max((s.final_distance for s in self.signals), default=None),
            },
            "constant_scan": {
                "replicas": self.settings.scan_replicas,
                "inputs": self.input_names,
                "levels": [lv.to_json(dt, cont) for lv in self.levels],
            },
            "external_mode": None
            if self.tune_in is None and not self.closed_loop
            else {
                "closed_loop": "not reliable by construction: the fed-back output makes the free run depend on its "
                "start (thesis 5.3.2); the verdict is for the open loop driven by input and output",
                "facts": [e.to_json() for e in self.closed_loop],
                "tune_in": None if self.tune_in is None else self.tune_in.to_json(),
            },
            "notes": self.notes,
            "timing_seconds": self.timing,
        }


def _finite(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _lyapunov(
    system: DrivenSystem,
    signals: list[TestSignal],
    X0: np.ndarray,
    k: int,
    rng: np.random.Generator,
    progress: Progress,
) -> dict[str, lyapunov.Exponents]:
    """Largest exponents per signal, maximum over the trajectories from the rows of X0."""
    out: dict[str, lyapunov.Exponents] = {}
    L = len(X0)
    by_len: dict[int, list[int]] = {}
    for i, s in enumerate(signals):
        by_len.setdefault(len(s.u), []).append(i)
    for idx in by_len.values():
        V = np.stack([system.drive(signals[i].u) for i in idx])  # (S, n, d)
        Vr = np.ascontiguousarray(np.repeat(V, L, axis=0).transpose(1, 0, 2))  # (n, S L, d)
        ex = lyapunov.exponents(system, Vr, np.tile(X0, (len(idx), 1)), k, rng, progress=progress)
        for j, i in enumerate(idx):
            mine = ex[j * L : (j + 1) * L]
            best = max(mine, key=lambda e: e.largest if np.isfinite(e.largest) else np.inf)
            out[signals[i].name] = best
    return out


def _tune_in(
    system: DrivenSystem, settings: Settings, rng: np.random.Generator, X0: np.ndarray, progress: Progress
) -> tuple[tune_in.TuneInResult | None, str]:
    """Tune-in samples an external-mode model needs, taught with the recorded output (the open
    loop's training signal holds input and output) or, without one, with its own closed-loop run."""
    cl = system.closed_loop
    assert cl is not None
    n_out = cl.n_outputs
    dom = system.inputs
    n_in = dom.n - n_out
    lo_m = system.drive(np.tile(dom.low, (2, 1)))[-1, -n_out:]
    hi_m = system.drive(np.tile(dom.high, (2, 1)))[-1, -n_out:]
    width = np.maximum(np.abs(hi_m - lo_m), 1e-12)
    max_k = settings.tune_in_max if settings.tune_in_max is not None else max(500, 2 * cl.tune_in)
    need = max_k + settings.horizon + 1
    rec = None
    if system.training_input is not None:
        rec = np.asarray(system.training_input, dtype=np.float64)
        lengths = system.training_lengths
        if lengths is not None and len(lengths):
            rec = rec[: int(lengths[0])]
        rec = rec[:need] if len(rec) >= settings.horizon + 1 else None
    if rec is not None:
        V = system.drive(rec)
        Vin, y_teach = V[:, :-n_out], V[:, -n_out:]
        source = getattr(system, "teacher_source", "recorded input and output")
    else:
        u = dom.mean[:n_in] + dom.std[:n_in] * rng.standard_normal((need, n_in))
        Vin = system.drive(np.hstack([u, np.tile(dom.mean[n_in:], (need, 1))]))[:, :-n_out]
        bounds = (np.minimum(lo_m, hi_m) - 10 * width, np.maximum(lo_m, hi_m) + 10 * width)
        y_teach, stop = tune_in.reference(system, Vin, bounds)
        if stop is not None and stop < settings.horizon + 1:
            return None, (
                "no recorded output, and the closed loop run from the rest state on white noise leaves the "
                f"output range at sample {stop}: the tune-in could not be measured"
            )
        if stop is not None:
            Vin, y_teach = Vin[:stop], y_teach[:stop]
        source = "white noise input, taught with the closed loop's own run from the rest state"
    res = tune_in.measure(system, Vin, y_teach, X0, width, settings.horizon, max_k, progress)
    return res, f"tune-in measured on the {source} ({len(Vin)} samples)"


def check(system: DrivenSystem, settings: Settings | None = None, progress: Progress = no_progress) -> Report:
    """Run every test on ``system`` and return the report with its verdict."""
    settings = settings or Settings()
    seeds = np.random.SeedSequence(settings.seed).spawn(6)
    rng_sig, rng_x, rng_scan, rng_lyap, rng_tune, rng_lvl = (np.random.default_rng(s) for s in seeds)
    n = int(settings.length or system.default_length)
    scale = system.scale()
    tol = settings.tolerance * scale
    apart = replicas.APART * scale
    timing: dict[str, float] = {}
    notes: list[str] = []
    reference_note = getattr(system, "reference_note", "")  # a fitted model's view says what it compares with
    if reference_note:
        notes.append(reference_note)

    t0 = time.perf_counter()
    progress("evidence", None, "algebraic evidence")
    evidence = system.evidence()
    closed = system.closed_loop.facts() if system.closed_loop is not None else []
    timing["evidence"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    signals = battery(system, n, rng_sig, list(settings.sines))
    X0 = system.sample_states(rng_x, settings.replicas)
    sig_results, families = replicas.run(system, signals, X0, tol, apart, progress, scale)
    timing["replica_test"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    XL = X0[: max(1, min(settings.lyapunov_replicas, len(X0)))]
    exps = _lyapunov(system, signals, XL, settings.exponents, rng_lyap, progress)
    timing["lyapunov"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    levels = constant_levels(system.inputs, settings.levels)
    Xs = system.sample_states(rng_scan, settings.scan_replicas)
    # a start exactly on an unstable invariant set (the rest state at zero drive) would stay there:
    # nudge every start so that only attractors are found
    lo, hi = system.state_box()
    Xs = Xs + NUDGE * (hi - lo) * rng_scan.standard_normal(Xs.shape)
    level_results = attractors.scan(system, levels, Xs, n, tol, rng_lvl, progress)
    timing["constant_scan"] = time.perf_counter() - t0

    tune = None
    if system.closed_loop is not None:
        t0 = time.perf_counter()
        tune, note = _tune_in(system, settings, rng_tune, X0, progress)
        notes.append(note)
        if tune is not None and tune.required is not None and tune.required > tune.configured:
            notes.append(
                f"the model tunes in on {tune.configured} samples but its free run needs {tune.required} "
                "to start on the right trajectory: raise tune_in"
            )
        timing["tune_in"] = time.perf_counter() - t0

    per_unit = 1.0 / system.sampling_time if system.continuous else 1.0
    unit = "time unit" if system.continuous else "step"
    verdict = decide(evidence, sig_results, families, exps, level_results, system.inputs.names, tol, unit, per_unit)
    timing["total"] = sum(timing.values())
    return Report(
        system.describe(),
        settings,
        n,
        scale,
        tol,
        evidence,
        sig_results,
        families,
        exps,
        level_results,
        verdict,
        system.inputs.names,
        system.sampling_time,
        system.continuous,
        closed,
        tune,
        notes,
        timing,
    )
