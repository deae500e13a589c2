"""family auto when the test input leaves the training range: validation inside the range cannot rank how the
candidates extrapolate, so the choice is never left to a single full fit (dynmodel.search.run)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from beyond_range import CASES
from conftest import benchmark, narx, write_csv

from dynmodel import engine
from dynmodel.data import load_dataset
from dynmodel.search import search_options
from dynmodel.search.run import SURVIVOR_FACTOR, SURVIVORS
from dynmodel.spec import validate_spec

WINDOW = 20


def _system(u: np.ndarray) -> np.ndarray:
    """The narx-system of conftest.narx driven by ``u``."""
    y = np.zeros(len(u))
    for t in range(len(u)):
        y1 = y[t - 1] if t >= 1 else 0.0
        y2 = y[t - 2] if t >= 2 else 0.0
        y[t] = 0.8 * y1 - 0.2 / (1 + abs(y2)) + u[t]
    return y


def _search(tmp_path: Path, test_gain: float, budget: float = 2, families: tuple[str, ...] = ("narx",)) -> dict:
    u, y = narx(3000, 11)
    ut = test_gain * np.random.default_rng(12).standard_normal(800)
    write_csv(tmp_path / "train.csv", {"u": u, "y": y})
    write_csv(tmp_path / "test.csv", {"u": ut, "y": _system(ut)})
    raw = {
        "name": "auto-extrapolation",
        "data": {
            "path": "train.csv",
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 0.7, "validation": 0.3},
            "test": {"path": "test.csv"},
            "init_window": {"test": WINDOW},
        },
        "model": {"family": "auto", "params": {"budget": budget, "families": list(families)}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec))
    return model.search


def _full(record: dict) -> int:
    """Candidates fitted in full (a candidate whose screening fit stands as its final one was not)."""
    return sum(
        1
        for c in record["candidates"]
        if "final" in c["levels"] and c["origin"] != "move" and not c.get("stands_screened")
    )


def _screened(record: dict) -> int:
    """Candidates that passed the screening (a finite score inside the band)."""
    return sum(
        1
        for c in record["candidates"]
        if "screen" in c["levels"] and c["levels"]["screen"]["score"] is not None and c["levels"]["screen"]["band_ok"]
    )


def _second_chances(record: dict) -> int:
    """Candidates fitted in full although their screening fit left the band (they validated better)."""
    return sum(1 for c in record["candidates"] if "screening fit left the output band" in c["origin"])


@pytest.mark.slow
def test_a_test_input_beyond_the_training_range_gets_several_full_fits(tmp_path):
    inside, beyond = tmp_path / "inside", tmp_path / "beyond"
    inside.mkdir()
    beyond.mkdir()
    small = _search(inside, 0.5)  # the test input stays inside the training range
    wide = _search(beyond, 1.4)  # ... leaves it (by far more than 5 % of its width)
    assert small["context"]["excursion"] <= 0.05 < wide["context"]["excursion"]
    # this budget leaves a single full fit when the test input stays inside the range ...
    assert _full(small) - _second_chances(small) == 1
    # ... and the best survivors are all fitted in full when it leaves it: the choice is made among them
    assert _full(wide) - _second_chances(wide) == min(SURVIVORS, _screened(wide)) >= 2
    assert any("leave the training range" in why for why in wide["cautious"])
    assert not any("about linear" in n for n in wide["notes"])  # a nonlinear system: the strict band stands
    # the start memory (three free runs per recording) is measured only where the choice reads it
    memories = {
        name: [c["levels"]["final"].get("start_memory") for c in rec["candidates"] if "final" in c["levels"]]
        for name, rec in (("inside", small), ("beyond", wide))
    }
    assert all(m is None for m in memories["inside"])
    assert any(isinstance(m, float) for m in memories["beyond"]), memories


@pytest.mark.slow
def test_a_budget_that_allows_it_fits_every_candidate_screened_near_the_best_in_full(tmp_path):
    """The screening variant ranks the full ones coarsely: with budget to spare, every candidate screened within
    SURVIVOR_FACTOR of the best is fitted in full, not only the best SURVIVORS; the rest are not."""
    record = _search(tmp_path, 0.5, budget=60)
    screened = {
        c["key"]: c["levels"]["screen"]["score"]
        for c in record["candidates"]
        if "screen" in c["levels"] and c["levels"]["screen"]["score"] is not None and c["levels"]["screen"]["band_ok"]
    }
    best = min(screened.values())
    near = {k for k, v in screened.items() if v <= SURVIVOR_FACTOR * best}
    # fitted in the full stage: a candidate screened in its full variant on the final layout (the linear output
    # error one) is final from its screening on
    refit = {c["key"] for c in record["candidates"] if not c["screen_is_final"]}
    full = {c["key"] for c in record["candidates"] if c["key"] in screened and "final" in c["levels"]} & refit
    near &= refit
    assert record["budget"]["planned"] < 0.5 * record["budget"]["allowance"]  # the budget was not the limit
    assert len(near) > SURVIVORS
    assert full == near < set(screened)  # the far ones (the linear model here) are not refitted


def _about_linear(tmp_path: Path, case: str, budget: float):
    """family auto on the generated recording ``case`` of beyond_range.py (the default split), in this process;
    asserts the search found the system about linear and returns the model."""
    columns, inputs = CASES[case]()
    write_csv(tmp_path / "d.csv", columns)
    raw = {
        "name": case,
        "data": {"path": "d.csv", "input": inputs, "output": [c for c in columns if c not in inputs]},
        "model": {"family": "auto", "params": {"budget": budget}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, load_dataset(spec))
    assert any("the system is about linear" in n for n in model.search["notes"]), model.search["notes"]
    return model


def test_a_linear_system_driven_beyond_its_training_range_keeps_a_linear_model(tmp_path):
    """A second-order linear plant tested at three times its training input amplitude: its output leaves the
    training output range as far as its input does, so the strict band rejected every linear candidate, and the
    search kept a saturating network at 2 % test NMSE. The linear reference validates as well as the best
    candidate: the system is about linear, and the band covers where the linear reference's free run goes."""
    model = _about_linear(tmp_path, "plant-3x", budget=10)
    assert model.search["context"]["excursion"] > 0.5  # the test input leaves the training range by 74 % of its width
    assert model.metrics["test"]["nmse"] < 0.01, (model.search["winner_summary"], model.metrics["test"])


@pytest.mark.slow
def test_a_drifting_integrator_keeps_a_linear_model(tmp_path):
    """A cart pushed by a force with a small mean: its position drifts beyond the training range while the force
    stays inside its own. The strict band rejected every model that follows the drift (the NARX default,
    0.005 % validation NMSE) and the search kept a network at 587 % test NMSE. A linear NARX candidate validates
    best and its run is affine in the input, so the system counts as about linear."""
    model = _about_linear(tmp_path, "cart", budget=10)
    assert model.search["context"]["excursion"] <= 0.05  # the force stays inside its training range
    assert model.metrics["test"]["nmse"] < 5.0, (model.search["winner_summary"], model.metrics["test"])


@pytest.mark.slow
def test_a_lightly_damped_resonance_keeps_its_linear_model(tmp_path):
    """A resonance at 1 Hz (damping 0.02) sampled at 1 kHz, driven by steps held 100 samples: the test input's
    realization takes the true output 0.53 training ranges beyond the training output range. Every linear NARX
    candidate (0.0015 % validation NMSE) left the band there, and the search kept an output-error model at
    87.5 % test NMSE. A linear candidate's band is half a range wider under the linear-system band."""
    model = _about_linear(tmp_path, "resonance", budget=20)
    assert model.metrics["test"]["nmse"] < 5.0, (model.search["winner_summary"], model.metrics["test"])


def test_the_spread_of_fits_on_the_test_inputs_bounds_their_test_error_from_below():
    """``spread``: the median over pairs of fits of their runs' mean squared difference on the test inputs (% of
    the training output variance). Whatever the test output, a pair's mean squared error is at least a quarter of
    their difference (||a - b||^2 <= 2 ||a - y||^2 + 2 ||b - y||^2)."""
    from dynmodel.search.checks import spread

    rng = np.random.default_rng(3)
    y = rng.standard_normal(500)
    runs = [{"test:1:0": y + 0.3 * rng.standard_normal(500)} for _ in range(2)]
    d = runs[0]["test:1:0"] - runs[1]["test:1:0"]
    s = spread(runs)
    assert s == pytest.approx(100 * np.mean(d * d))
    errors = [100 * np.mean((r["test:1:0"] - y) ** 2) for r in runs]
    assert np.mean(errors) >= s / 4
    # the median over the three pairs of three fits; a fit with no shared test split adds no pair
    third = {"test:1:0": y + 1.0}
    pairs = [spread([runs[0], runs[1]]), spread([runs[0], third]), spread([runs[1], third])]
    assert spread([*runs, third, {"test:2:0": y}]) == pytest.approx(float(np.median(pairs)))
    assert spread(runs[:1]) is None and spread([]) is None


def test_the_test_runs_are_scaled_by_the_training_outputs_and_thinned(tmp_path):
    """``test_runs``: the free run over each test split, divided by the training outputs' standard deviation, at
    most SPREAD_SAMPLES samples (every k-th from the range's start), keyed by split, recording and start, and NaN
    before the first sample the evaluation scores (the transient, the model's tune-in), as the band check leaves
    them out. Thesis 5.3.3: an annealed network's fits, run from their zero state, reached about 1e8 standard
    deviations inside the test's 500-sample transient only; counted there, their spread (2.5e17 %) set aside the
    candidate that tests best (0.79 % test NMSE). Fits of one candidate with another tune-in (a NARX model whose
    lags each fold chooses) share the grid, so their pair is compared."""
    from dynmodel.search.checks import SPREAD_SAMPLES, pair_differences, spread, test_runs, usual_runs
    from dynmodel_plugins.narx import Narx

    u, y = narx(3000, 11)
    ut = np.random.default_rng(5).standard_normal(4500)
    write_csv(tmp_path / "train.csv", {"u": u, "y": y})
    write_csv(tmp_path / "test.csv", {"u": ut, "y": _system(ut)})
    raw = {
        "name": "runs",
        "data": {
            "path": "train.csv",
            "input": ["u"],
            "output": ["y"],
            "test": {"path": "test.csv"},
            "transient": 300,
            "transient_at": "recording",
        },
        "model": {"family": "narx", "params": {"lags": {"u": [0, 1], "y": [1, 2]}, "degree": 2}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    ds = load_dataset(spec)
    model, _ = engine.fit_dataset(spec, ds)
    assert isinstance(model.family, Narx)
    runs = usual_runs(model, ds)
    got = test_runs(ds, runs, model.warmup)
    ((key, run),) = got.items()
    ((rec, a, b),) = ds.ranges["test"]
    assert (a, b) == (0, 4500) and key == f"test:{rec}:0" and len(run) == 1500 <= SPREAD_SAMPLES  # every 3rd
    std = np.std(ds.concat_outputs("train"), axis=0)
    assert np.isnan(run[:100]).all()  # the transient's 300 samples
    np.testing.assert_allclose(run[100:], runs[rec][0][300:b:3] / std)
    # a longer tune-in: the same grid, fewer samples compared
    later = test_runs(ds, runs, 310)[key]
    assert len(later) == 1500 and np.isnan(later[:104]).all() and np.isfinite(later[104:]).all()
    shifted = {key: later + 0.1}
    assert spread([got, shifted]) == pytest.approx(100 * 0.01)
    # three fits: every pair (0-1, 0-2, 1-2); the spread is their median, the closest pair their smallest
    far = {key: later + 0.3}
    assert pair_differences([got, shifted, far]) == pytest.approx([1.0, 9.0, 4.0])
    assert spread([got, shifted, far]) == pytest.approx(4.0)


def test_the_search_records_how_far_the_fits_of_each_candidate_part_ways_on_the_test_inputs(tmp_path, monkeypatch):
    """Every candidate level with two or more fits records its ``test_spread``; the note on the chosen model's
    fits parting ways is written when a quarter of its spread exceeds SPREAD_NOTE x its validation error (here
    set to 0 so that it must appear) and names that floor."""
    import dynmodel.search.run as search_run

    monkeypatch.setattr(search_run, "SPREAD_NOTE", 0.0)
    monkeypatch.setattr(search_run, "SPREAD_FLOOR", 0.0)
    rec = _search(tmp_path, 1.4, families=("esn",))
    levels = [lv for c in rec["candidates"] for lv in c["levels"].values()]
    several = [lv for lv in levels if lv["fits"] >= 2 and lv["status"] == "ok"]
    assert several and all(lv["test_spread"] is not None and lv["test_spread"] > 0 for lv in several)
    assert all(lv["test_spread"] is None for lv in levels if lv["fits"] < 2)
    # the closest pair is a pair too: no further apart than the median one, and recorded with it
    assert all(0 < lv["test_spread_closest"] <= lv["test_spread"] for lv in several)
    assert all(lv["test_spread_closest"] is None for lv in levels if lv["fits"] < 2)
    winner = next(c for c in rec["candidates"] if c["key"] == rec["winner"])
    parted = winner["levels"][rec["level"]]["test_spread"]
    (note,) = [n for n in rec["notes"] if "part ways on the test inputs" in n]
    assert f"at least {parted / 4:.3g} %" in note


def _population_narx_over_parted_networks(tmp_path, k: int, first_seed: int, description: str):
    """``family: auto`` on system ``sysK`` of the population drawn from ``first_seed`` (the benchmark's own generator,
    its 80 / 20 split and a test recording of its own), checked to keep a NARX model through the refit-agreement
    stage over an esn candidate set aside for its seeds: (the model, its search record, the winner's record, the
    best-validating esn candidate that stays in the output band)."""
    drawn, train, test = benchmark("auto_population").system(k, first_seed)
    assert drawn == description
    write_csv(tmp_path / "train.csv", train)
    write_csv(tmp_path / "test.csv", test)
    raw = {
        "name": f"population-{first_seed}-{k}",
        "data": {
            "path": "train.csv",
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 0.8, "validation": 0.2},
            "test": {"path": "test.csv"},
        },
        "model": {"family": "auto"},
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    model, _ = engine.fit_dataset(spec, load_dataset(spec))
    rec = model.search
    assert model.family.name == "narx" and any(s["stage"] == "full: refit agreement" for s in rec["stages"])
    winner = next(c for c in rec["candidates"] if c["key"] == rec["winner"])
    best = min(
        (c for c in rec["candidates"] if c["family"] == "esn" and c["levels"].get("final", {}).get("band_ok")),
        key=lambda c: c["levels"]["final"]["score"],
    )
    assert best["verdict"].startswith("set aside: its seeds part ways on the test inputs")
    return model, rec, winner, best


def test_networks_whose_seeds_part_ways_give_way_to_a_narx_model_whose_refit_holds_on_the_test_inputs(tmp_path):
    """Seeds 2100's sys22 of the population (a Wiener system, a saturation at +-0.8 after a linear filter, driven by
    held steps; the test's steps are held for another time; 8000 training and 2000 validation samples): every
    internal network fitted in full parts ways on the test inputs, and the NARX default was screened out. The
    network kept validated at 0.025 % and tested 1.51 %. Now the NARX default is fitted in full and again on every
    sample; its two fits nearly agree on the test inputs, it validates below the networks' floor and is chosen:
    0.100 % (the NARX default alone 0.137 %)."""
    model, rec, winner, best = _population_narx_over_parted_networks(
        tmp_path, 22, 2100, "wiener sat steps n=10000 noise=0"
    )
    apart = winner["levels"]["final"]["test_refit_apart"]
    assert apart is not None and apart / 4 < winner["levels"]["final"]["score"]
    assert best["levels"]["final"]["score"] < winner["levels"]["final"]["score"]  # it validated better
    assert any("whose refit on every sample departs from its validated fit there" in n for n in rec["notes"])
    assert model.metrics["test"]["nmse"] < 0.3  # measured 0.100; the network kept before 1.51
    assert rec["refit"]["refitted"]  # the model kept is that refit


@pytest.mark.slow
def test_a_narx_model_screened_above_the_floor_of_networks_whose_seeds_part_ways_is_fitted_in_full_and_chosen(
    tmp_path,
):
    """Seeds 300's sys21 of the population (a Hammerstein system, a saturation before a linear filter, driven by held
    steps; 8000 training and 2000 validation samples): the internal networks validate best and their seeds part
    ways on the test inputs (all but one err there by at least 0.012 %). The NARX default screened at 0.019 % with
    least-squares weights, above that floor, and was left out of the refit-agreement stage: the network kept tested
    0.116 %. A candidate screened within SURVIVOR_FACTOR of the floor is now fitted in full (0.0104 % on
    validation) and again on every sample, and is chosen: 0.0114 % (the NARX default alone 0.0105 %)."""
    model, _, winner, best = _population_narx_over_parted_networks(
        tmp_path, 21, 300, "hammerstein sat steps n=10000 noise=0"
    )
    floor = best["levels"]["final"]["test_spread_closest"] / 4
    assert floor < winner["levels"]["screen"]["score"] < SURVIVOR_FACTOR * floor  # screened above it, within reach
    assert winner["levels"]["final"]["score"] < floor  # fitted in full, it validates below it
    assert model.metrics["test"]["nmse"] < 0.03  # measured 0.0114; the network kept before 0.116
