"""Thesis figure 3.9 with dynmodel: noisy training outputs, clean test, one-step against free-running estimation.

    python benchmarks/narx_noise_sweep.py                       # levels 0, 0.1, ..., 1.0; 3 noise seeds
    python benchmarks/narx_noise_sweep.py --seeds 5 --levels 0,0.5,1.0
    python benchmarks/narx_noise_sweep.py --json sweep.json     # every figure, per seed

Task: ``specs/thesis-3.2.4-narx.yaml`` (the NARX system of eq. 3.37, degree-5 pool of u_t,
u_{t-1}, u_{t-2}, y_{t-1}, y_{t-2}, 8000 training and 2000 validation samples, clean separate
test realization). Noise of std ``level`` x the clean output std is added to the training and
validation outputs (noise seeds 0 .. seeds-1). Variants (rows):

* ``fos8 mse1``      FOS on the noisy data keeps 8 terms, least-squares weights;
* ``fos8 mse_inf``   the same 8 terms, weights re-estimated on the free-running error (eq. 3.15);
* ``free_run mse_inf`` ``specs/thesis-3.2.4-narx-noise.yaml``: terms chosen on the linearised
  free-running error, stopped by the first rise of the free-running validation error (at most 8);
* ``eq3.38 mse1`` / ``eq3.38 mse_inf``  the thesis protocol of figure 3.9: the structure FOS finds
  on the *clean* data (eq. 3.38: 1, y_{t-1}, y_{t-2}, u_t, y_{t-2}^2 .. y_{t-2}^5) is kept, and
  only its weights are estimated on the noisy data.

Printed: the median [min, max] over the noise seeds of the free-run NMSE (%) on the clean test
realization. Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.spec import NoiseSpec, load_spec

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "specs/thesis-3.2.4-narx.yaml"
FREE = ROOT / "specs/thesis-3.2.4-narx-noise.yaml"


def clean_structure() -> list[str]:
    """The terms FOS selects on the clean data (eq. 3.38 in the thesis)."""
    spec = load_spec(BASE)
    return engine.fit(spec).family.terms_[0]


def variants(terms: list[str]) -> dict[str, tuple[Path, str, dict]]:
    return {
        "fos8 mse1": (BASE, "mse1", {}),
        "fos8 mse_inf": (BASE, "mse_inf", {}),
        "free_run mse_inf": (FREE, "mse_inf", {}),
        "eq3.38 mse1": (BASE, "mse1", {"terms": terms}),
        "eq3.38 mse_inf": (BASE, "mse_inf", {"terms": terms}),
    }


def run(path: Path, cost: str, params: dict, level: float, seed: int) -> tuple[float, int, float]:
    spec = load_spec(path)
    spec.cost, spec.seed = cost, seed
    spec.data.noise = NoiseSpec(std=level, splits=["train", "validation"]) if level > 0 else None
    for key, value in params.items():
        setattr(spec.model.params, key, value)
    t0 = time.perf_counter()
    m = engine.fit(spec)
    v = m.metrics["test"]["nmse"]
    return (np.inf if v is None else float(v)), int(m.family.weights_.size), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default="0,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,0.9,1.0")
    ap.add_argument("--seeds", type=int, default=3, help="noise realizations per level (median reported)")
    ap.add_argument("--only", default=None, help="comma-separated variant names")
    ap.add_argument("--json", type=Path, default=None, help="write every figure to this file")
    args = ap.parse_args()
    levels = [float(x) for x in args.levels.split(",")]
    t_start = time.perf_counter()
    terms = clean_structure()
    table = variants(terms)
    if args.only:
        table = {k: v for k, v in table.items() if k in args.only.split(",")}
    print(f"clean-data FOS structure (eq. 3.38): {' + '.join(terms)}")
    print(f"clean-test free-run NMSE %, median [min, max] over {args.seeds} noise seeds; (terms) median model size\n")
    results: dict = {}
    header = f"{'noise':>5} " + "".join(f"| {name:^30} " for name in table)
    print(header)
    print("-" * len(header))
    for level in levels:
        cells = []
        for name, (path, cost, params) in table.items():
            rows = [run(path, cost, params, level, seed) for seed in range(args.seeds)]
            v = np.array([r[0] for r in rows])
            results.setdefault(name, {})[level] = {
                "nmse": v.tolist(),
                "terms": [r[1] for r in rows],
                "seconds": [r[2] for r in rows],
            }
            cells.append(
                f"{np.median(v):7.4g} [{np.min(v):6.3g}, {np.max(v):6.3g}] ({int(np.median([r[1] for r in rows]))})"
            )
        print(f"{level:5.1f} " + "".join(f"| {c:>30} " for c in cells), flush=True)
    print(f"\n({time.perf_counter() - t_start:.0f} s)")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
