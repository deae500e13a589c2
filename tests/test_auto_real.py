"""family: auto on real recordings it was not tuned for (../shared/data; the tests skip without it).

The pneumatic seal rig's other seals (not the NAPN seal the seal benchmark uses), force from position and
pressure resampled to 50 Hz, as in benchmarks/auto_small_data.py; here the last fifth of each recording is
given as a separate test recording, as a user with a second file does. A test file of its own starts a free
run of its own, and the search counts that start on validation too (docs/auto.md, "The start of a test
recording"): before, it validated them as a continuation of the training run and chose internal networks whose
start-up transient the test then scored (KDN 3.0 %, kidney 9.8 % test NMSE where the NARX default scores
0.94 and 0.34 %). The search now counts a validation run started afresh as well.
"""

from __future__ import annotations

import pytest
from conftest import ROOT, SHARED_DATA, benchmark

SEALS = SHARED_DATA / "pneumatic_seal_friction" / "friction"
needs_seals = pytest.mark.skipif(not SEALS.is_dir(), reason=f"real friction data not found at {SEALS}")


@pytest.mark.slow
@needs_seals
@pytest.mark.parametrize(("name", "ceiling"), [("kdn-3bar", 0.8), ("kidney-2bar", 0.5)])
def test_with_a_separate_test_recording_auto_is_as_good_as_the_narx_default(name, ceiling):
    """Measured: KDN 0.57 % (NARX default 0.94), kidney 0.34 % (0.34); before, 3.0 and 9.8 %."""
    bench = benchmark("auto_small_data")
    data = bench.separate_test(bench.CASES[name])
    base = {"name": "seal", "data": data, "seed": 0, "evaluation": {"metrics": ["nmse"]}}
    auto, _ = bench.fit_timed({**base, "model": {"family": "auto"}}, None)
    default, _ = bench.fit_timed({**base, "model": {"family": "narx"}}, 1)
    assert any("also counts its start as a test recording's" in n for n in auto.search["notes"])
    assert auto.metrics["test"]["nmse"] < ceiling
    assert auto.metrics["test"]["nmse"] < 1.05 * default.metrics["test"]["nmse"]


@pytest.mark.slow
@needs_seals
def test_after_a_cross_validation_the_model_kept_fits_its_data_as_the_folds_did():
    """500 samples of the NAP310 seal (300 training, 100 validation, 100 test), cross-validated in five blocks.
    The winner, a linear NARX model whose ridge factor is chosen on validation, validated at 0.69 % on the
    folds; fitted on the spec's own split, the factor chosen on its 100 validation samples (at another force
    level) was 607 and the model a constant: 102 % NMSE on training, 124 % on validation, 62 474 % on a test
    whose output barely moves (the NARX default: 321 %). Its fit validated with the last block held out fits
    those samples 56 x better, and it is now the model (refitted on every sample): 242 % on that test."""
    bench = benchmark("auto_small_data")
    data = {**bench.CASES["nap310-1bar"], "segments": [[0, 500]]}
    spec = {"name": "nap500", "data": data, "model": {"family": "auto"}, "seed": 0}
    auto, _ = bench.fit_timed(spec, None)
    assert any(
        "as validated with fold 5/5 held out: it fits the training and validation samples clearly better" in n
        for n in auto.search["notes"]
    )
    assert auto.metrics["train"]["nmse"] < 10 and auto.metrics["validation"]["nmse"] < 10
    assert auto.metrics["test"]["nmse"] < 1000


@needs_seals
def test_when_every_candidate_leaves_the_band_the_best_is_kept_as_the_note_says():
    """The first 500 samples of the PK seal: the pressure rises from 0 to 5 bar, the validation and test inputs go
    172 and 181 % beyond the training range, and every candidate's free run leaves the output band somewhere.
    The choice keeps the best on validation anyway and says so; its final fit left the band too, and the search
    then failed ("found no usable model: ... kept the best on validation anyway"). It is now the model, and the
    evaluation shows how poor it is."""
    bench = benchmark("auto_small_data")
    data = bench.first_samples(bench.CASES["pk-5bar"], 500)
    auto, _ = bench.fit_timed({"name": "pk500", "data": data, "model": {"family": "auto"}, "seed": 0}, None)
    assert any("kept the best on validation anyway" in n for n in auto.search["notes"])
    assert auto.search["winner"] is not None
    assert auto.metrics["test"]["nmse"] > 1000


SILVERBOX = SHARED_DATA / "silverbox"


@pytest.mark.slow
@pytest.mark.skipif(not SILVERBOX.is_dir(), reason=f"Silverbox data not found at {SILVERBOX}")
def test_on_silverbox_auto_prefers_a_model_that_forgets_its_start_and_extrapolates_the_arrow_as_an_expert():
    """The benchmark's protocol, the default budget (specs/benchmarks/silverbox-auto.yaml). The arrow's tail goes
    25 % beyond the training input range. The degree-4 model that validates best remembers its start (a second
    attractor at its output clip) and tested 0.79 mV RMSE there; the search now fits the smallest screened
    candidates in full, prefers the 42-term model that forgets its start (validated 11 % behind), and tests at
    0.31 mV, the tuned figure (0.311 mV; the issue asks for at most 1.15 x that, 0.358)."""
    import yaml

    from dynmodel import engine
    from dynmodel.data import load_dataset
    from dynmodel.search.checks import FORGETS
    from dynmodel.spec import validate_spec

    folder = ROOT / "specs" / "benchmarks"
    raw = yaml.safe_load((folder / "silverbox-auto.yaml").read_text())
    raw["data"]["root"] = str(SILVERBOX)
    spec = validate_spec(raw, "silverbox-auto.yaml", folder)
    model, _ = engine.fit_dataset(spec, load_dataset(spec))
    chosen = next(c for c in model.search["candidates"] if c["verdict"] == "chosen")
    assert chosen["levels"]["final"]["start_memory"] <= FORGETS
    assert any(c["verdict"].startswith("set aside: its free run remembers") for c in model.search["candidates"])
    rmse_mv = {k: v["rmse"] for k, v in model.metrics.items() if k.startswith("test")}  # in mV (rmse_units)
    assert model.metrics["test:arrow-full"].get("rmse_units") == "mV"
    assert rmse_mv["test:arrow-full"] <= 0.358, rmse_mv
    assert rmse_mv["test:multisine"] <= 0.301 and rmse_mv["test:arrow-no-extrapolation"] <= 0.259, rmse_mv
