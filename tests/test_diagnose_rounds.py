"""dynmodel diagnose in rounds: a cause hidden behind a dominant inadequacy surfaces once the larger one is
fixed; every significant cause is listed with why it is (not) named; the adequacy reference keeps a useless
model from being called adequate."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import write_yaml
from hidden_effects import MASKED, Case, linear_system

from dynmodel.diagnose import Settings, diagnose
from dynmodel.errors import DataError

#: seeds of the masked-cause cases run by default; the slow test runs 1..8
FAST = {"sensor-drift": 2, "missing-delay": 3}


def _masked_outcome(cause: str, seed: int, tmp_path):
    case = MASKED[cause](seed)
    result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(seeds=2))
    hits = [f for r in result.rounds for f in r.significant if f.cause == cause]
    return case, result, hits


def _evidence_matches(cause: str, case: Case, finding) -> bool:
    ev, truth = finding.evidence, case.truth
    if cause == "missing-delay":
        return abs(ev["lag_samples"] - truth["lag"]) <= 3
    t0, t1 = ev["window"]
    true_change = truth["size"] * (np.exp(-t0 / truth["tau"]) - np.exp(-t1 / truth["tau"]))
    return abs(ev["drift_change"] / true_change - 1) <= 0.3


@pytest.mark.parametrize("cause", list(FAST))
def test_a_cause_masked_by_a_dominant_inadequacy_surfaces_in_some_round(cause, tmp_path):
    """GMS friction with a hidden drift or delayed path, fitted by the default echo state network (test NMSE
    25-50 %, dominated by the direction dependence of friction): the hidden cause is named in some round with
    the right evidence, and the rounds together cut the test NMSE by at least 30 %."""
    case, result, hits = _masked_outcome(cause, FAST[cause], tmp_path)
    assert result.baseline.nmse("test") > 20.0  # a dominant inadequacy
    assert hits, [(i, c) for i, c in result.named]
    assert _evidence_matches(cause, case, hits[0]), (hits[0].evidence, case.truth)
    assert len(result.rounds) >= 2 and result.gain["relative_reduction"] >= 0.3, result.gain
    summary = result.to_json()
    named = summary["extended"]["named"]
    assert {"round", "cause"} <= set(named[0]) and cause in [n["cause"] for n in named]
    rounds = summary["extended"]["rounds"]
    assert all({"named", "checks", "gain", "outcome"} <= set(r) for r in rounds)
    applied = [r["gain"] for r in rounds if r["accepted"]]
    assert applied and all(g["nmse_after"] < g["nmse_before"] for g in applied)
    assert [g["cause"] for g in summary["gain"]["rounds"] if g["accepted"]] == [g["cause"] for g in applied]


@pytest.mark.slow
@pytest.mark.parametrize("cause", list(FAST))
def test_masked_causes_over_eight_seeds(cause, tmp_path):
    """The same over seeds 1..8 (random strength, lag or time constant, trajectory): named with the right
    evidence in at least 7 of 8, every total gain at least 30 %."""
    found, gains = 0, []
    for seed in range(1, 9):
        folder = tmp_path / str(seed)
        folder.mkdir()
        case, result, hits = _masked_outcome(cause, seed, folder)
        found += bool(hits) and _evidence_matches(cause, case, hits[0])
        g = result.gain
        if g.get("baseline_diverged_on_test") and not g.get("extended_diverged_on_test"):
            # the default network's free run leaves the divergence band on the test input (every family's
            # run is held to it since issue 15) and the extended model does not: the whole error is removed
            gains.append(1.0)
        else:
            gains.append(g["relative_reduction"])
    assert found >= 7 and min(gains) >= 0.3, (found, gains)


def test_every_check_says_why_it_is_or_is_not_named(cli, tmp_path):
    spec = write_yaml(tmp_path / "s.yaml", MASKED["missing-delay"](1).spec(tmp_path))
    r = cli("diagnose", spec, "--json", tmp_path / "d.json", "-q", "--rounds", "1")
    assert r.exit_code == 0, r.stderr
    assert "why (not) named" in r.stdout and ">= alpha" in r.stdout and "causes named:" in r.stdout
    summary = json.loads((tmp_path / "d.json").read_text())
    checks = summary["baseline"]["checks"]
    assert len(checks) >= 13
    for c in checks:
        assert c["reason"], c["cause"]
        if c["significant"]:
            assert c["gates"]["p_value"] is None or c["gates"]["p_value"] < c["gates"].get("alpha", 1.0)
        elif c["gates"].get("p_value") is not None and c["gates"]["p_value"] >= c["gates"]["alpha"]:
            assert ">= alpha" in c["reason"]
    named = [c for c in checks if c["significant"]]
    assert len(named) >= 2 and len(summary["findings"]) == len(named)  # every significant cause, not only the top
    assert summary["extended"]["rounds"][0]["checks"][0]["cause"] == summary["findings"][0]["cause"]


# ------------------------------------------------------------------ adequacy reference
def test_data_growing_without_bound_is_never_called_adequate(tmp_path):
    """An unstable system's output grows without bound: the model explains nothing of it (NMSE near
    100 % or worse), and the diagnosis says so instead of 'adequate'. Growth to about 1e44 is refused
    earlier, when the data are loaded (a one-line data error naming the column), never 'adequate'."""
    rng = np.random.default_rng(3)
    n = 5000
    u = rng.standard_normal(n)
    y = linear_system(u, a0=1.003)
    assert np.abs(y).max() > 1e7
    case = Case("growth", {"u": u, "y": y}, {"family": "narx", "params": {"degree": 1, "lags": {"u": [0, 1]}}})
    result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(rounds=1))
    assert result.verdict != "adequate"
    found = {f.cause: f for f in result.findings}
    assert "inadequate-structure" in found
    ev = found["inadequate-structure"].evidence
    assert ev["model_nmse"][ev["split"]] >= 90.0 and ev["mean_nmse"][ev["split"]] > 0
    assert "near useless" in found["inadequate-structure"].reason

    y = linear_system(u, a0=1.02)
    assert np.abs(y).max() > 1e40
    case = Case("growth44", {"u": u, "y": y}, {"family": "narx", "params": {"degree": 1, "lags": {"u": [0, 1]}}})
    with pytest.raises(DataError, match="output column 'y' reaches"):
        diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(rounds=1))


def test_a_model_that_a_linear_reference_beats_is_named_with_the_reference_figure(tmp_path):
    """A slow first-order system (time constant 30 samples) and a polynomial without output feedback whose
    three input lags cannot remember it: the linear ARX/OE reference does far better on validation, so the
    model is not adequate, and the reference's orders become the narx family's own proposal."""
    rng = np.random.default_rng(4)
    u = rng.standard_normal(6000)
    y = linear_system(u, a0=np.exp(-1 / 30))
    y += 0.01 * y.std() * rng.standard_normal(len(y))
    case = Case("slow", {"u": u, "y": y}, {"family": "narx", "params": {"degree": 2, "lags": {"u": [0, 1, 2]}}})
    result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(rounds=1))
    found = {f.cause: f for f in result.findings}
    assert "inadequate-structure" in found, [f.cause for f in result.findings]
    f = found["inadequate-structure"]
    ref = f.evidence["reference"]
    assert ref["nmse"]["validation"] < 0.5 * result.baseline.nmse("validation")
    assert f"{ref['nmse']['validation']:.4g} %" in f.summary
    proposed = [x.summary for x in f.extensions]
    assert any("linear reference's lags" in s for s in proposed)
    assert result.gain["relative_reduction"] > 0.9


def test_an_adequate_model_beats_its_references(tmp_path):
    """The exact-form linear model on noisy linear data: the reference is no better, nothing is named."""
    rng = np.random.default_rng(5)
    u = rng.standard_normal(5000)
    y = linear_system(u) + 0.3 * rng.standard_normal(5000)
    case = Case(
        "lin",
        {"u": u, "y": y},
        {"family": "narx", "params": {"degree": 1, "lags": {"u": [0], "y": [1]}}},
        cost="mse_inf",
    )
    result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings())
    assert result.verdict == "adequate" and len(result.rounds) == 1
    check = next(f for f in result.checks if f.cause == "inadequate-structure")
    assert not check.significant and result.reference["linear"]["nmse"]["validation"] > 0


def test_adequate_with_little_power_says_so(tmp_path):
    """A lightly damped Duffing oscillator (the output-nonlinearity case, seed 111): its narrow-band residual
    leaves about ten independent batches on validation, no check reaches p < 0.001, yet the model explains
    only a third of the output variance. The verdict stays 'adequate' (nothing is significant) but says that
    the data gave the checks too little power, and which check came closest."""
    from hidden_effects import HIDDEN

    case = HIDDEN["output-nonlinearity"](111)
    result = diagnose(case.spec(tmp_path), "<test>", tmp_path, Settings(rounds=1))
    assert result.verdict == "adequate" and result.baseline.nmse("validation") > 50.0
    outcome = result.rounds[0].outcome
    assert "too little power" in outcome and "closest: output-nonlinearity" in outcome
