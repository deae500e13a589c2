"""Benchmark protocols in the spec: named test sets, input and output in two files, initialization
windows, scoring every sample, reporting units, and the metrics' shape in JSON and the model file."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import scipy.io
from conftest import make_spec, narx, write_csv, write_yaml

from dynmodel import engine, store
from dynmodel.data import load_dataset
from dynmodel.errors import DataError, SpecError

NARX = {"family": "narx", "params": {"lags": {"u": [0, 1, 2], "y": [1, 2]}, "degree": 3, "max_terms": 8}}


@pytest.fixture
def files(tmp_path):
    """A training recording and two test recordings of the eq. 3.37 NARX system."""
    for name, (n, seed) in {"train": (3000, 1), "a": (1500, 2), "b": (1000, 3)}.items():
        u, y = narx(n, seed)
        write_csv(tmp_path / f"{name}.csv", {"u": u, "y": y})
    return tmp_path


def _raw(**data):
    base = {"path": "train.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.8, "validation": 0.2}}
    return {"name": "p", "data": {**base, **data}, "model": NARX, "evaluation": {"metrics": ["nmse", "rmse", "max"]}}


def _fit(raw, base):
    spec = make_spec(raw, base)
    return engine.fit_dataset(spec, load_dataset(spec))[0]


def _same(entry_a: dict, entry_b: dict, keys=("samples", "nmse", "rmse", "max", "nmse_1")) -> None:
    for key in keys:
        assert entry_a[key] == entry_b[key], key


def test_named_test_sets_score_each_exactly_as_separate_runs_would(files):
    both = _fit(_raw(test=[{"name": "a", "path": "a.csv"}, {"name": "b-2", "path": "b.csv"}]), files)
    assert list(both.metrics) == ["train", "validation", "test:a", "test:b-2"]
    only_a = _fit(_raw(test={"path": "a.csv"}), files)
    only_b = _fit(_raw(test={"path": "b.csv"}), files)
    assert list(only_a.metrics) == ["train", "validation", "test"]  # a single unnamed test set keeps its key
    _same(both.metrics["test:a"], only_a.metrics["test"])
    _same(both.metrics["test:b-2"], only_b.metrics["test"])
    _same(both.metrics["validation"], only_a.metrics["validation"])
    assert both.metrics["test:a"]["samples"] == 1500 - 2 and both.metrics["test:b-2"]["samples"] == 1000 - 2


def test_named_test_sets_in_the_table_json_and_model_file(files, cli):
    raw = _raw(
        test=[{"name": "a", "path": "a.csv"}, {"name": "late", "segments": [[2000, 3000]]}],
        init_window=20,
    )
    raw["data"]["split"] = {"train": [0, 1600], "validation": [1600, 2000]}
    spec_path = write_yaml(files / "spec.yaml", raw)
    res = cli("fit", spec_path, "--json", files / "m.json", "--out", files / "m.h5", "-q")
    assert res.exit_code == 0, res.output
    assert "test:a" in res.output and "test:late" in res.output
    payload = json.loads((files / "m.json").read_text())
    assert list(payload["metrics"]) == ["train", "validation", "test:a", "test:late"]
    assert payload["metrics"]["test:late"]["init_window"] == 20 and payload["metrics"]["test:late"]["samples"] == 980
    assert "init_window" not in payload["metrics"]["train"]
    with h5py.File(files / "m.h5", "r") as f:
        assert sorted(f["eval"]) == ["test_a", "test_late", "train", "validation"]
        assert f["eval/test_late"].attrs["split"] == "test:late"
        assert f["eval/test_a"].attrs["rmse"] == payload["metrics"]["test:a"]["rmse"]
    assert store.load(files / "m.h5").metrics == payload["metrics"]
    shown = cli("inspect", files / "m.h5")
    assert shown.exit_code == 0 and "test:late" in shown.output


def test_init_window_never_scores_inside_the_window_and_never_trims_training(files):
    raw = _raw(test={"path": "a.csv"}, init_window=40)
    spec = make_spec(raw, files)
    ds = load_dataset(spec)
    plain = load_dataset(make_spec(_raw(test={"path": "a.csv"}), files))
    assert ds.scored("train") == plain.scored("train") == [(0, 0, 2400)]  # training untouched
    # the validation range inside the training file became a run of its own, scored after its window
    ((rec, a, b),) = ds.ranges["validation"]
    assert (a, b) == (0, 600) and ds.recordings[rec].n == 600
    np.testing.assert_array_equal(ds.recordings[rec].y, plain.recordings[0].y[2400:3000])
    assert ds.scored("validation") == [(rec, 40, 600)] and ds.n_scored("test") == 1500 - 40

    model, _ = engine.fit_dataset(spec, ds)
    # the window's outputs beyond the model's measured start (2 samples) are never read nor scored
    spoiled = files / "spoiled.csv"
    u, y = narx(1500, 2)
    y[2:40] = 1e6
    write_csv(spoiled, {"u": u, "y": y})
    again = _fit(_raw(test={"path": "spoiled.csv"}, init_window=40), files)
    _same(again.metrics["test"], model.metrics["test"], ("samples", "nmse", "rmse", "max"))  # the free run's scores
    # and the score is the RMSE of y[40:] of the free run started from the first measured outputs
    run = model.predict(u[:, None], y[:2, None])
    expected = np.sqrt(np.mean((run[40:, 0] - narx(1500, 2)[1][40:]) ** 2))
    assert model.metrics["test"]["rmse"] == pytest.approx(expected, rel=1e-12)
    assert model.metrics["train"] == _fit(_raw(test={"path": "a.csv"}), files).metrics["train"]


def test_init_window_per_split_and_per_test_set(files):
    raw = _raw(
        test=[{"name": "a", "path": "a.csv"}, {"name": "b", "path": "b.csv", "init_window": 5}],
        init_window={"test": 30},
    )
    ds = load_dataset(make_spec(raw, files))
    assert ds.windows == {"test:a": 30, "test:b": 5}
    assert ds.ranges["validation"] == [(0, 2400, 3000)]  # no validation window: the run continues from training


def test_a_run_needing_more_measured_outputs_than_the_window_fails_in_one_line(files, cli):
    esn = {"family": "esn", "params": {"size": 20, "mode": "external", "tune_in": 100}}
    raw = {**_raw(test={"path": "a.csv"}, init_window=50), "model": esn}
    res = cli("fit", write_yaml(files / "esn.yaml", raw), "-q")
    assert res.exit_code == 2
    line = res.output.strip()
    assert "\n" not in line and "first 100 measured outputs" in line and "allows the first 50" in line
    assert "tune_in to at most 50" in line
    raw = {
        **_raw(test={"path": "a.csv"}, init_window=4),
        "model": {"family": "narx", "params": {"lags": {"u": [0, 6]}}},
    }
    with pytest.raises(SpecError, match="first 6 measured outputs.*lags of at most 4 samples, or initial: settled"):
        _fit(raw, files)
    raw["data"]["init_window"] = 6
    assert _fit(raw, files).metrics["test"]["init_window"] == 6


def test_score_all_scores_every_sample_and_refuses_measured_starts(files):
    raw = _raw(test={"path": "a.csv"}, transient=100)
    raw["evaluation"]["score"] = "all"
    with pytest.raises(SpecError, match="scores every sample, so no measured output may be used"):
        _fit(raw, files)
    raw["model"] = {"family": "narx", "params": {**NARX["params"], "initial": "zeros"}}
    model = _fit(raw, files)
    assert model.metrics["test"]["samples"] == 1500 and model.metrics["test"]["score"] == "all"
    assert model.metrics["validation"]["samples"] == 600
    assert model.metrics["train"]["samples"] == 2400 - 100  # the transient still trims training
    u, y = narx(1500, 2)
    rmse = np.sqrt(np.mean((model.predict(u[:, None])[:, 0] - y) ** 2))
    assert model.metrics["test"]["rmse"] == pytest.approx(rmse, rel=1e-12)


def test_units_convert_the_rmse_for_reporting(files, cli):
    raw = _raw(test={"path": "a.csv"})
    plain = _fit(raw, files)
    raw["evaluation"]["units"] = {"y": {"scale": 1000, "name": "mm"}}
    scaled = _fit(raw, files)
    for split in ("train", "validation", "test"):
        assert scaled.metrics[split]["rmse"] == pytest.approx(1000 * plain.metrics[split]["rmse"], rel=1e-14)
        assert scaled.metrics[split]["nmse"] == plain.metrics[split]["nmse"]
        assert scaled.metrics[split]["rmse_units"] == "mm"
    res = cli("fit", write_yaml(files / "mm.yaml", raw), "-q", "--out", files / "mm.h5")
    assert res.exit_code == 0 and "RMSE (mm)" in res.output
    raw["evaluation"]["units"] = {"q": {"scale": 1000, "name": "mm"}}
    with pytest.raises(SpecError, match="'q' is not an output"):
        load_dataset(make_spec(raw, files))


def test_input_and_output_from_two_files_and_variables_of_one_file(tmp_path):
    u, y = narx(2000, 4)
    scipy.io.savemat(tmp_path / "uval.mat", {"uval": u[None, :]})
    scipy.io.savemat(tmp_path / "yval.mat", {"yval": y[None, :]})
    scipy.io.savemat(tmp_path / "both.mat", {"uEst": u[:, None], "yEst": y[:, None], "uVal": y[:, None]})
    raw = {
        "data": {
            "path": "both.mat",
            "input": ["uEst"],
            "output": ["yEst"],
            "test": [
                {
                    "name": "files",
                    "path": {"input": "uval.mat", "output": "yval.mat"},
                    "input": ["uval"],
                    "output": ["yval"],
                },
                {"name": "swapped", "input": ["uVal"], "output": ["uEst"]},
            ],
        },
        "model": NARX,
    }
    ds = load_dataset(make_spec(raw, tmp_path))
    ((rec, _, _),) = ds.ranges["test:files"]
    np.testing.assert_array_equal(ds.recordings[rec].u[:, 0], u)
    np.testing.assert_array_equal(ds.recordings[rec].y[:, 0], y)
    assert ds.recordings[rec].name == "test:files:uval.mat/yval.mat"
    ((rec, _, _),) = ds.ranges["test:swapped"]
    np.testing.assert_array_equal(ds.recordings[rec].u[:, 0], y)
    np.testing.assert_array_equal(ds.recordings[rec].y[:, 0], u)
    resolved = make_spec(raw, tmp_path).resolved()
    assert resolved["data"]["test"][0]["path"] == {
        "input": str(tmp_path / "uval.mat"),
        "output": str(tmp_path / "yval.mat"),
    }
    scipy.io.savemat(tmp_path / "yval.mat", {"yval": y[None, :1999]})
    with pytest.raises(DataError, match="the input file uval.mat has 2000 samples and the output file 1999"):
        load_dataset(make_spec(raw, tmp_path))


@pytest.mark.parametrize(
    "test, expected",
    [
        ([{"name": "a", "path": "a.csv"}, {"name": "a", "path": "b.csv"}], "two test sets are named 'a'"),
        ([{"name": "a b", "path": "a.csv"}], "should match pattern"),
        ([{"path": "a.csv"}], "required key is missing"),
        ([], "the list of test sets is empty"),
    ],
)
def test_named_test_set_mistakes(files, test, expected):
    with pytest.raises(SpecError, match=expected) as info:
        make_spec(_raw(test=test), files)
    assert "\n" not in str(info.value)


def test_a_test_split_given_twice_is_refused(files):
    raw = _raw(test=[{"name": "a", "path": "a.csv"}])
    raw["data"]["split"] = {"train": 0.7, "validation": 0.1, "test": 0.2}
    with pytest.raises(SpecError, match="the test split is given twice"):
        load_dataset(make_spec(raw, files))
