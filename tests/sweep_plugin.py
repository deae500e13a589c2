"""A model family for the sweep tests only, registered through a real ``dynmodel.families`` entry point
(tests/test_sweep.py writes a dist-info folder for it onto the path of the test process and of every
worker it starts).

``sleepy`` fits a static affine map y = W u + w0 by least squares. When ``sleep`` > 0 and the file
``marker`` does not exist yet, the fit first writes its process id into ``marker`` and sleeps: the
test reads the pid and kills that worker mid-point; the retried fit finds the marker and runs at once.
With ``crash`` every fit kills its own process (kill -9), as a point that always crashes its worker.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from dynmodel.family import Family, FamilyParams, Simulation, no_progress


class SleepyParams(FamilyParams):
    marker: str = Field("", description="file written (with the pid) by the first fit, which then sleeps")
    sleep: float = Field(0.0, ge=0, description="seconds the first fit sleeps")
    crash: bool = Field(False, description="every fit kills its own process (a point that always crashes)")


class AffineArrays:
    """The stored arrays of a test family fitted as an affine map y = u W + w0 (``W_``, ``w0_``)."""

    W_: np.ndarray
    w0_: np.ndarray

    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        return {"W": self.W_, "w0": self.w0_}, {}

    @classmethod
    def from_arrays(cls, params, arrays, attrs):
        model = cls(**params)
        model.W_, model.w0_ = np.asarray(arrays["W"]), np.asarray(arrays["w0"])
        return model


class Sleepy(AffineArrays, Family):
    name = "sleepy"
    description = "test family: an affine map whose first fit can stall"
    Params = SleepyParams
    stochastic = False

    def fit(self, data, cost="mse1", rng=None, progress=no_progress):
        if self.params.crash:
            os.kill(os.getpid(), signal.SIGKILL)
        marker = Path(self.params.marker) if self.params.marker else None
        if marker is not None and self.params.sleep > 0 and not marker.exists():
            tmp = marker.with_suffix(".tmp")
            tmp.write_text(str(os.getpid()))
            tmp.replace(marker)
            time.sleep(self.params.sleep)
        u = data.stack("train", [s.u for s in data.series])
        y = data.targets("train")
        x = np.column_stack([u, np.ones(len(u))])
        coef, *_ = np.linalg.lstsq(x, y, rcond=None)
        self.W_, self.w0_ = coef[:-1], coef[-1]
        return self

    def simulate(self, u, y_measured=None, bounds=None):
        return Simulation(np.asarray(u) @ self.W_ + self.w0_)


def worker_facts() -> dict[str, Any]:
    """What a worker process runs with: its pid, thread variables and BLAS threads (run in a worker)."""
    from threadpoolctl import threadpool_info

    return {
        "pid": os.getpid(),
        "env": {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "NUMBA_NUM_THREADS")},
        "blas_threads": sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}),
    }
