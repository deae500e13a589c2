"""Seconds for 400 simulated-annealing steps with a 60-element network on 10000 samples.

The same annealing loop (``dynmodel.anneal``, same moves, same random stream) runs twice:
with dynmodel's evaluator (compiled network kernel writing into reused buffers, centred Gram
matrix, small eigen-solve) and with the objective written in plain numpy (a Python loop over
samples with ``np.tanh(C @ x + ...)``, then ``np.linalg.lstsq``). The states agree to rounding;
the two least-squares solvers differ slightly on these nearly collinear states (both objectives
are printed for the starting network), so the two annealing paths part after a few accepted
moves and their best validation NMSE differs by chance. Prints figures; asserts nothing.

    python benchmarks/anneal_speed.py [--steps 400] [--size 60] [--n 10000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from dynmodel.anneal import Schedule, anneal, run_restarts
from dynmodel.data import Preprocessor, load_dataset, training_data
from dynmodel.engine import family_rng
from dynmodel.spec import validate_spec
from dynmodel_plugins.annealed_rnn import AnnealedRnn
from dynmodel_plugins.annealed_rnn.search import Evaluator, make_moves
from dynmodel_plugins.esn.network import Network


class NumpyEvaluator:
    """The same objective as :class:`Evaluator` (internal mode, least-squares readout), in plain numpy."""

    def __init__(self, data, p):
        self.data, self.p = data, p
        self.Yv = data.targets("validation")

    def score(self, s: Network) -> float:
        g = s.g
        B = np.hstack([s.B_in, s.B_back])
        feats = []
        for series in self.data.series:
            x = np.zeros(s.size)
            X = np.empty((series.n, s.size + 1))
            for t in range(series.n):
                x = s.a * x + g * np.tanh(s.C @ x + s.c0 + B @ series.u[t])
                X[t, :-1] = x
            X[:, -1] = 1.0
            feats.append(X)
        F, Y = self.data.stack("train", feats), self.data.targets("train")
        w, *_ = np.linalg.lstsq(F, Y, rcond=None)
        pred = self.data.stack("validation", feats) @ w
        return float(np.mean(np.mean((self.Yv - pred) ** 2, axis=0) / np.var(self.Yv, axis=0)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--size", type=int, default=60)
    ap.add_argument("--n", type=int, default=10000)
    args = ap.parse_args()
    spec = validate_spec(
        {
            "data": {
                "generator": "narx-system",
                "n": args.n,
                "seed": 1,
                "split": {"train": 0.8, "validation": 0.2},
                "transient": 1000,
                "transient_at": "recording",
                "scaling": "none",
            },
            "model": {"family": "annealed-rnn", "params": {"size": args.size, "steps": args.steps}},
        }
    )
    ds = load_dataset(spec)
    td = training_data(ds, Preprocessor.fit(ds, [], "none"))
    fam = AnnealedRnn(**spec.model.params.model_dump())
    fam._prepare(td)
    p = fam.params
    schedule = Schedule(p.steps, p.t0, p.t_end)

    results = {}
    for label, evaluator in [
        ("dynmodel", Evaluator(td, p, fam.training_drives(td))),
        ("plain numpy", NumpyEvaluator(td, p)),
    ]:
        rng = family_rng(0)
        state = fam._initial_state(td, rng)
        evaluator.score(state)  # compile / warm up outside the timing
        t0 = time.perf_counter()
        score = evaluator.score(state)
        result = anneal(state, score, evaluator.score, make_moves(p), schedule, rng)
        results[label] = (time.perf_counter() - t0, 100 * result.best_score, 100 * score)

    # independent restarts in threads (the compiled kernels release the GIL)
    def search(k, rng, halt):
        ev = Evaluator(td, p, fam.training_drives(td))
        state = fam._initial_state(td, rng)
        return anneal(state, ev.score(state), ev.score, make_moves(p), schedule, rng).best_score

    workers = os.cpu_count() or 1
    t0 = time.perf_counter()
    run_restarts(search, workers, workers, family_rng(1))
    t_par = time.perf_counter() - t0
    (t_fast, v_fast, s_fast), (t_slow, v_slow, s_slow) = results["dynmodel"], results["plain numpy"]
    print(f"{args.steps} annealing steps, {args.size} elements, {args.n} samples (8000 train / 2000 validation):")
    print(f"  dynmodel      {t_fast:7.2f} s   start {s_fast:.5g} %  best validation NMSE {v_fast:.5g} %")
    print(f"  plain numpy   {t_slow:7.2f} s   start {s_slow:.5g} %  best validation NMSE {v_slow:.5g} %")
    print(f"  speed-up      {t_slow / t_fast:7.1f}x")
    print(f"  {workers} restarts in {workers} threads: {t_par:.2f} s ({t_par / workers:.2f} s per run)")


if __name__ == "__main__":
    main()
