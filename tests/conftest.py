"""Shared helpers: in-process CLI runs, small generated data files, spec building."""

from __future__ import annotations

import os

# The tests' linear algebra is on small matrices, where threaded BLAS only adds contention (and
# run-to-run timing noise on shared machines); results are also independent of the thread count.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from dynmodel.cli import app
from dynmodel.spec import validate_spec

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


def benchmark(name: str) -> ModuleType:
    """The script ``benchmarks/<name>.py`` as a module (its cases and generators, the ones measured there); the
    benchmarks folder is on the import path while it loads, for the scripts' shared helpers."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return module


def narx(n: int, seed: int, a0: float = 0.8, b0: float = -0.2, c0: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Plain-python twin of the narx-system generator (eq. 3.37), for independent checks."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(n):
        y1 = y[t - 1] if t >= 1 else 0.0
        y2 = y[t - 2] if t >= 2 else 0.0
        y[t] = a0 * y1 + b0 / (1 + abs(y2)) + c0 * u[t]
    return u, y


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> Path:
    names = list(columns)
    data = np.column_stack([columns[n] for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return path


def write_yaml(path: Path, spec: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def make_spec(raw: dict[str, Any], base: Path | None = None):
    return validate_spec(raw, "<test>", base)


def narx_spec(
    mode: str = "internal",
    seed: int = 0,
    cost: str = "mse1",
    n: int = 10000,
    test_n: int = 10000,
    transient: int = 1000,
    noise: float | None = None,
    split: dict | None = None,
    scaling: str = "none",
    **params,
) -> dict[str, Any]:
    """The thesis 5.3.2 task: narx-system, separate test realization, 1000-sample transient."""
    data: dict[str, Any] = {
        "generator": "narx-system",
        "n": n,
        "seed": 1,
        "split": split or {"train": 1.0},
        "test": {"seed": 2, "n": test_n},
        "transient": transient,
        "scaling": scaling,
    }
    if noise is not None:
        data["noise"] = {"std": noise, "splits": ["train", "validation"]}
    model_params = {
        "size": 200,
        "mode": mode,
        "connectivity": 0.01,
        "input_connectivity": 0.1,
        "bias_connectivity": 0.8,
        "scale": {"by": "singular", "value": 0.95},
        "relaxation": 0.0,  # the thesis's plain elements, without output clipping, tuned in on 100 samples
        "relaxation_gain": False,
        "tune_in": 100,
        "bounds": None,
        **params,
    }
    return {
        "name": "narx",
        "data": data,
        "model": {"family": "esn", "params": model_params},
        "cost": cost,
        "seed": seed,
    }


@pytest.fixture
def cli():
    runner = CliRunner()

    def run(*args: str):
        return runner.invoke(app, [str(a) for a in args], catch_exceptions=False)

    return run


@pytest.fixture
def narx_csvs(tmp_path: Path) -> tuple[Path, Path]:
    u, y = narx(4000, 11)
    ut, yt = narx(3000, 12)
    return write_csv(tmp_path / "train.csv", {"u": u, "y": y}), write_csv(tmp_path / "test.csv", {"u": ut, "y": yt})
