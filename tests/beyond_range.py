"""Generated systems about linear whose test output rightly leaves the training output range (the search's
linear-system band, docs/auto.md): shared by tests/test_auto_extrapolation.py and
benchmarks/auto_beyond_range.py. Each returns the recording's columns (inputs first) and the input names; the
default split (60 / 20 / 20 % in time order) puts the excursion in the test split."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.signal import cont2discrete, lfilter

Columns = dict[str, np.ndarray]


def plant_at_three_times() -> tuple[Columns, list[str]]:
    rng = np.random.default_rng(16)
    u = lfilter([0.6], [1, -0.4], rng.standard_normal(5000))
    u /= u.std()
    u[4000:] *= 3.0
    y = lfilter([0.0, 0.25, 0.15], [1, -1.2, 0.52], u) + 0.005 * rng.standard_normal(5000)
    return {"u": u, "y": y}, ["u"]


def hotter_thermal() -> tuple[Columns, list[str]]:
    rng = np.random.default_rng(20)
    n = 6000
    power = np.repeat(rng.choice([0.0, 500.0, 1000.0, 1500.0], n // 300 + 1), 300)[:n]
    power[4800:] = np.repeat(rng.choice([2000.0, 2500.0, 3000.0], 5), 240)[:1200]
    a = np.exp(-1 / 500.0)
    temp = np.zeros(n)
    temp[0] = 300.0 + 0.02 * power[0]
    for k in range(1, n):
        temp[k] = 300.0 + a * (temp[k - 1] - 300.0) + (1 - a) * 0.02 * power[k - 1]
    return {"heater_W": power, "T_K": temp + 0.02 * rng.standard_normal(n)}, ["heater_W"]


def drifting_cart() -> tuple[Columns, list[str]]:
    rng = np.random.default_rng(15)
    n, dt = 4000, 0.01
    force = lfilter([0.2], [1, -0.8], rng.standard_normal(n)) + 0.15
    v, x = np.zeros(n), np.zeros(n)
    for k in range(1, n):
        v[k] = v[k - 1] + dt * (force[k - 1] - 0.5 * v[k - 1])
        x[k] = x[k - 1] + dt * v[k - 1]
    return {"force_N": force, "pos_m": x + 1e-4 * rng.standard_normal(n)}, ["force_N"]


def hotter_heat_exchanger() -> tuple[Columns, list[str]]:
    rng = np.random.default_rng(29)
    n = 5500
    inlet = 300 + 2 * np.repeat(rng.uniform(-1, 1, n // 50 + 1), 50)[:n]
    inlet[4500:] += 8
    flow = 1 + 0.2 * np.repeat(rng.uniform(-1, 1, n // 30 + 1), 30)[:n]
    outlet = lfilter([0.05], [1, -0.95], 0.8 * inlet) + lfilter([0.1], [1, -0.9], 3 * (flow - 1))
    outlet += 0.01 * rng.standard_normal(n)
    return {"T_in": inlet[500:], "flow": flow[500:], "T_out": outlet[500:]}, ["T_in", "flow"]


def oversampled_resonance() -> tuple[Columns, list[str]]:
    rng = np.random.default_rng(30)
    n, wn = 6000, 2 * np.pi
    num, den, _ = cont2discrete(([wn**2], [1, 0.04 * wn, wn**2]), 1e-3, method="zoh")
    u = np.repeat(rng.standard_normal(n // 100 + 1), 100)[:n]
    y = lfilter(np.ravel(num), den, u)
    return {"u": u, "y": y + 0.005 * y.std() * rng.standard_normal(n)}, ["u"]


CASES: dict[str, Callable[[], tuple[Columns, list[str]]]] = {
    "plant-3x": plant_at_three_times,
    "thermal-2x": hotter_thermal,
    "cart": drifting_cart,
    "heat-exchanger": hotter_heat_exchanger,
    "resonance": oversampled_resonance,
}
