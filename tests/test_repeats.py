"""A validation or test input that repeats the training input (a periodic excitation split period by
period): found, named, and the search made cautious by it (dynmodel/data/repeats.py)."""

from __future__ import annotations

import numpy as np
import pytest

from dynmodel.data.dataset import Dataset, Recording
from dynmodel.data.repeats import MISMATCH, best_match, repeats_training
from dynmodel.search.select import Summary, choose
from dynmodel.search.views import Layout, repeated_validation

PERIOD = 700


def _periodic(periods: int, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    one = rng.standard_normal(PERIOD)
    return np.tile(one, periods) + noise * rng.standard_normal(periods * PERIOD)


def _dataset(u: np.ndarray, splits: dict[str, tuple[int, int]], test: np.ndarray | None = None) -> Dataset:
    recordings = [Recording("r.csv", u[:, None], np.zeros((len(u), 1)))]
    ranges = {k: [(0, a, b)] for k, (a, b) in splits.items()}
    if test is not None:
        recordings.append(Recording("t.csv", test[:, None], np.zeros((len(test), 1))))
        ranges["test"] = [(1, 0, len(test))]
    return Dataset(recordings, ranges, 0, ["u"], ["y"], 1.0)


def test_best_match_finds_a_shifted_copy_and_nothing_in_an_unrelated_signal():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3000, 2))
    shift, mismatch = best_match(x, x[1234:1734])
    assert shift == 1234 and mismatch < 1e-6  # FFT rounding
    _, unrelated = best_match(x, rng.standard_normal((500, 2)))
    assert unrelated > 1.0  # an independent signal: the mismatch of the best shift is near sqrt(2)
    assert best_match(x, np.full((500, 2), 0.3))[1] == np.inf  # a held input repeats nothing


def test_a_periodic_record_split_period_by_period_repeats_and_a_new_realization_does_not():
    u = _periodic(6, noise=0.01)  # measured: 1 % noise on the input
    ds = _dataset(u, {"train": (0, 5 * PERIOD), "validation": (5 * PERIOD, 6 * PERIOD)}, test=_periodic(2, seed=9))
    found = repeats_training(ds, "validation")
    assert found is not None and found["period"] == PERIOD and 0.005 < found["mismatch"] < MISMATCH
    assert repeats_training(ds, "test") is None
    notes = ds.repeat_notes()
    assert list(notes) == ["validation"] and f"{PERIOD} samples back" in notes["validation"]
    # the search is cautious: the validation repeats, the test input is new
    assert repeated_validation(ds, Layout("full")) == found
    # a validation that is not a repeat: a random input throughout
    random = np.random.default_rng(3).standard_normal(6 * PERIOD)
    assert repeats_training(_dataset(random, {"train": (0, 3500), "validation": (3500, 4200)}), "validation") is None
    # noise beyond the tolerance (20 % of the input's spread): not a repeat
    noisy = _dataset(_periodic(6, noise=0.2), {"train": (0, 5 * PERIOD), "validation": (5 * PERIOD, 6 * PERIOD)})
    assert repeats_training(noisy, "validation") is None


def test_a_test_set_that_repeats_the_training_input_too_leaves_the_validation_as_representative():
    u = _periodic(8)
    ds = _dataset(
        u, {"train": (0, 5 * PERIOD), "validation": (5 * PERIOD, 6 * PERIOD), "test": (6 * PERIOD, 8 * PERIOD)}
    )
    assert repeats_training(ds, "validation") is not None and repeats_training(ds, "test") is not None
    assert repeated_validation(ds, Layout("full")) is None


def _s(score: float, size: float) -> Summary:
    return Summary(score, True, 0.5, size, {0: score}, 0)


def test_a_repeated_validation_input_widens_the_tie_to_the_simpler_candidate():
    from dynmodel.search.run import REPEATED, Ranking

    labels = {"big": "big", "small": "small"}
    summaries = {"big": _s(1.0, 70), "small": _s(1.07, 30)}
    found = {"split": "validation", "chunks": 8, "mismatch": 0.0, "period": PERIOD}
    assert Ranking("holdout", 0, None).doubt() is None
    assert choose(summaries, labels, short_validation=Ranking("holdout", 0, None).doubt()).key == "big"
    doubt = Ranking("holdout", 0, None, repeated=found).doubt()
    assert doubt == REPEATED
    cautious = choose(summaries, labels, short_validation=doubt)
    assert cautious.key == "small" and cautious.cautious == [REPEATED]
    assert "chose the simpler small" in cautious.notes[0]
    # beyond the 10 % tie the better one stays
    assert choose({"big": _s(1.0, 70), "small": _s(1.2, 30)}, labels, short_validation=doubt).key == "big"
    # with a short validation too, both reasons are given; the tail's missing validation split is not one
    both = Ranking("holdout", 0, "the validation split has only 400 scored samples", repeated=found).doubt()
    assert both == f"the validation split has only 400 scored samples; {REPEATED}"
    assert Ranking("tail", 5, "there is no validation split", repeated=found).doubt() == REPEATED
    assert Ranking("holdout", 0, None, repeated=found).repeat_caution().endswith("so simpler candidates are preferred")


@pytest.mark.parametrize("periods", [3, 6])
def test_the_period_reported_is_the_nearest_copy(periods):
    u = _periodic(periods)
    n = periods * PERIOD
    found = repeats_training(_dataset(u, {"train": (0, n - PERIOD), "validation": (n - PERIOD, n)}), "validation")
    assert found is not None and found["period"] == PERIOD


def test_phase_fold_holds_one_fifth_of_the_period_out_of_every_period():
    from dynmodel.search.views import phase_fold, view

    u = _periodic(6)
    ds = _dataset(u, {"train": (0, 5 * PERIOD), "validation": (5 * PERIOD, 6 * PERIOD)}, test=_periodic(2, seed=9))
    width = PERIOD // 5
    last = phase_fold(ds, 4, 5, PERIOD)  # the last fifth
    assert last.ranges["validation"] == [(0, 6 * PERIOD - width, 6 * PERIOD)]
    assert last.ranges["train"] == [(0, j * PERIOD, (j + 1) * PERIOD - width) for j in range(6)]
    middle = phase_fold(ds, 2, 5, PERIOD)  # [2/5, 3/5) of every period held out
    lo, hi = 2 * width, 3 * width
    assert middle.ranges["validation"] == [(0, 5 * PERIOD + lo, 5 * PERIOD + hi)]
    expected = (
        [(0, 0, lo)]
        + [(0, j * PERIOD + hi, (j + 1) * PERIOD + lo) for j in range(5)]
        + [(0, 5 * PERIOD + hi, 6 * PERIOD)]
    )
    assert middle.ranges["train"] == expected
    assert "test" not in view(ds, Layout("fold", fold=2, folds=5, period=PERIOD)).ranges  # never fitted on
    for i in range(5):  # every phase window's input occurs in no training range: a new input to every model
        assert repeats_training(phase_fold(ds, i, 5, PERIOD), "validation") is None


def _wiener_hammerstein(u: np.ndarray) -> np.ndarray:
    from scipy.signal import lfilter

    v = lfilter([0.3], [1.0, -0.7], u)
    return lfilter([0.2], [1.0, -0.8], np.tanh(1.5 * v))


def test_a_periodic_record_is_ranked_on_phases_held_out_and_the_choice_refitted_on_all(tmp_path):
    """Six periods of one multisine (the last the validation split), tested on another realization: the search
    ranks its candidates on each fifth of the period held out of every period in turn, and refits the choice
    on the whole training split."""
    from conftest import write_csv

    from dynmodel import engine
    from dynmodel.data import load_dataset
    from dynmodel.search import search_options
    from dynmodel.spec import validate_spec

    period = 1000
    rng = np.random.default_rng(5)

    def multisine() -> np.ndarray:
        spectrum = np.zeros(period // 2 + 1, complex)
        spectrum[5:150] = np.exp(2j * np.pi * rng.random(145))
        one = np.fft.irfft(spectrum, period)
        return np.tile(one / one.std(), 8)

    u, ut = multisine(), multisine()
    y, yt = _wiener_hammerstein(u)[2 * period :], _wiener_hammerstein(ut)[2 * period :]
    y = y + 0.01 * y.std() * rng.standard_normal(len(y))
    write_csv(tmp_path / "train.csv", {"u": u[2 * period :], "y": y})
    write_csv(tmp_path / "test.csv", {"u": ut[2 * period :], "y": yt})
    raw = {
        "name": "periodic",
        "data": {
            "path": "train.csv",
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 5 / 6, "validation": 1 / 6},
            "test": {"path": "test.csv"},
        },
        "model": {"family": "auto", "params": {"families": ["narx"], "budget": 4}},
        "seed": 0,
    }
    spec = validate_spec(raw, "<test>", tmp_path)
    ds = load_dataset(spec)
    with search_options(workers=1):
        model, _ = engine.fit_dataset(spec, ds)
    rec = model.search
    assert rec["mode"] == "phase" and rec["folds"] == 5
    assert rec["layouts"]["final"] == [Layout("fold", fold=i, folds=5, period=period).to_json() for i in range(5)]
    assert any("a periodic excitation of 1000 samples" in n for n in rec["notes"])
    assert model.metrics["train"]["samples"] == ds.n_scored(
        "train", model.warmup
    )  # refitted on the whole training split
    assert model.metrics["test"]["nmse"] < 1.0


def test_fit_notes_a_validation_split_that_repeats_the_training_input(tmp_path, cli):
    """`dynmodel fit` with any family says when the validation input is the training input again."""
    import yaml
    from conftest import write_csv
    from scipy.signal import lfilter

    u = _periodic(6)
    y = lfilter([0.3], [1.0, -0.7], u) + 0.01 * np.random.default_rng(2).standard_normal(len(u))
    write_csv(tmp_path / "d.csv", {"u": u, "y": y})
    spec = {
        "name": "periodic",
        "data": {"path": "d.csv", "input": ["u"], "output": ["y"], "split": {"train": 5 / 6, "validation": 1 / 6}},
        "model": {"family": "narx", "params": {"degree": 1, "lags": {"u": [0, 1], "y": [1]}}},
    }
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(spec))
    result = cli("fit", tmp_path / "s.yaml", "--out", tmp_path / "m.h5")
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert f"the validation input repeats the training input (exactly, {PERIOD} samples back" in text


def test_a_short_periodic_record_is_ranked_on_phases_not_on_blocks_in_time(tmp_path):
    """Four periods of one input, 20 % validation (fewer than 1000 scored samples, so the search would
    cross-validate in blocks of time, each of which repeats the input of the periods around it): ranked on
    the phases of the period held out instead. A random input of the same length keeps the blocks."""
    from conftest import write_csv

    from dynmodel.data import load_dataset
    from dynmodel.search.run import CV_BELOW, context
    from dynmodel.spec import validate_spec

    def ranking(u: np.ndarray, name: str):
        y = _wiener_hammerstein(u)
        write_csv(tmp_path / f"{name}.csv", {"u": u, "y": y})
        # a new realization to test on (its outputs are never read by the layout)
        write_csv(tmp_path / f"{name}-test.csv", {"u": _periodic(2, seed=9), "y": y[: 2 * PERIOD]})
        raw = {
            "name": name,
            "data": {
                "path": f"{name}.csv",
                "input": ["u"],
                "output": ["y"],
                "split": {"train": 0.8, "validation": 0.2},
                "test": {"path": f"{name}-test.csv"},
            },
            "model": {"family": "auto"},
        }
        spec = validate_spec(raw, "<test>", tmp_path)
        ds = load_dataset(spec)
        assert ds.n_scored("validation") < CV_BELOW
        return context(spec, ds, spec.model.params, None)[1]

    periodic = ranking(_periodic(4), "periodic")
    assert (periodic.mode, periodic.period, periodic.folds) == ("phase", PERIOD, 5)
    assert f"a periodic excitation of {PERIOD} samples" in (periodic.short or "")
    random = ranking(np.random.default_rng(4).standard_normal(4 * PERIOD), "random")
    assert (random.mode, random.period) == ("folds", 0)
