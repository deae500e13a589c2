"""Issue 15 below the command line: output paths, model-file writes, one place for errors, data
checks, encodings, the divergence band for every family, usefulness notes, predict's table."""

from __future__ import annotations

import errno
import json
import os
import warnings
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from bad_inputs import base_spec, csv_text, write_csv
from conftest import make_spec, narx

from dynmodel import engine, paths, store
from dynmodel.data import load_dataset
from dynmodel.data.readers import read_columns
from dynmodel.errors import DataError, Interrupted, OutputError
from dynmodel.explain import explain, internal_error_line
from dynmodel.model import band_check
from dynmodel.textfiles import DataNote, decode_text
from dynmodel.usefulness import (
    assess,
    carry_over,
    held_out_splits,
    input_dependence,
    search_validation,
    stability_fix,
    summary_line,
)


def _spec(folder, **data):
    return make_spec(base_spec(**data), folder)


@pytest.fixture
def folder(tmp_path):
    u, y = narx(600, 1)
    write_csv(tmp_path / "run.csv", {"t": np.arange(600.0), "u": u, "y": y})
    return tmp_path


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("fitted")
    u, y = narx(600, 1)
    write_csv(d / "run.csv", {"t": np.arange(600.0), "u": u, "y": y})
    spec = make_spec(base_spec(), d)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    return model, ds, runs, d


# ---------------------------------------------------------------- paths


def test_output_checks_name_each_problem(folder):
    data = folder / "run.csv"
    with pytest.raises(OutputError, match="data file the command reads"):
        paths.check_output(data, "model", {"data file": [data]}, option="--out")
    with pytest.raises(OutputError, match="is a folder"):
        paths.check_output(folder, "model")
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="a model replaces only a model"):
        paths.check_output(folder / "notes.txt", "model", force=True)
    with pytest.raises(OutputError, match="add --force"):
        paths.check_output(folder / "notes.txt", "json")
    assert paths.check_output(folder / "notes.txt", "json", force=True) == folder / "notes.txt"
    with pytest.raises(OutputError, match="'.*run.csv' is a file"):
        paths.check_output(data / "m.h5", "model")
    with pytest.raises(OutputError, match="the file system allows 255"):
        paths.check_output(folder / ("y" * 300 + ".h5"), "model")
    with pytest.raises(OutputError, match="not a figure format"):
        paths.check_output(folder / "plot.txt", "plot")
    with pytest.raises(OutputError, match="cannot create files in '/proc'"):
        paths.check_output("/proc/m.h5", "model")
    assert paths.check_output(folder / "new" / "deeper" / "m.h5", "model") == folder / "new" / "deeper" / "m.h5"
    assert not (folder / "new").exists()  # checking creates nothing
    with pytest.raises(OutputError, match="--out and --json name the same file"):
        paths.check_outputs([(folder / "a.h5", "model", "--out"), (folder / "a.h5", "json", "--json")])


def test_previous_outputs_of_the_same_kind_are_replaced_without_force(folder, fitted):
    model = fitted[0]
    store.save(model, folder / "m.h5")
    paths.check_output(folder / "m.h5", "model")
    (folder / "s.json").write_text(json.dumps({"metrics": {}, "model": "m.h5"}))
    paths.check_output(folder / "s.json", "json")
    (folder / "p.csv").write_text("t,y,measured\n0,1,1\n")
    paths.check_output(folder / "p.csv", "csv", columns=[["t", "y", "measured"], ["t", "y"]])
    with pytest.raises(OutputError, match="--force"):
        paths.check_output(folder / "p.csv", "csv", columns=["t", "y"])
    with pytest.raises(OutputError, match="replaces a CSV file only when asked"):
        paths.check_output(folder / "run.csv", "csv")  # generate: never without --force
    from dynmodel.plots import recording

    recording(folder / "r.png", np.arange(5.0), np.zeros((5, 1)), np.zeros((5, 1)), ["u"], ["y"], "r")
    paths.check_output(folder / "r.png", "plot")
    (folder / "photo.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)
    with pytest.raises(OutputError, match="a PNG image, not a plot dynmodel wrote"):
        paths.check_output(folder / "photo.png", "plot")


def test_report_folders(folder):
    paths.check_output(folder / "fresh", "report")
    (folder / "empty").mkdir()
    paths.check_output(folder / "empty", "report")
    (folder / "old").mkdir()
    (folder / "old" / "index.md").write_text("# Diagnosis of `x`\n")
    paths.check_output(folder / "old", "report")
    with pytest.raises(OutputError, match="not a diagnosis report"):
        paths.check_output(folder, "report")
    with pytest.raises(OutputError, match="the report needs a folder"):
        paths.check_output(folder / "run.csv", "report")
    # a summary inside the report folder would be replaced by the report's own index.md, or replace it
    for inside in ("old/index.md", "old/sub/summary.json"):
        with pytest.raises(OutputError, match="--json lies inside the report folder of --report"):
            paths.check_outputs([(folder / "old", "report", "--report"), (folder / inside, "json", "--json")])
    paths.check_outputs([(folder / "old", "report", "--report"), (folder / "summary.json", "json", "--json")])


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_and_file(folder):
    (folder / "ro").mkdir()
    (folder / "ro").chmod(0o555)
    try:
        with pytest.raises(OutputError, match="permission denied"):
            paths.check_output(folder / "ro" / "m.h5", "model")
    finally:
        (folder / "ro").chmod(0o755)
    (folder / "locked.json").write_text("{}")
    (folder / "locked.json").chmod(0o444)
    with pytest.raises(OutputError, match="read-only"):
        paths.check_output(folder / "locked.json", "json", force=True)


def test_spec_inputs_and_safe_names(folder):
    (folder / "test.csv").write_text((folder / "run.csv").read_text())
    spec = _spec(folder, split={"train": 0.7, "validation": 0.3}, test={"path": "test.csv"})
    roles = paths.spec_inputs(spec, folder / "s.yaml")
    assert roles["spec"] == [folder / "s.yaml"]
    assert sorted(p.name for p in roles["data file"]) == ["run.csv", "test.csv"]
    # inputs and outputs in files of their own, and a benchmark's folder: every file is an input
    u, y = narx(200, 1)
    write_csv(folder / "in.csv", {"t": np.arange(200.0), "u": u})
    write_csv(folder / "out.csv", {"t": np.arange(200.0), "y": y})
    pair = _spec(folder, path={"input": "in.csv", "output": "out.csv"}, time_column="t")
    assert sorted(p.name for p in paths.spec_inputs(pair)["data file"]) == ["in.csv", "out.csv"]
    with pytest.raises(OutputError, match="this is the data file the command reads"):
        paths.check_output(folder / "out.csv", "json", paths.spec_inputs(pair), force=True)
    assert paths.safe_name("x" * 300) == "x" * 80
    assert paths.safe_name("my model/v2: µ") == "my-model-v2"
    assert paths.safe_name("///") == "model"


# ---------------------------------------------------------------- model files


def test_model_files_follow_the_umask_and_stale_temporaries_go(folder, fitted):
    model = fitted[0]
    old = os.umask(0o027)
    try:
        store.save(model, folder / "m.h5")
    finally:
        os.umask(old)
    assert (folder / "m.h5").stat().st_mode & 0o777 == 0o640
    store.save(model, folder / "n.h5")
    assert (folder / "n.h5").stat().st_mode & 0o777 == 0o666 & ~old
    host = store._host()
    alive = folder / f".m.h5.{os.getpid()}@{host}.aaaa.tmp"  # a write in progress (this process)
    dead = folder / f".m.h5.4194000@{host}.bbbb.tmp"
    recent = folder / ".m.h5.cccc.tmp"  # unknown writer, recent: may still be writing
    ancient = folder / ".m.h5.dddd.tmp"
    for p in (alive, dead, recent, ancient):
        p.write_bytes(b"partial")
    os.utime(ancient, (1e9, 1e9))
    if _alive(4194000):
        pytest.skip("pid 4194000 is running")
    store.save(model, folder / "m.h5")
    assert alive.exists() and recent.exists() and not dead.exists() and not ancient.exists()
    assert store.load(folder / "m.h5").metrics == model.metrics


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


# ---------------------------------------------------------------- one place for errors


def test_explain_maps_expected_failures_and_leaves_bugs():
    full = explain(OSError(errno.ENOSPC, "No space left on device", "/data/m.h5"))
    assert (
        full.line()
        == "/data/m.h5: cannot access the file: no space left on the device. Fix: free some space or write to another disk"
    )
    assert isinstance(explain(KeyboardInterrupt()), Interrupted) and explain(KeyboardInterrupt()).exit_code == 130
    assert "not enough memory" in explain(MemoryError()).line()
    assert explain(ValueError("index out of range")) is None
    assert explain(ZeroDivisionError()) is None
    assert "a bug in dynmodel" in internal_error_line(KeyError("x"))


def test_cli_interrupt_and_bug_lines(cli, folder, monkeypatch):
    from dynmodel import engine as eng

    def stop(*a, **k):
        raise KeyboardInterrupt

    (folder / "s.yaml").write_text(json.dumps(base_spec()))
    monkeypatch.chdir(folder)
    monkeypatch.setattr(eng, "fit_dataset", stop)
    r = cli("fit", "s.yaml")
    assert r.exit_code == 130 and r.stderr.strip() == (
        "error: interrupted (Ctrl-C). Fix: rerun the command; files are written only when it completes"
    )
    assert not (folder / "m.h5").exists()

    def bug(*a, **k):
        raise IndexError("list index out of range")

    monkeypatch.setattr(eng, "fit_dataset", bug)
    r = cli("fit", "s.yaml")
    assert r.exit_code == 3 and r.stderr.startswith("internal error: IndexError") and len(r.stderr.splitlines()) == 1


def test_an_interrupted_annealing_says_so(monkeypatch):
    from dynmodel_plugins.annealed_rnn import search

    calls = {"n": 0}
    original = search.Evaluator.score

    def score(self, state):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return original(self, state)

    monkeypatch.setattr(search.Evaluator, "score", score)
    raw = {
        "data": {"generator": "narx-system", "n": 400, "split": {"train": 0.7, "validation": 0.3}, "transient": 20},
        "model": {"family": "annealed-rnn", "params": {"size": 5, "steps": 30, "workers": 1}},
    }
    with pytest.warns(UserWarning, match="annealing was interrupted \\(Ctrl-C\\): the model keeps the best network"):
        model = engine.fit(make_spec(raw))
    assert model.family.search_["interrupted"]


# ---------------------------------------------------------------- encodings and formats


@pytest.mark.parametrize("encoding", ["utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-16-be", "latin-1"])
def test_text_encodings(tmp_path, encoding):
    u, y = narx(50, 2)
    text = csv_text({"u": u, "y": y, "Temp_°C": np.zeros(50)}, sep="\t")
    (tmp_path / "d.csv").write_bytes(text.encode(encoding))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cols = read_columns(tmp_path / "d.csv", ["u", "y", "Temp_°C"])
    np.testing.assert_allclose(cols["y"], y, rtol=1e-9)
    notes = [str(w.message) for w in caught if issubclass(w.category, DataNote)]
    assert notes == (
        ["%s: not valid UTF-8, read as Latin-1 (check accented column names; save as UTF-8)" % (tmp_path / "d.csv")]
        if encoding == "latin-1"
        else []
    )


def test_binary_content_is_named():
    with pytest.raises(DataError, match="not a text file: it looks like a gzip-compressed file"):
        decode_text(b"\x1f\x8b\x08\x00" + bytes(range(256)), "d.csv")


def test_content_decides_the_format(tmp_path):
    u, y = narx(40, 3)
    with h5py.File(tmp_path / "d.csv", "w") as f:
        f["u"], f["y"] = u, y
    with pytest.warns(DataNote, match="named .csv but holds an HDF5 file"):
        np.testing.assert_array_equal(read_columns(tmp_path / "d.csv", ["y"])["y"], y)
    write_csv(tmp_path / "d.h5", {"u": u, "y": y})
    with pytest.warns(DataNote, match="named .h5 but holds text"):
        np.testing.assert_allclose(read_columns(tmp_path / "d.h5", ["u"])["u"], u, rtol=1e-9)
    np.savez(tmp_path / "o.npz", u=np.array([1, None], dtype=object))
    with pytest.raises(DataError, match="'u' is an object array") as info:
        read_columns(tmp_path / "o.npz", ["u"])
    assert "allow_pickle" not in str(info.value)


def test_decimal_commas(tmp_path):
    u, y = narx(30, 4)
    write_csv(tmp_path / "semi.csv", {"u": u, "y": y}, sep=";", decimal=",")
    with pytest.warns(DataNote, match="decimal commas read as decimal points"):
        np.testing.assert_allclose(read_columns(tmp_path / "semi.csv", ["y"])["y"], y, rtol=1e-9)
    write_csv(tmp_path / "comma.csv", {"u": u, "y": y}, sep=",", decimal=",")
    with pytest.raises(DataError, match="decimal commas with comma separators"):
        read_columns(tmp_path / "comma.csv", ["u", "y"])
    # quoted, a decimal comma is unambiguous beside comma separators (a spreadsheet's CSV export)
    quoted = "".join(f'"{a!r}","{b!r}"\n'.replace(".", ",") for a, b in zip(u.tolist(), y.tolist()))
    (tmp_path / "quoted.csv").write_text("u,y\n" + quoted)
    with pytest.warns(DataNote, match="decimal commas read as decimal points"):
        np.testing.assert_array_equal(read_columns(tmp_path / "quoted.csv", ["y"])["y"], y)


def test_a_units_row_under_the_header_is_skipped_and_said(tmp_path):
    """Lab exports often put the units under the names (s, mm, N): they are no sample."""
    u, y = narx(30, 4)
    rows = "".join(f"{i * 0.01:.2f};{float(a)!r};{float(b)!r}\n" for i, (a, b) in enumerate(zip(u, y)))
    (tmp_path / "units.csv").write_text("t;u;y\n[s];[mm];[N]\n" + rows + "0.30;1.0;oops\n")
    with pytest.warns(DataNote, match=r"line 2 \(\[s\], \[mm\], \[N\]\) holds no number: read as the columns' units"):
        got = read_columns(tmp_path / "units.csv", ["u"])
    np.testing.assert_array_equal(got["u"][:30], u)
    with pytest.raises(DataError, match="'oops' at line 33"), warnings.catch_warnings():  # the file's own line
        warnings.simplefilter("ignore")
        read_columns(tmp_path / "units.csv", ["y"])
    (tmp_path / "text.csv").write_text("t;u;y\n0;a;b\n1;2;3\n")  # a number in the row: not units
    with pytest.raises(DataError, match="'a' at line 2"):
        read_columns(tmp_path / "text.csv", ["u"])


# ---------------------------------------------------------------- data checks


@pytest.mark.parametrize(
    "change, message",
    [
        (
            lambda d: d.__setitem__("y", np.full(600, 2.5)),
            "output 'y' is constant \\(2.5\\) on every scored sample of the train split",
        ),
        (
            lambda d: d["y"].__setitem__(slice(480, None), 1.0),
            "constant \\(1\\) on every scored sample of the test split",
        ),
        (lambda d: d.__setitem__("u", np.ones(600)), "input 'u' is constant \\(1\\) on every training sample"),
        (lambda d: d["y"].__setitem__(77, 1e300), "'y' holds 1e\\+300 at sample 77 of 'run.csv', too large"),
        (
            lambda d: d.__setitem__("y", d["y"] * np.exp(np.linspace(0, 101, 600))),
            "reaches -2.11e\\+44 at sample 599 of 'run.csv'",
        ),
        (lambda d: d.__setitem__("y", d["u"].copy()), "input 'u' and output 'y' hold identical values"),
    ],
)
def test_data_no_model_can_use_is_one_line_at_load(folder, change, message):
    u, y = narx(600, 1)
    d = {"t": np.arange(600.0), "u": u, "y": y}
    change(d)
    write_csv(folder / "run.csv", d)
    with pytest.raises(DataError, match=message):
        load_dataset(_spec(folder))


def test_a_tune_in_longer_than_a_split(folder):
    raw = base_spec(split={"train": 0.5, "validation": 0.5})
    raw["model"]["params"] = {"size": 10, "mode": "external", "tune_in": 700}
    spec = make_spec(raw, folder)
    with pytest.raises(DataError, match="tunes in on the first 700 samples .* no scored sample in the train split"):
        engine.check_plan(spec, load_dataset(spec))


def test_segments_are_described_with_file_indices_and_test_columns_by_their_own_name(folder):
    spec = _spec(folder, segments=[[100, 600]], split={"train": 0.5, "validation": 0.5})
    from dynmodel.data import describe

    rows = {r["split"]: r["segments"] for r in describe(load_dataset(spec))}
    assert rows == {"train": ["run.csv[100:350]"], "validation": ["run.csv[350:600]"]}
    u, y = narx(300, 9)
    u[150] = 10 * np.abs(u).max()
    write_csv(folder / "bench.csv", {"force_cmd": u, "pos": y})
    spec = _spec(
        folder,
        split={"train": 0.7, "validation": 0.3},
        test={"path": "bench.csv", "input": ["force_cmd"], "output": ["pos"]},
    )
    notes = [n for n in load_dataset(spec).excursion_notes() if n.startswith("the test input")]
    assert len(notes) == 1 and notes[0].startswith("the test input 'force_cmd' leaves the training range")


# ---------------------------------------------------------------- divergence band and usefulness


def test_band_check_cuts_after_tune_in():
    y = np.array([[1e9], [0.0], [0.5], [50.0], [0.1]])
    out, k = band_check(y, (np.array([-10.0]), np.array([10.0])), None, start=1)
    assert k == 3 and np.isnan(out[3:]).all() and out[2, 0] == 0.5
    assert band_check(y[1:3], (np.array([-10.0]), np.array([10.0])))[1] is None
    assert band_check(y, None, 2, start=1)[1] == 2


def test_usefulness_of_a_good_and_of_a_useless_model(fitted, folder):
    model, ds, runs, _ = fitted
    assert assess(model, ds, runs) == []
    assert input_dependence(model, ds, runs=runs) > 0.5
    rng = np.random.default_rng(3)
    write_csv(folder / "noise.csv", {"u": rng.standard_normal(600), "y": rng.standard_normal(600)})
    spec = make_spec(base_spec("noise.csv"), folder)
    ds2 = load_dataset(spec)
    useless, runs2 = engine.fit_dataset(spec, ds2)
    notes = assess(useless, ds2, runs2)
    assert {n.kind for n in notes} >= {"poor"} and all(
        n.split in ("validation", "test") for n in notes if n.kind == "poor"
    )
    line = summary_line(notes, "s.yaml", "mse1")
    assert (
        line.startswith("this model is of little use: its free-run NMSE is")
        and "Fix: try `dynmodel diagnose s.yaml`" in line
    )
    assert "cost: mse_inf" in line and "cost: mse_inf" not in summary_line(notes, "s.yaml", "mse_inf")


def test_a_validation_split_where_the_rig_stands_idle_is_not_called_useless(folder):
    """The input held at 0 over the validation split (a rig left idle at the end of the recording): its output is
    the sensor noise alone (3 % of the training output's standard deviation), so a good model's free run scores
    about 100 % NMSE there. Judged against the training output's variance it is fine, and `fit` says the split
    tells little instead of calling the model useless; a model as far off on the training output's scale is
    still poor."""
    from dynmodel.usefulness import CARRY_OVER_FACTOR, CARRY_OVER_FLOOR, QUIET_FIX, _quiet

    rng = np.random.default_rng(4)
    u = rng.standard_normal(3000)
    u[2300:] = 0.0  # idle from 100 samples before the validation split: its output has settled
    y = np.zeros(3000)
    for t in range(1, 3000):
        y[t] = 0.8 * y[t - 1] + 0.3 * np.tanh(u[t - 1])
    y += 0.01 * rng.standard_normal(3000)
    write_csv(folder / "idle.csv", {"u": u, "y": y})
    raw = {
        "data": {"path": "idle.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.8, "validation": 0.2}},
        "model": {"family": "narx", "params": {"terms": ["1", "y[t-1]", "u[t-1]", "u[t-1]^3"]}},
    }
    spec = make_spec(raw, folder)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    assert model.metrics["train"]["nmse"] < 5.0 and model.metrics["validation"]["nmse"] > 90.0
    notes = assess(model, ds, runs)
    assert [n.kind for n in notes] == ["quiet"]
    assert notes[0].value < 1.0  # percent of the training output's variance
    line = summary_line(notes, "s.yaml", "mse1")
    assert "validation split's output barely moves" in line and line.endswith(QUIET_FIX)
    assert "of little use" not in line
    # the narx default's terms chosen on that validation: a constant predicts its noise as well as any model,
    # so no input term is kept; measured on the training split instead, the model is said to ignore its input
    raw["model"] = {"family": "narx", "params": {"lags": {"u": [1], "y": [1]}, "degree": 3}}
    spec = make_spec(raw, folder)
    with pytest.warns(UserWarning, match="no kept term depends on an input"):
        model, runs = engine.fit_dataset(spec, ds)
    notes = assess(model, ds, runs)
    assert [(n.kind, n.split) for n in notes] == [("quiet", "validation"), ("ignores-input", "train")]
    line = summary_line(notes, "s.yaml", "mse1")
    assert line.startswith("this model is of little use: it ignores its input") and "barely moves" in line
    # idle over the test split only: no carry-over from a validation that moves to a test that is noise
    raw["data"]["split"] = {"train": 0.6, "validation": 0.2, "test": 0.2}
    raw["model"] = {"family": "narx", "params": {"terms": ["1", "y[t-1]", "u[t-1]", "u[t-1]^3"]}}
    spec = make_spec(raw, folder)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    test, validation = model.metrics["test"]["nmse"], model.metrics["validation"]["nmse"]
    assert test >= CARRY_OVER_FLOOR and test >= CARRY_OVER_FACTOR * validation  # would be "does not carry over"
    assert [(n.kind, n.split) for n in assess(model, ds, runs)] == [("quiet", "test")]
    assert _quiet(100.0, {}, np.array([1e-3]), "validation") is not None
    assert _quiet(float("nan"), {}, np.array([1e-3]), "validation") is None
    assert _quiet(1e5, {}, np.array([1e-3]), "validation") is None  # 100 % of the training variance: poor
    assert _quiet(100.0, {}, np.array([0.02]), "validation") is None  # 14 % of the training spread: not quiet


def test_a_poor_auto_model_names_the_better_candidates_the_test_band_rejected():
    """Advice to raise the budget was wrong where the search had better-validating candidates and rejected them
    because their run left the output band on the test input: the user is told which, and what to do."""
    from dynmodel.usefulness import Note, what_to_try

    band = "rejected: leaves the output band on the test input at sample 3896"
    record = {
        "candidates": [
            {"family": "esn", "summary": "internal, 200 elements", "validation_nmse": 27.2, "verdict": "chosen"},
            {"family": "narx", "summary": "the default", "validation_nmse": 1.7e-7, "verdict": band},
            {"family": "narx", "summary": "linear", "validation_nmse": 2e-7, "verdict": band},
            {"family": "arx", "summary": "output error", "validation_nmse": 370.0, "verdict": band},
        ]
    }
    advice = what_to_try("s.yaml", "mse_inf", record)
    assert advice.startswith("try `dynmodel diagnose s.yaml`") and "larger search budget" in advice
    assert "; also, 2 candidate(s) that validated clearly better were rejected" in advice
    assert "narx: the default" in advice
    notes = [Note("poor", "test", "its free-run NMSE is 587 % on test", 587.0)]
    assert "2 candidate(s) that validated clearly better" in summary_line(notes, "s.yaml", "mse_inf", record)
    assert "also," not in what_to_try("s.yaml", "mse_inf", {"candidates": record["candidates"][:1]})
    record["candidates"][1:3] = [{**c, "validation_nmse": 20.0} for c in record["candidates"][1:3]]
    assert "also," not in what_to_try("s.yaml", "mse_inf", record)  # not clearly better than the chosen 27.2 %


def test_a_test_recording_with_an_offset_is_said_to_be_one(tmp_path):
    """A test file recorded with a shifted sensor zero: the model is right (its error is a constant), and the
    warning said "validate on data like the test's ... or prefer a simpler model"."""
    u, y = narx(2000, 1)
    ut, yt = narx(800, 2)
    write_csv(tmp_path / "train.csv", {"u": u, "y": y})
    write_csv(tmp_path / "test.csv", {"u": ut, "y": yt + 2.0 * yt.std()})
    raw = {
        "data": {"path": "train.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.8, "validation": 0.2}},
        "model": {"family": "narx", "params": {"degree": 3, "lags": {"u": [0, 1, 2], "y": [1, 2]}}},
        "cost": "mse_inf",
    }
    raw["data"]["test"] = {"path": "test.csv"}
    spec = make_spec(raw, tmp_path)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    line = summary_line(assess(model, ds, runs), "s.yaml", "mse_inf")
    assert "mostly a constant offset (mean error" in line and "(a sensor offset?)" in line
    assert "prefer a simpler model" not in line


def test_one_useless_output_of_two_is_named(tmp_path):
    """A model with one good output and one that is noise unrelated to the input: the mean over outputs
    (about 55 %) stays under the 90 % line, so the useless output must be judged on its own."""
    u, y = narx(1500, 1)
    z = np.convolve(np.random.default_rng(7).standard_normal(1500), np.ones(5) / 5, mode="same")
    write_csv(tmp_path / "two.csv", {"u": u, "y": y, "z": z})
    raw = base_spec("two.csv")
    raw["data"]["output"] = ["y", "z"]
    raw["model"] = {"family": "narx", "params": {"degree": 2}}
    spec = make_spec(raw, tmp_path)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    assert model.metrics["validation"]["nmse"] < 90.0  # the mean alone would pass
    notes = [n for n in assess(model, ds, runs) if n.kind == "poor"]
    assert notes and {n.output for n in notes} == {"z"} and {n.split for n in notes} >= {"validation"}
    line = summary_line(notes, "s.yaml", "mse_inf")
    assert "on validation for output 'z'" in line and "for output 'y'" not in line


def test_fit_json_holds_the_printed_notes_and_warning(cli, tmp_path):
    """--json carries what fit prints below the table: the notes on the data and the usefulness line."""
    u, y = narx(1000, 1)
    u[900:] *= 3  # the test input goes beyond the training range
    write_csv(tmp_path / "run.csv", {"t": np.arange(1000.0), "u": u, "y": np.random.default_rng(99).normal(size=1000)})
    spec_path = tmp_path / "s.yaml"
    spec_path.write_text(
        "data: {path: run.csv, input: [u], output: [y], split: {train: 0.6, validation: 0.2, test: 0.2}}\n"
        "model: {family: narx}\n"
    )
    r = cli("fit", spec_path, "--json", tmp_path / "f.json", "-q")
    report = json.loads((tmp_path / "f.json").read_text())
    printed = " ".join(r.stdout.split())
    assert any(n.startswith("the test input 'u' leaves the training range") for n in report["notes"])
    assert all(" ".join(n.split()) in printed for n in report["notes"])
    assert report["warning"].startswith("this model is of little use")


def test_a_constant_model_ignores_its_input(fitted):
    model, ds, runs, _ = fitted
    import copy

    const = copy.deepcopy(model)
    const.family.W_ = np.zeros_like(const.family.W_)
    const.family.D_ = np.zeros_like(const.family.D_)
    const.family.w0_ = np.zeros_like(const.family.w0_)  # the training mean (standard scaling)
    const.metrics = {k: dict(v) for k, v in model.metrics.items()}
    notes = assess(const, ds)
    assert [n.kind for n in notes if n.kind == "ignores-input"] == ["ignores-input"]
    assert input_dependence(const, ds) == 0.0


def test_carry_over_thresholds():
    def kinds(validation, test, key="test"):
        return [n.kind for n in carry_over({"validation": {"nmse": validation}, key: {"nmse": test}})]

    assert kinds(0.1, 48.7) == ["does-not-carry-over"]  # EMPS, 6000 samples: validates at 0.1 %, tests at 48.7 %
    assert kinds(0.1, 48.7, "test:pulses") == ["does-not-carry-over"]
    assert kinds(0.5, 9.9) == []  # 20 x, but under 10 %: a small model error
    assert kinds(2.0, 19.9) == []  # under 10 x
    assert kinds(2.0, 20.0) == ["does-not-carry-over"]
    assert carry_over({"train": {"nmse": 0.1}, "test": {"nmse": 90.0}}) == []  # no validation to compare with
    assert carry_over({"validation": {"nmse": 0.1}, "validation:b": {"nmse": 90.0}}) == []  # not a test split
    # family auto without a validation split: the search's own held-out score (EMPS with split {train: 1.0}:
    # chosen at 0.0054 % on the held-out tail, 45.8 % on the test, which used to pass unremarked)
    (note,) = carry_over({"train": {"nmse": 0.001}, "test": {"nmse": 45.8}}, searched=0.0054)
    assert note.kind == "does-not-carry-over" and "validation NMSE in the search" in note.text
    assert carry_over({"validation": {"nmse": 30.0}, "test": {"nmse": 45.8}}, searched=0.0054) == []  # its own wins
    # refitted on the validation samples too: their score is in-sample, the search's is the hold-out
    refitted = {"validation": {"nmse": 0.5, "fitted": True}}
    assert carry_over({**refitted, "test": {"nmse": 20.0}}, searched=3.0) == []  # 40 x the fitted, 6.7 x the search
    (note,) = carry_over({**refitted, "test": {"nmse": 45.8}}, searched=2.0)
    assert "validation NMSE in the search" in note.text and "(2 %)" in note.text
    auto = SimpleNamespace(search={"winner": "narx-1", "candidates": [{"key": "narx-1", "validation_nmse": 0.0054}]})
    assert search_validation(auto) == 0.0054 and search_validation(SimpleNamespace(search=None)) is None


def test_a_model_that_does_not_carry_over_to_the_test_is_said_so(tmp_path):
    """The system changes in the test part of the recording (its input gain triples): the model validates
    well on the part before, and the fit says its validation did not represent the test."""
    u, y = narx(1000, 4)
    y_changed = narx(1000, 4, c0=3.0)[1]
    y = np.concatenate([y[:800], y_changed[800:]])
    write_csv(tmp_path / "run.csv", {"u": u, "y": y})
    raw = base_spec("run.csv")
    raw["model"] = {"family": "narx"}
    spec = make_spec(raw, tmp_path)
    ds = load_dataset(spec)
    model, runs = engine.fit_dataset(spec, ds)
    assert model.metrics["validation"]["nmse"] < 1.0 and model.metrics["test"]["nmse"] > 20.0
    notes = assess(model, ds, runs)
    assert [n.kind for n in notes] == ["does-not-carry-over"]
    line = summary_line(notes, "s.yaml", "mse_inf")
    assert line.startswith("this model does not carry over to the test data: its test NMSE (")
    assert "Fix: validate on data like the test's" in line


def test_split_keys_are_generic():
    metrics = {"train": {"nmse": 1.0}, "validation": {"nmse": 2.0}, "test:bench": {"nmse": 95.0}}
    assert held_out_splits(metrics) == ["validation", "test:bench"]
    assert held_out_splits({"train": {}}) == ["train"]


def test_stability_fix_does_not_repeat_the_cost():
    narx_hint = (
        "use cost: mse_inf (free-running estimation), bounds: 0.1 (clip the output, eq. 6.25), ridge: auto, or a "
        "lower degree"
    )
    assert stability_fix(narx_hint, "mse1") == narx_hint
    assert stability_fix(narx_hint, "mse_inf") == (
        "use bounds: 0.1 (clip the output, eq. 6.25), ridge: auto, or a lower degree"
    )
    assert stability_fix("use cost: mse_inf, the internal mode or a smaller spectral scale", "mse_inf") == (
        "use the internal mode or a smaller spectral scale"
    )
    assert "even with cost: mse_inf" in stability_fix("use cost: mse_inf", "mse_inf")


# ---------------------------------------------------------------- predict


def test_predict_keeps_the_time_column_and_says_where_the_plot_is(cli, fitted, tmp_path, monkeypatch):
    model, *_ = fitted
    store.save(model, tmp_path / "m.h5")
    u, y = narx(200, 5)
    write_csv(tmp_path / "run.csv", {"time": 12.5 + np.arange(200) * 1.0, "u": u, "y": y})
    monkeypatch.chdir(tmp_path)
    r = cli("predict", "m.h5", "--input", "run.csv", "--out", "p.csv", "--plot", "p.png")
    assert r.exit_code == 0, r.stderr
    assert "plot written to p.png" in r.stderr and (tmp_path / "p.png").stat().st_size > 5000
    text = (tmp_path / "p.csv").read_text().splitlines()
    assert text[0] == "time,y" and text[1].startswith("12.5,")
    # a table of time and outputs alone has the header of a file of measured outputs: never replaced unasked
    write_csv(tmp_path / "measured.csv", {"time": np.arange(200) * 1.0, "y": y})
    before = (tmp_path / "measured.csv").read_text()
    r = cli("predict", "m.h5", "--input", "run.csv", "--out", "measured.csv")
    assert r.exit_code == 2 and "replaces a CSV file only when asked" in r.stderr
    assert (tmp_path / "measured.csv").read_text() == before
    r = cli("predict", "m.h5", "--input", "run.csv", "--out", "p.csv", "--force")  # its own table, when asked
    assert r.exit_code == 0, r.stderr


def test_a_searched_model_of_little_use_is_not_told_to_try_the_search():
    """After family: auto, 'try family: auto' is no advice; a larger budget or more data is."""
    from dynmodel.usefulness import what_to_try

    assert "family: auto" in what_to_try("s.yaml") or "another family" in what_to_try("s.yaml")
    searched = what_to_try("s.yaml", searched=True)
    assert "family: auto" not in searched and "budget" in searched and "dynmodel diagnose s.yaml" in searched


def test_predict_reads_measured_outputs_with_gaps_after_the_tune_in(cli, tmp_path, monkeypatch):
    """Only the tune-in rows of the measured outputs must be complete: a gap later in the output column (a
    dropped sample) used to refuse the whole file; a gap inside the tune-in is one clear line."""
    from dynmodel_plugins.narx import Narx

    u, y = narx(800, 1)
    store.save(Narx(degree=3, lags={"u": [0, 1, 2], "y": [1, 2]}).fit(u, y).model_, tmp_path / "m.h5")
    ut, yt = narx(300, 5)
    cells = [f"{v:.10g}" for v in yt]
    late, early = list(cells), list(cells)
    late[200], early[1] = "", ""
    (tmp_path / "late.csv").write_text(
        "t,u,y\n" + "".join(f"{i},{a:.10g},{b}\n" for i, (a, b) in enumerate(zip(ut, late)))
    )
    (tmp_path / "early.csv").write_text(
        "t,u,y\n" + "".join(f"{i},{a:.10g},{b}\n" for i, (a, b) in enumerate(zip(ut, early)))
    )
    monkeypatch.chdir(tmp_path)
    r = cli("predict", "m.h5", "--input", "late.csv", "--out", "p.csv")
    assert r.exit_code == 0, r.stderr
    rows = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    assert rows.shape == (300, 3) and np.isfinite(rows).all()
    r = cli("predict", "m.h5", "--input", "early.csv", "--out", "q.csv")
    assert r.exit_code == 2 and "the tune-in needs 2 finite measured output samples, found 1" in r.stderr


def test_predict_says_when_the_predicted_output_leaves_the_training_range(tmp_path):
    """An output beyond the training output range is said with where it starts (a network started at rest
    far from the data's state, or a clipped extrapolation), not only an input beyond its range."""
    from dynmodel.commands.predict import predict_file
    from dynmodel_plugins.narx import Narx

    u, y = narx(800, 1)
    store.save(Narx(degree=3, lags={"u": [0, 1, 2], "y": [1, 2]}).fit(u, y).model_, tmp_path / "m.h5")
    ut, yt = narx(300, 5)
    write_csv(tmp_path / "same.csv", {"t": np.arange(300.0), "u": ut, "y": yt})
    write_csv(tmp_path / "big.csv", {"t": np.arange(300.0), "u": 4 * ut, "y": yt})
    assert predict_file(tmp_path / "m.h5", tmp_path / "same.csv").output_notes() == []
    (note,) = predict_file(tmp_path / "m.h5", tmp_path / "big.csv").output_notes()
    assert note.startswith("the predicted output 'y' leaves the training output range by") and "from sample" in note
    assert "starts from rest" not in note  # a NARX model's state is its measured tune-in


def test_a_test_file_with_unknown_outputs_is_unscored_not_a_crash(cli, tmp_path):
    """Test outputs held back (NaN): a NARX model starts from measured outputs, so it cannot run there; the fit
    says the split is not scored and why (it ended in an internal error after the whole fit)."""
    u, y = narx(1500, 1)
    ut, _ = narx(500, 2)
    write_csv(tmp_path / "run.csv", {"t": np.arange(1500.0), "u": u, "y": y})
    write_csv(tmp_path / "hidden.csv", {"t": np.arange(500.0), "u": ut, "y": np.full(500, np.nan)})
    (tmp_path / "s.yaml").write_text(
        "data: {path: run.csv, input: [u], output: [y], test: {path: hidden.csv}}\n"
        "model: {family: narx, params: {degree: 1}}\n"
    )
    r = cli("fit", tmp_path / "s.yaml", "--json", tmp_path / "f.json", "-q")
    assert r.exit_code == 0, r.stderr
    report = json.loads((tmp_path / "f.json").read_text())
    assert report["metrics"]["test"]["nmse"] is None
    (note,) = [n for n in report["notes"] if "not scored" in n]
    assert "measured outputs, so it was not run there" in note


def test_a_test_file_with_a_gap_of_unknown_outputs_is_scored_where_known(cli, tmp_path):
    """50 of 800 test outputs NaN (a logging gap): the whole test split went unscored ("the measured outputs are
    unknown"), where 750 samples could be."""
    u, y = narx(1500, 1)
    ut, yt = narx(800, 2)
    gap = yt.copy()
    gap[400:450] = np.nan
    write_csv(tmp_path / "run.csv", {"u": u, "y": y})
    write_csv(tmp_path / "gap.csv", {"u": ut, "y": gap})
    write_csv(tmp_path / "whole.csv", {"u": ut, "y": yt})
    for name in ("gap", "whole"):
        (tmp_path / f"{name}.yaml").write_text(
            f"data: {{path: run.csv, input: [u], output: [y], test: {{path: {name}.csv}}}}\n"
            "model: {family: narx, params: {degree: 3, lags: {u: [0, 1, 2], y: [1, 2]}}}\n"
        )
        assert cli("fit", tmp_path / f"{name}.yaml", "--json", tmp_path / f"{name}.json", "-q").exit_code == 0
    part = json.loads((tmp_path / "gap.json").read_text())
    whole = json.loads((tmp_path / "whole.json").read_text())["metrics"]["test"]
    test = part["metrics"]["test"]
    assert test["samples"] == whole["samples"] - 50 and test["unknown"] == 50
    assert test["nmse"] == pytest.approx(whole["nmse"], rel=0.2)  # the same model, 94 % of the samples
    assert any("scored on its 748 samples with known outputs: 50 with NaN outputs" in n for n in part["notes"])


def test_held_out_data_that_are_training_data_are_said(tmp_path):
    """Overlapping segments of one file, and the training file given again as the test: the scores would
    measure the fit to training data, which the notes say; disjoint splits give none."""
    u, y = narx(3000, 1)
    write_csv(tmp_path / "run.csv", {"t": np.arange(3000.0), "u": u, "y": y})
    (tmp_path / "copy").mkdir()
    write_csv(tmp_path / "copy" / "run.csv", {"t": np.arange(3000.0), "u": u, "y": y})

    def notes(**data):
        return load_dataset(_spec(tmp_path, **data)).overlap_notes()

    assert notes() == []  # the default 60/20/20 split of one recording
    (overlap, *_) = notes(segments=[[0, 2000], [1000, 3000]])
    assert "shares" in overlap and "with the training split" in overlap
    (shares,) = notes(split={"train": 0.8, "validation": 0.2}, test={"path": "copy/run.csv"})
    assert shares.startswith("the test split shares 2400 of its 3000 samples with the training split")
    write_csv(tmp_path / "again.csv", {"t": np.arange(3000.0), "u": u, "y": y})
    (again,) = notes(split={"train": 0.8, "validation": 0.2}, test={"path": "again.csv"})
    assert again.startswith("the test recording") and "holds the samples of the training recording" in again
    u2, y2 = narx(3000, 2)
    write_csv(tmp_path / "copy" / "run.csv", {"t": np.arange(3000.0), "u": u2, "y": y2})  # same name, other data
    assert notes(split={"train": 0.8, "validation": 0.2}, test={"path": "copy/run.csv"}) == []


def test_a_split_too_small_to_score_is_said(tmp_path):
    u, y = narx(600, 1)
    write_csv(tmp_path / "run.csv", {"t": np.arange(600.0), "u": u, "y": y})
    small = load_dataset(_spec(tmp_path, split={"train": [0, 590], "validation": [590, 600]}, transient=0))
    (note,) = small.small_split_notes()
    assert note.startswith("the validation split has only 10 scored sample(s)")
    assert load_dataset(_spec(tmp_path)).small_split_notes() == []
