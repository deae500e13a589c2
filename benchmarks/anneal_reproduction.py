"""Thesis 5.3.4 (annealed 60-element networks vs random 400-element networks) and 5.3.3 (FOS
readout vs least squares under noise), with dynmodel.

    python benchmarks/anneal_reproduction.py              # 5.3.4, 20 annealing runs, 40 random networks
    python benchmarks/anneal_reproduction.py --runs 10    # fewer annealing runs
    python benchmarks/anneal_reproduction.py --fos        # + the 5.3.3 table (N x noise, FOS vs lstsq)

Test NMSE (%) of the free run on a separate clean realization. Median and interquartile range
(the spread of figures 5.13 / 5.14). Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.spec import NoiseSpec, load_spec

SPECS = Path(__file__).resolve().parents[1] / "specs"


def summary(v: np.ndarray) -> str:
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return (
        f"median {med:8.4g}  IQR [{q1:.4g}, {q3:.4g}]  mean {np.mean(v):8.4g}  min {np.min(v):.4g}  max {np.max(v):.4g}"
    )


def runs(spec_file: str, seeds, params: dict | None = None, data: dict | None = None) -> np.ndarray:
    out = []
    for seed in seeds:
        spec = load_spec(SPECS / spec_file)
        spec.seed = seed
        for k, v in (params or {}).items():
            setattr(spec.model.params, k, v)
        for k, v in (data or {}).items():
            setattr(spec.data, k, v)
        value = engine.fit(spec).metrics["test"]["nmse"]
        out.append(np.inf if value is None else value)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="annealing runs (random networks: twice as many)")
    ap.add_argument("--fos", action="store_true", help="also the 5.3.3 FOS table")
    ap.add_argument("--fos-nets", type=int, default=5)
    args = ap.parse_args()
    t0 = time.perf_counter()

    print("thesis 5.3.4, narx-system, internal mode, test NMSE % (train 8000 / validation 2000 / test 10000):")
    annealed = runs("thesis-5.3.4-annealed.yaml", range(args.runs))
    print(f"  annealed-rnn, 60 elements, 400 steps ({args.runs} runs)     {summary(annealed)}")
    random400 = runs("thesis-5.3.4-random-esn.yaml", range(2 * args.runs))
    print(f"  esn, random 400 elements ({2 * args.runs} networks)            {summary(random400)}")
    leaky400 = runs(
        "thesis-5.3.4-random-esn.yaml", range(2 * args.runs), params={"relaxation": (0.0, 0.9), "relaxation_gain": True}
    )
    print(f"  esn, random 400 elements with eq. 6.21 elements           {summary(leaky400)}")
    no_search = runs("thesis-5.3.4-annealed.yaml", range(args.runs), params={"steps": 0})
    print(f"  annealed-rnn with 0 steps (its random start, 60 elements) {summary(no_search)}")

    if args.fos:
        print(
            "\nthesis 5.3.3, rossler-lorenz, 200 random elements, mean test NMSE % over "
            f"{args.fos_nets} networks (both readouts fitted on the same 80 % of N):"
        )
        print("  noise    N     lstsq       fos")
        from dynmodel_plugins.esn.params import Readout

        for level in (0.0, 0.2, 0.4):
            for n in (1000, 2000, 4000, 10000):
                row = {}
                for solver in ("lstsq", "fos"):
                    row[solver] = runs(
                        "thesis-5.3.3-fos.yaml",
                        range(args.fos_nets),
                        params={"readout": Readout(solver=solver, direct=False)},
                        data={"n": n, "noise": NoiseSpec(std=level) if level else None},
                    ).mean()
                print(f"  {level:4.1f} {n:6d} {row['lstsq']:9.4g} {row['fos']:9.4g}")
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
