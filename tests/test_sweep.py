"""dynmodel sweep: grids, bad input, faults, resume, determinism across executors (a real Dask
LocalCluster of 2 worker processes, real process pools, real kill -9; no mocks)."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from conftest import write_yaml
from typer.testing import CliRunner

import dynmodel
from dynmodel import registry
from dynmodel import spec as spec_mod
from dynmodel.batch import Variant, run_specs
from dynmodel.cli import app
from dynmodel.executors import InProcessExecutor, LocalPoolExecutor, make_executor, numba_cache_dir
from dynmodel.sweeps import build_points, load_grid, parse_grid, point_seed

TESTS = Path(__file__).resolve().parent


def tiny(n: int = 600, **params) -> dict:
    """A spec that fits in milliseconds: a 20-element ESN on 600 samples of the NARX system."""
    return {
        "name": "tiny",
        "data": {
            "generator": "narx-system",
            "n": n,
            "seed": 1,
            "split": {"train": 0.6, "validation": 0.2, "test": 0.2},
            "transient": 50,
        },
        "model": {"family": "esn", "params": {"size": 20, **params}},
    }


def sleepy(marker: Path) -> dict:
    raw = tiny()
    raw["model"] = {"family": "sleepy", "params": {"marker": str(marker)}}
    return raw


def stall_first(sleep: float) -> dict:
    """Four points; the first one's fit sleeps (once) until its worker is killed."""
    return {"zip": {"model.params.sleep": [sleep, 0, 0, 0], "data.n": [400, 500, 600, 700]}}


def run_cli(*args, env: dict | None = None):
    runner = CliRunner()
    return runner.invoke(app, [str(a) for a in args], catch_exceptions=False, env=env)


def one_line_error(r, code: int = 2) -> str:
    assert r.exit_code == code, (r.exit_code, r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Fix:" in lines[0], r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    return lines[0]


def results(folder: Path) -> dict[str, dict]:
    return {p["point"]: p for p in json.loads((folder / "results.json").read_text())["points"]}


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def kill_when_stalled(marker: Path, timeout: float = 90.0) -> int | None:
    """Wait for the stalled fit to write its pid, then kill -9 its process."""
    deadline = time.monotonic() + timeout
    while not marker.exists():
        if time.monotonic() > deadline:
            return None
        time.sleep(0.05)
    pid = int(marker.read_text())
    os.kill(pid, signal.SIGKILL)
    return pid


# ------------------------------------------------------------------------------ fixtures


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    """The test family `sleepy`, installed through a real entry point (a dist-info folder on the path
    of this process and, through PYTHONPATH, of every worker process started afterwards)."""
    root = tmp_path_factory.mktemp("plugin")
    shutil.copy(TESTS / "sweep_plugin.py", root / "dynmodel_test_sleepy.py")
    dist = root / "dynmodel_test_sleepy-0.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: dynmodel-test-sleepy\nVersion: 0.0\n")
    (dist / "entry_points.txt").write_text("[dynmodel.families]\nsleepy = dynmodel_test_sleepy:Sleepy\n")
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(root), str(TESTS)] + ([old] if old else []))
    sys.path.insert(0, str(root))
    registry._load_group.cache_clear()
    spec_mod.spec_model.cache_clear()
    assert "sleepy" in registry.families()
    yield root
    sys.path.remove(str(root))
    if old is None:
        os.environ.pop("PYTHONPATH", None)
    else:
        os.environ["PYTHONPATH"] = old
    registry._load_group.cache_clear()
    spec_mod.spec_model.cache_clear()


@pytest.fixture(scope="module")
def dask_cluster(plugin):
    """One LocalCluster of 2 single-threaded worker processes for every Dask test of this module,
    made by the same code as --scheduler local:2."""
    pytest.importorskip("distributed")
    executor = make_executor(scheduler="local:2")
    yield executor
    executor.shutdown()


@pytest.fixture(scope="module")
def local_pool(plugin):
    pool = LocalPoolExecutor(2)
    yield pool
    pool.shutdown(wait=False)


@pytest.fixture
def spec_file(tmp_path):
    return write_yaml(tmp_path / "spec.yaml", tiny())


# ------------------------------------------------------------------------------ the grid


def test_grid_points_values_and_seeds(tmp_path):
    grid = parse_grid(
        {
            "model.params.size": [10, 20],
            "model.params.scale.value": {"linspace": [0.8, 0.9, 3]},
            "zip": {"data.delay_lines": [[], [5, 10]], "cost": ["mse1", "mse_inf"]},
        }
    )
    points = build_points(tiny(), tmp_path, grid)
    assert len(points) == 2 * 3 * 2 == len({p.key for p in points})
    assert points[0].values == {
        "model.params.size": 10,
        "model.params.scale.value": 0.8,
        "data.delay_lines": [],
        "cost": "mse1",
    }
    assert points[1].values["data.delay_lines"] == [5, 10] and points[1].values["cost"] == "mse_inf"
    assert [p.values["model.params.scale.value"] for p in points[::2][:3]] == [0.8, 0.85, 0.9]
    assert points[-1].raw["model"]["params"]["size"] == 20 and points[-1].raw["data"]["delay_lines"] == [5, 10]
    # seeds: derived from the spec seed and the point's values, recorded in the point's spec
    seeds = [p.seed for p in points]
    assert len(set(seeds)) == len(seeds) and all(p.raw["seed"] == p.seed for p in points)
    assert seeds[0] == point_seed(0, points[0].values)
    # a configuration keeps its seed when the grid around it grows
    wider = build_points(tiny(), tmp_path, parse_grid({"model.params.size": [5, 10, 20]}))
    narrow = build_points(tiny(), tmp_path, parse_grid({"model.params.size": [10, 20]}))
    assert [p.seed for p in wider[1:]] == [p.seed for p in narrow]
    # another spec seed gives other seeds; a swept seed is used as given
    assert (
        build_points({**tiny(), "seed": 5}, tmp_path, parse_grid({"model.params.size": [10]}))[0].seed != wider[1].seed
    )
    swept = build_points(tiny(), tmp_path, parse_grid({"seed": {"range": [3, 9, 2]}, "model.params.size": [10]}))
    assert [p.seed for p in swept] == [3, 5, 7]


def test_grid_value_spelling_does_not_change_the_configuration(tmp_path):
    """1e-1 and 0.1e0 (PyYAML read the first as text), 1 and 1.0: the same value, the same point seed."""
    (tmp_path / "a.yaml").write_text("model.params.scale.value: [1e-1, 1]\n")
    (tmp_path / "b.yaml").write_text("model.params.scale.value: [0.1e0, 1.0]\n")
    a = build_points(tiny(), tmp_path, load_grid(tmp_path / "a.yaml"))
    b = build_points(tiny(), tmp_path, load_grid(tmp_path / "b.yaml"))
    assert [p.values["model.params.scale.value"] for p in a] == [0.1, 1]
    assert [p.seed for p in a] == [p.seed for p in b] and a[0].seed != a[1].seed


@pytest.mark.parametrize(
    "grid, expected",
    [
        ({"model.params.sise": [100, 200]}, ["model.params.sise=100", "unknown key 'sise'", "did you mean 'size'"]),
        ({"modle.params.size": [100]}, ["unknown key 'modle'", "did you mean 'model'"]),
        ({"model.params.size": []}, ["model.params.size: the list of values is empty"]),
        ({"model.params.size": [100, -5]}, ["model.params.size=-5", "greater than 0"]),
        ({"cost": ["mse1", "mse2"]}, ["cost=mse2", "mse_inf"]),
        ({"model.params.size": 100}, ["takes a list of values", "model.params.size: [100]"]),
        ({"data.delay_lines": [80, 160]}, ["list of lists", "data.delay_lines: [[80]]"]),
        ({"zip": {"model.params.size": [1, 2], "seed": [1]}}, ["differ in length"]),
        ({"seed": {"range": ["a"]}}, ["malformed range"]),
        (
            {"model.params.size": [30], "model.params": [{"size": 40}]},
            ["'model.params' and 'model.params.size' overlap"],
        ),
    ],
)
def test_a_bad_grid_fails_in_one_line_before_anything_runs(tmp_path, spec_file, grid, expected):
    write_yaml(tmp_path / "grid.yaml", grid)
    line = one_line_error(run_cli("sweep", spec_file, "--grid", tmp_path / "grid.yaml", "--out", tmp_path / "out"))
    for text in expected:
        assert text in line, line
    assert "grid.yaml" in line and not (tmp_path / "out").exists()


def test_missing_data_of_a_point_fails_before_any_fit(tmp_path):
    write_yaml(tmp_path / "spec.yaml", {**tiny(), "data": {"path": "a.csv", "input": ["u"], "output": ["y"]}})
    (tmp_path / "a.csv").write_text("u,y\n" + "\n".join(f"{i},{(7 * i) % 13}" for i in range(300)) + "\n")
    write_yaml(tmp_path / "grid.yaml", {"data.path": ["a.csv", "b.csv"]})
    line = one_line_error(run_cli("sweep", tmp_path / "spec.yaml", "--grid", tmp_path / "grid.yaml", "--workers", 1))
    assert "b.csv" in line and "not found" in line
    assert not (tmp_path / "spec-sweep").exists() and not (tmp_path / "tiny-sweep").exists()


def test_unreachable_scheduler_and_bad_executor_options(tmp_path, spec_file):
    write_yaml(tmp_path / "grid.yaml", {"model.params.size": [10]})
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    args = ("sweep", spec_file, "--grid", tmp_path / "grid.yaml", "--out", tmp_path / "out")
    line = one_line_error(run_cli(*args, "--scheduler", f"tcp://127.0.0.1:{port}"))
    assert f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port}" in line
    line = one_line_error(run_cli(*args, "--scheduler", "local:x"))
    assert "local:N" in line
    line = one_line_error(run_cli(*args, "--scheduler", "local:2", "--workers", "2"))
    assert "give one of them" in line
    line = one_line_error(run_cli(*args, "--keep", "some"))
    assert "--keep" in line
    assert not (tmp_path / "out").exists()


def test_missing_dask_extra_is_one_line(tmp_path, spec_file, monkeypatch):
    write_yaml(tmp_path / "grid.yaml", {"model.params.size": [10]})
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if dask were not installed
    line = one_line_error(
        run_cli("sweep", spec_file, "--grid", tmp_path / "grid.yaml", "--scheduler", "local:2", "--out", tmp_path / "o")
    )
    assert 'pip install "dynmodel[dask]"' in line and not (tmp_path / "o").exists()


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.rglob("*") if p.is_file()
    }


def test_an_output_folder_holding_another_sweep_is_left_alone(tmp_path, spec_file):
    write_yaml(tmp_path / "a.yaml", {"model.params.size": [10, 20]})
    write_yaml(tmp_path / "b.yaml", {"model.params.size": [10, 30]})
    out = tmp_path / "out"
    r = run_cli("sweep", spec_file, "--grid", tmp_path / "a.yaml", "--workers", 1, "--out", out, "-q")
    assert r.exit_code == 0, r.stderr
    before = _snapshot(out)
    line = one_line_error(run_cli("sweep", spec_file, "--grid", tmp_path / "b.yaml", "--workers", 1, "--out", out))
    assert "holds another sweep" in line and "2 points" in line
    line = one_line_error(run_cli("sweep", spec_file, "--grid", tmp_path / "a.yaml", "--workers", 1, "--out", out))
    assert "already holds this sweep (2 of 2 points finished)" in line and "--resume" in line
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    line = one_line_error(run_cli("sweep", spec_file, "--grid", tmp_path / "a.yaml", "--out", tmp_path / "other"))
    assert "not empty" in line
    assert _snapshot(out) == before and (tmp_path / "other" / "notes.txt").read_text() == "mine"


def test_sweep_files_get_the_umask_like_every_other_output(tmp_path, spec_file):
    """sweep.json, results, points and specs are 0666 minus the umask (they were the 0600 of a temporary file)."""
    write_yaml(tmp_path / "g.yaml", {"model.params.size": [10, 20]})
    out = tmp_path / "out"
    previous = os.umask(0o002)
    try:
        r = run_cli("sweep", spec_file, "--grid", tmp_path / "g.yaml", "--workers", 1, "--out", out, "-q")
    finally:
        os.umask(previous)
    assert r.exit_code == 0, r.stderr
    modes = {str(p.relative_to(out)): p.stat().st_mode & 0o777 for p in out.rglob("*") if p.is_file()}
    assert {"sweep.json", "results.csv", "results.json", "points/p0000.json", "specs/p0001.yaml"} <= set(modes)
    assert set(modes.values()) == {0o664}, modes


def test_an_output_folder_that_cannot_be_written_is_refused_before_the_data(tmp_path):
    """As fit refuses an --out it cannot write, before loading anything (the data file here does not exist:
    its error would come first if the data were read before the folder was checked)."""
    raw = tiny()
    raw["data"] = {"path": "missing.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.7, "validation": 0.3}}
    spec = write_yaml(tmp_path / "spec.yaml", raw)
    write_yaml(tmp_path / "g.yaml", {"model.params.size": [10]})
    for out, reason in (("/proc/dynmodel-sweep", "/proc"), ("/sys/dynmodel-sweep", "/sys")):
        line = one_line_error(run_cli("sweep", spec, "--grid", tmp_path / "g.yaml", "--workers", 1, "--out", out))
        assert line.startswith(f"error: {out}: cannot create files in '{reason}'") and "--out" in line, line


def test_the_data_a_sweep_reads_never_takes_its_json(tmp_path):
    """--json onto the spec's data file is refused even with --force (it replaced the training data)."""
    from conftest import narx as narx_data
    from conftest import write_csv

    u, y = narx_data(600, 1)
    data = write_csv(tmp_path / "train.csv", {"u": u, "y": y})
    raw = tiny()
    raw["data"] = {"path": "train.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.7, "validation": 0.3}}
    spec = write_yaml(tmp_path / "spec.yaml", raw)
    write_yaml(tmp_path / "g.yaml", {"model.params.size": [10]})
    before = data.read_bytes()
    line = one_line_error(
        run_cli("sweep", spec, "--grid", tmp_path / "g.yaml", "--workers", 1, "--json", data, "--force", "-q")
    )
    assert "this is the data file the command reads" in line and data.read_bytes() == before


def test_resume_refuses_data_that_changed_since_the_sweep_started(tmp_path):
    """The identity covers the specs, not the files: a resume after the data file changed would mix points
    scored on the old data with points scored on the new."""
    from conftest import narx as narx_data
    from conftest import write_csv

    u, y = narx_data(600, 1)
    data = write_csv(tmp_path / "train.csv", {"u": u, "y": y})
    raw = tiny()
    raw["data"] = {"path": "train.csv", "input": ["u"], "output": ["y"], "split": {"train": 0.7, "validation": 0.3}}
    spec = write_yaml(tmp_path / "spec.yaml", raw)
    write_yaml(tmp_path / "g.yaml", {"model.params.size": [10, 12]})
    args = ("sweep", spec, "--grid", tmp_path / "g.yaml", "--workers", 1, "--out", tmp_path / "out", "-q")
    assert run_cli(*args).exit_code == 0
    assert run_cli(*args, "--resume").exit_code == 0  # unchanged data: nothing to run, no complaint
    u2, y2 = narx_data(600, 2)
    write_csv(data, {"u": u2, "y": y2})
    line = one_line_error(run_cli(*args, "--resume"))
    assert "train.csv changed since this sweep started" in line and "new --out" in line


# ------------------------------------------------------------------------------ results and faults


def test_results_failing_and_diverging_points_are_recorded(tmp_path):
    # an external ESN of 100 elements on 360 training samples, plain least squares on every state without
    # tune-in and without the output clip (bounds: null): its fed-back output explodes at once, whatever the
    # seed (see test_cli); narx with a lag longer than the data: fails in fit; the others fit
    write_yaml(tmp_path / "spec.yaml", tiny())
    grid = {
        "zip": {
            "model.params": [
                {"size": 20},
                {
                    "size": 100,
                    "mode": "external",
                    "tune_in": 0,
                    "readout": {"solver": "lstsq", "direct": False},
                    "bounds": None,
                },
                {"lags": {"u": [0, 1], "y": [1, 900]}},
                {"lags": {"u": [0, 1], "y": [1, 2]}},
            ],
            "model.family": ["esn", "esn", "narx", "narx"],
        }
    }
    write_yaml(tmp_path / "grid.yaml", grid)
    out = tmp_path / "out"
    r = run_cli(
        "sweep", tmp_path / "spec.yaml", "--grid", tmp_path / "grid.yaml", "--workers", 1, "--out", out,
        "--keep", "all", "--json", tmp_path / "r.json", "-q",
    )  # fmt: skip
    assert r.exit_code == 0, r.stderr
    pts = results(out)
    assert [pts[k]["status"] for k in sorted(pts)] == ["ok", "diverged", "error", "ok"]
    assert "tunes in on the first" in pts["p0002"]["message"] and "model.params" in pts["p0002"]["message"]
    assert "diverged on the train split" in pts["p0001"]["message"] and pts["p0001"]["metrics"]["train"]["nmse"] is None
    assert "p0002: " in r.stdout and "tunes in on the first" in r.stdout
    # the table ranks stable points by validation NMSE, then the diverged one, then the error
    csv_rows = (out / "results.csv").read_text().splitlines()
    header = csv_rows[0].split(",")
    assert header[:3] == ["point", "status", "model.params"] and "validation.nmse" in header and "test.max" in header
    ok = sorted(["p0000", "p0003"], key=lambda k: pts[k]["metrics"]["validation"]["nmse"])
    order = [line.split()[1] for line in r.stdout.splitlines() if line.startswith("│ p0")]
    assert order == ok + ["p0001", "p0002"]
    assert json.loads((tmp_path / "r.json").read_text())["best"] == ok[0]
    # --keep all: every stable and diverged model is written and loads
    for k in ("p0000", "p0001", "p0003"):
        model = dynmodel.load(out / pts[k]["model"])
        assert model.metrics == pts[k]["metrics"]
    assert pts["p0002"]["model"] is None and (out / "sweep.png").stat().st_size > 10000


def test_resume_runs_only_the_missing_and_failed_points(tmp_path, spec_file):
    narx_too_long = {"lags": {"u": [0], "y": [1, 900]}}  # fails in fit: more lag than data
    grid = {
        "zip": {"model.family": ["esn", "esn", "narx"], "model.params": [{"size": 10}, {"size": 20}, narx_too_long]}
    }
    write_yaml(tmp_path / "grid.yaml", {**grid, "seed": [0, 1]})
    out = tmp_path / "out"
    args = ("sweep", spec_file, "--grid", tmp_path / "grid.yaml", "--workers", 1, "--out", out, "-q")
    r = run_cli(*args)
    assert r.exit_code == 0, r.stderr
    first = results(out)
    errors = [k for k, p in first.items() if p["status"] == "error"]
    assert errors == ["p0004", "p0005"]
    best = json.loads((out / "results.json").read_text())["best"]
    assert sorted(p.name for p in (out / "models").iterdir()) == [f"{best}.h5"]  # --keep best
    lost = next(k for k in ("p0000", "p0001", "p0002", "p0003") if k != best)
    (out / "points" / f"{lost}.json").unlink()  # as if the sweep had been stopped before it finished
    kept = {k: (out / "points" / f"{k}.json").read_bytes() for k in first if k != lost and k not in errors}
    r = run_cli(*args, "--resume")
    assert r.exit_code == 0, r.stderr
    assert "3 fitted on in-process (1 worker)" in r.stdout and "3 finished earlier" in r.stdout
    again = results(out)
    rerun = sorted(k for k in again if again[k]["run"] != first[k]["run"])
    assert rerun == sorted([lost, *errors])  # errors are retried: they may have been transient
    assert all((out / "points" / f"{k}.json").read_bytes() == v for k, v in kept.items())
    assert again[lost]["metrics"] == first[lost]["metrics"]  # the same seed, the same numbers


def test_python_api_returns_a_sortable_table(tmp_path):
    raw = tiny()
    result = dynmodel.sweep(raw, {"model.params.size": [10, 20], "seed": [0, 1]}, executor=InProcessExecutor())
    assert len(result) == 4 and result.counts()["ok"] == 4 and result.folder is None
    assert result.columns[:4] == ["point", "status", "model.params.size", "seed"]
    ranked = result.sort()
    vals = [row["validation.nmse"] for row in ranked]
    assert vals == sorted(vals) and ranked[0]["point"] == result.best["point"]
    by_size = result.sort("model.params.size", descending=True)
    assert [r["model.params.size"] for r in by_size] == [20, 20, 10, 10]
    # the best model is kept in memory and predicts like a freshly fitted one
    best = result.best
    model = result.best_model
    assert model.metrics == result.records[best["point"]]["metrics"]
    refit = dynmodel.fit(spec_mod.validate_spec(next(p.raw for p in result.points if p.key == best["point"])))
    assert refit.metrics == model.metrics
    u = np.random.default_rng(0).standard_normal(300)
    np.testing.assert_array_equal(model.predict(u), refit.predict(u))
    assert len(result.summary) == 2 and {e["ok"] for e in result.summary} == {2}
    pd = pytest.importorskip("pandas")
    frame = result.to_pandas()
    assert isinstance(frame, pd.DataFrame) and frame.shape[0] == 4 and "test.nmse" in frame.columns


def test_run_specs_stops_on_cancel_and_budget():
    pulled = []

    def variants():
        for i in range(10):
            pulled.append(i)
            yield Variant(f"v{i}", {**tiny(), "seed": i})

    stop = threading.Event()
    got = []
    for res in run_specs(variants(), InProcessExecutor(), cancel=stop):
        got.append(res.key)
        if len(got) == 2:
            stop.set()
    assert got == ["v0", "v1"] and pulled == [0, 1]  # lazily consumed: nothing pulled after the stop
    assert list(run_specs(variants(), InProcessExecutor(), budget=0)) == []


def test_numba_cache_goes_to_a_writable_folder(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    assert numba_cache_dir(tmp_path) is None  # writable: numba's default, next to the sources
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")  # nothing can be created below a file, like a read-only install
    fallback = numba_cache_dir(blocked)
    assert fallback is not None and Path(fallback).parent == Path(tempfile.gettempdir())
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert numba_cache_dir(blocked) is None  # the user's choice stands


# ------------------------------------------------------------------------------ parallel: pool and Dask


def test_metrics_are_bit_identical_serial_pooled_and_on_dask(tmp_path, local_pool, dask_cluster):
    # ridge readouts of 150 states: with 2 BLAS threads instead of 1 their last bits differ, so the serial
    # run, made with 2 BLAS threads in this process, also checks that fits pin BLAS to one thread
    from threadpoolctl import threadpool_limits

    write_yaml(tmp_path / "spec.yaml", tiny(n=1500, readout={"solver": "ridge"}))
    write_yaml(tmp_path / "grid.yaml", {"model.params.size": [20, 150], "seed": {"range": [0, 2]}})
    common = ["sweep", tmp_path / "spec.yaml", "--grid", tmp_path / "grid.yaml", "-q", "--keep", "none"]
    with threadpool_limits(limits=2, user_api="blas"):
        r = run_cli(*common, "--workers", 1, "--out", tmp_path / "serial")
    assert r.exit_code == 0, r.stderr
    pooled = dynmodel.sweep(
        tmp_path / "spec.yaml", tmp_path / "grid.yaml", executor=local_pool, out=tmp_path / "pool", keep="best"
    )
    assert pooled.counts()["ok"] == 4
    r = run_cli(*common, "--scheduler", dask_cluster.address, "--out", tmp_path / "dask")
    assert r.exit_code == 0, r.stderr
    runs = {name: results(tmp_path / name) for name in ("serial", "pool", "dask")}
    workers = {name: {p["worker"] for p in pts.values()} for name, pts in runs.items()}
    assert len(workers["serial"]) == 1 and all(len(w) >= 1 for w in workers.values())
    assert workers["pool"].isdisjoint(workers["serial"]) and workers["dask"].isdisjoint(workers["pool"])
    for key, point in runs["serial"].items():
        assert point["status"] == "ok"
        for name in ("pool", "dask"):
            assert runs[name][key]["metrics"] == point["metrics"], (name, key)  # == on floats: bit for bit
    # a worker loads the recording once, not once per point
    for name, pts in runs.items():
        loads = [p["load_seconds"] > 0 for p in pts.values()]
        assert sum(loads) <= len(workers[name]), (name, loads)
    # each point's spec, fitted alone, gives the same numbers
    best = pooled.best["point"]
    r = run_cli("fit", tmp_path / "pool" / "specs" / f"{best}.yaml", "--json", tmp_path / "fit.json", "-q")
    assert r.exit_code == 0, r.stderr
    assert json.loads((tmp_path / "fit.json").read_text())["metrics"] == runs["serial"][best]["metrics"]
    assert dynmodel.load(tmp_path / "pool" / "models" / f"{best}.h5").metrics == runs["serial"][best]["metrics"]


def test_family_auto_sweeps_like_any_family_on_a_pool_and_on_dask(tmp_path, local_pool, dask_cluster):
    """A sweep of ``family: auto`` (here over seeds) was refused ("unknown family 'auto'"). Each point's
    search runs inside its worker (in-process there), the numbers are the same serial, pooled and on Dask, a
    point's spec fitted alone gives them too, and a kept model file holds the record of its search."""
    from dynmodel.search import search_options

    raw = tiny(n=1500)
    raw["model"] = {"family": "auto", "params": {"budget": 2, "families": ["narx"], "seeds": 1}}
    write_yaml(tmp_path / "spec.yaml", raw)
    grid = {"seed": [0, 1]}
    serial = dynmodel.sweep(tmp_path / "spec.yaml", grid, executor=InProcessExecutor(), out=tmp_path / "serial")
    pooled = dynmodel.sweep(tmp_path / "spec.yaml", grid, executor=local_pool, out=tmp_path / "pool", keep="all")
    on_dask = dynmodel.sweep(tmp_path / "spec.yaml", grid, executor=dask_cluster, out=tmp_path / "dask")
    for result in (serial, pooled, on_dask):
        assert result.counts()["ok"] == 2
    runs = {name: results(tmp_path / name) for name in ("serial", "pool", "dask")}
    for key, point in runs["serial"].items():
        assert point["metrics"]["test"]["nmse"] < 1.0
        for name in ("pool", "dask"):
            assert runs[name][key]["metrics"] == point["metrics"], (name, key)
    key = sorted(runs["serial"])[0]
    kept = dynmodel.load(tmp_path / "pool" / "models" / f"{key}.h5")
    with search_options(workers=1):
        alone = dynmodel.fit(dynmodel.load_spec(tmp_path / "pool" / "specs" / f"{key}.yaml"))
    assert kept.metrics == alone.metrics == runs["serial"][key]["metrics"]
    assert kept.search is not None and kept.search["winner"] == alone.search["winner"]
    assert kept.family.name == alone.family.name != "auto"


def test_pool_workers_run_single_threaded(local_pool):
    from dynmodel_test_sleepy import worker_facts

    facts = [local_pool.submit(worker_facts).result(timeout=120) for _ in range(2)]
    for f in facts:
        assert f["env"] == {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
        assert f["blas_threads"] == [1]


def test_a_worker_killed_mid_sweep_loses_no_point(tmp_path, local_pool):
    marker = tmp_path / "stalled.pid"
    with ThreadPoolExecutor(1) as watcher:
        killing = watcher.submit(kill_when_stalled, marker)
        result = dynmodel.sweep(sleepy(marker), stall_first(120), executor=local_pool, keep="none")
        killed = killing.result()
    assert killed is not None and not pid_alive(killed)
    assert result.counts() == {"points": 4, "ok": 4, "diverged": 0, "error": 0, "not_run": 0}
    stalled = result.records["p0000"]
    assert stalled["attempts"] == 2 and not stalled["worker"].endswith(f":{killed}")
    assert local_pool.submit(os.getpid).result(timeout=120) != killed  # the rebuilt pool keeps working


@pytest.mark.slow
def test_a_point_that_always_kills_its_worker_is_recorded_and_spares_the_others(tmp_path, local_pool):
    raw = sleepy(tmp_path / "unused")
    grid = {"zip": {"model.params.crash": [False, True, False, False], "data.n": [400, 500, 600, 700]}}
    result = dynmodel.sweep(raw, grid, executor=local_pool, keep="none")
    assert [result.records[k]["status"] for k in sorted(result.records)] == ["ok", "error", "ok", "ok"]
    assert "died 3 times" in result.records["p0001"]["message"]
    assert local_pool.submit(os.getpid).result(timeout=120) > 0  # the rebuilt pool keeps working


def test_a_dask_worker_killed_mid_sweep_loses_no_point(tmp_path, dask_cluster):
    marker = tmp_path / "stalled.pid"
    with ThreadPoolExecutor(1) as watcher:
        killing = watcher.submit(kill_when_stalled, marker)
        result = dynmodel.sweep(sleepy(marker), stall_first(120), executor=dask_cluster, keep="none")
        killed = killing.result()
    assert killed is not None
    assert result.counts() == {"points": 4, "ok": 4, "diverged": 0, "error": 0, "not_run": 0}
    assert not result.records["p0000"]["worker"].endswith(f":{killed}")  # Dask rescheduled it elsewhere
    dask_cluster.client.wait_for_workers(2, timeout=120)  # the nanny restarts the killed worker


def test_cancelling_abandons_a_running_point_and_keeps_finished_ones(tmp_path, local_pool):
    marker = tmp_path / "stalled.pid"
    variants = [
        Variant(
            "slow", {**sleepy(marker), "model": {"family": "sleepy", "params": {"marker": str(marker), "sleep": 120}}}
        ),
        *(Variant(f"v{i}", {**sleepy(marker), "seed": i}) for i in range(3)),
    ]
    t0 = time.monotonic()
    got: list[str] = []
    for res in run_specs(variants, local_pool, cancel=lambda: marker.exists() and len(got) >= 3):
        got.append(res.key)
    assert sorted(got) == ["v0", "v1", "v2"] and time.monotonic() - t0 < 100
    local_pool.restart()  # stop the abandoned fit


def test_ctrl_c_keeps_finished_points_and_resume_finishes(tmp_path, plugin):
    marker = tmp_path / "stalled.pid"
    write_yaml(tmp_path / "spec.yaml", sleepy(marker))
    write_yaml(tmp_path / "grid.yaml", {"zip": {"model.params.sleep": [0, 0, 0, 120], "data.n": [400, 500, 600, 700]}})
    out = tmp_path / "out"
    args = ("sweep", tmp_path / "spec.yaml", "--grid", tmp_path / "grid.yaml", "--workers", 1, "--out", out, "-q")

    def press_ctrl_c() -> None:  # SIGINT to this process once the last point stalls, as a terminal sends it
        deadline = time.monotonic() + 120
        while not marker.exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    # a process started in the background by a non-interactive shell (`.ci/run &`) inherits an ignored
    # SIGINT; a user's foreground terminal gives Python's own handler, which this test is about
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with ThreadPoolExecutor(1) as watcher:
            watcher.submit(press_ctrl_c)
            r = run_cli(*args)
    finally:
        signal.signal(signal.SIGINT, inherited)
    assert r.exit_code == 130, (r.stdout, r.stderr)
    assert "interrupted: 3 of 4 points finished" in r.stderr and "--resume" in r.stderr
    assert sorted(p.stem for p in (out / "points").iterdir()) == ["p0000", "p0001", "p0002"]
    assert [p["status"] for p in results(out).values()] == ["ok", "ok", "ok", "not run"]
    r = run_cli(*args, "--resume")
    assert r.exit_code == 0, r.stderr
    assert "1 fitted" in r.stdout and "3 finished earlier" in r.stdout
    assert [p["status"] for p in results(out).values()] == ["ok"] * 4
