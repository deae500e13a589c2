"""Data sources, splits, transient, noise, delay lines, scaling and the family's view."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
from conftest import make_spec, narx, narx_spec, write_csv

from dynmodel.data import Preprocessor, delayed_copies, delayed_differences, load_dataset, training_data
from dynmodel.data.readers import read_columns
from dynmodel.errors import DataError


def _file_spec(path, **data):
    raw = {"data": {"path": str(path), "input": ["u"], "output": ["y"], **data}, "model": {"family": "esn"}}
    return make_spec(raw, path.parent)


@pytest.fixture
def columns():
    rng = np.random.default_rng(5)
    return {"u": rng.standard_normal(50), "y": rng.standard_normal(50), "q": rng.standard_normal(50)}


def test_every_format_reads_the_same_columns(tmp_path, columns):
    csv = write_csv(tmp_path / "d.csv", columns)
    np.savez(tmp_path / "d.npz", **columns)
    with h5py.File(tmp_path / "d.h5", "w") as f:
        for k, v in columns.items():
            f.create_dataset(f"g/{k}", data=v)
    scipy.io.savemat(tmp_path / "d.mat", {k: v[:, None] for k, v in columns.items()})
    ref = read_columns(csv, ["u", "y"])
    for path, sel in [
        (tmp_path / "d.npz", ["u", "y"]),
        (tmp_path / "d.h5", ["g/u", "g/y"]),
        (tmp_path / "d.mat", ["u", "y"]),
    ]:
        got = read_columns(path, sel)
        np.testing.assert_array_equal(got[sel[0]], ref["u"])
        np.testing.assert_array_equal(got[sel[1]], ref["y"])


def test_headerless_tab_separated_text_with_column_names(tmp_path, columns):
    path = tmp_path / "rig.txt"
    np.savetxt(path, np.column_stack([columns["u"], columns["y"]]), delimiter="\t", fmt="%.17g")
    got = read_columns(path, ["pos", "force"], header=False, columns=["pos", "force"])
    np.testing.assert_array_equal(got["force"], columns["y"])
    got = read_columns(path, [1], header=False)
    np.testing.assert_array_equal(got["1"], columns["y"])


def test_two_dimensional_arrays_pick_columns(tmp_path):
    a = np.arange(20.0).reshape(10, 2)
    np.savez(tmp_path / "m.npz", a=a)
    np.testing.assert_array_equal(read_columns(tmp_path / "m.npz", ["a[1]"])["a[1]"], a[:, 1])
    with pytest.raises(DataError, match="shape"):
        read_columns(tmp_path / "m.npz", ["a"])


def test_missing_column_lists_the_available_ones(tmp_path, columns):
    csv = write_csv(tmp_path / "d.csv", columns)
    with pytest.raises(DataError) as info:
        load_dataset(_file_spec(csv, input=["x"]))
    assert "no column 'x'" in str(info.value) and "u, y, q" in str(info.value) and "d.csv" in str(info.value)


def test_nan_and_inf_are_located(tmp_path, columns):
    columns["y"][17] = np.nan
    columns["y"][30] = np.inf
    csv = write_csv(tmp_path / "d.csv", columns)
    with pytest.raises(DataError) as info:
        load_dataset(_file_spec(csv))
    assert "column 'y' has NaN at sample 17 (2 non-finite values" in str(info.value)


def test_empty_cells_empty_files_and_folders_are_named(tmp_path):
    (tmp_path / "gap.csv").write_text("u,y\n1,2\n3,\n")
    with pytest.raises(DataError, match="column 'y' has no value at line 3 \\(sample 1\\)"):
        read_columns(tmp_path / "gap.csv", ["u", "y"])
    (tmp_path / "head.csv").write_text("u,y\n")
    with pytest.raises(DataError, match="header row but no samples"):
        read_columns(tmp_path / "head.csv", ["u", "y"])
    (tmp_path / "folder.csv").mkdir()
    with pytest.raises(DataError, match="is not a file"):
        read_columns(tmp_path / "folder.csv", ["u"])


def test_an_empty_cell_of_a_specs_data_is_a_gap_as_the_text_nan_is(tmp_path, columns):
    """pandas writes a missing value as an empty cell: in a spec's data it reads as NaN, so a training gap gets
    the advice a 'NaN' does (data.segments around it) and a test output gap is left out of the score, instead of
    a refusal that asks to remove the line (which would join the two sides of the gap)."""
    u, y = columns["u"], columns["y"]

    def write(name: str, gap: str, rows: slice, column: str) -> Path:
        lines = ["u,y"]
        for i in range(len(u)):
            cells = [repr(float(u[i])), repr(float(y[i]))]
            if i in range(len(u))[rows]:
                cells[["u", "y"].index(column)] = gap
            lines.append(",".join(cells))
        (tmp_path / name).write_text("\n".join(lines) + "\n")
        return tmp_path / name

    messages = []
    for gap in ("", "NaN"):
        with pytest.raises(DataError) as info:
            load_dataset(_file_spec(write(f"train{gap}.csv", gap, slice(20, 25), "u")))
        messages.append(str(info.value).replace(f"train{gap}.csv", "train.csv"))
    assert messages[0] == messages[1]
    assert "column 'u' has NaN at sample 20 (5 non-finite values" in messages[0]
    assert "data.segments: [[0, 20], [25, 50]]" in messages[0]
    clean = write_csv(tmp_path / "clean.csv", {"u": u, "y": y})
    tested = []
    for gap in ("", "NaN"):
        test = write(f"test{gap}.csv", gap, slice(30, 40), "y")
        ds = load_dataset(_file_spec(clean, split={"train": 0.8, "validation": 0.2}, test={"path": test.name}))
        tested.append(ds.concat_outputs("test")[:, 0])
    np.testing.assert_array_equal(tested[0], tested[1])
    assert np.isnan(tested[0]).sum() == 10


def test_text_cell_that_is_not_a_number(tmp_path):
    (tmp_path / "d.csv").write_text("u,y\n1,2\n3,abc\n")
    with pytest.raises(DataError, match="'abc' at line 3"):
        read_columns(tmp_path / "d.csv", ["u", "y"])
    # a logger's date-and-time stamps are named as such, with how to give the time instead
    (tmp_path / "t.csv").write_text("time,u,y\n2024-01-01 00:00:00.000000,1,2\n2024-01-01 00:00:00.010000,3,4\n")
    with pytest.raises(DataError) as info:
        read_columns(tmp_path / "t.csv", ["time", "u", "y"])
    assert "holds the date and time '2024-01-01 00:00:00.000000' at line 2" in str(info.value)
    assert "seconds since the start" in str(info.value) and "header: false" not in str(info.value)
    # the line of the file, whatever comment and blank lines come before it
    (tmp_path / "e.csv").write_text("# rig 7\nu,y\n\n1,2\n# pause\n3,abc\n")
    with pytest.raises(DataError, match="'abc' at line 6"):
        read_columns(tmp_path / "e.csv", ["u", "y"])


def test_fraction_and_range_splits_with_transient():
    spec = make_spec(narx_spec(n=1000, test_n=500, split={"train": 0.7, "validation": 0.3}, transient=100))
    ds = load_dataset(spec)
    assert ds.ranges["train"] == [(0, 0, 700)] and ds.ranges["validation"] == [(0, 700, 1000)]
    assert ds.ranges["test"] == [(1, 0, 500)]
    assert ds.scored("validation") == [(0, 800, 1000)] and ds.n_scored("test") == 400
    raw = narx_spec(n=2000, split={"train": [0, 800], "validation": [800, 1000], "test": [1000, 2000]}, transient=50)
    raw["data"].pop("test")
    ds = load_dataset(make_spec(raw))
    assert [ds.scored(s) for s in ("train", "validation", "test")] == [
        [(0, 50, 800)],
        [(0, 850, 1000)],
        [(0, 1050, 2000)],
    ]


def test_too_little_data_for_the_split_or_the_transient():
    raw = narx_spec(n=5000, split={"train": [0, 4000], "test": [4000, 6000]})
    raw["data"].pop("test")
    with pytest.raises(DataError, match="needs 6000 samples but recording 'narx-system\\(seed=1\\)' has 5000"):
        load_dataset(make_spec(raw))
    with pytest.raises(DataError, match="no sample left after the transient of 2000"):
        load_dataset(make_spec(narx_spec(n=5000, test_n=1500, transient=2000)))


def test_noise_is_added_only_to_the_chosen_splits():
    clean = load_dataset(make_spec(narx_spec(n=20000, split={"train": 0.5, "validation": 0.5})))
    noisy = load_dataset(make_spec(narx_spec(n=20000, split={"train": 0.5, "validation": 0.5}, noise=0.4)))
    train_diff = noisy.recordings[0].y[:10000] - clean.recordings[0].y[:10000]
    assert abs(train_diff.std() / clean.recordings[0].y.std() - 0.4) < 0.01
    np.testing.assert_array_equal(noisy.recordings[1].y, clean.recordings[1].y)  # the test recording stays clean
    only_train = narx_spec(n=20000, split={"train": 0.5, "validation": 0.5}, noise=0.4)
    only_train["data"]["noise"]["splits"] = ["train"]
    ds = load_dataset(make_spec(only_train))
    np.testing.assert_array_equal(ds.recordings[0].y[10000:], clean.recordings[0].y[10000:])


def test_delay_lines_hold_the_first_value():
    u = np.arange(1.0, 7.0)[:, None]
    out = delayed_copies(u, [2, 4])
    np.testing.assert_array_equal(out[:, 1], [1, 1, 1, 2, 3, 4])
    np.testing.assert_array_equal(out[:, 2], [1, 1, 1, 1, 1, 2])


def test_delay_lines_as_differences():
    u = np.arange(1.0, 7.0)[:, None] ** 2
    out = delayed_differences(u, [2])
    np.testing.assert_array_equal(out[:, 0], u[:, 0])
    np.testing.assert_array_equal(out[:, 1], [0, 3, 8, 12, 16, 20])  # u(t) - u(t - 2), u(t < 0) = u(0)


def test_difference_form_is_level_invariant_scaled_and_stored(tmp_path):
    """delay_form: difference gives u~d = (u(t) - u(t - d)) / std on training: shifting the input
    by a constant changes only the undelayed channel; the scale and form survive the model file."""
    raw = narx_spec(n=3000, split={"train": 0.7, "validation": 0.3}, transient=0, scaling="standard", size=30)
    raw["data"].update(delay_lines=[5, 50], delay_form="difference")
    spec = make_spec(raw)
    ds = load_dataset(spec)
    pre = Preprocessor.fit(ds, [5, 50], "standard", delay_form="difference")
    assert pre.model_input_names == ["u", "u~5", "u~50"]
    u = ds.recordings[0].u
    v = pre.inputs(u)
    train = v[:2100]
    assert np.allclose(train[:, 1:].std(axis=0), 1.0, atol=1e-12)
    np.testing.assert_allclose(
        v[:, 2] * pre.difference_scale[1] * pre.input_scale[0],
        u[:, 0] - np.concatenate([np.full(50, u[0, 0]), u[:-50, 0]]),
        atol=1e-12,
    )
    np.testing.assert_allclose(pre.inputs(u + 7.0)[:, 1:], v[:, 1:], atol=1e-9)
    from dynmodel import engine, store

    model = engine.fit(spec)
    assert model.preprocessor.delay_form == "difference"
    store.save(model, tmp_path / "m.h5")
    back = store.load(tmp_path / "m.h5")
    assert back.preprocessor.delay_form == "difference"
    np.testing.assert_array_equal(back.preprocessor.difference_scale, model.preprocessor.difference_scale)
    np.testing.assert_allclose(back.predict(u[:500]), model.predict(u[:500]), rtol=1e-12)


def test_scaling_uses_training_statistics_and_hides_test_outputs():
    raw = narx_spec(
        n=3000,
        split={"train": [0, 1000], "test": [1000, 2000], "validation": [2000, 3000]},
        transient=0,
        scaling="standard",
    )
    raw["data"].pop("test")
    raw["data"]["delay_lines"] = [3]
    ds = load_dataset(make_spec(raw))
    pre = Preprocessor.fit(ds, [3], "standard")
    y = ds.recordings[0].y
    assert np.allclose(pre.output_offset, y[:1000].mean(axis=0)) and np.allclose(pre.output_scale, y[:1000].std(axis=0))
    td = training_data(ds, pre)
    assert td.input_names == ["u", "u@3"] and td.series[0].u.shape == (3000, 2)
    assert np.isnan(td.series[0].y[1000:2000]).all() and np.isfinite(td.series[0].y[:1000]).all()
    assert np.isfinite(td.targets("validation")).all()


def test_several_recordings_keep_their_own_starts(tmp_path):
    u1, y1 = narx(3000, 1)
    u2, y2 = narx(2000, 2)
    write_csv(tmp_path / "a.csv", {"u": u1, "y": y1})
    write_csv(tmp_path / "b.csv", {"u": u2, "y": y2})
    raw = {
        "data": {
            "path": ["a.csv", "b.csv"],
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 0.5, "validation": 0.5},
            "transient": 100,
        },
        "model": {"family": "esn"},
    }
    ds = load_dataset(make_spec(raw, tmp_path))
    assert [r.name for r in ds.recordings] == ["a.csv", "b.csv"]
    assert ds.scored("train") == [(0, 100, 1500), (1, 100, 1000)]
    assert ds.scored("validation") == [(0, 1600, 3000), (1, 1100, 2000)]
    raw["data"] = {**raw["data"], "path": "a.csv", "segments": [[0, 1000], [1000, 3000]]}
    ds = load_dataset(make_spec(raw, tmp_path))
    assert [r.n for r in ds.recordings] == [1000, 2000]


def test_training_data_converts_physical_output_values_to_model_space(tmp_path):
    u, y = narx(2000, 4)
    path = write_csv(tmp_path / "d.csv", {"u": u, "y": 50 + 3 * y})
    ds = load_dataset(_file_spec(path))
    pre = Preprocessor.fit(ds, [], "standard")
    td = training_data(ds, pre)
    values = np.array([40.0, 60.0])
    np.testing.assert_allclose(td.to_model_outputs(values[:, None])[:, 0], pre.outputs(values[:, None])[:, 0])
    np.testing.assert_allclose(pre.physical_outputs(td.to_model_outputs(values[:, None])), values[:, None])


def test_inputs_beyond_the_training_range_are_named_with_split_sample_and_excess():
    from dynmodel.data.dataset import Dataset, Recording

    u = np.sin(np.linspace(0, 20, 1000))[:, None]
    u[900] = 1.5  # the test split goes half the training width (2) beyond its top (1)
    rec = Recording("r.csv", u, np.zeros((1000, 1)))
    ds = Dataset(
        [rec], {"train": [(0, 0, 600)], "validation": [(0, 600, 800)], "test": [(0, 800, 1000)]}, 0, ["u"], ["y"], 1.0
    )
    found = ds.input_excursions()
    assert len(found) == 1 and found[0]["split"] == "test" and found[0]["sample"] == 900
    assert found[0]["excess"] == pytest.approx(0.25, abs=0.01)  # 0.5 over a training width of about 2
    assert "leaves the training range by 25 %" in ds.excursion_notes()[0]
    u[900] = 0.5
    assert ds.input_excursions() == []


def test_a_header_written_as_a_comment_by_numpy_savetxt_is_read(tmp_path):
    """numpy.savetxt(header='t,u,y') writes '# t,u,y' above the numbers: the names are taken from it."""
    data = np.column_stack([np.arange(5.0), np.linspace(0, 1, 5), np.linspace(1, 2, 5)])
    np.savetxt(tmp_path / "a.csv", data, delimiter=",", header="t,u,y")
    np.savetxt(tmp_path / "b.txt", data, header="t u y")
    for name in ("a.csv", "b.txt"):
        with pytest.warns(UserWarning, match="column names are read from the comment line"):
            cols = read_columns(tmp_path / name, ["u", "y"])
        np.testing.assert_array_equal(cols["y"], data[:, 2])


def test_decimal_commas_under_unnamed_header_columns_are_refused(tmp_path):
    """'t,position,force,,,' over rows '0,004,1,5,2,25': decimal commas split every number in two; the values
    land under the unnamed columns, and reading the named ones would take the fractions for numbers."""
    (tmp_path / "d.csv").write_text("t,position,force,,,\n0,000,1,5,2,25\n0,004,1,6,2,75\n")
    with pytest.raises(DataError, match="rows hold values under the unnamed ones.*decimal commas"):
        read_columns(tmp_path / "d.csv", ["position"])
    (tmp_path / "e.csv").write_text("t,position,force,,\n0,1.5,2.5,,\n1,1.6,2.75,,\n")  # empty trailing columns
    assert read_columns(tmp_path / "e.csv", ["force"])["force"].tolist() == [2.5, 2.75]
