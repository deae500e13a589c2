"""dynmodel diagnose on real friction data: the pneumatic seal rig (non-uniformly sampled, headerless
text) and EMPS (MATLAB files). The data live in ../shared/data next to the repository; the tests
skip when that folder is absent. The figures quoted in the README come from these runs."""

from __future__ import annotations

import json

import pytest
from conftest import ROOT, SHARED_DATA

from dynmodel.diagnose import Settings, diagnose
from dynmodel.spec import parse_yaml

PNEUMATIC = SHARED_DATA / "pneumatic_seal_friction"
EMPS = SHARED_DATA / "emps"
needs_pneumatic = pytest.mark.skipif(not PNEUMATIC.is_dir(), reason=f"real friction data not found at {PNEUMATIC}")
needs_emps = pytest.mark.skipif(not EMPS.is_dir(), reason=f"EMPS data not found at {EMPS}")


def _run(name: str, **settings):
    path = ROOT / "specs" / f"diagnose-{name}.yaml"
    raw = parse_yaml(path.read_text(), str(path))
    return diagnose(raw, str(path), path.parent, Settings(**settings))


@needs_pneumatic
def test_pneumatic_seal_one_step_model_loses_track_and_free_running_estimation_fixes_it():
    result = _run("pneumatic-seal", rounds=2)
    assert result.baseline.ds.sampling_time == 0.01  # resampled from the ~10 ms stamps
    top = result.findings[0]
    assert top.cause == "free-run-instability"
    assert top.evidence["nmse_free_run"] > 90.0 and top.evidence["nmse_one_step"] < 0.1
    chosen = result.rounds[0].chosen
    assert chosen.extension.patch == {"cost": "mse_inf"} and result.rounds[0].accepted
    assert result.rounds[1].verdict == "adequate"
    gain = result.gain
    assert gain["test_nmse_before"] > 80.0 and gain["test_nmse_after"] < 2.0
    assert gain["uncertainty"]["relative_reduction"]["interval_95"][0] > 0.9


@needs_pneumatic
def test_pneumatic_seal_extrapolating_to_a_higher_pressure_diverges(cli, tmp_path):
    spec = ROOT / "specs" / "diagnose-pneumatic-seal-pressures.yaml"
    r = cli("diagnose", spec, "--report", tmp_path / "rep", "--json", tmp_path / "d.json", "-q")
    assert r.exit_code == 0, r.stderr
    summary = json.loads((tmp_path / "d.json").read_text())
    top = summary["findings"][0]
    assert top["cause"] == "free-run-instability"
    ev = top["evidence"]
    assert ev["diverged"] and ev["split"] == "test" and "7bar" in ev["recording"]
    # fitted at 1-5 bar the model is excellent on validation; of the stabilizers, the terms selected on the
    # free-running error (grown from the linear model since issue 14) validate best, and they stay bounded at
    # 7 bar, where the one-step structure diverges; the gain says what the test split shows
    assert summary["baseline"]["metrics"]["validation"]["nmse"] < 0.5
    first = summary["extended"]["rounds"][0]
    assert first["accepted"] and first["chosen"]["patch"]["model"]["params"]["selection"] == "free_run"
    assert first["chosen"]["metrics"]["test"]["nmse"] is not None  # bounded where the baseline diverged
    assert summary["gain"]["baseline_diverged_on_test"] and summary["gain"]["relative_reduction"] is None
    assert (tmp_path / "rep" / "index.md").exists()


@needs_emps
def test_emps_trend_is_named_but_the_time_term_brings_no_gain():
    result = _run("emps", rounds=2)
    assert result.baseline.ds.sampling_time == pytest.approx(0.001, rel=1e-6)
    assert result.baseline.nmse("test") < 1.0
    top = result.findings[0]
    assert top.cause == "sensor-drift" and top.evidence["input_explained_share"] < 0.5
    # the measured gain refutes a sensor drift: the remedy changes nothing, so the round is not accepted
    assert not result.rounds[0].accepted and abs(result.gain["relative_reduction"]) < 0.05
