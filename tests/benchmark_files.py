"""Small stand-ins for the benchmark files: the same file names, variables and lengths as the
official ones, random numbers inside (for fast tests of the benchmark sources' splits)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import scipy.io

#: benchmark -> sample counts per split key, as documented in docs/benchmarks.md (1.0.1 splits)
COUNTS = {
    "silverbox": {
        "train": 65062,
        "test:multisine": 21688,
        "test:arrow-full": 40475,
        "test:arrow-no-extrapolation": 32000,
    },
    "cascaded-tanks": {"train": 1024, "test": 1024},
    "emps": {"train": 24841, "test": 24841},
    "bouc-wen": {"train": 40960, "test:multisine": 8192, "test:sinesweep": 153000},
    "wiener-hammerstein": {"train": 100000, "test": 78800},
    "ced": {"train": 800, "test:low": 100, "test:high": 100},
}
#: benchmark -> initialization window of its test sets ("all": every sample scored)
WINDOWS = {
    "silverbox": 50,
    "cascaded-tanks": 50,
    "emps": 20,
    "bouc-wen": "all",
    "wiener-hammerstein": 50,
    "ced": 10,
}


def _row(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.standard_normal((1, n))


def write(name: str, root: Path, seed: int = 0) -> Path:
    """Write the files of benchmark ``name`` into ``root`` (created); returns ``root``."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    if name == "silverbox":
        scipy.io.savemat(root / "SNLS80mV.mat", {"V1": _row(rng, 131072), "V2": _row(rng, 131072)})
    elif name == "cascaded-tanks":
        cols = {k: rng.uniform(0, 10, 1024) for k in ("uEst", "uVal", "yEst", "yVal")}
        lines = ['"uEst","uVal","yEst","yVal","Ts",']
        for i in range(1024):
            ts = "4" if i == 0 else ""
            lines.append(",".join(f"{cols[k][i]:.17g}" for k in ("uEst", "uVal", "yEst", "yVal")) + f",{ts},")
        (root / "dataBenchmark.csv").write_text("\n".join(lines) + "\n")
    elif name == "emps":
        t = (np.arange(24841) * 1e-3)[:, None]
        for fname in ("DATA_EMPS.mat", "DATA_EMPS_PULSES.mat"):
            scipy.io.savemat(
                root / fname,
                {"t": t, "qm": rng.standard_normal((24841, 1)), "vir": rng.standard_normal((24841, 1))},
            )
    elif name == "bouc-wen":
        with h5py.File(root / "train.h5", "w") as f:
            f.create_dataset("multisine/u", data=rng.standard_normal((40960, 1)))
            f.create_dataset("multisine/y", data=rng.standard_normal((40960, 1)))
        for test, n in (("multisine", 8192), ("sinesweep", 153000)):
            scipy.io.savemat(root / f"uval_{test}.mat", {f"uval_{test}": _row(rng, n)})
            scipy.io.savemat(root / f"yval_{test}.mat", {f"yval_{test}": _row(rng, n)})
    elif name == "wiener-hammerstein":
        scipy.io.savemat(
            root / "WienerHammerBenchMark.mat",
            {"uBenchMark": _row(rng, 188000).T, "yBenchMark": _row(rng, 188000).T, "fs": np.array([[51200.0]])},
        )
    elif name == "ced":
        scipy.io.savemat(
            root / "DATAUNIF.MAT", {k: rng.standard_normal((500, 1)) for k in ("u11", "u12", "z11", "z12")}
        )
    else:
        raise ValueError(name)
    return root
