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
    """Round 1: the one-step model loses track, free-running estimation fixes it (test NMSE 91 % -> 1 %).
    Round 2: what remains is a nonlinear function of the force itself (the seal's force saturates when it
    slides), and a leaky echo state network, offered by the esn family for that cause, quarters it."""
    result = _run("pneumatic-seal", rounds=3)
    assert result.baseline.ds.sampling_time == 0.01  # resampled from the ~10 ms stamps
    top = result.findings[0]
    assert top.cause == "free-run-instability"
    assert top.evidence["nmse_free_run"] > 90.0 and top.evidence["nmse_one_step"] < 0.1
    first = result.rounds[0]
    assert first.chosen.extension.patch == {"cost": "mse_inf"} and first.accepted
    assert first.chosen.fit.nmse("test") < 2.0
    assert result.rounds[1].verdict == "output-nonlinearity" and result.rounds[1].accepted
    assert result.rounds[-1].verdict == "adequate"
    gain = result.gain
    assert gain["test_nmse_before"] > 80.0 and gain["test_nmse_after"] < 0.5
    assert min(gain["uncertainty"]["relative_reduction"]["values"]) > 0.99


@pytest.mark.slow
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


SILVERBOX = SHARED_DATA / "silverbox"
TANKS = SHARED_DATA / "cascaded_tanks"
needs_silverbox = pytest.mark.skipif(not SILVERBOX.is_dir(), reason=f"Silverbox data not found at {SILVERBOX}")
needs_tanks = pytest.mark.skipif(not TANKS.is_dir(), reason=f"Cascaded Tanks data not found at {TANKS}")


def _rmse(fit) -> float:
    return float(fit.metrics["test"]["rmse"])


@pytest.mark.slow
@needs_silverbox
def test_silverbox_default_narx_misses_the_cubic_stiffness_and_the_diagnosis_finds_it(cli, tmp_path):
    """Silverbox (an electronic Duffing oscillator) with the narx defaults (degree 2): the residual is a
    nonlinear function of the model's own output; the extension the narx family offers for it (degree 3
    with output-dependent terms) lowers the multisine test RMSE at least tenfold."""
    spec = ROOT / "specs" / "diagnose-silverbox.yaml"
    r = cli("diagnose", spec, "--report", tmp_path / "rep", "--json", tmp_path / "d.json", "-q")
    assert r.exit_code == 0, r.stderr
    summary = json.loads((tmp_path / "d.json").read_text())
    assert summary["findings"][0]["cause"] == "output-nonlinearity"
    assert "named cause: output-nonlinearity" in r.stdout and "x lower" in r.stdout
    before = summary["baseline"]["metrics"]["test"]["rmse"]
    after = summary["extended"]["metrics"]["test"]["rmse"]
    assert before / after >= 10.0, (before, after)
    assert "## Gain on the held-out test split" in (tmp_path / "rep" / "index.md").read_text()


@pytest.mark.slow
@needs_tanks
def test_cascaded_tanks_default_narx_is_not_called_adequate():
    """Cascaded Tanks with the narx defaults: free-running estimation fits the free run significantly better
    (no noise signature: the one-step structure is biased for the free run), and the diagnosis says so and
    measures the gain (the first version called this model adequate)."""
    result = _run("cascaded-tanks")
    assert result.verdict == "noise-bias" and result.rounds[0].accepted
    assert result.findings[0].evidence["noise_signature"] < 0.3
    assert _rmse(result.final) < 0.9 * _rmse(result.baseline)


@pytest.mark.slow
@needs_tanks
@pytest.mark.xfail(
    strict=True,
    reason="target not reached: the diagnosis lowers the Tanks test RMSE by 12 % (0.789 -> 0.690 V); the tuned "
    "narx needs degree 3, output lags 1..3 and mse_inf together, whose causes are not significant on 205 "
    "validation samples (p 0.0098 > 0.001), and selection: free_run returns a constant model (issue 14)",
)
def test_cascaded_tanks_diagnosis_reaches_the_target_gain():
    result = _run("cascaded-tanks")
    assert _rmse(result.final) <= 0.7 * _rmse(result.baseline)
