"""The commands as library functions (dynmodel.commands): the whole job of each CLI command from Python,
without typer or rich, with the same numbers and files as the CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import ROOT, narx, write_csv, write_yaml

import dynmodel
from dynmodel.commands import (
    check_reliability,
    fit_and_save,
    generate_recording,
    inspect_model,
    installed_plugins,
    parse_params,
    predict_file,
    run_control,
    schema_text,
    validate_spec_file,
)
from dynmodel.control import Settings as ControlSettings
from dynmodel.errors import DynmodelError, SpecError
from dynmodel.family import Family
from dynmodel.reliability import Settings as ReliabilitySettings
from dynmodel.spec import Spec, spec_json_schema


@pytest.fixture
def small_spec(tmp_path):
    """The quick start (an external-mode ESN on the NARX system), shortened."""
    spec = yaml.safe_load((ROOT / "specs/quickstart.yaml").read_text())
    spec["data"].update({"n": 3000, "transient": 200})
    spec["data"]["test"]["n"] = 2000
    spec["output"] = str(tmp_path / "m.h5")
    return write_yaml(tmp_path / "s.yaml", spec)


def test_fit_and_save_equals_the_cli_fit(cli, tmp_path, small_spec):
    stages: list[str] = []
    result = fit_and_save(
        small_spec,
        out=tmp_path / "lib.h5",
        json_path=tmp_path / "lib.json",
        plot=tmp_path / "lib.png",
        progress=lambda stage, fraction, message: stages.append(stage),
    )
    assert isinstance(result.spec, Spec) and result.path == (tmp_path / "lib.h5").resolve()
    assert result.problem() is None and result.warning() is None and result.notes == []
    assert result.family_label == "esn" and result.cost == "mse1" and result.seconds > 0
    assert stages[0] == "data" and "evaluate" in stages
    assert (tmp_path / "lib.png").stat().st_size > 10000 and result.plot_path == tmp_path / "lib.png"

    r = cli("fit", small_spec, "--out", tmp_path / "cli.h5", "--json", tmp_path / "cli.json", "-q")
    assert r.exit_code == 0, r.stderr
    assert f"model written to {(tmp_path / 'cli.h5').resolve()}" in r.stdout
    lib, via_cli = (json.loads((tmp_path / f"{k}.json").read_text()) for k in ("lib", "cli"))
    assert lib["model"] == str(result.path) and via_cli["model"] == str((tmp_path / "cli.h5").resolve())
    assert lib["metrics"] == via_cli["metrics"] and lib["assessment"] == via_cli["assessment"] == []
    assert lib["metrics"] == result.to_json()["metrics"]
    assert lib["metrics"]["test"]["nmse"] < 0.5  # the quick start's ESN on the NARX system: a useful model

    loaded, loaded_cli = dynmodel.load(tmp_path / "lib.h5"), dynmodel.load(tmp_path / "cli.h5")
    assert loaded.metrics == result.model.metrics == loaded_cli.metrics
    u, y = narx(600, 5)
    np.testing.assert_array_equal(loaded.predict(u, y[: loaded.warmup]), loaded_cli.predict(u, y[: loaded.warmup]))


def test_fit_and_save_checks_the_output_paths_before_any_work(tmp_path, small_spec):
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    stages: list[str] = []
    with pytest.raises(DynmodelError, match="not a dynmodel model"):
        fit_and_save(small_spec, out=notes, progress=lambda stage, fraction, message: stages.append(stage))
    assert stages == [] and notes.read_text() == "my notes\n"  # nothing loaded, nothing replaced
    with pytest.raises(DynmodelError):
        fit_and_save(small_spec, json_path=notes)
    assert not (tmp_path / "m.h5").exists()  # the json path was refused before the model was fitted

    result = fit_and_save(small_spec, seed=3)
    assert result.spec.seed == 3 and dynmodel.load(tmp_path / "m.h5").provenance["seed"] == 3
    again = fit_and_save(small_spec, seed=3)  # a previous model is replaced, with the same numbers
    assert again.model.metrics == result.model.metrics


def test_predict_and_inspect_a_model_file(tmp_path, small_spec):
    fitted = fit_and_save(small_spec, json_path=tmp_path / "fit.json")
    u, y = narx(800, 9)
    write_csv(tmp_path / "new.csv", {"u": u, "y": y})
    result = predict_file(fitted.path, tmp_path / "new.csv", out=tmp_path / "pred.csv", plot=tmp_path / "p.png")
    assert result.problem() is None and result.columns == ["t", "y", "measured"]
    warm = fitted.model.warmup
    assert result.written_line() == (
        f"800 predictions written to {tmp_path / 'pred.csv'} "
        f"(the first {warm} rows are the measured tune-in, marked in column 'measured')"
    )
    table = np.loadtxt(tmp_path / "pred.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[:, 0], np.arange(800.0))
    free = fitted.model.predict(u, y_tune=y[:warm])[:, 0]
    np.testing.assert_allclose(table[warm:, 1], free[warm:], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(table[:, 2], (np.arange(800) < warm).astype(float))
    assert (tmp_path / "p.png").stat().st_size > 10000
    # without --out nothing is written: the caller prints the rows
    in_memory = predict_file(fitted.path, tmp_path / "new.csv")
    assert in_memory.out is None and np.array_equal(in_memory.rows, result.rows)

    summary = inspect_model(fitted.path, json_path=tmp_path / "inspect.json")
    assert summary.summary["family"] == "esn" and summary.summary["inputs"] == ["u"]
    assert summary.summary["model"] == fitted.model.family.summary() and summary.note is None
    assert json.loads((tmp_path / "inspect.json").read_text()) == json.loads(json.dumps(summary.summary))
    assert summary.model.metrics == json.loads((tmp_path / "fit.json").read_text())["metrics"]


def test_validate_generate_schema_and_plugins(tmp_path):
    checked = validate_spec_file(ROOT / "specs/examples/file-example.yaml")
    assert isinstance(checked.plan, Family) and checked.plan.name == checked.spec.model.family == "esn"
    train = next(row for row in checked.splits if row["split"] == "train")
    assert train["samples"] == 7000 and train["segments"] == ["train.csv[0:7000]"]

    rec = generate_recording("driven-logistic", tmp_path / "g.csv", n=300, seed=4, params={"alpha": 0.3})
    same = generate_recording("driven-logistic", tmp_path / "h.csv", n=300, seed=4, params=["alpha=0.3"])
    np.testing.assert_array_equal(same.y, rec.y)
    assert rec.n == 300 and rec.columns == ["t", "u", "y"]
    data = np.loadtxt(tmp_path / "g.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(data, np.loadtxt(tmp_path / "h.csv", delimiter=",", skiprows=1))
    u, y = data[:, 1], data[:, 2]
    assert np.allclose(y[1:], 0.7 * 4 * y[:-1] * (1 - y[:-1]) + 0.3 * u[1:], atol=1e-9)
    with pytest.raises(SpecError, match="invalid parameter"):
        generate_recording("driven-logistic", tmp_path / "bad.csv", n=10, params={"alpha": "x"})
    with pytest.raises(SpecError, match="is not key=value"):
        parse_params(["alpha"])

    text = schema_text(tmp_path / "schema.json")
    assert json.loads(text) == spec_json_schema() == json.loads((tmp_path / "schema.json").read_text())
    groups = {g.title: g for g in installed_plugins()}
    families = {row[0]: row for row in groups["model families"].rows}
    assert {"narx", "esn", "annealed-rnn", "lorenz-net"} <= set(families)
    assert families["narx"][2].startswith("dynmodel_plugins")


def test_check_reliability_of_a_test_system(tmp_path):
    settings = ReliabilitySettings(replicas=4, scan_replicas=4, length=300, levels=3)
    ok = check_reliability(
        system="tanh-network", params={"sigma": 0.95}, settings=settings, json_path=tmp_path / "ok.json"
    )
    assert ok.report.verdict.verdict == "reliable" and ok.report.exit_code == 0
    written = json.loads((tmp_path / "ok.json").read_text())
    assert written["test_system"] == "tanh-network" and written["params"]["sigma"] == 0.95
    bad = check_reliability(system="tanh-network", settings=settings)
    assert bad.report.verdict.verdict == "unreliable" and bad.report.exit_code == 1
    with pytest.raises(DynmodelError, match="give either a model file or --system"):
        check_reliability()
    with pytest.raises(SpecError, match="AMPLITUDE:OMEGA"):
        check_reliability(system="tanh-network", sines=["3"], settings=settings)


def test_run_control_of_a_small_feedforward_model(tmp_path):
    spec = {
        "name": "tiny",
        "data": {
            "generator": "friction-plant",
            "n": 6000,
            "seed": 1,
            "input": ["position"],
            "output": ["force"],
            "split": {"train": 0.8, "validation": 0.2},
            "delay_lines": [50, 100],
        },
        "model": {"family": "esn", "params": {"size": 50, "relaxation": [0.0, 0.95]}},
        "output": str(tmp_path / "tiny.h5"),
    }
    fitted = fit_and_save(write_yaml(tmp_path / "tiny.yaml", spec))
    settings = ControlSettings(duration=10, switch=5, skip=2, realizations=2)
    result = run_control(fitted.path, settings=settings, json_path=tmp_path / "c.json", plot=tmp_path / "c.png")
    assert result.name == "friction-plant" and len(result.report.model) == 2
    summary = result.summary()
    assert summary["perfect"]["alpha"]["mean"] > 99.9  # the plant's own force cancels the friction
    written = json.loads((tmp_path / "c.json").read_text())
    assert written["plant"]["generator"] == "friction-plant" and len(written["realizations"]) == 2
    assert written["perfect"]["alpha"]["mean"] == pytest.approx(summary["perfect"]["alpha"]["mean"])
    assert (tmp_path / "c.png").stat().st_size > 20000
    with pytest.raises(SpecError, match="--hold"):
        run_control(fitted.path, settings=ControlSettings(hold="cubic"))


def test_the_library_functions_need_neither_typer_nor_rich(tmp_path, small_spec):
    path = small_spec
    code = (
        "import sys\n"
        "from dynmodel.commands import fit_and_save, inspect_model\n"
        f"r = fit_and_save({str(path)!r}, json_path={str(tmp_path / 'm.json')!r})\n"
        "i = inspect_model(r.path)\n"
        "assert i.model.metrics == r.model.metrics\n"
        "print(sorted(m for m in ('typer', 'rich', 'click') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=tmp_path)
    assert out.stdout.strip() == "[]"
    assert yaml.safe_load((tmp_path / "m.json").read_text())["metrics"]["test"]["nmse"] < 0.5


def test_diagnose_spec_file_names_a_hidden_delay_and_writes_the_report(tmp_path):
    from hidden_effects import missing_delay

    from dynmodel.commands import diagnose_spec_file
    from dynmodel.diagnose import Settings as DiagnoseSettings

    spec = write_yaml(tmp_path / "delay.yaml", missing_delay(3).spec(tmp_path))
    with pytest.raises(DynmodelError, match="not a JSON summary"):
        (tmp_path / "notes.txt").write_text("mine\n")
        diagnose_spec_file(spec, json_path=tmp_path / "notes.txt")
    assert not any(p.name.endswith("-diagnosis") for p in tmp_path.iterdir())  # refused before any work
    done = diagnose_spec_file(spec, report=tmp_path / "rep", json_path=tmp_path / "d.json", settings=DiagnoseSettings())
    assert done.diagnosis.verdict == "missing-delay" and done.index == tmp_path / "rep" / "index.md"
    assert done.extended == tmp_path / "rep" / "extended.yaml" and done.extended.exists()
    summary = json.loads((tmp_path / "d.json").read_text())
    assert summary["findings"][0]["cause"] == "missing-delay"
    assert summary["gain"]["test_nmse_after"] < summary["gain"]["test_nmse_before"]
    refit = fit_and_save(done.extended)  # the extended spec runs as it is
    assert refit.model.metrics["test"]["nmse"] == pytest.approx(summary["gain"]["test_nmse_after"], rel=1e-9)
