"""Thesis 4.4.2 with dynmodel: 32 driven Lorenz systems, parallel vs feed-forward strategy, on the
rossler-cross task; also random (not annealed) networks of 32 and 200 elements for scale.

    python benchmarks/lorenz_reproduction.py [--runs 20]

Test NMSE (%) of the free run on a fresh 10000-sample realization (first 1000 not scored).
Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.spec import load_spec

SPECS = Path(__file__).resolve().parents[1] / "specs"


def runs(spec_file: str, seeds, **params) -> tuple[np.ndarray, float]:
    out, seconds = [], []
    for seed in seeds:
        spec = load_spec(SPECS / spec_file)
        spec.seed = seed
        for k, v in params.items():
            setattr(spec.model.params, k, v)
        t0 = time.perf_counter()
        value = engine.fit(spec).metrics["test"]["nmse"]
        seconds.append(time.perf_counter() - t0)
        out.append(np.inf if value is None else value)
    return np.array(out), float(np.mean(seconds))


def line(label: str, v: np.ndarray, sec: float) -> str:
    return (
        f"  {label:44s} mean {np.mean(v):7.3f}  std {np.std(v):6.3f}  median {np.median(v):7.3f}  "
        f"min {np.min(v):6.3f}  max {np.max(v):6.3f}   ({sec:.1f} s per fit)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    args = ap.parse_args()
    seeds = range(args.runs)
    t0 = time.perf_counter()
    print(f"thesis 4.4.2, rossler-cross, test NMSE % over {args.runs} runs (thesis: parallel 1.9, feed-forward 0.9):")
    for strategy in ("parallel", "feed-forward"):
        v, sec = runs(f"thesis-4.4.2-{strategy}.yaml", seeds)
        print(line(f"{strategy}, 32 elements, 400 steps", v, sec))
    for strategy in ("parallel", "feed-forward"):
        v, sec = runs(f"thesis-4.4.2-{strategy}.yaml", seeds, steps=0)
        print(line(f"{strategy}, 32 elements, not annealed", v, sec))
    v, sec = runs("thesis-4.4.2-parallel.yaml", seeds, steps=0, size=200)
    print(line("parallel, 200 elements, not annealed", v, sec))
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
