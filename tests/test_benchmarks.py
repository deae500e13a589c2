"""Benchmark sources: the 1.0.1 splits, windows and units from local files, the missing-file line,
a cross-check against the nonlinear-benchmarks package, and the shipped benchmark specs."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from benchmark_files import COUNTS, WINDOWS, write
from conftest import ROOT, SHARED_DATA, make_spec, write_yaml

from dynmodel import registry
from dynmodel.data import load_dataset
from dynmodel.errors import DataError, SpecError
from dynmodel.spec import load_spec

FOLDERS = {"silverbox": "silverbox", "cascaded-tanks": "cascaded_tanks", "emps": "emps", "bouc-wen": "bouc_wen"}
UNITS = {
    "silverbox": "mV",
    "cascaded-tanks": "V",
    "emps": "mm",
    "bouc-wen": "m",
    "wiener-hammerstein": "mV",
    "ced": "ticks/s",
}


def _spec(name: str, root: Path, **data):
    return make_spec({"data": {"benchmark": name, "root": str(root), **data}, "model": {"family": "narx"}})


def _counts(ds) -> dict[str, int]:
    """Samples per split key (a steady-state test set counted without its lead-in copy)."""
    out = {k: sum(b - a for _, a, b in ds.ranges[k]) - ds.lead_in.get(k, 0) for k in ds.splits()}
    out["train"] = out.get("train", 0) + out.pop("validation", 0)
    return out


def _check_layout(name: str, ds) -> None:
    assert _counts(ds) == COUNTS[name]
    for key in ds.test_splits():
        if WINDOWS[name] == "all":
            assert key in ds.score_all and ds.n_scored(key) == COUNTS[name][key]
        else:
            assert ds.windows[key] == WINDOWS[name]
            assert ds.n_scored(key) == COUNTS[name][key] - WINDOWS[name]
    assert {n: u[1] for n, u in ds.units.items()} == {"y": UNITS[name]}


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_every_benchmark_source_yields_the_documented_split_sizes(tmp_path, name):
    ds = load_dataset(_spec(name, write(name, tmp_path / name), split={"train": 1.0}))
    _check_layout(name, ds)
    assert ds.input_names == ["u"] and ds.output_names == ["y"]


def test_validation_is_carved_from_training_as_a_run_of_its_own(tmp_path):
    root = write("emps", tmp_path / "emps")
    ds = load_dataset(_spec("emps", root, split={"train": 0.8, "validation": 0.2}))
    assert ds.ranges["train"] == [(0, 0, 19873)]
    ((rec, a, b),) = ds.ranges["validation"]
    assert (a, b) == (0, 24841 - 19873) and ds.windows["validation"] == 20
    np.testing.assert_array_equal(ds.recordings[rec].y, ds.recordings[0].y[19873:])
    assert ds.n_scored("train") == 19873  # the window never trims training


def test_test_sets_can_be_chosen_and_windows_overridden(tmp_path):
    root = write("silverbox", tmp_path / "sb")
    ds = load_dataset(_spec("silverbox", root, test=["arrow-full", "multisine"], init_window={"test": 10}))
    assert ds.test_splits() == ["test:arrow-full", "test:multisine"]
    assert ds.windows["test:multisine"] == 10
    ds = load_dataset(_spec("bouc-wen", write("bouc-wen", tmp_path / "bw"), init_window=6))
    assert ds.windows["test:sinesweep"] == 6 and not ds.score_all  # an explicit window replaces score-all


def test_a_steady_state_test_period_is_scored_after_a_copy_of_itself(tmp_path):
    root = write("bouc-wen", tmp_path / "bw")
    ds = load_dataset(_spec("bouc-wen", root, split={"train": 0.8, "validation": 0.2}))
    ((rec, a, b),) = ds.ranges["test:multisine"]
    assert (a, b) == (0, 2 * 8192) and ds.lead_in["test:multisine"] == 8192
    np.testing.assert_array_equal(ds.recordings[rec].u[:8192], ds.recordings[rec].u[8192:])
    assert ds.scored("test:multisine") == [(rec, 8192, 16384)] and "test:multisine" in ds.score_all
    # the validation period continues the training run (the estimation set repeats one period)
    assert ds.ranges["validation"] == [(0, 32768, 40960)] and ds.n_scored("validation") == 8192
    spec = _spec("bouc-wen", root, split={"train": 0.8, "validation": 0.2})
    spec.model.params.initial = "zeros"
    spec.model.params.degree = 1
    from dynmodel import engine

    model, _ = engine.fit_dataset(spec, ds)
    m = model.metrics["test:multisine"]
    assert m["samples"] == 8192 and m["score"] == "all" and m["lead_in"] == 8192
    u = ds.recordings[rec].u
    run, y = model.predict(u)[8192:, 0], ds.recordings[rec].y[8192:, 0]
    assert m["nmse"] == pytest.approx(100 * np.mean((run - y) ** 2) / np.var(y), rel=1e-12)


def test_a_missing_file_is_one_line_naming_what_to_fetch_and_from_where(tmp_path):
    root = write("bouc-wen", tmp_path / "bw")
    (root / "yval_sinesweep.mat").unlink()
    with pytest.raises(DataError) as info:
        load_dataset(_spec("bouc-wen", root))
    line = str(info.value)
    assert "\n" not in line and "needs yval_sinesweep.mat" in line and "nonlinearbenchmark.org" in line
    with pytest.raises(DataError, match=r"no such folder.*needs SNLS80mV.mat or SNLS80mV.csv.*SilverboxFiles.zip"):
        load_dataset(_spec("silverbox", tmp_path / "nowhere"))


def test_benchmark_spec_mistakes_are_one_line(tmp_path):
    with pytest.raises(SpecError, match="benchmark 'silverbox' has no test set 'arrow'"):
        _spec("silverbox", tmp_path, test=["arrow"])
    with pytest.raises(SpecError, match="a benchmark has no separate validation recording"):
        make_spec(
            {"data": {"benchmark": "emps", "root": ".", "validation": {"path": "x"}}, "model": {"family": "narx"}}
        )
    with pytest.raises(SpecError, match="did you mean 'cascaded-tanks'"):
        make_spec({"data": {"benchmark": "cascaded-tank", "root": "."}, "model": {"family": "narx"}})
    with pytest.raises(SpecError, match="the test split is given twice"):
        load_dataset(_spec("emps", write("emps", tmp_path / "e"), split={"train": 0.8, "test": 0.2}))


def test_benchmarks_are_listed_apart_from_generators(cli):
    assert set(registry.benchmarks()) == set(COUNTS)
    assert not set(registry.sources()) & set(COUNTS)
    res = cli("plugins")
    assert res.exit_code == 0 and "benchmark sources" in res.output and "wiener-hammerstein" in res.output


def test_fit_on_a_benchmark_source_reports_its_units(tmp_path, cli):
    root = write("ced", tmp_path / "ced")
    spec = {
        "name": "ced",
        "data": {"benchmark": "ced", "root": str(root), "split": {"train": 0.75, "validation": 0.25}},
        "model": {"family": "narx", "params": {"degree": 1}},
        "evaluation": {"metrics": ["rmse"]},
    }
    res = cli("fit", write_yaml(tmp_path / "ced.yaml", spec), "--json", tmp_path / "m.json", "-q")
    assert res.exit_code == 0, res.output
    metrics = json.loads((tmp_path / "m.json").read_text())["metrics"]
    assert list(metrics) == ["train", "validation", "test:low", "test:high"]
    assert metrics["test:low"]["samples"] == 90 and metrics["test:low"]["rmse_units"] == "ticks/s"
    assert "RMSE (ticks/s)" in res.output


# ------------------------------------------------------------------ the real files


def _real(name: str) -> Path:
    root = SHARED_DATA / FOLDERS[name]
    if not root.is_dir():
        pytest.skip(f"{root} is not available")
    return root


@pytest.mark.parametrize("name", sorted(FOLDERS))
def test_the_shared_benchmark_files_give_the_documented_split_sizes(name):
    ds = load_dataset(_spec(name, _real(name), split={"train": 1.0}))
    _check_layout(name, ds)


def _no_downloads(monkeypatch, nb) -> None:
    def refuse(*args, **kwargs):
        raise RuntimeError("the cross-check never downloads")

    monkeypatch.setattr(nb.utilities.urllib.request, "urlretrieve", refuse)
    monkeypatch.setattr(nb.utilities, "download_file_from_google_drive", refuse)


def _cache(tmp: Path, folder: str, marker: str | None, files: dict[str, Path]) -> None:
    """The folder layout the package's loader expects after a download (so that it reads, never fetches)."""
    base = tmp / folder
    base.mkdir(parents=True, exist_ok=True)
    if marker:
        (base / marker).write_bytes(b"")
    for rel, src in files.items():
        (base / rel).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(src, base / rel) if src.exists() else None


def _ours(name: str, root: Path):
    ds = load_dataset(_spec(name, root, split={"train": 1.0}))
    train = [ds.recordings[r] for r, _, _ in ds.ranges["train"]]
    tests = {k: ds.recordings[ds.ranges[k][0][0]] for k in ds.test_splits()}
    return ds, train, tests


def _same(ours, theirs) -> None:
    np.testing.assert_array_equal(ours.u[:, 0], np.ravel(theirs.u))
    np.testing.assert_array_equal(ours.y[:, 0], np.ravel(theirs.y))


def test_splits_agree_with_the_nonlinear_benchmarks_package(tmp_path, monkeypatch):
    nb = pytest.importorskip("nonlinear_benchmarks")
    _no_downloads(monkeypatch, nb)
    cache = tmp_path / "cache"
    checked = []
    if (SHARED_DATA / "silverbox").is_dir():
        _cache(
            cache,
            "Silverbox",
            "SilverboxFiles.zip",
            {"SilverboxFiles/SNLS80mV.mat": SHARED_DATA / "silverbox/SNLS80mV.mat"},
        )
        train, tests = nb.Silverbox(dir_placement=cache)
        ds, ours_train, ours_tests = _ours("silverbox", SHARED_DATA / "silverbox")
        _same(ours_train[0], train)
        for key, theirs in zip(["test:multisine", "test:arrow-full", "test:arrow-no-extrapolation"], tests):
            _same(ours_tests[key], theirs)
            assert ds.windows[key] == theirs.state_initialization_window_length
        assert ds.sampling_time == pytest.approx(train.sampling_time)
        checked.append("silverbox")
    if (SHARED_DATA / "emps").is_dir():
        files = {f: SHARED_DATA / "emps" / f for f in ("DATA_EMPS.mat", "DATA_EMPS_PULSES.mat")}
        _cache(cache, "EMPS", "EMPS.zip", files)
        train, test = nb.EMPS(dir_placement=cache)
        ds, ours_train, ours_tests = _ours("emps", SHARED_DATA / "emps")
        _same(ours_train[0], train)
        _same(ours_tests["test"], test)
        assert ds.windows["test"] == test.state_initialization_window_length
        assert ds.sampling_time == pytest.approx(train.sampling_time)
        checked.append("emps")
    if (SHARED_DATA / "cascaded_tanks").is_dir():  # the package reads the .mat of the zip: made from our CSV
        ds, ours_train, ours_tests = _ours("cascaded-tanks", SHARED_DATA / "cascaded_tanks")
        mat = tmp_path / "dataBenchmark.mat"
        tr, te = ours_train[0], ours_tests["test"]
        scipy.io.savemat(mat, {"uEst": tr.u, "yEst": tr.y, "uVal": te.u, "yVal": te.y, "Ts": np.array([[4.0]])})
        _cache(cache, "Cascaded_Tanks", "CascadedTanksFiles.zip", {"CascadedTanksFiles/dataBenchmark.mat": mat})
        train, test = nb.Cascaded_Tanks(dir_placement=cache)
        assert ds.windows["test"] == test.state_initialization_window_length
        assert ds.sampling_time == train.sampling_time
        checked.append("cascaded-tanks")
    if (SHARED_DATA / "bouc_wen").is_dir():
        folder = "BoucWenFiles/Test signals/Validation signals"
        files = {
            f"{folder}/{k}val_{t}.mat": SHARED_DATA / f"bouc_wen/{k}val_{t}.mat"
            for k in "uy"
            for t in ("multisine", "sinesweep")
        }
        _cache(cache, "BoucWen", "Hysteretic Benchmark with a Dynamic Nonlinearity_1_all.zip", files)
        theirs = nb.not_splitted_benchmarks.BoucWen(train_test_split=False, dir_placement=cache)
        _, _, ours_tests = _ours("bouc-wen", SHARED_DATA / "bouc_wen")
        multisine = ours_tests["test:multisine"]  # one steady-state period, simulated after a copy of itself
        n = len(np.ravel(theirs[0].u))
        np.testing.assert_array_equal(multisine.u[n:, 0], np.ravel(theirs[0].u))
        np.testing.assert_array_equal(multisine.u[:n, 0], np.ravel(theirs[0].u))
        np.testing.assert_array_equal(multisine.y[n:, 0], np.ravel(theirs[0].y))
        _same(ours_tests["test:sinesweep"], theirs[1])
        checked.append("bouc-wen")
    # the two benchmarks we hold no data for: stand-in files in the official layout
    wh = write("wiener-hammerstein", tmp_path / "wh")
    _cache(cache, "WienerHammerBenchMark", None, {"WienerHammerBenchMark.mat": wh / "WienerHammerBenchMark.mat"})
    train, test = nb.WienerHammerBenchMark(dir_placement=cache)
    ds, ours_train, ours_tests = _ours("wiener-hammerstein", wh)
    _same(ours_train[0], train)
    _same(ours_tests["test"], test)
    assert ds.windows["test"] == test.state_initialization_window_length
    ced = write("ced", tmp_path / "ced")
    _cache(cache, "CED", "FULLTEXT01.zip", {"DATAUNIF.MAT": ced / "DATAUNIF.MAT"})
    train, test = nb.CED(dir_placement=cache)
    ds, ours_train, ours_tests = _ours("ced", ced)
    for ours, theirs in zip(ours_train, train):
        _same(ours, theirs)
    for key, theirs in zip(["test:low", "test:high"], test):
        _same(ours_tests[key], theirs)
        assert ds.windows[key] == theirs.state_initialization_window_length
    assert ds.sampling_time == train[0].sampling_time
    checked.append("wiener-hammerstein, ced")
    assert len(checked) >= 1


# ------------------------------------------------------------------ the shipped specs

#: spec -> {metrics key: the issue's target RMSE in the reporting units}
TARGETS = {
    "silverbox-narx.yaml": {"test:multisine": 0.22, "test:arrow-full": 0.32, "test:arrow-no-extrapolation": 0.23},
    "cascaded-tanks-narx.yaml": {"test": 0.45},
    "bouc-wen-narx.yaml": {"test:multisine": 3.1e-5, "test:sinesweep": 1.6e-5},
    "emps-narx.yaml": {"test": 2.9},
}
#: the level each shipped spec reaches (README leaderboard); a fit may not get worse than this
REACHED = {
    "silverbox-narx.yaml": {"test:multisine": 0.2110, "test:arrow-full": 0.4755, "test:arrow-no-extrapolation": 0.2179},
    "cascaded-tanks-narx.yaml": {"test": 0.4143},
    "bouc-wen-narx.yaml": {"test:multisine": 3.150e-5, "test:sinesweep": 1.416e-5},
    "emps-narx.yaml": {"test": 4.499},
}
FOLDER = {"silverbox": "silverbox", "cascaded": "cascaded_tanks", "bouc": "bouc_wen", "emps": "emps"}


def test_the_shipped_benchmark_specs_validate():
    found = sorted(p.name for p in (ROOT / "specs/benchmarks").glob("*.yaml"))
    assert set(TARGETS) <= set(found)
    for name in found:
        spec = load_spec(ROOT / "specs/benchmarks" / name)
        assert spec.data.benchmark in registry.benchmarks()


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """Fit a shipped benchmark spec once per session: its metrics by metrics key."""
    cache: dict[str, dict] = {}

    def fit(spec_name: str) -> dict:
        if not (SHARED_DATA / FOLDER[spec_name.split("-")[0]]).is_dir():
            pytest.skip("the shared benchmark data are not available")
        if spec_name not in cache:
            from dynmodel import engine

            spec = load_spec(ROOT / "specs/benchmarks" / spec_name)
            spec.data.root = str(SHARED_DATA / FOLDER[spec_name.split("-")[0]])
            cache[spec_name] = engine.fit(spec).metrics
        return cache[spec_name]

    return fit


@pytest.mark.slow
@pytest.mark.parametrize("spec_name", sorted(REACHED))
def test_the_shipped_benchmark_specs_keep_their_level(shipped, spec_name):
    metrics = shipped(spec_name)
    for key, level in REACHED[spec_name].items():
        assert metrics[key]["rmse"] <= 1.02 * level, f"{key}: {metrics[key]['rmse']:.4g} > {level:.4g}"


def _target_cases():
    for spec_name, targets in sorted(TARGETS.items()):
        for key, target in targets.items():
            reached = REACHED[spec_name][key]
            marks = []
            if reached > target:
                marks = [pytest.mark.xfail(strict=True, reason=f"not reached: {reached:.4g} > {target:.4g}")]
            yield pytest.param(spec_name, key, target, marks=marks, id=f"{spec_name}:{key}")


@pytest.mark.slow
@pytest.mark.parametrize("spec_name, key, target", list(_target_cases()))
def test_the_shipped_benchmark_specs_reach_the_issue_targets(shipped, spec_name, key, target):
    assert shipped(spec_name)[key]["rmse"] <= target


def test_the_files_of_a_benchmark_folder_are_never_written(tmp_path):
    """A benchmark source reads its folder: none of its files may take an output, even with --force."""
    from dynmodel import paths
    from dynmodel.errors import OutputError

    root = write("emps", tmp_path / "emps")
    spec = _spec("emps", root)
    target = next(f for f in sorted(root.iterdir()) if f.is_file())
    with pytest.raises(OutputError, match="this is the data file the command reads"):
        paths.check_output(target, "json", paths.spec_inputs(spec), force=True)
