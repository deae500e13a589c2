"""How much one training window decides a model's test error: a family's default fitted on sub-windows of a
population system's training recording (benchmarks/auto_population.py), each scored on the system's test.

    python benchmarks/population_windows.py                      # sys2 and sys21 of the fresh population
    python benchmarks/population_windows.py --first-seed 100 --systems 4 10 --family esn --params '{"size": 400}'

For each system, the model is fitted (80 % training, 20 % validation, seed 0, no search) on the whole training
recording, on its first and last three quarters and on its middle three quarters. Printed per window: the
validation and test NMSE (%); then, as ``family: auto`` measures the fits of one candidate
(docs/auto.md, "When the fits part ways on the test inputs"), the median over pairs of windows of their free
runs' mean squared difference on the test inputs (% of the training output variance) and a quarter of it, a
floor of their mean test error. On sys2 (seeds 300) the NARX default tests at 0.038 % on the whole recording
and at 428 and 94 % on two of the other windows. Asserts nothing; the data come from fixed seeds.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from auto_population import system
from auto_small_data import fit_timed

from dynmodel.search.checks import spread

#: (first, last) fractions of the training recording each fit sees
WINDOWS = ((0.0, 1.0), (0.0, 0.75), (0.25, 1.0), (0.125, 0.875))


def windows(k: int, first_seed: int, family: str, params: dict, folder: Path) -> None:
    """Fit ``family`` on every window of system ``k``'s training recording and print what each tests at."""
    description, train, test = system(k, first_seed)
    print(f"sys{k} (seed {first_seed} + {k}): {description}; {family} {json.dumps(params)}")
    test_file = folder / f"sys{k}-test.csv"
    np.savetxt(test_file, np.column_stack([test["u"], test["y"]]), delimiter=",", header="u,y", comments="")
    n = len(train["u"])
    std = float(np.std(train["y"]))
    runs: list[dict[str, np.ndarray]] = []
    for lo, hi in WINDOWS:
        a, b = int(lo * n), int(hi * n)
        path = folder / f"sys{k}-train-{a}-{b}.csv"
        np.savetxt(path, np.column_stack([train["u"][a:b], train["y"][a:b]]), delimiter=",", header="u,y", comments="")
        data = {
            "path": str(path),
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 0.8, "validation": 0.2},
            "test": {"path": str(test_file)},
        }
        raw = {"name": f"sys{k}", "data": data, "seed": 0, "model": {"family": family, "params": params}}
        model, _ = fit_timed(raw, 1)
        start = test["y"][: model.warmup, None] if model.warmup else None
        run = np.asarray(model.run(test["u"][:, None], start).y) / std
        run[: model.warmup] = np.nan  # its tune-in: measured outputs, not scored (as the search leaves it out)
        runs.append({"test": run})
        m = model.metrics
        print(f"  samples {a:>6}-{b:<6} validation {m['validation']['nmse']:10.4g}   test {m['test']['nmse']:10.4g}")
    apart = spread(runs)  # the search's own measure, over the windows instead of a candidate's fits
    if apart is not None:
        print(
            f"  windows' runs on the test inputs differ by {apart:.4g} % (median over pairs); a quarter: {apart / 4:.4g} %"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--first-seed", type=int, default=300, help="the population (default: the fresh one, 300)")
    ap.add_argument("--systems", type=int, nargs="*", default=[2, 21], help="system numbers K (default: 2 21)")
    ap.add_argument("--family", default="narx", help="the family whose default (or --params) is fitted")
    ap.add_argument("--params", default="{}", help="the family's params as JSON (default: its defaults)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for k in args.systems:
            windows(k, args.first_seed, args.family, json.loads(args.params), Path(tmp))


if __name__ == "__main__":
    main()
