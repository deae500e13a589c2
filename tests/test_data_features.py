"""Data-layer features the diagnosis needs and any spec can use: derived input channels (time
functions, direction of motion, travel since the last reversal), detrending, and resampling of
non-uniformly sampled files."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from conftest import make_spec, write_csv, write_yaml

import dynmodel
from dynmodel.data import load_dataset
from dynmodel.data.derived import channel_name, reversals, time_matrix
from dynmodel.errors import DataError, SpecError
from dynmodel.textfiles import DataNote


def test_reversals_of_a_triangle_with_noise_and_a_deadband():
    x = np.concatenate([np.linspace(0, 10, 101), np.linspace(10, 2, 81)[1:], np.linspace(2, 6, 41)[1:]])
    noisy = x + 0.02 * np.random.default_rng(0).standard_normal(len(x))
    d, s = reversals(noisy, deadband=0.2)
    assert np.all(d[5:98] == 1) and np.all(d[105:178] == -1) and np.all(d[185:] == 1)
    assert np.sum(d[1:] != d[:-1]) == 2  # the noise does not flip the direction
    assert s[178] == pytest.approx(-8.0, abs=0.3) and s[-1] == pytest.approx(4.0, abs=0.3)


def test_time_functions_start_at_zero():
    m = time_matrix(["linear", {"saturating": 2.0}], 5, 0.5)
    np.testing.assert_allclose(m[:, 0], [0, 0.5, 1.0, 1.5, 2.0])
    np.testing.assert_allclose(m[:, 1], 1 - np.exp(-m[:, 0] / 2.0))
    assert channel_name({"time": {"saturating": 2.0}}) == "time_saturating_2"
    assert channel_name({"direction": "x"}) == "x_direction"


def _friction_csv(tmp_path, n=3000, drift=0.0):
    rng = np.random.default_rng(1)
    t = np.arange(n)
    x = np.sin(2 * np.pi * t / 300) + 0.3 * np.sin(2 * np.pi * t / 77)
    d, _ = reversals(x)
    force = 2.0 * x + 0.5 * d + drift * t / n + 0.01 * rng.standard_normal(n)
    return write_csv(tmp_path / "f.csv", {"x": x, "force": force})


def test_direction_input_lets_a_static_model_fit_coulomb_friction(tmp_path):
    path = _friction_csv(tmp_path)
    raw = {
        "data": {"path": str(path), "input": ["x"], "output": ["force"]},
        "model": {"family": "narx", "params": {"lags": {"x": [0]}, "degree": 1}},
    }
    plain = dynmodel.fit(make_spec(raw, tmp_path))
    raw["data"]["derived_inputs"] = [{"direction": "x"}]
    raw["model"]["params"]["lags"]["x_direction"] = [0]
    with_dir = dynmodel.fit(make_spec(raw, tmp_path))
    assert with_dir.preprocessor.model_input_names == ["x", "x_direction"]
    assert with_dir.metrics["test"]["nmse"] < 0.1 < plain.metrics["test"]["nmse"]


def test_detrending_adds_the_trend_back_and_survives_the_model_file(tmp_path):
    path = _friction_csv(tmp_path, drift=3.0)
    raw = {
        "data": {
            "path": str(path),
            "input": ["x"],
            "output": ["force"],
            "detrend": ["linear"],
            "derived_inputs": [{"direction": "x"}, {"time": {"saturating": 500.0}}],
        },
        "model": {"family": "narx", "params": {"lags": {"x": [0], "x_direction": [0]}, "degree": 1}},
    }
    model = dynmodel.fit(make_spec(raw, tmp_path))
    assert model.preprocessor.trend_coef[0, 0] == pytest.approx(3.0 / 3000, rel=0.05)
    assert model.metrics["test"]["nmse"] < 0.1  # scored against the measured, trending output
    dynmodel.save(model, tmp_path / "m.h5")
    again = dynmodel.load(tmp_path / "m.h5")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(again.predict(data[:, 0]), model.predict(data[:, 0]), rtol=1e-12, atol=1e-12)
    assert again.preprocessor.derived == model.preprocessor.derived


def test_time_inputs_model_a_drift(tmp_path):
    path = _friction_csv(tmp_path, drift=3.0)
    raw = {
        "data": {
            "path": str(path),
            "input": ["x"],
            "output": ["force"],
            "derived_inputs": [{"direction": "x"}, {"time": "linear"}],
        },
        "model": {
            "family": "narx",
            "params": {"lags": {"x": [0], "x_direction": [0], "time_linear": [0]}, "degree": 1},
        },
    }
    assert dynmodel.fit(make_spec(raw, tmp_path)).metrics["test"]["nmse"] < 0.1


def test_derived_input_errors_are_one_line(tmp_path):
    path = _friction_csv(tmp_path)
    raw = {
        "data": {"path": str(path), "input": ["x"], "output": ["force"], "derived_inputs": [{"direction": "q"}]},
        "model": {"family": "narx"},
    }
    with pytest.raises(dynmodel.DynmodelError, match="'q' is not an input column"):
        dynmodel.fit(make_spec(raw, tmp_path))
    raw["data"]["derived_inputs"] = [{"direction": "x", "speed": 2}]
    with pytest.raises(SpecError, match="unknown key 'speed'"):
        make_spec(raw, tmp_path)
    raw["data"]["derived_inputs"] = [{"velocity": "x"}]
    with pytest.raises(SpecError, match="direction: INPUT"):
        make_spec(raw, tmp_path)


def _stamped(tmp_path, name="rig.tsv", jitter=True, n=400):
    rng = np.random.default_rng(2)
    steps = 10.0 + (rng.uniform(-3, 3, n - 1) if jitter else np.zeros(n - 1))
    t = np.concatenate([[0.0], np.cumsum(steps)])
    t[50:] += 200.0  # a gap of 20 steps
    u = 0.01 * t  # linear in time: interpolation is exact
    y = 3.0 + 0.002 * t
    path = tmp_path / name
    np.savetxt(path, np.column_stack([t, u, y]), delimiter="\t", fmt="%.10g")
    return path, t


def test_resampling_a_non_uniform_headerless_file(tmp_path):
    path, t = _stamped(tmp_path)
    raw = {
        "data": {
            "path": str(path),
            "header": False,
            "columns": ["t_ms", "u", "y"],
            "time_column": "t_ms",
            "time_unit": 0.001,
            "resample": 0.01,
            "input": ["u"],
            "output": ["y"],
        },
        "model": {"family": "narx"},
    }
    with pytest.warns(UserWarning, match="gap"):
        ds = load_dataset(make_spec(raw, tmp_path))
    assert ds.sampling_time == 0.01
    rec = ds.recordings[0]
    assert rec.n == int(np.floor(t[-1] / 10.0 + 1e-9)) + 1
    grid = np.arange(rec.n) * 10.0
    np.testing.assert_allclose(rec.u[:, 0], 0.01 * grid, atol=1e-9)
    np.testing.assert_allclose(rec.y[:, 0], 3.0 + 0.002 * grid, atol=1e-9)


def test_time_column_checks(tmp_path):
    path, _ = _stamped(tmp_path)
    raw = {
        "data": {
            "path": str(path),
            "header": False,
            "columns": ["t_ms", "u", "y"],
            "time_column": "t_ms",
            "time_unit": 0.001,
            "input": ["u"],
            "output": ["y"],
        },
        "model": {"family": "narx"},
    }
    # the rig's gap of 20 steps: samples missing, not a jitter to interpolate over
    with pytest.raises(DataError, match=r"jump by 0\.207232 s after t = 0\.492964 s \(sample 49; .*Fix: cut the file"):
        load_dataset(make_spec(raw, tmp_path))
    jitter = np.loadtxt(path)
    np.savetxt(path, np.vstack([jitter[:50], jitter[50:] - [200.0, 0, 0]]), delimiter="\t", fmt="%.10g")
    with pytest.raises(DataError, match="not uniform.*Fix: add 'resample: 0.0099"):
        load_dataset(make_spec(raw, tmp_path))
    uniform, _ = _stamped(tmp_path, "u.tsv", jitter=False)
    data = np.loadtxt(uniform)
    np.savetxt(uniform, np.vstack([data[:50], data[50:] - [200.0, 0, 0]]), delimiter="\t", fmt="%.10g")
    raw["data"]["path"] = str(uniform)
    assert load_dataset(make_spec(raw, tmp_path)).sampling_time == pytest.approx(0.01)
    gap = np.loadtxt(uniform)
    gap[300:, 0] += 500.0  # 50 samples missing after sample 299 (stamps in ms)
    np.savetxt(uniform, gap, delimiter="\t", fmt="%.10g")
    with pytest.raises(DataError, match=r"jump by 0\.51 s after t = .* \(sample 299; .*samples are missing.*Fix: cut"):
        load_dataset(make_spec(raw, tmp_path))
    n = len(gap)
    with pytest.raises(DataError, match=rf"data.segments: \[\[0, 300\], \[300, {n}\]\]\)"):
        load_dataset(make_spec(raw, tmp_path))
    # the segments the message proposes: two recordings, each uniform, at the file's sampling time
    cut = load_dataset(make_spec({**raw, "data": {**raw["data"], "segments": [[0, 300], [300, n]]}}, tmp_path))
    assert cut.sampling_time == pytest.approx(0.01) and [r.n for r in cut.recordings] == [300, n - 300]
    with pytest.raises(DataError, match=r"\[0:301\].*jump by 0\.51 s"):  # a segment across the gap
        load_dataset(make_spec({**raw, "data": {**raw["data"], "segments": [[0, 301], [301, n]]}}, tmp_path))
    back = np.loadtxt(uniform)
    back[300:, 0] -= 500.0
    back[10, 0] = back[8, 0]
    np.savetxt(uniform, back, delimiter="\t", fmt="%.10g")
    with pytest.raises(DataError, match="do not increase at sample 10.*Fix: sort the rows"):
        load_dataset(make_spec(raw, tmp_path))
    restart = np.loadtxt(uniform)
    restart[:, 0] = np.arange(len(restart)) * 10.0  # ms
    restart[200:, 0] -= restart[200, 0]  # a second run logged after the first, its clock from 0
    np.savetxt(uniform, restart, delimiter="\t", fmt="%.10g")
    n = len(restart)
    with pytest.raises(DataError, match=rf"clock restarts there.*data.segments: \[\[0, 200\], \[200, {n}\]\]"):
        load_dataset(make_spec(raw, tmp_path))
    runs = load_dataset(make_spec({**raw, "data": {**raw["data"], "segments": [[0, 200], [200, n]]}}, tmp_path))
    assert [r.n for r in runs.recordings] == [200, n - 200]
    raw["data"].pop("time_column")
    raw["data"]["resample"] = 0.01
    with pytest.raises(SpecError, match="resample needs the time stamps"):
        load_dataset(make_spec(raw, tmp_path))


@pytest.mark.parametrize(
    "column, unit", [("t_ms", "0.001"), ("time (ms)", "0.001"), ("Time [us]", "1e-6"), ("t_msec", "0.001")]
)
def test_a_time_column_named_in_milliseconds_needs_its_unit(tmp_path, column, unit):
    """Read as seconds, stamps in ms make resample: 0.01 a grid of 10 us (a 1000-fold upsampling)."""
    raw = {
        "data": {"path": "f.csv", "time_column": column, "resample": 0.01, "input": ["u"], "output": ["y"]},
        "model": {"family": "narx"},
    }
    with pytest.raises(SpecError, match=rf"'{re.escape(column)}' reads as .*add time_unit: {unit} "):
        make_spec(raw, tmp_path)
    make_spec({**raw, "data": {**raw["data"], "time_unit": 1}}, tmp_path)  # said explicitly: seconds
    make_spec({**raw, "data": {**raw["data"], "time_column": "t"}}, tmp_path)


def test_rounded_time_stamps_get_the_mean_step_as_resampling_grid():
    """Stamps rounded to 1 ms on a 3.3 ms period step by 3 or 4 ms, median 3 ms: resampling at the median (the
    advice) stretched the record by 10 %."""
    from dynmodel.data import resample

    t = np.round(np.arange(3000) * 0.0033, 3)
    with pytest.raises(DataError, match=r"add 'resample: 0\.00330\d*'"):
        resample.uniform(t, np.zeros((3000, 1)), None, "f.csv")


def test_a_gap_of_nan_outputs_can_be_cut_out_with_segments(tmp_path):
    """20 NaN outputs in a recording: refused (a fit would carry NaN), and the fix names the segments around them,
    which then load: only the samples the segments use must be finite (the whole file was checked)."""
    u = np.sin(np.arange(3000) * 0.05)
    y = np.roll(u, 1)
    y[1000:1020] = np.nan
    write_csv(tmp_path / "d.csv", {"u": u, "y": y})
    raw = {"data": {"path": "d.csv", "input": ["u"], "output": ["y"]}, "model": {"family": "narx"}}
    with pytest.raises(DataError, match=r"has NaN at sample 1000.*data.segments: \[\[0, 1000\], \[1020, 3000\]\]"):
        load_dataset(make_spec(raw, tmp_path))
    cut = {**raw, "data": {**raw["data"], "segments": [[0, 1000], [1020, 3000]]}}
    assert [r.n for r in load_dataset(make_spec(cut, tmp_path)).recordings] == [1000, 1980]
    across = {**raw, "data": {**raw["data"], "segments": [[0, 1010], [1020, 3000]]}}
    with pytest.raises(DataError, match="has NaN at sample 1000"):
        load_dataset(make_spec(across, tmp_path))


def test_an_input_quiet_in_the_training_split_is_noted(tmp_path):
    """A record excited only after its first 75 %: with the default split the training input barely moves."""
    rng = np.random.default_rng(0)
    u = np.concatenate([0.002 * rng.standard_normal(3000), rng.standard_normal(1000)])
    write_csv(tmp_path / "d.csv", {"u": u, "y": np.roll(u, 1)})
    raw = {"data": {"path": "d.csv", "input": ["u"], "output": ["y"]}, "model": {"family": "narx"}}
    (note,) = load_dataset(make_spec(raw, tmp_path)).training_input_notes()
    assert note.startswith("the input 'u' barely moves in the training split (std 0.002") and "data.split" in note
    excited = {**raw, "data": {**raw["data"], "split": {"train": [1000, 3800], "validation": [3800, 4000]}}}
    assert load_dataset(make_spec(excited, tmp_path)).training_input_notes() == []
    write_csv(tmp_path / "two.csv", {"u": u, "v": u.copy(), "y": np.roll(u, 1)})
    twice = {**excited, "data": {**excited["data"], "path": "two.csv", "input": ["u", "v"]}}
    (dup,) = load_dataset(make_spec(twice, tmp_path)).training_input_notes()
    assert dup.startswith("the input 'v' equals the input 'u' on every training sample")


def test_a_time_column_the_spec_does_not_use_is_noted(tmp_path):
    """A file with a column t in steps of 0.1 s, and no time_column: the sampling time silently stayed 1 s."""
    u = np.sin(np.arange(300) * 0.1)
    write_csv(tmp_path / "d.csv", {"t": np.arange(300) * 0.1, "u": u, "y": np.roll(u, 1)})
    raw = {"data": {"path": "d.csv", "input": ["u"], "output": ["y"]}, "model": {"family": "narx"}}
    with pytest.warns(DataNote, match=r"the column 't' steps by 0.1 but data.time_column is not set.*time_column: t"):
        assert load_dataset(make_spec(raw, tmp_path)).sampling_time == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataNote)
        named = load_dataset(make_spec({**raw, "data": {**raw["data"], "time_column": "t"}}, tmp_path))
        assert named.sampling_time == pytest.approx(0.1)
        load_dataset(make_spec({**raw, "data": {**raw["data"], "sampling_time": 0.1}}, tmp_path))


def test_validate_cli_shows_the_resampled_data(cli, tmp_path):
    path, _ = _stamped(tmp_path)
    spec = write_yaml(
        tmp_path / "s.yaml",
        {
            "data": {
                "path": path.name,
                "header": False,
                "columns": ["t_ms", "u", "y"],
                "time_column": "t_ms",
                "time_unit": 0.001,
                "resample": 0.01,
                "input": ["u"],
                "output": ["y"],
            },
            "model": {"family": "narx"},
        },
    )
    r = cli("validate", spec)
    assert r.exit_code == 0 and "sampling time 0.01" in r.stdout
