"""Thesis chapter 3 with dynmodel's `narx` family: bias of one-step estimation and its cure.

    python benchmarks/narx_reproduction.py              # 3.2.2, 3.2.3, 3.2.4 (noise seeds 0, 1, 2)
    python benchmarks/narx_reproduction.py --seeds 10

* 3.2.2 (``specs/thesis-3.2.2-linear.yaml``): y_t = 0.8 y_{t-1} + u_t measured with noise of
  variance 0.64 x the output variance; model a y_{t-1} + b u_t. One-step least squares should give
  a = 0.8 / 1.64 = 0.488 (eq. 3.32), free-running estimation a = 0.8; b = 1 for both.
* 3.2.3 (``specs/thesis-3.2.3-logistic.yaml``): the driven logistic map, alpha 0.5, lambda 4,
  noise std = output std; model a y_{t-1} + b y_{t-1}^2 + c u_t, true a = 2, b = -2, c = 0.5.
* 3.2.4 (``specs/thesis-3.2.4-narx.yaml``): FOS on the degree-5 pool, clean data; the selected
  terms and the free-run NMSE on the clean test realization (8 terms, and the default stop at
  the first rise of the validation error). The noise sweep of figure 3.9 is
  ``benchmarks/narx_noise_sweep.py``.

The noise seed changes only the noise realization (the data seed is fixed in the specs).
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


def weights(spec_file: str, cost: str, seed: int) -> dict[str, float]:
    spec = load_spec(SPECS / spec_file)
    spec.cost, spec.seed = cost, seed
    fam = engine.fit(spec).family
    return dict(zip(fam.terms_[0], fam.weights_))


def table(spec_file: str, names: dict[str, str], truth: dict[str, dict[str, float]], seeds) -> None:
    for cost in ("mse1", "mse_inf"):
        rows = [weights(spec_file, cost, s) for s in seeds]
        cells = []
        for term, label in names.items():
            v = np.array([r[term] for r in rows])
            cells.append(f"{label} = {v.mean():7.4f} +- {v.std():.4f} (expected {truth[cost][term]:g})")
        print(f"  {cost:8s} " + "   ".join(cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="noise realizations (mean +- std reported)")
    args = ap.parse_args()
    seeds = range(args.seeds)
    t0 = time.perf_counter()
    print(f"3.2.2 linear system, noise variance 0.64 x output variance, N = 10000 ({args.seeds} noise seeds)")
    table(
        "thesis-3.2.2-linear.yaml",
        {"y[t-1]": "a", "u[t]": "b"},
        {"mse1": {"y[t-1]": 0.8 / 1.64, "u[t]": 1.0}, "mse_inf": {"y[t-1]": 0.8, "u[t]": 1.0}},
        seeds,
    )
    print(f"\n3.2.3 driven logistic map, noise std = output std, N = 10000 ({args.seeds} noise seeds)")
    truth = {"y[t-1]": 2.0, "y[t-1]^2": -2.0, "u[t]": 0.5}
    table(
        "thesis-3.2.3-logistic.yaml",
        {"y[t-1]": "a", "y[t-1]^2": "b", "u[t]": "c"},
        {"mse1": truth, "mse_inf": truth},
        seeds,
    )
    print(
        "\n3.2.4 NARX system (eq. 3.37), degree-5 pool of u_t, u_t-1, u_t-2, y_t-1, y_t-2 (252 monomials), clean data"
    )
    for label, changes in [
        ("FOS, 8 terms", {}),
        ("FOS, first rise of the validation error", {"max_terms": None, "patience": 1}),
    ]:
        spec = load_spec(SPECS / "thesis-3.2.4-narx.yaml")
        for key, value in changes.items():
            setattr(spec.model.params, key, value)
        m = engine.fit(spec)
        print(
            f"  {label}: {len(m.family.weights_)} terms, test NMSE {m.metrics['test']['nmse']:.4f} % "
            f"(one-step {m.metrics['test']['nmse_1']:.4f} %)"
        )
        print(f"    y = {m.family.summary()['model y']}")
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
