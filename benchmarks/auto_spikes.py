"""family: auto on outputs measured by a glitching sensor (isolated spikes, docs/errors-and-outputs.md).

    python benchmarks/auto_spikes.py                  # three seeds, about 3 min on 2 cores
    python benchmarks/auto_spikes.py --seeds 0 --share 0.02 --size 5

Each case is one generated recording of a lightly damped, mildly nonlinear plant driven by random held levels
(tests/spiky.py), 3000 samples, the default split (60 % train, 20 % validation, 20 % test, in time order) and
`family: auto` with a 30 s budget in one process, fitted three times: on the clean output, on the output with
glitches (a share of the samples off by some output stds) with `data.spikes: replace` (the default) and with
`data.spikes: keep`. Printed per seed: the free run's test NMSE (%) against the clean output, the spikes the
note names in the training and validation outputs and the glitches there. Asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.search import search_options
from dynmodel.spec import validate_spec

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from spiky import spiky  # noqa: E402 - the generated rig, shared with the tests


def fit(u: np.ndarray, y: np.ndarray, clean: np.ndarray, spikes: str, budget: float, folder: Path):
    """(test NMSE % against the clean output, spikes replaced in the fitted splits)."""
    np.savetxt(folder / "rig.csv", np.column_stack([u, y]), delimiter=",", header="u,y", comments="", fmt="%.17g")
    raw = {
        "name": "rig",
        "data": {"path": "rig.csv", "input": ["u"], "output": ["y"], "spikes": spikes},
        "model": {"family": "auto", "params": {"budget": budget}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<benchmark>", folder)
    ds = load_dataset(spec)
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, ds)
    start = int(round(0.8 * len(u)))
    run = model.predict(u[start:, None], y_tune=clean[start : start + model.warmup, None])[:, 0]
    nmse = 100.0 * float(np.mean((run - clean[start:]) ** 2) / np.var(clean[start:]))
    found = sum(len(a.where) for a in ds.artifacts if a.kind == "spikes" and a.split in ("train", "validation"))
    return nmse, found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="*", type=int, default=[0, 1, 2])
    parser.add_argument("--share", type=float, default=0.01, help="share of samples spiked (default 0.01)")
    parser.add_argument("--size", type=float, default=10.0, help="spike size in output stds (default 10)")
    parser.add_argument("--budget", type=float, default=30.0, help="search budget in seconds (default 30)")
    args = parser.parse_args()
    print(f"{'seed':>4} {'clean':>8} {'replace':>8} {'keep':>8}  spikes found / glitches in train+validation")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            u, y, clean, glitches = spiky(seed=seed, share=args.share, size=args.size)
            base, _ = fit(u, clean, clean, "replace", args.budget, Path(tmp))
            replaced, found = fit(u, y, clean, "replace", args.budget, Path(tmp))
            kept, _ = fit(u, y, clean, "keep", args.budget, Path(tmp))
            fitted = int(np.sum(glitches < int(round(0.8 * len(u)))))
            print(f"{seed:4d} {base:8.4g} {replaced:8.4g} {kept:8.4g}  {found} / {fitted}")


if __name__ == "__main__":
    main()
