"""Detection rates, evidence accuracy, gains and false alarms of `dynmodel diagnose` (prints figures).

Every built-in cause is hidden at random strength, lag, frequency (the cases of tests/hidden_effects.py)
for seeds start .. start + seeds - 1; clean data with adequate models for as many seeds as --clean.

    python benchmarks/diagnose_rates.py --start 100 --seeds 50 --clean 100
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import hidden_effects as H  # noqa: E402
import numpy as np  # noqa: E402

from dynmodel.diagnose import Settings, diagnose  # noqa: E402
from dynmodel.diagnose.fitting import Fitter  # noqa: E402
from dynmodel.diagnose.runner import detect  # noqa: E402


def evidence_error(cause: str, case: H.Case, ev: dict) -> tuple[str, float] | None:
    """(what, value) comparing the named cause's evidence with the hidden truth."""
    t = case.truth
    if cause == "missing-delay":
        return "lag error (samples)", ev["lag_samples"] - t["lag"]
    if cause == "unmodeled-oscillation":
        return "frequency error (%)", 100 * (ev["frequency_hz"] / t["frequency_hz"] - 1)
    if cause == "insufficient-memory":
        return "time constant found / true", ev["best_time_constant_samples"] / t["tau"]
    if cause == "sensor-drift":
        t0, t1 = ev["window"]
        f = lambda x: t["size"] * (1 - np.exp(-x / t["tau"])) + t["slope"] * x  # noqa: E731
        return "drift change found / true", ev["drift_change"] / (f(t1) - f(t0))
    if cause == "free-run-instability":
        a, b = t["windows"][0]
        return "divergence inside the first burst (1 = yes)", float(a <= ev.get("sample", -1) <= b + 50)
    return None


def hidden(start: int, count: int) -> None:
    print(f"hidden causes, seeds {start}..{start + count - 1}")
    for cause, make in H.HIDDEN.items():
        t0 = time.perf_counter()
        named, gains, errors, misses = 0, [], [], []
        for seed in range(start, start + count):
            case = make(seed)
            with tempfile.TemporaryDirectory() as d:
                result = diagnose(case.spec(Path(d)), "<bench>", Path(d), Settings(seeds=2))
            if result.verdict == cause:
                named += 1
                errors.append(evidence_error(cause, case, result.findings[0].evidence))
            else:
                misses.append((seed, result.verdict))
            g = (result.gain or {}).get("relative_reduction")
            if g is not None:
                gains.append(g)
        gtxt = (
            f"test NMSE reduction median {100 * np.median(gains):.1f} %, min {100 * np.min(gains):.1f} %"
            if gains
            else "baseline diverges on the test split in every run; the extension stays finite"
        )
        print(f"  {cause:22s} named first {named}/{count}; {gtxt} ({time.perf_counter() - t0:.0f} s)")
        errors = [x for x in errors if x is not None]
        if errors:
            values = np.array([v for _, v in errors])
            print(
                f"      evidence, {errors[0][0]}: median {np.median(values):.3g}, range [{values.min():.3g}, "
                f"{values.max():.3g}]"
            )
        for seed, verdict in misses:
            print(f"      seed {seed}: named {verdict}")


def generator_friction(start: int, count: int) -> None:
    """Direction dependence in data of the friction simulators (the `dahl` generator)."""
    t0 = time.perf_counter()
    named, gains, chosen, misses = 0, [], {}, []
    for seed in range(start, start + count):
        spec, _ = H.dahl_generator_spec(seed)
        with tempfile.TemporaryDirectory() as d:
            result = diagnose(spec, "<bench>", Path(d), Settings(seeds=2))
        named += result.verdict == "direction-dependence"
        if result.verdict != "direction-dependence":
            misses.append((seed, result.verdict))
        if result.gain and result.gain.get("relative_reduction") is not None:
            gains.append(result.gain["relative_reduction"])
        if result.rounds[0].chosen is not None:
            key = result.rounds[0].chosen.extension.summary.split(":")[0]
            chosen[key] = chosen.get(key, 0) + 1
    print(
        f"  dahl generator         named first {named}/{count}; test NMSE reduction median "
        f"{100 * np.median(gains):.1f} %, min {100 * np.min(gains):.1f} %; chosen {chosen} "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    for seed, verdict in misses:
        print(f"      seed {seed}: named {verdict}")


def clean(count: int) -> None:
    print(f"clean data, adequate models, seeds 0..{count - 1}")
    for name, make in H.CLEAN.items():
        t0 = time.perf_counter()
        alarms = []
        for seed in range(count):
            case = make(seed)
            with tempfile.TemporaryDirectory() as d:
                fitter = Fitter("<bench>", Path(d))
                findings, _ = detect(fitter.fit(case.spec(Path(d))), Settings(), fitter)
            alarms += [(seed, f.cause) for f in findings if f.significant]
        print(f"  {name:14s} false alarms {len(alarms)}/{count} {alarms} ({time.perf_counter() - t0:.0f} s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--start", type=int, default=100)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--clean", type=int, default=50)
    args = ap.parse_args()
    hidden(args.start, args.seeds)
    generator_friction(args.start, args.seeds)
    clean(args.clean)


if __name__ == "__main__":
    main()
