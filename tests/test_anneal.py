"""Simulated annealing (core) and the `annealed-rnn` family (thesis 5.3.4, 6.4.5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT, make_spec, narx

import dynmodel
from dynmodel import engine
from dynmodel.anneal import Schedule, anneal, relative_improvement
from dynmodel.spec import load_spec
from dynmodel_plugins.annealed_rnn import AnnealedRnnParams
from dynmodel_plugins.annealed_rnn.search import grow, make_moves
from dynmodel_plugins.esn.network import Network

# ------------------------------------------------------------------ the optimizer


def test_worse_candidates_are_accepted_with_probability_exp_delta_over_t():
    """Every move makes the objective 10 % worse; at constant T = 0.05 the acceptance rate is exp(-2)."""

    def worse(state, rng, scale):
        return state * 1.1

    result = anneal(
        1.0, 1.0, lambda s: s, [("worse", 1.0, worse)], Schedule(6000, 0.05, 0.05), np.random.default_rng(1)
    )
    rate = result.accepted / 6000
    assert abs(rate - math.exp(-0.1 / 0.05)) < 0.015  # delta = (old - new) / old = -0.1
    assert result.best_score == 1.0  # the best is kept while the current state wanders


def test_cooling_reaches_the_final_temperature_and_better_is_always_accepted():
    seen = []
    result = anneal(
        10.0,
        10.0,
        lambda s: s,
        [("better", 1.0, lambda s, r, k: s * 0.99)],
        Schedule(50, 0.2, 2e-4),
        np.random.default_rng(0),
        on_step=lambda step, T, cur, best, info: seen.append(T),
    )
    assert seen[0] == pytest.approx(0.2) and seen[-1] == pytest.approx(2e-4)
    assert result.accepted == 50 and result.best_score == pytest.approx(10 * 0.99**50)
    assert relative_improvement(2.0, 1.0) == 0.5 and relative_improvement(1.0, math.inf) == -math.inf


def test_annealing_escapes_local_minima_that_trap_greedy_descent():
    """1 + Rastrigin in 2-D from (3, -3): accepting worse steps early finds deeper minima than a
    greedy search (the same moves at a temperature too low to accept anything worse)."""

    def f(x):
        return float(21 + np.sum(x**2 - 10 * np.cos(2 * np.pi * x)))

    def step(x, rng, scale):
        return x + 0.3 * rng.standard_normal(2)

    x0 = np.array([3.0, -3.0])

    def best(t0, t_end, seed):
        return anneal(
            x0, f(x0), f, [("step", 1.0, step)], Schedule(3000, t0, t_end), np.random.default_rng(seed)
        ).best_score

    annealed = [best(0.3, 1e-3, s) for s in range(10)]
    greedy = [best(1e-6, 1e-9, s) for s in range(10)]
    assert np.median(annealed) < np.median(greedy) - 1.5  # about one basin deeper (basins are ~1 apart)
    assert min(annealed) < 1.1  # the global basin (value 1) is reached


def test_interruption_returns_the_best_so_far():
    calls = {"n": 0}

    def objective(s):
        calls["n"] += 1
        if calls["n"] == 30:
            raise KeyboardInterrupt
        return s

    result = anneal(
        5.0, 5.0, objective, [("down", 1.0, lambda s, r, k: s - 0.1)], Schedule(100), np.random.default_rng(0)
    )
    assert result.interrupted and result.best == pytest.approx(5.0 - 0.1 * 29)


# ------------------------------------------------------------------ moves and growth


def _state(rng, m=20):
    C = np.where(rng.random((m, m)) < 0.2, rng.standard_normal((m, m)), 0.0)
    C *= 0.9 / np.linalg.norm(C, 2)
    a = rng.uniform(0, 0.9, m)
    return Network(C, np.where(rng.random((m, 1)) < 0.5, 1.0, 0.0), np.zeros((m, 0)), rng.standard_normal(m), a, 1 - a)


def test_moves_change_the_structure_as_named_and_keep_sigma_below_the_bound():
    p = AnnealedRnnParams(max_singular=0.95)
    rng = np.random.default_rng(3)
    moves = dict((name, fn) for name, _, fn in make_moves(p))
    for _ in range(200):
        s = _state(rng)
        for name, fn in moves.items():
            new = fn(s, rng, 1.0)
            assert np.linalg.norm(new.C, 2) <= 0.95 + 1e-12
            nnz, new_nnz = np.count_nonzero(s.C), np.count_nonzero(new.C)
            expected = {"add": nnz + 1, "cut": nnz - 1}.get(name, nnz)
            assert new_nnz == expected, name
            if name in ("input", "bias", "relaxation", "weight"):
                assert np.array_equal(new.B_in != 0, s.B_in != 0) and np.array_equal(new.c0 != 0, s.c0 != 0)
            assert np.all((0 <= new.a) & (new.a <= 0.99))


def test_growth_appends_elements_and_keeps_the_old_network():
    p = AnnealedRnnParams()
    s = _state(np.random.default_rng(4))
    g = grow(s, 5, p, np.random.default_rng(5))
    assert g.size == 25 and g.B_in.shape == (25, 1)
    ratio = g.C[:20, :20][s.C != 0] / s.C[s.C != 0]
    assert np.allclose(ratio, ratio[0])  # the old block, at most rescaled as a whole
    assert np.linalg.norm(g.C, 2) <= p.max_singular + 1e-12


# ------------------------------------------------------------------ the family


def _raw(steps=60, **params):
    return {
        "data": {
            "generator": "narx-system",
            "n": 4000,
            "seed": 1,
            "split": {"train": 0.75, "validation": 0.25},
            "test": {"seed": 2, "n": 2000},
            "transient": 300,
            "transient_at": "recording",
            "scaling": "none",
        },
        "model": {"family": "annealed-rnn", "params": {"size": 20, "steps": steps, **params}},
        "seed": 0,
    }


def test_annealing_improves_on_its_random_start_and_is_reproducible(tmp_path):
    a = engine.fit(make_spec(_raw()))
    b = engine.fit(make_spec(_raw()))
    start = engine.fit(make_spec(_raw(steps=0)))
    stage = a.family.search_["restarts"][0]["stages"][0]
    assert stage["steps"] == 60 and stage["accepted"] > 0
    assert a.family.search_["restarts"][0]["validation_nmse"] < start.family.search_["restarts"][0]["validation_nmse"]
    for key, arr in a.family.to_arrays()[0].items():
        np.testing.assert_array_equal(arr, b.family.to_arrays()[0][key], err_msg=key)
    loaded = dynmodel.load(dynmodel.save(a, tmp_path / "a.h5"))
    u, _ = narx(500, 5)
    np.testing.assert_array_equal(loaded.predict(u), a.predict(u))
    assert "annealing" in loaded.family.summary()


def test_annealed_networks_pass_the_reliability_check():
    """Leaky elements (eq. 6.21) with sigma(C) <= 0.95: no algebraic proof applies in general (the
    bound max|a| + sigma(diag(g) C) exceeds 1), so the numerical tests decide."""
    from dynmodel.reliability import check_model

    report = check_model(engine.fit(make_spec(_raw(steps=40))))
    assert report.verdict.verdict == "reliable", report.verdict.reasons
    assert max(e.largest for e in report.exponents.values()) < 0


def test_restarts_in_threads_equal_restarts_in_sequence():
    par = engine.fit(make_spec(_raw(steps=20, restarts=2, workers=2)))
    seq = engine.fit(make_spec(_raw(steps=20, restarts=2, workers=1)))
    assert par.family.search_ == seq.family.search_
    np.testing.assert_array_equal(par.family.W_, seq.family.W_)


def test_growth_adds_elements_while_it_helps():
    m = engine.fit(make_spec(_raw(steps=60, size=8, grow=True, grow_by=4, patience=20, max_size=20)))
    sizes = [s["size"] for s in m.family.search_["restarts"][0]["stages"]]
    assert sizes[0] == 8 and len(sizes) >= 2 and all(b - a == 4 for a, b in zip(sizes, sizes[1:]))
    assert m.family.network_.size in sizes and m.family.network_.size <= 20


def test_progress_reports_temperature_and_best_validation_nmse():
    lines = []
    engine.fit(make_spec(_raw(steps=30)), progress=lambda stage, frac, msg: lines.append((stage, frac, msg)))
    anneal_lines = [msg for stage, _, msg in lines if stage == "anneal"]
    assert anneal_lines and "T = " in anneal_lines[-1] and "best validation NMSE" in anneal_lines[-1]


def test_external_mode_and_a_validation_split_is_required():
    m = engine.fit(make_spec(_raw(steps=20, mode="external", tune_in=50)))
    assert m.warmup == 50 and m.metrics["test"]["nmse"] < 10.0  # 20 elements, 20 steps; a constant scores 100
    raw = _raw()
    raw["data"]["split"] = {"train": 1.0}
    with pytest.raises(dynmodel.DynmodelError, match="needs a validation split|optimizes the network on a validation"):
        engine.fit(make_spec(raw))


# ------------------------------------------------------------------ thesis reproductions


def _test_nmse(spec_file, seeds, **params):
    out = []
    for seed in seeds:
        spec = load_spec(ROOT / "specs" / spec_file)
        spec.seed = seed
        for k, v in params.items():
            setattr(spec.model.params, k, v)
        out.append(engine.fit(spec).metrics["test"]["nmse"])
    return np.array(out)


@pytest.mark.slow
def test_thesis_5_3_4_optimized_60_beat_random_400():
    annealed = _test_nmse("thesis-5.3.4-annealed.yaml", range(8))
    random400 = _test_nmse("thesis-5.3.4-random-esn.yaml", range(16))
    print(
        f"\nannealed 60: median {np.median(annealed):.4g} IQR {np.percentile(annealed, [25, 75])}; "
        f"random 400: median {np.median(random400):.4g} IQR {np.percentile(random400, [25, 75])}"
    )
    assert np.median(annealed) < np.median(random400)
    assert np.percentile(annealed, 75) < np.percentile(random400, 25)  # the whole middle halves are apart


@pytest.mark.slow
def test_thesis_5_3_3_fos_readout_beats_least_squares_under_noise():
    from dynmodel_plugins.esn.params import Readout

    fos = _test_nmse("thesis-5.3.3-fos.yaml", range(4))
    lstsq = _test_nmse("thesis-5.3.3-fos.yaml", range(4), readout=Readout(solver="lstsq", direct=False))
    print(f"\nrossler-lorenz N=2000 noise 0.4: fos mean {fos.mean():.4g}, lstsq mean {lstsq.mean():.4g}")
    assert fos.mean() < lstsq.mean()
