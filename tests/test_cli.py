"""The command line: the README flow, and one clear line (no traceback) for every bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from conftest import ROOT, narx, narx_spec, write_csv, write_yaml

import dynmodel


@pytest.fixture
def quick_spec(tmp_path):
    spec = yaml.safe_load((ROOT / "specs/quickstart.yaml").read_text())
    spec["data"]["n"] = 4000
    spec["data"]["test"]["n"] = 3000
    spec["data"]["transient"] = 200
    spec["output"] = str(tmp_path / "quick.h5")
    return write_yaml(tmp_path / "quick.yaml", spec)


def test_fit_predict_inspect_round_trip(cli, tmp_path, quick_spec):
    r = cli("fit", quick_spec, "--json", tmp_path / "fit.json", "--plot", tmp_path / "fit.png", "-q")
    assert r.exit_code == 0, r.stderr
    for header in ("split", "NMSE %", "MAX", "train", "validation", "test"):
        assert header in r.stdout
    report = json.loads((tmp_path / "fit.json").read_text())
    assert set(report) == {"metrics", "model", "assessment", "warning", "notes", "interrupted"}
    assert report["assessment"] == [] and report["interrupted"] is None
    assert report["warning"] is None and report["notes"] == []
    assert set(report["metrics"]) == {"train", "validation", "test"}
    assert set(report["metrics"]["test"]) >= {"nmse", "max", "samples", "nmse_1"}
    assert report["metrics"]["test"]["nmse"] < 0.1  # external ESN on the NARX system
    assert (tmp_path / "fit.png").stat().st_size > 10000

    u, y = narx(1200, 77)
    write_csv(tmp_path / "new.csv", {"u": u, "y": y})
    r = cli("predict", report["model"], "--input", tmp_path / "new.csv", "--out", tmp_path / "pred.csv")
    assert r.exit_code == 0, r.stderr
    pred = np.loadtxt(tmp_path / "pred.csv", delimiter=",", skiprows=1)
    model = dynmodel.load(report["model"])
    warm = model.warmup
    free = model.predict(u, y_tune=y[:warm])[:, 0]
    np.testing.assert_allclose(pred[warm:, 1], free[warm:], rtol=1e-9, atol=1e-12)
    # the tune-in rows hold the measured outputs the model was fed, marked in column 'measured'
    assert (tmp_path / "pred.csv").read_text().splitlines()[0] == "t,y,measured"
    np.testing.assert_array_equal(pred[:warm, 2], 1.0)
    np.testing.assert_array_equal(pred[warm:, 2], 0.0)
    np.testing.assert_allclose(pred[:warm, 1], y[:warm], rtol=1e-9)
    assert "the first 20 rows are the measured tune-in" in r.stderr

    r = cli("inspect", report["model"], "--json", tmp_path / "inspect.json")
    assert r.exit_code == 0 and "sigma(C)" in r.stdout and "esn" in r.stdout
    summary = json.loads((tmp_path / "inspect.json").read_text())
    assert summary["model"]["mode"] == "external" and summary["tune_in_samples"] == 20  # the default tune-in
    r = cli("inspect", report["model"], "--json", "-")  # '-': the JSON on stdout, the table on stderr
    assert r.exit_code == 0 and json.loads(r.stdout) == summary and "sigma(C)" in r.stderr
    assert not (tmp_path / "-").exists() and not Path("-").exists()


def test_predict_says_where_the_input_leaves_the_training_range(cli, tmp_path, quick_spec):
    """As fit says of a test split: beyond the training input range by more than 5 % of its width the model
    extrapolates; predict names the input, how far and where (stderr), and writes the predictions anyway."""
    r = cli("fit", quick_spec, "--out", tmp_path / "m.h5", "-q")
    assert r.exit_code == 0, r.stderr
    model = dynmodel.load(tmp_path / "m.h5")
    lo, hi = model.train_input.min(), model.train_input.max()
    u, y = narx(600, 78)
    write_csv(tmp_path / "inside.csv", {"u": np.clip(u, lo, hi), "y": y})
    r = cli("predict", tmp_path / "m.h5", "--input", tmp_path / "inside.csv", "--out", tmp_path / "p1.csv")
    assert r.exit_code == 0 and "training range" not in r.stderr
    big = np.clip(u, lo, hi)
    big[400] = hi + 0.3 * (hi - lo)
    write_csv(tmp_path / "beyond.csv", {"u": big, "y": y})
    r = cli("predict", tmp_path / "m.h5", "--input", tmp_path / "beyond.csv", "--out", tmp_path / "p2.csv")
    assert r.exit_code == 0 and (tmp_path / "p2.csv").exists()
    assert "note: the input 'u' leaves the training range by 30 % of its width (sample 400" in r.stderr


def test_out_overrides_the_spec_output(cli, tmp_path, quick_spec):
    r = cli("fit", quick_spec, "--out", tmp_path / "other.h5", "-q")
    assert r.exit_code == 0 and (tmp_path / "other.h5").exists() and not (tmp_path / "quick.h5").exists()


def test_external_model_asks_for_tune_in_outputs(cli, tmp_path, quick_spec):
    cli("fit", quick_spec, "-q")
    u, _ = narx(500, 3)
    write_csv(tmp_path / "only_u.csv", {"u": u})
    r = cli("predict", tmp_path / "quick.h5", "--input", tmp_path / "only_u.csv")
    assert r.exit_code == 2
    assert "tunes in on the first 20 measured samples of output column(s) 'y'" in r.stderr  # the default tune-in
    assert "--tune-in" in r.stderr and "Traceback" not in r.stderr + r.stdout
    write_csv(tmp_path / "tune.csv", {"y": narx(500, 3)[1]})
    r = cli("predict", tmp_path / "quick.h5", "--input", tmp_path / "only_u.csv", "--tune-in", tmp_path / "tune.csv")
    assert r.exit_code == 0 and len(r.stdout.splitlines()) == 501
    r = cli("predict", tmp_path / "quick.h5", "--input", tmp_path / "only_u.csv", "--tune-in", tmp_path / "nope.csv")
    assert "nope.csv: --tune-in file not found" in _one_line_error(r)


def test_plugins_schema_validate_generate(cli, tmp_path):
    r = cli("plugins")
    assert r.exit_code == 0 and "esn" in r.stdout and "rossler-lorenz" in r.stdout
    r = cli("schema")
    schema = json.loads(r.stdout)
    assert "properties" in schema and "model" in schema["properties"]
    r = cli("validate", ROOT / "specs/examples/file-example.yaml")
    assert r.exit_code == 0 and "train.csv[0:7000]" in r.stdout and "6000" in r.stdout
    r = cli("generate", "driven-logistic", "--n", 300, "--seed", 4, "--out", tmp_path / "g.csv", "-p", "alpha=0.3")
    assert r.exit_code == 0
    data = np.loadtxt(tmp_path / "g.csv", delimiter=",", skiprows=1)
    assert data.shape == (300, 3) and (tmp_path / "g.csv").read_text().startswith("t,u,y")
    u, y = data[:, 1], data[:, 2]
    assert np.allclose(y[1:], 0.7 * 4 * y[:-1] * (1 - y[:-1]) + 0.3 * u[1:], atol=1e-9)


@pytest.mark.parametrize("command", [[], ["fit"], ["reliability-check"], ["generate"]])
def test_help_shows_flags_without_a_value_type(cli, command):
    r = cli(*command, "--help")
    assert r.exit_code == 0 and "--help" in r.stdout and "<bool>" not in r.stdout and "[[" not in r.stdout


def test_rmse_and_fit_metrics(cli, tmp_path):
    spec = narx_spec(n=3000, test_n=2000, transient=100, size=50, split={"train": 0.8, "validation": 0.2})
    spec["evaluation"] = {"metrics": ["nmse", "max", "rmse", "fit"]}
    spec["output"] = str(tmp_path / "m.h5")
    r = cli("fit", write_yaml(tmp_path / "s.yaml", spec), "--json", tmp_path / "m.json", "-q")
    assert r.exit_code == 0 and "RMSE" in r.stdout and "fit %" in r.stdout
    test = json.loads((tmp_path / "m.json").read_text())["metrics"]["test"]
    # fit = 100 (1 - RMSE / std) and NMSE = 100 RMSE^2 / var on the same samples
    assert test["fit"] == pytest.approx(100 * (1 - np.sqrt(test["nmse"] / 100)), rel=1e-9)
    spec["evaluation"] = {"metrics": ["nmse", "rmse"]}  # MAX left out: no column of dashes
    r = cli("fit", write_yaml(tmp_path / "s.yaml", spec), "--force", "-q")
    assert r.exit_code == 0 and "RMSE" in r.stdout and "MAX" not in r.stdout and "fit %" not in r.stdout


def test_fit_notes_a_test_input_beyond_the_training_range(cli, tmp_path, narx_csvs):
    train, test = narx_csvs
    spec = {
        "data": {
            "path": str(train),
            "input": ["u"],
            "output": ["y"],
            "split": {"train": 0.8, "validation": 0.2},
            "test": {"path": str(test)},
        },
        "model": {"family": "narx"},
        "output": str(tmp_path / "m.h5"),
    }
    r = cli("fit", write_yaml(tmp_path / "s.yaml", spec), "-q")
    assert r.exit_code == 0 and "extrapolates" not in r.stdout  # the same uniform input on both files
    u, y = np.loadtxt(test, delimiter=",", skiprows=1, unpack=True)
    u[1500] = 2 * u.max()  # one sample twice as far out as anything in training
    write_csv(test, {"u": u, "y": y})
    r = cli("fit", tmp_path / "s.yaml", "-q")
    assert (
        "note: the test input 'u' leaves the training range by" in r.stdout
        and "sample 1500 of 'test:test.csv'" in r.stdout
    )


def test_generate_reports_invalid_parameters_on_one_line(cli, tmp_path):
    r = cli("generate", "linear-system", "-p", "a0=2", "--out", tmp_path / "g.csv")
    line = _one_line_error(r)
    assert "a0: Input should be less than 1" in line and "errors.pydantic.dev" not in line


# ------------------------------------------------------------------------------ bad input


def _one_line_error(r, code: int = 2) -> str:
    assert r.exit_code == code, (r.exit_code, r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert "Fix:" in lines[0]
    return lines[0]


def test_malformed_yaml(cli, tmp_path):
    (tmp_path / "s.yaml").write_text("data:\n  generator: narx-system\n   n: 5\n")
    line = _one_line_error(cli("fit", tmp_path / "s.yaml"))
    assert "s.yaml:3:" in line and "malformed YAML" in line


def test_unknown_key(cli, tmp_path):
    spec = narx_spec()
    spec["data"]["transcient"] = 5
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert "unknown key 'transcient'" in line and "did you mean 'transient'" in line


@pytest.mark.parametrize(
    "where, value, expected",
    [
        ("family", "narxx", "unknown family 'narxx'"),
        ("generator", "narx", "unknown generator 'narx'"),
    ],
)
def test_unknown_family_or_generator(cli, tmp_path, where, value, expected):
    spec = narx_spec()
    if where == "family":
        spec["model"]["family"] = value
    else:
        spec["data"]["generator"] = value
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert expected in line and ("esn" in line if where == "family" else "narx-system" in line)


def test_missing_column_and_missing_file(cli, tmp_path, narx_csvs):
    spec = {"data": {"path": "train.csv", "input": ["position"], "output": ["y"]}, "model": {"family": "esn"}}
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert "no column 'position'" in line and "train.csv" in line and "u, y" in line
    spec["data"]["path"] = "nope.csv"
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert "nope.csv: file not found" in line


def test_nan_in_data(cli, tmp_path):
    u, y = narx(3000, 1)
    y[1234] = np.nan
    write_csv(tmp_path / "d.csv", {"u": u, "y": y})
    spec = {"data": {"path": "d.csv", "input": ["u"], "output": ["y"]}, "model": {"family": "esn"}}
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert "column 'y' has NaN at sample 1234" in line and "d.csv" in line


def test_series_too_short_for_split_and_transient(cli, tmp_path):
    spec = narx_spec(n=3000, test_n=800, transient=1000)
    line = _one_line_error(cli("fit", write_yaml(tmp_path / "s.yaml", spec)))
    assert "test split has no sample left after the transient of 1000" in line and "data.transient" in line


def test_diverging_free_run_names_the_sample(cli, tmp_path):
    # plain least squares on every state, no tune-in: the fed-back output explodes at once
    spec = narx_spec(
        mode="external", n=3000, test_n=1000, transient=200, tune_in=0, readout={"solver": "lstsq", "direct": False}
    )
    spec["output"] = str(tmp_path / "div.h5")
    r = cli("fit", write_yaml(tmp_path / "s.yaml", spec), "--json", tmp_path / "div.json", "-q")
    line = _one_line_error(r, code=1)
    report = json.loads((tmp_path / "div.json").read_text())
    bad = next(m["unstable_from"] for m in report["metrics"].values() if m.get("unstable_from"))
    assert f"diverged on the train split at sample {bad['sample']}" in line
    assert "unstable from t =" in r.stdout
    assert (tmp_path / "div.h5").exists()  # kept for inspection


def test_corrupt_and_newer_model_files(cli, tmp_path, quick_spec):
    u, _ = narx(100, 1)
    write_csv(tmp_path / "u.csv", {"u": u})
    (tmp_path / "bad.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    line = _one_line_error(cli("predict", tmp_path / "bad.h5", "--input", tmp_path / "u.csv"))
    assert "not a readable HDF5 model file" in line
    cli("fit", quick_spec, "-q")
    shutil.copy(tmp_path / "quick.h5", tmp_path / "newer.h5")
    with h5py.File(tmp_path / "newer.h5", "a") as f:
        f.attrs["format_version"] = 99
    line = _one_line_error(cli("inspect", tmp_path / "newer.h5"))
    assert "newer dynmodel" in line and "upgrade" in line


def test_bad_option_values_are_usage_errors(cli, tmp_path):
    r = cli("generate", "linear-system", "--out", tmp_path / "x.csv", "-p", "a0=2.5")
    line = _one_line_error(r)
    assert "--param" in line


def test_the_spec_inspect_prints_refits_the_model_elsewhere(cli, tmp_path, quick_spec):
    """inspect --spec prints the resolved spec without its output: fitting it reproduces the model's metrics and
    writes next to the printed spec, never over the model file it came from."""
    r = cli("fit", quick_spec, "--out", tmp_path / "m.h5", "-q")
    assert r.exit_code == 0, r.stderr
    before = (tmp_path / "m.h5").read_bytes()
    r = cli("inspect", tmp_path / "m.h5", "--spec")
    lines = r.stdout.splitlines()
    text = "\n".join(lines[next(i for i, ln in enumerate(lines) if ln.startswith("name:")) :])
    assert "\noutput:" not in text
    (tmp_path / "again").mkdir()
    (tmp_path / "again" / "s.yaml").write_text(text)
    r = cli("fit", tmp_path / "again" / "s.yaml", "-q")
    assert r.exit_code == 0, r.stderr
    assert (tmp_path / "m.h5").read_bytes() == before
    refit = dynmodel.load(tmp_path / "again" / "quickstart.h5")  # <name>.h5 next to the spec
    assert refit.metrics["test"]["nmse"] == dynmodel.load(tmp_path / "m.h5").metrics["test"]["nmse"]
