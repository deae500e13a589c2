"""The standard nonlinear system-identification benchmarks as data sources (local files only).

Splits, state-initialization windows and units follow the ``nonlinear-benchmarks`` package,
version 1.0.1 (its ``benchmarks.py``); Bouc-Wen, for which that package fixes no split, follows
its benchmark document. Every channel is named ``u`` (input) and ``y`` (output), as in that
package. Sample counts per split are listed in docs/benchmarks.md and checked by the tests.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dynmodel.benchmark import BenchmarkData, BenchmarkSource, TestSet
from dynmodel.data.readers import read_columns
from dynmodel.errors import DataError

MILLI = 1000.0


def _columns(path: Path, names: list[str]) -> list[np.ndarray]:
    cols = read_columns(path, names)
    return [cols[n] for n in names]


def _mat_scalar(path: Path, name: str, default: float) -> float:
    """A scalar variable of a MATLAB file (a sampling time or rate), or ``default`` without one."""
    if path.suffix.lower() != ".mat":
        return default
    import scipy.io

    try:
        value = np.asarray(scipy.io.loadmat(path, variable_names=[name]).get(name, default), dtype=np.float64)
    except Exception as exc:  # noqa: BLE001 - an unreadable file is the user's to fix
        raise DataError(f"not a readable MATLAB file ({exc})", str(path), "fetch the file again") from None
    return float(value.ravel()[0]) if value.size else default


class Silverbox(BenchmarkSource):
    name = "silverbox"
    description = (
        "Silverbox electronic Duffing oscillator (Wigren & Schoukens 2013): u = V1, y = V2 [V], reported in mV; "
        "tests multisine, arrow-full, arrow-no-extrapolation, 50-sample windows"
    )
    test_sets = ("multisine", "arrow-full", "arrow-no-extrapolation")
    fetch = (
        "SilverboxFiles.zip of https://www.nonlinearbenchmark.org/benchmarks/silverbox "
        "(https://drive.google.com/file/d/17iS-6oBUUgrmiAcrZoG9S5sOaljZnDSy/view)"
    )
    citation = "T. Wigren, J. Schoukens, Three free data sets for development and benchmarking in nonlinear system identification, ECC 2013"
    #: the SNLS80mV record: multisine block [40650, 127400) (first 75 % train, last 25 % test), arrow [100, 40575)
    MULTISINE = (40650, 127400)
    ARROW = (100, 40575)
    NO_EXTRAPOLATION = 32000
    WINDOW = 50

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        path = cls.require(root, "SNLS80mV.mat", "SNLS80mV.csv")
        u, y = _columns(path, ["V1", "V2"])
        a, b = cls.MULTISINE
        s = a + int((b - a) * 0.75)
        arrow_a, arrow_b = cls.ARROW
        no_extra = arrow_a + cls.NO_EXTRAPOLATION

        def rec(lo: int, hi: int):
            return cls.recording(f"{path.name}[{lo}:{hi}]", u[lo:hi], y[lo:hi])

        tests = [
            TestSet("multisine", [rec(s, b)], cls.WINDOW),
            TestSet("arrow-full", [rec(arrow_a, arrow_b)], cls.WINDOW),
            TestSet("arrow-no-extrapolation", [rec(arrow_a, no_extra)], cls.WINDOW),
        ]
        return BenchmarkData([rec(a, s)], tests, ["u"], ["y"], 1.0 / 610.35, {"y": (MILLI, "mV")}, window=cls.WINDOW)


class CascadedTanks(BenchmarkSource):
    name = "cascaded-tanks"
    description = (
        "Cascaded tanks with overflow (Schoukens et al. 2016): u = pump voltage, y = lower tank level [V]; "
        "train uEst/yEst, test uVal/yVal, 50-sample window (score: all gives the PDF's every-point protocol)"
    )
    fetch = (
        "CascadedTanksFiles.zip of https://www.nonlinearbenchmark.org/benchmarks/cascaded-tanks "
        "(https://data.4tu.nl/file/d4810b78-6cdd-48fe-8950-9bd601e5f47f/3b697e42-01a4-4979-a370-813a456c36f5)"
    )
    citation = "M. Schoukens, P. Mattsson, T. Wigren, J.P. Noel, Cascaded tanks benchmark combining soft and hard nonlinearities, 2016"
    WINDOW = 50

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        path = cls.require(root, "dataBenchmark.mat", "dataBenchmark.csv")
        u_est, y_est, u_val, y_val = _columns(path, ["uEst", "yEst", "uVal", "yVal"])
        ts = _mat_scalar(path, "Ts", 4.0)  # the CSV holds Ts = 4 s in its first row only
        return BenchmarkData(
            [cls.recording(f"{path.name}(uEst,yEst)", u_est, y_est)],
            [TestSet(None, [cls.recording(f"{path.name}(uVal,yVal)", u_val, y_val)], cls.WINDOW)],
            ["u"],
            ["y"],
            ts,
            {"y": (1.0, "V")},
            window=cls.WINDOW,
        )


class Emps(BenchmarkSource):
    name = "emps"
    description = (
        "EMPS electro-mechanical positioning system (Janot et al. 2019): u = vir (force command), y = qm (position) "
        "[m], reported in mm; train DATA_EMPS, test DATA_EMPS_PULSES, 20-sample window"
    )
    fetch = (
        "EMPS.zip of https://www.nonlinearbenchmark.org/benchmarks/emps "
        "(https://drive.google.com/file/d/1zwoXYa9-3f8NQ0ohzmjpF7UxbNgRTHkS/view)"
    )
    citation = "A. Janot, M. Gautier, M. Brunot, Data Set and Reference Models of EMPS, Nonlinear System Identification Benchmarks 2019"
    WINDOW = 20

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        train = cls.require(root, "DATA_EMPS.mat")
        test = cls.require(root, "DATA_EMPS_PULSES.mat")
        recs = []
        for path in (train, test):
            t, u, y = _columns(path, ["t", "vir", "qm"])
            recs.append((cls.recording(path.name, u, y), float(t[1] - t[0])))
        return BenchmarkData(
            [recs[0][0]],
            [TestSet(None, [recs[1][0]], cls.WINDOW)],
            ["u"],
            ["y"],
            recs[0][1],
            {"y": (MILLI, "mm")},
            window=cls.WINDOW,
        )


class BoucWen(BenchmarkSource):
    name = "bouc-wen"
    description = (
        "Bouc-Wen hysteretic oscillator, simulated (Noel & Schoukens 2016): u = force [N], y = displacement [m]; "
        "tests multisine (one steady-state period) and sinesweep (from rest), scored on every sample from the "
        "input alone (the benchmark document's protocol); training from an estimation set you generate (train.h5)"
    )
    test_sets = ("multisine", "sinesweep")
    fetch = (
        "BoucWenFiles.zip of https://www.nonlinearbenchmark.org/benchmarks/bouc-wen (test signals "
        "uval_/yval_multisine.mat, uval_/yval_sinesweep.mat); the benchmark ships no training data: generate an "
        "estimation set with its simulator and save it as train.h5 (datasets multisine/u, multisine/y), e.g. the "
        "train.h5 of github.com/forgi86/dynonet examples/BW"
    )
    citation = "J.P. Noel, M. Schoukens, Hysteretic benchmark with a dynamic nonlinearity, Nonlinear System Identification Benchmarks 2016"
    SAMPLING_TIME = 1.0 / 750.0

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        train_path = cls.require(root, "train.h5", "forgione_generated_train.h5")
        u, y = _columns(train_path, ["multisine/u", "multisine/y"])
        tests = []
        for name in cls.test_sets:
            up = cls.require(root, f"uval_{name}.mat")
            yp = cls.require(root, f"yval_{name}.mat")
            (ut,) = _columns(up, [f"uval_{name}"])
            (yt,) = _columns(yp, [f"yval_{name}"])
            label = f"{up.name}/{yp.name}"
            if name == "multisine":  # one period in steady state: simulated over two periods, the second scored
                test = cls.steady_state(label, ut, yt)
                test.name = name
            else:  # the sine-sweep starts from rest
                test = TestSet(name, [cls.recording(label, ut, yt)], 0, score_all=True)
            tests.append(test)
        # the estimation set repeats one multisine period: a validation period carved from it is scored in
        # steady state, continuing the training run (window None), like the multisine test
        return BenchmarkData(
            [cls.recording(train_path.name, u, y)],
            tests,
            ["u"],
            ["y"],
            cls.SAMPLING_TIME,
            {"y": (1.0, "m")},
            window=None,
        )


class WienerHammerstein(BenchmarkSource):
    name = "wiener-hammerstein"
    description = (
        "Wiener-Hammerstein 2009 electronic circuit (Schoukens et al. 2009): u, y [V], reported in mV; "
        "train [5200:105200], test [105200:184000] of the record, 50-sample window"
    )
    fetch = (
        "WienerHammerBenchMark.mat of https://www.nonlinearbenchmark.org/benchmarks/wiener-hammerstein "
        "(http://www.ee.kth.se/~hjalmars/ifac_tc11_benchmarks/2009_wienerhammerstein/WienerHammerBenchMark.mat)"
    )
    citation = "J. Schoukens, J. Suykens, L. Ljung, Wiener-Hammerstein benchmark, SYSID 2009"
    START, STOP, TRAIN = 5200, 184000, 100000
    WINDOW = 50

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        path = cls.require(root, "WienerHammerBenchMark.mat")
        u, y = _columns(path, ["uBenchMark", "yBenchMark"])
        fs = _mat_scalar(path, "fs", 51200.0)
        mid = cls.START + cls.TRAIN
        return BenchmarkData(
            [cls.recording(f"{path.name}[{cls.START}:{mid}]", u[cls.START : mid], y[cls.START : mid])],
            [
                TestSet(
                    None,
                    [cls.recording(f"{path.name}[{mid}:{cls.STOP}]", u[mid : cls.STOP], y[mid : cls.STOP])],
                    cls.WINDOW,
                )
            ],
            ["u"],
            ["y"],
            1.0 / fs,
            {"y": (MILLI, "mV")},
            window=cls.WINDOW,
        )


class Ced(BenchmarkSource):
    name = "ced"
    description = (
        "Coupled electric drives (Wigren & Schoukens 2017): u = drive voltage, y = pulley speed [ticks/s]; "
        "two records (low and high input amplitude), the first 400 samples of each train, the rest test, "
        "10-sample windows"
    )
    test_sets = ("low", "high")
    fetch = (
        "the data of https://www.nonlinearbenchmark.org/benchmarks/coupled-electric-drives "
        "(https://uu.diva-portal.org/smash/get/diva2:1165531/FULLTEXT01.zip, DATAUNIF.MAT)"
    )
    citation = "T. Wigren, M. Schoukens, Coupled Electric Drives Data Set and Reference Models, Uppsala University 2017"
    TRAIN = 400
    WINDOW = 10

    @classmethod
    def load(cls, root: Path) -> BenchmarkData:
        path = cls.require(root, "DATAUNIF.MAT", "DATAUNIF.mat")
        u11, z11, u12, z12 = _columns(path, ["u11", "z11", "u12", "z12"])
        n = cls.TRAIN
        train = [
            cls.recording(f"{path.name}(u11,z11)[:{n}]", u11[:n], z11[:n]),
            cls.recording(f"{path.name}(u12,z12)[:{n}]", u12[:n], z12[:n]),
        ]
        tests = [
            TestSet("low", [cls.recording(f"{path.name}(u11,z11)[{n}:]", u11[n:], z11[n:])], cls.WINDOW),
            TestSet("high", [cls.recording(f"{path.name}(u12,z12)[{n}:]", u12[n:], z12[n:])], cls.WINDOW),
        ]
        return BenchmarkData(train, tests, ["u"], ["y"], 0.02, {"y": (1.0, "ticks/s")}, window=cls.WINDOW)


__all__ = ["Silverbox", "CascadedTanks", "Emps", "BoucWen", "WienerHammerstein", "Ced"]
