"""Thesis chapter 6 reproductions with the shipped specs: pre-sliding and sliding cross-prediction
(6.2 / 6.3), feed-forward control of the GMS plant (6.4.5), and the real EMPS benchmark.

Thresholds sit a little above the figures measured on the reference machine (README, Results);
the 6.4.5 targets of the issue (alpha >= 99.5 %, beta >= 90 %) are asserted as they stand and
marked as an expected failure while they are not reached (strict: a model that reaches them
turns the mark into a failure, so it gets removed)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT, SHARED_DATA

import dynmodel
from dynmodel import control as ctl
from dynmodel.spec import load_spec

SPECS = ROOT / "specs"
EMPS = SHARED_DATA / "emps"
needs_emps = pytest.mark.skipif(
    not (EMPS / "DATA_EMPS.mat").is_file(), reason=f"the EMPS benchmark data are not in {EMPS} (see the README)"
)


def fitted(name: str, tmp_path):
    spec = load_spec(SPECS / f"{name}.yaml")
    spec.output = str(tmp_path / f"{name}.h5")
    return dynmodel.fit(spec)


# ----------------------------------------------------------------------------- 6.2 pre-sliding
def test_presliding_networks_beat_the_narx_model(tmp_path):
    """6.2.3: free-running test NMSE on the last 8000 of 24000 samples (thesis, measured data:
    RNN 0.86 %, NARX 2.49 %). Measured here: NARX 4.3 %, annealed RNN 1.9 %, ESN 1.0 %."""
    nmse = {
        name: fitted(f"thesis-6.2-presliding-{name}", tmp_path).metrics["test"]["nmse"]
        for name in ("narx", "rnn", "esn")
    }
    assert nmse["narx"] < 6.0
    assert nmse["rnn"] < 2.5 and nmse["esn"] < 1.5
    assert max(nmse["rnn"], nmse["esn"]) < nmse["narx"]


# ----------------------------------------------------------------------------- 6.3 sliding
@pytest.mark.slow
def test_sliding_networks_beat_the_narx_model(tmp_path):
    """6.3.2: 110000 samples at 2500 Hz, test on the last 20000 (thesis: RNN 0.13 %, NARX 1.11 %).
    Measured here: NARX 19.5 %, annealed RNN 5.1 %, ESN 2.3 %."""
    nmse = {
        name: fitted(f"thesis-6.3-sliding-{name}", tmp_path).metrics["test"]["nmse"] for name in ("narx", "rnn", "esn")
    }
    assert nmse["narx"] is not None and nmse["narx"] < 25.0
    assert nmse["rnn"] < 7.0 and nmse["esn"] < 3.0
    assert max(nmse["rnn"], nmse["esn"]) < 0.5 * nmse["narx"]


# ----------------------------------------------------------------------------- 6.4.5 control
def _p_control_and_perfect(params: dict, seed: int) -> dict:
    """One 100 s tracking run as in 6.4.4: P-control to 50 s, then the perfect model's feed-forward."""
    plant, _ = ctl.make_plant("friction-plant", params)
    n, switch, skip = 100_000, 50_000, 20_000
    task = plant.tracking_task(n, np.random.default_rng(seed))
    run = task.start(switch, np.random.default_rng([seed, 1]))
    pos, _ = run.resume(task.perfect_feedforward())
    e = np.concatenate([run.position, pos]) - task.reference
    out = ctl.criteria(task.reference, e, switch, skip)
    out["max_over_rms"] = float(np.max(np.abs(e[skip:switch])) / np.sqrt(np.mean(e[skip:switch] ** 2)))
    return out


@pytest.mark.slow
def test_645_default_plant_reproduces_the_published_p_control_and_perfect_model_figures():
    """Friction system 1 as published (6.4.5): NMSE_P 0.897 %, MAX_P 0.280 (a P-error whose peaks are
    2.95 times its rms), perfect model alpha 99.992 %, beta 99.65 %. The plant's reference is
    calibrated on these figures (the thesis does not give its signal generator); the previous one
    (std 5 cm over 0.05 - 0.5 Hz) gave MAX_P 0.14, a peak ratio 1.55 and a perfect beta of 94.6 %."""
    runs = [_p_control_and_perfect({}, seed) for seed in range(5)]
    mean = {k: float(np.mean([r[k] for r in runs])) for k in runs[0]}
    assert 0.75 < mean["nmse_p"] < 1.0
    assert 0.24 < mean["max_p"] < 0.32
    assert 2.5 < mean["max_over_rms"] < 3.5
    assert mean["alpha"] > 99.99 and mean["beta"] > 99.0
    previous = [_p_control_and_perfect({"reference": {"std": 0.05, "band": [0.05, 0.5]}}, seed) for seed in range(3)]
    assert np.mean([r["max_p"] for r in previous]) < 0.18 and np.mean([r["beta"] for r in previous]) < 97.0


def _control(name: str, d):
    model = fitted(name, d)
    data = model.spec["data"]
    plant, _ = ctl.make_plant(data["generator"], data["params"])
    report = ctl.run(model, plant, ctl.Settings(realizations=5))
    return model, report.summary()


@pytest.fixture(scope="module")
def control_645(tmp_path_factory):
    return _control("thesis-6.4.5-rnn", tmp_path_factory.mktemp("c645"))


@pytest.fixture(scope="module")
def control_645_esn(tmp_path_factory):
    return _control("thesis-6.4.5-esn", tmp_path_factory.mktemp("c645esn"))


@pytest.mark.slow
def test_645_esn_with_wide_input_weights_is_the_best_feedforward(control_645_esn):
    """The best shipped model of the ablation on the calibrated plant (docs/ablations.md; seeds 0 - 4: NMSE_s
    0.75 %, alpha 97.8 ± 0.7 %, beta 83.2 ± 1.9 %): input weights of std 30 put the turnover of the friction after a reversal
    into the nonlinear part of tanh (std 3: NMSE_s 1.5 %, alpha 96.0 %, beta 74 %)."""
    model, s = control_645_esn
    assert model.metrics["test"]["nmse"] < 1.0
    assert s["model"]["alpha"]["mean"] > 97.0 and s["model"]["beta"]["mean"] > 79.0


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="6.4.5 targets not reached on the calibrated plant: the best shipped model (thesis-6.4.5-esn) gives "
    "alpha 97.8 %, beta 83.2 % (NMSE_s 0.75 %, 5 seeds); its error structure needs NMSE_s ~0.12 % (docs/ablations.md)",
)
def test_645_best_model_reaches_the_thesis_targets(control_645_esn):
    _, s = control_645_esn
    assert s["model"]["alpha"]["mean"] >= 99.5
    assert s["model"]["beta"]["mean"] >= 90.0


@pytest.mark.slow
def test_645_feedforward_reduces_the_tracking_error(control_645):
    """What the shipped annealed network reaches on the calibrated plant (docs/ablations.md, seed 0: NMSE_s
    1.66 %, alpha 98.2 %, beta 84.8 %; seeds 0 - 2: alpha 95.2 ± 3.6 %, beta 74 ± 11 %), and the perfect
    model's limits (thesis: alpha 99.992 %, beta 99.65 %)."""
    model, s = control_645
    assert model.metrics["test"]["nmse"] < 5.0
    assert s["model"]["nmse_ff"]["mean"] < 0.05 * s["model"]["nmse_p"]["mean"]
    assert s["model"]["alpha"]["mean"] > 94.0 and s["model"]["beta"]["mean"] > 50.0
    assert s["perfect"]["alpha"]["mean"] > 99.99 and s["perfect"]["beta"]["mean"] > 95.0


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="6.4.5 targets not reached: the shipped annealed network gives alpha 98.2 %, beta 84.8 % (seed 0; "
    "seeds 0 - 2: 95.2 / 74 %) on the calibrated plant (docs/ablations.md)",
)
def test_645_reaches_the_thesis_targets(control_645):
    _, s = control_645
    assert s["model"]["alpha"]["mean"] >= 99.5
    assert s["model"]["beta"]["mean"] >= 90.0


# ----------------------------------------------------------------------------- EMPS (real data)
@needs_emps
def test_emps_standard_benchmark(tmp_path):
    """vir -> qm, train DATA_EMPS, test DATA_EMPS_PULSES scored after the first 20 samples
    (published best black-box: fit 96.8 %, RMSE about 2.64e-3 m; measured here: 96.5 %, 2.87e-3 m)."""
    model = fitted("emps-benchmark-narx", tmp_path)
    test = model.metrics["test"]
    assert test["samples"] == 24841 - 20
    assert test["fit"] > 96.0 and test["rmse"] < 3.2e-3
    assert test["fit"] == pytest.approx(100 * (1 - np.sqrt(test["nmse"] / 100)), rel=1e-9)


@needs_emps
def test_emps_cross_prediction_position_to_force(tmp_path):
    """qm -> vir with a free-running network: the held-out end of DATA_EMPS is predicted closely
    (measured fit 97.2 %); on DATA_EMPS_PULSES the force pulses are not predictable from the
    position before they have moved the axis (measured fit 7.6 %)."""
    model = fitted("emps-cross-esn", tmp_path)
    assert model.metrics["validation"]["fit"] > 95.0
    assert model.metrics["test"]["fit"] is not None and model.metrics["test"]["samples"] == 24841 - 20
