"""Data with one effect hidden in it, for the diagnosis tests (each case draws its strength, lag,
frequency, ... from its own seed) and the clean twins on which no cause may be named.

Systems: the thesis's NARX system (eq. 3.37) and linear system (eq. 3.19), and friction: a
position signal with reversals driving a spring-damper with Dahl friction (the pre-sliding
hysteresis of thesis 6.1/6.2), all written here in plain numpy so the tests do not depend on
the generators under test.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from conftest import write_csv
from scipy import signal

SPLIT = {"train": 0.6, "validation": 0.2, "test": 0.2}


def narx_system(u: np.ndarray, a0: float = 0.8, b0: float = -0.2, c0: float = 1.0) -> np.ndarray:
    """y_t = a0 y_{t-1} + b0 / (1 + |y_{t-2}|) + c0 u_t (eq. 3.37)."""
    y = np.zeros(len(u))
    y1 = y2 = 0.0
    for t in range(len(u)):
        y[t] = a0 * y1 + b0 / (1.0 + abs(y2)) + c0 * u[t]
        y2, y1 = y1, y[t]
    return y


def saturating_system(u: np.ndarray, a0: float = 0.5, b0: float = 0.4) -> np.ndarray:
    """y_t = a0 y_{t-1} + b0 tanh(y_{t-2}) + u_t: stable, but a polynomial fitted to tanh extrapolates."""
    y = np.zeros(len(u))
    y1 = y2 = 0.0
    for t in range(len(u)):
        y[t] = a0 * y1 + b0 * np.tanh(y2) + u[t]
        y2, y1 = y1, y[t]
    return y


def linear_system(u: np.ndarray, a0: float = 0.8, b0: float = 1.0) -> np.ndarray:
    """y_t = a0 y_{t-1} + b0 u_t (eq. 3.19)."""
    return signal.lfilter([b0], [1.0, -a0], u)


def position(n: int, rng: np.random.Generator, period: float = 400.0) -> np.ndarray:
    """A smooth position with reversals: three sines of random phase around ``period`` samples."""
    t = np.arange(n)
    x = np.zeros(n)
    for amp, f in zip((1.0, 0.5, 0.3), (1.0, 2.3, 0.37)):
        x += amp * np.sin(2 * np.pi * f * t / period + rng.uniform(0, 2 * np.pi))
    return x


def dahl(x: np.ndarray, sigma: float, fc: float) -> np.ndarray:
    """Dahl friction force driven by a position, dF/dx = sigma (1 - F / Fc sgn(dx)), integrated exactly
    over each step: F <- d Fc + (F - d Fc) exp(-sigma |dx| / Fc), d = sgn(dx)."""
    f = np.zeros(len(x))
    for t in range(1, len(x)):
        dx = x[t] - x[t - 1]
        d = np.sign(dx)
        f[t] = d * fc + (f[t - 1] - d * fc) * np.exp(-sigma * abs(dx) / fc)
    return f


def ema(u: np.ndarray, tau: float) -> np.ndarray:
    a = 1.0 / tau
    return signal.lfilter([a], [1.0, -(1.0 - a)], u)


@dataclass
class Case:
    cause: str  # the hidden cause ("adequate" for a clean case)
    columns: dict[str, np.ndarray]
    model: dict[str, Any]
    truth: dict[str, Any] = field(default_factory=dict)
    cost: str = "mse1"
    data: dict[str, Any] = field(default_factory=dict)  # extra data keys
    sampling_time: float = 1.0

    def spec(self, folder: Path) -> dict[str, Any]:
        path = write_csv(folder / f"{self.cause}.csv", self.columns)
        names = list(self.columns)
        data = {
            "path": str(path),
            "input": names[:-1],
            "output": names[-1:],
            "split": dict(SPLIT),
            "sampling_time": self.sampling_time,
            **self.data,
        }
        return {
            "name": self.cause,
            "data": data,
            "model": pre_issue_14(self.model, names),
            "cost": self.cost,
            "seed": 0,
        }


#: the families' defaults these cases were built on (before issue 14 made the defaults search and clip):
#: each case hides one effect in a deliberately plain model
_NARX_BEFORE = {"stop_on": "one_step", "patience": 1, "bounds": None}
_ESN_BEFORE = {"relaxation": 0.0, "relaxation_gain": False, "input_connectivity": 0.1, "tune_in": 100, "bounds": None}


def pre_issue_14(model: dict[str, Any], columns: list[str]) -> dict[str, Any]:
    """``model`` with the defaults it was written against pinned (the given parameters win)."""
    params = dict(model.get("params") or {})
    if model["family"] == "narx":
        before = dict(_NARX_BEFORE)
        if "degree" not in params and "terms" not in params:
            before["degree"] = 2
        if "lags" not in params and "terms" not in params:
            before["lags"] = {**{c: [0, 1, 2] for c in columns[:-1]}, columns[-1]: [1, 2]}
        params = before | params
    elif model["family"] == "esn" and "weights" not in params:
        params = _ESN_BEFORE | params
    return {**model, "params": params}


NARX3 = {"family": "narx", "params": {"degree": 3}}
#: position to force without output feedback: exact for a spring-damper, F = k x + c dx/dt
FIR_X = {"family": "narx", "params": {"lags": {"x": [0, 1, 2]}, "degree": 2}}


def missing_delay(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    lag, gain = int(rng.integers(25, 150)), float(rng.uniform(0.3, 0.6))
    u = rng.standard_normal(n)
    y = narx_system(u)
    y[lag:] += gain * u[:-lag]
    return Case(
        "missing-delay",
        {"u": u, "y": y},
        {"family": "narx", "params": {"degree": 2}},
        {"lag": lag, "gain": gain},
        sampling_time=0.002,
    )


def sensor_drift(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    st = 0.004
    u = rng.standard_normal(n)
    y = narx_system(u)
    t = np.arange(n) * st
    tau = float(rng.uniform(0.1, 0.4)) * t[-1]
    size = float(rng.uniform(0.4, 0.8)) * y.std()
    slope = float(rng.uniform(0.0, 0.3)) * size / t[-1]
    y += size * (1 - np.exp(-t / tau)) + slope * t
    return Case("sensor-drift", {"u": u, "y": y}, NARX3, {"tau": tau, "size": size, "slope": slope}, sampling_time=st)


def noise_bias(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = narx_system(u)
    level = float(rng.uniform(0.5, 1.0))
    noisy = y.copy()
    cut = int(0.8 * n)  # train and validation are measured with noise, the test split is clean
    noisy[:cut] += level * y.std() * rng.standard_normal(cut)
    return Case("noise-bias", {"u": u, "y": noisy}, NARX3, {"noise": level})


def instability(seed: int, n: int = 6000) -> Case:
    """Bursts of a larger input in the validation and the test split: a 10-term degree-5 polynomial fitted
    on the calmer training data extrapolates tanh and diverges there (the user switched off the
    validation stop and drop_unstable)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    amp = float(rng.uniform(2.5, 3.5))
    windows = []
    for lo, hi in ((0.62, 0.74), (0.82, 0.94)):
        start = int(rng.integers(int(lo * n), int(hi * n)))
        width = int(rng.integers(150, 250))
        u[start : start + width] *= amp
        windows.append([start, start + width])
    y = saturating_system(u)
    model = {"family": "narx", "params": {"degree": 5, "drop_unstable": False, "max_terms": 10, "patience": None}}
    return Case("free-run-instability", {"u": u, "y": y}, model, {"windows": windows, "amp": amp})


def direction(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    x = position(n, rng)
    fc = float(rng.uniform(0.3, 0.6))
    sigma = float(rng.uniform(20.0, 60.0))
    v = np.gradient(x)
    force = 1.0 * x + 40.0 * v + dahl(x, sigma, fc)
    force += 0.01 * rng.standard_normal(n)
    return Case("direction-dependence", {"x": x, "force": force}, FIR_X, {"fc": fc, "sigma": sigma}, sampling_time=0.01)


def oscillation(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    f = float(rng.uniform(0.04, 0.2))
    r = 0.98
    gain = float(rng.uniform(0.1, 0.25))
    u = rng.standard_normal(n)
    slow = linear_system(u)
    mode = signal.lfilter([gain], [1.0, -2 * r * np.cos(2 * np.pi * f), r * r], u)
    # the resonance peak of 1 / |1 - 2 r cos(w) z^-1 + r^2 z^-2|: cos(theta) = (1 + r^2) cos(w) / (2 r)
    peak = float(np.arccos((1 + r * r) * np.cos(2 * np.pi * f) / (2 * r)) / (2 * np.pi))
    y = slow + mode
    y += 0.01 * y.std() * rng.standard_normal(n)
    model = {"family": "narx", "params": {"lags": {"u": [0, 1, 2], "y": [1]}, "degree": 2}}
    st = 0.001
    return Case("unmodeled-oscillation", {"u": u, "y": y}, model, {"frequency_hz": peak / st}, sampling_time=st)


def static_nonlinearity(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    g = float(rng.uniform(0.2, 0.5))
    y = linear_system(u) + g * np.tanh(1.5 * u) ** 2 - g * np.tanh(1.5 * u) ** 3 * 0.5
    model = {"family": "narx", "params": {"lags": {"u": [0, 1], "y": [1]}, "degree": 1}}
    return Case("static-nonlinearity", {"u": u, "y": y}, model, {"gain": g})


def _fir(u: np.ndarray) -> np.ndarray:
    u1, u2 = np.r_[0.0, u[:-1]], np.r_[0.0, 0.0, u[:-2]]
    return u + 0.5 * u1 - 0.3 * u2**2 + 0.2 * u * u1


def insufficient_memory(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    tau = float(rng.uniform(20, 80))
    g = float(rng.uniform(2.0, 4.0))
    y = _fir(u) + g * ema(u, tau)
    model = {"family": "narx", "params": {"lags": {"u": [0, 1, 2, 3]}, "degree": 2}}
    return Case("insufficient-memory", {"u": u, "y": y}, model, {"tau": tau, "gain": g})


def unreliable(seed: int, n: int = 4000) -> Case:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = narx_system(u)
    value = float(rng.uniform(1.6, 2.2))
    model = {
        "family": "esn",
        "params": {"size": 60, "connectivity": 0.2, "bias_scale": 0.0, "scale": {"by": "spectral", "value": value}},
    }
    return Case("unreliable-model", {"u": u, "y": y}, model, {"spectral_radius": value})


def duffing(u: np.ndarray, dt: float, omega: float, zeta: float, k3: float, substeps: int = 4) -> np.ndarray:
    """Displacement of x'' + 2 zeta omega x' + omega^2 x + k3 x^3 = u (a Duffing oscillator, the Silverbox's
    structure), classical Runge-Kutta with ``substeps`` steps per sample, the input held over a sample."""
    h = dt / substeps
    x = v = 0.0
    out = np.empty(len(u))

    def acc(x: float, v: float, f: float) -> float:
        return f - 2.0 * zeta * omega * v - omega * omega * x - k3 * x * x * x

    for t, f in enumerate(u):
        for _ in range(substeps):
            k1x, k1v = v, acc(x, v, f)
            k2x, k2v = v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v, f)
            k3x, k3v = v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v, f)
            k4x, k4v = v + h * k3v, acc(x + h * k3x, v + h * k3v, f)
            x += h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
        out[t] = x
    return out


def output_nonlinearity(seed: int, n: int = 6000) -> Case:
    """A Duffing oscillator driven by band-limited noise; the cubic stiffness at the output's rms level is a
    random 30-100 % of the linear one. The default narx (degree 2) cannot form x^3."""
    rng = np.random.default_rng(seed)
    st = 1.0 / 600.0
    f0 = float(rng.uniform(30.0, 60.0))
    omega, zeta = 2 * np.pi * f0, float(rng.uniform(0.05, 0.15))
    u = signal.lfilter(*signal.butter(4, float(rng.uniform(0.15, 0.3))), rng.standard_normal(n))
    u *= omega**2 / u.std()  # a static displacement of order 1
    x_lin = duffing(u, st, omega, zeta, 0.0)
    strength = float(rng.uniform(0.3, 1.0))
    k3 = strength * omega**2 / x_lin.var()
    y = duffing(u, st, omega, zeta, k3)
    y += 0.001 * y.std() * rng.standard_normal(n)
    return Case(
        "output-nonlinearity",
        {"u": u, "y": y},
        {"family": "narx"},
        {"f0": f0, "zeta": zeta, "strength": strength},
        sampling_time=st,
    )


def missing_dynamics(seed: int, n: int = 6000) -> Case:
    """A fourth-order linear system (two real poles and a damped complex pair, drawn at random) and the
    default narx, whose lags (inputs 0-2, outputs 1-2) allow a second-order model only."""
    rng = np.random.default_rng(seed)
    p1, p2 = float(rng.uniform(0.75, 0.92)), float(rng.uniform(0.3, 0.6))
    r, theta = float(rng.uniform(0.6, 0.8)), float(rng.uniform(0.3, 0.8))
    den = np.poly([p1, p2, r * np.exp(1j * theta), r * np.exp(-1j * theta)]).real
    num = np.array([0.0, 1.0, float(rng.uniform(-0.5, 0.5))])
    u = rng.standard_normal(n)
    y = signal.lfilter(num, den, u)
    y += 0.01 * y.std() * rng.standard_normal(n)
    return Case(
        "missing-dynamics",
        {"u": u, "y": y},
        {"family": "narx"},
        {"poles": [p1, p2, r, theta]},
        sampling_time=0.01,
    )


def structure_stopped_early(seed: int, n: int = 6000) -> Case:
    """The NARX system of eq. 3.37 with a second, slower input path, and a narx model whose user-set
    threshold stops Fast Orthogonal Search after a few terms (each further term explains less than the
    threshold's share of y'y, yet together they matter)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    g = float(rng.uniform(0.3, 0.6))
    y = narx_system(u) + g * signal.lfilter([0.0, 0.0, 1.0], [1.0, -0.5], u)
    threshold = float(rng.uniform(0.01, 0.03))
    model = {
        "family": "narx",
        "params": {"degree": 2, "lags": {"u": [0, 1, 2, 3], "y": [1, 2, 3]}, "threshold": threshold, "patience": 50},
    }
    return Case("structure-stopped-early", {"u": u, "y": y}, model, {"threshold": threshold, "gain": g})


def clean_narx(seed: int, n: int = 6000) -> Case:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return Case("adequate", {"u": u, "y": narx_system(u)}, NARX3)


def clean_friction(seed: int, n: int = 6000) -> Case:
    """A spring-damper position-to-force system with a little measurement noise and an exact model."""
    rng = np.random.default_rng(seed)
    x = position(n, rng)
    v = np.gradient(x)
    force = 1.0 * x + 40.0 * v + 0.01 * rng.standard_normal(n)
    return Case("adequate", {"x": x, "force": force}, FIR_X, sampling_time=0.01)


def clean_noisy_linear(seed: int, n: int = 6000) -> Case:
    """The linear system (eq. 3.19) measured with white noise on every split, the model of its exact form
    estimated on the free-running error: the residual is the noise."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = linear_system(u)
    y += float(rng.uniform(0.1, 0.4)) * y.std() * rng.standard_normal(n)
    model = {"family": "narx", "params": {"lags": {"u": [0], "y": [1]}, "degree": 1}}
    return Case("adequate", {"u": u, "y": y}, model, cost="mse_inf")


def clean_esn(seed: int, n: int = 4000) -> Case:
    """The NARX system and a reliable echo state network of 200 elements (internal mode, leaky elements):
    free-run NMSE about 0.15 %. (With 100 elements the NMSE is about 0.4 % and half of that residual is a
    nonlinear function of the output, b0 / (1 + |y|) of eq. 3.37, that a larger network removes: the
    diagnosis names output-nonlinearity there, rightly, so that network is no adequate model.)"""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    model = {"family": "esn", "params": {"size": 200, "relaxation": [0.0, 0.5], "relaxation_gain": True}}
    return Case("adequate", {"u": u, "y": narx_system(u)}, model)


def dahl_generator_spec(seed: int, n: int = 10000) -> tuple[dict[str, Any], dict[str, Any]]:
    """Friction from the ``dahl`` generator (issue 7's simulators): a multisine position of 10 um std with an
    8 s period drives Dahl pre-sliding hysteresis of random Coulomb force; 1 % output noise. The baseline
    sees the position only through its last three samples (narx without output lags). Returns (spec, truth)."""
    rng = np.random.default_rng(seed)
    fc = float(rng.uniform(10.0, 30.0))
    params = {
        "coulomb": fc,
        "sigma": 1e7,
        "position_unit": "um",
        "trajectory": {"kind": "multisine", "std": 1e-5, "period": 8.0, "band": [0.1, 1.0]},
    }
    spec = {
        "name": "dahl",
        "data": {
            "generator": "dahl",
            "n": n,
            "seed": seed,
            "params": params,
            "split": dict(SPLIT),
            "noise": {"std": 0.01, "splits": ["train", "validation", "test"]},
        },
        "model": pre_issue_14(
            FIR_X | {"params": {"lags": {"position": [0, 1, 2]}, "degree": 2}}, ["position", "force"]
        ),
        "seed": 0,
    }
    return spec, {"coulomb": fc}


def gms_friction(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, float, np.random.Generator]:
    """GMS friction (the `gms` generator of issue 7's simulators) along a random position of 1 mm std over
    0.05-5 Hz: sliding with many reversals; (position, force, sampling time, the seed's generator)."""
    from dynmodel import registry

    gen = registry.source("gms")
    rng = np.random.default_rng(seed)
    params = gen.Params.model_validate({"trajectory": {"kind": "random", "std": 1e-3, "band": [0.05, 5.0]}})
    x, force = gen.generate(params, n, rng)
    return x[:, 0], force[:, 0], float(params.sampling_time), rng


#: the default network a new user fits first
DEFAULT_ESN = {"family": "esn"}


def masked_drift(seed: int, n: int = 8000) -> Case:
    """GMS friction with a sensor drift of random size (30-60 % of the force's std) and time constant (10-40 %
    of the record), fitted by the default echo state network: the direction dependence of friction dominates
    the residual."""
    x, force, st, rng = gms_friction(seed, n)
    t = np.arange(n) * st
    tau = float(rng.uniform(0.1, 0.4)) * t[-1]
    size = float(rng.uniform(0.3, 0.6)) * force.std()
    force = force + size * (1 - np.exp(-t / tau))
    return Case(
        "sensor-drift",
        {"position": x, "force": force},
        DEFAULT_ESN,
        {"tau": tau, "size": size, "slope": 0.0},
        sampling_time=st,
    )


def masked_delay(seed: int, n: int = 8000) -> Case:
    """GMS friction plus a delayed path of the position (lag 50-200 samples, 30-60 % of the force's std),
    fitted by the default echo state network. (The position's own correlation time is about 50 samples: a
    shorter delay is partly what the network forms from the position's recent history.)"""
    x, force, st, rng = gms_friction(seed, n)
    lag, gain = int(rng.integers(50, 200)), float(rng.uniform(0.3, 0.6))
    xs = (x - x.mean()) / x.std()
    force = force.copy()
    force[lag:] += gain * force.std() * xs[:-lag]
    return Case(
        "missing-delay", {"position": x, "force": force}, DEFAULT_ESN, {"lag": lag, "gain": gain}, sampling_time=st
    )


MASKED: dict[str, Callable[[int], Case]] = {"sensor-drift": masked_drift, "missing-delay": masked_delay}

HIDDEN: dict[str, Callable[[int], Case]] = {
    "sensor-drift": sensor_drift,
    "missing-delay": missing_delay,
    "noise-bias": noise_bias,
    "free-run-instability": instability,
    "direction-dependence": direction,
    "unmodeled-oscillation": oscillation,
    "static-nonlinearity": static_nonlinearity,
    "insufficient-memory": insufficient_memory,
    "unreliable-model": unreliable,
    "output-nonlinearity": output_nonlinearity,
    "missing-dynamics": missing_dynamics,
    "structure-stopped-early": structure_stopped_early,
}
CLEAN: dict[str, Callable[[int], Case]] = {
    "narx-system": clean_narx,
    "spring-damper": clean_friction,
    "noisy-linear": clean_noisy_linear,
    "esn": clean_esn,
}
