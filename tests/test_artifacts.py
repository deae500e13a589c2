"""Measurement artifacts in the outputs (dynmodel.data.artifacts): isolated spikes are found, replaced in the
training and validation outputs (never in the test's) and named; a clipped sensor is named; signals with sharp
features of their own (a pulse response, a differentiator, a quantized encoder) raise nothing."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from conftest import SHARED_DATA, make_spec, write_csv, write_yaml
from scipy.signal import lfilter
from spiky import plant as _plant
from spiky import spiky as _spiky
from spiky import steps as _steps

import dynmodel
from dynmodel.data import load_dataset
from dynmodel.data.artifacts import clipping, spikes


def test_glitches_of_a_sensor_are_found_and_nothing_else():
    u, y, clean, glitches = _spiky()
    found = spikes(y, u[:, None])
    assert set(found) == set(glitches)
    assert spikes(clean, u[:, None]).size == 0


@pytest.mark.parametrize(
    "case", ["pulse response", "differentiator", "feedthrough", "quantized", "laplace noise", "relay"]
)
def test_sharp_features_of_the_system_are_not_spikes(case):
    rng = np.random.default_rng(3)
    n = 4000
    u = rng.choice([-1.0, 1.0], n)
    if case == "pulse response":  # sparse one-sample pulses: the output peaks sharply one sample later
        u = np.zeros(n)
        u[rng.choice(n, 40, replace=False)] = 1.0
        y = lfilter([0.0, 1.0], [1.0, -0.3], u)
    elif case == "differentiator":  # a spike at every input step
        y = np.diff(u, prepend=u[0]) + 0.01 * rng.standard_normal(n)
    elif case == "feedthrough":
        y = u + 0.05 * lfilter([1.0], [1.0, -0.5], u)
    elif case == "quantized":  # an encoder: steps of 0.25 std
        u = _steps(n, rng)
        x = _plant(u)
        q = 0.25 * np.std(x)
        y = np.round(x / q) * q
    elif case == "relay":  # a relay with hysteresis on a noisy input chatters for single samples
        u = np.sin(0.01 * np.arange(n)) + 0.3 * rng.standard_normal(n)
        y = np.empty(n)
        state = 1.0
        for t in range(n):
            state = 1.0 if u[t] > 0.1 else -1.0 if u[t] < -0.1 else state
            y[t] = state
        assert np.sum((y[1:-1] != y[:-2]) & (y[2:] == y[:-2])) > 10  # it does chatter
    else:
        y = lfilter([0.5], [1.0, -0.9], u) + 0.05 * rng.laplace(size=n)
    assert spikes(y, u[:, None]).size == 0
    assert clipping(y) == []


def test_a_clipped_sensor_is_told_from_a_quantized_top_level():
    rng = np.random.default_rng(1)
    x = _plant(_steps(3000, rng))
    top = np.percentile(x, 85)
    clip = clipping(np.minimum(x, top))
    assert [(c.side, c.value) for c in clip] == [("maximum", top)]
    assert clip[0].share == pytest.approx(0.15, abs=0.005)
    assert clipping(x) == []
    q = 0.5 * np.std(x)
    assert clipping(np.round(x / q) * q) == []  # the highest level of an encoder is held less than the next


def _raw(path, spikes_mode: str | None = None) -> dict:
    data: dict = {"path": str(path), "input": ["u"], "output": ["y"]}
    if spikes_mode:
        data["spikes"] = spikes_mode
    return {
        "data": data,
        "model": {"family": "narx", "params": {"lags": {"u": [1, 2], "y": [1, 2]}, "degree": 2}},
        "cost": "mse1",
        "evaluation": {"metrics": ["nmse"]},
    }


def test_fit_replaces_training_spikes_says_so_and_leaves_the_test_alone(tmp_path):
    u, y, clean, glitches = _spiky()
    path = write_csv(tmp_path / "rig.csv", {"u": u, "y": y})
    ds = load_dataset(make_spec(_raw(path), tmp_path))
    kinds = {(a.kind, a.split, a.replaced) for a in ds.artifacts}
    assert kinds == {("spikes", "train", True), ("spikes", "validation", True), ("spikes", "test", False)}
    rec = ds.recordings[0]
    fitted = glitches[glitches < 2400]
    tested = glitches[glitches >= 2400]
    # replaced by the mean of the neighbours where fitted, as measured in the test
    np.testing.assert_allclose(rec.y[fitted, 0], 0.5 * (y[fitted - 1] + y[fitted + 1]))
    np.testing.assert_array_equal(rec.y[tested, 0], y[tested])
    others = np.setdiff1d(np.arange(len(y)), fitted)
    np.testing.assert_array_equal(rec.y[others, 0], y[others])
    notes = ds.artifact_notes()
    assert f"{fitted[fitted < 1800].size} sample(s) of the training output 'y' stand out as isolated spikes" in notes[0]
    assert "each was replaced by the mean of its neighbours" in notes[0] and "data.spikes: keep" in notes[0]
    assert "the test scores include them (test outputs are never changed)" in notes[2]

    replaced = dynmodel.fit(make_spec(_raw(path), tmp_path))
    kept = dynmodel.fit(make_spec(_raw(path, "keep"), tmp_path))
    keep_ds = load_dataset(make_spec(_raw(path, "keep"), tmp_path))
    np.testing.assert_array_equal(keep_ds.recordings[0].y[:, 0], y)
    assert "kept as measured (data.spikes: keep)" in keep_ds.artifact_notes()[0]
    # the free run against the clean output of the test part: the glitches no longer bend the model
    error = {}
    for name, model in (("replaced", replaced), ("kept", kept)):
        run = model.predict(u[2400:, None], y_tune=clean[2400 : 2400 + model.warmup, None])[:, 0]
        error[name] = float(np.mean((run - clean[2400:]) ** 2) / np.var(clean[2400:]))
    assert error["replaced"] < 0.2 * error["kept"]


def test_the_decision_never_reads_the_test_outputs(tmp_path):
    u, y, _, _ = _spiky(seed=5)
    train = write_csv(tmp_path / "train.csv", {"u": u[:2400], "y": y[:2400]})
    seen = write_csv(tmp_path / "test.csv", {"u": u[2400:], "y": y[2400:]})
    unseen = write_csv(tmp_path / "blind.csv", {"u": u[2400:], "y": np.full(600, np.nan)})
    fitted = {}
    for name, test in (("seen", seen), ("unseen", unseen)):
        raw = _raw(train)
        raw["data"]["test"] = {"path": str(test)}
        ds = load_dataset(make_spec(raw, tmp_path))
        fitted[name] = ds.recordings[0].y
        assert any(a.replaced for a in ds.artifacts)
    np.testing.assert_array_equal(fitted["seen"], fitted["unseen"])


def test_validate_and_fit_json_carry_the_notes(tmp_path, cli):
    u, y, _, _ = _spiky()
    path = write_csv(tmp_path / "rig.csv", {"u": u, "y": y})
    spec = write_yaml(tmp_path / "s.yaml", _raw(path))
    out = cli("validate", spec)
    assert out.exit_code == 0
    assert "note: " in out.output and "stand out as isolated spikes" in out.output
    res = cli("fit", spec, "--json", "-")
    assert res.exit_code == 0
    notes = json.loads(res.stdout)["notes"]
    assert sum("isolated spikes" in n for n in notes) == 3


REAL = {
    "silverbox": "specs/benchmarks/silverbox-auto.yaml",
    "emps": "specs/benchmarks/emps-auto.yaml",
    "bouc-wen": "specs/benchmarks/bouc-wen-auto.yaml",
    "cascaded-tanks": "specs/benchmarks/cascaded-tanks-narx.yaml",  # trained on both overflows
}


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason=f"real data not found at {SHARED_DATA}")
@pytest.mark.parametrize("name", sorted(REAL))
def test_real_benchmarks_raise_no_spike_note(name):
    from conftest import ROOT

    ds = load_dataset(dynmodel.spec.load_spec(ROOT / REAL[name]))
    assert [a.kind for a in ds.artifacts] == (["clipping"] if name == "cascaded-tanks" else [])
    if name == "cascaded-tanks":  # the upper tank overflows: the output sits at 10 V
        assert ds.artifacts[0].clip is not None and ds.artifacts[0].clip.value == 10.0


def test_the_callers_arrays_are_not_changed_and_a_notebook_is_told():
    from dynmodel.textfiles import DataNote
    from dynmodel_plugins.narx import Narx

    u, y, _, glitches = _spiky()
    measured = y.copy()
    with pytest.warns(DataNote, match=r"sample\(s\) of the training output 'y' stand out as isolated spikes"):
        model = Narx(lags={"u": [1, 2], "y": [1, 2]}, degree=2).fit(u, y)
    np.testing.assert_array_equal(y, measured)
    assert model.model_.spec["data"]["spikes"] == "replace"
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataNote)
        with pytest.raises(DataNote, match="kept as measured"):
            Narx(lags={"u": [1, 2], "y": [1, 2]}, degree=2).fit(u, y, spikes="keep")
