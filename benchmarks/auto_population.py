"""family: auto on a random population of block-structured systems, next to each family's default.

    python benchmarks/auto_population.py                  # 24 systems (about 16 min on 2 cores)
    python benchmarks/auto_population.py --only sys7 --no-defaults
    python benchmarks/auto_population.py --first-seed 300    # a fresh population, drawn from seeds 300 + K
    python benchmarks/auto_population.py --records out/      # also each search's record, out/sysK.json

The other generated cases are chosen by hand, each for a difficulty the search was then taught; this one draws
its systems from seeds, so that none was picked for the search. System ``sysK`` comes from seed 100 + K (the
first twelve showed the failure mended by the runs from measured starts, docs/auto.md; the other twelve were
drawn after it; ``--first-seed S`` draws another population, from seeds S + K, for data the search was never
looked at on):

* a structure: Wiener (linear, then static), Hammerstein (static, then linear), Wiener-Hammerstein, or a
  static nonlinearity in negative feedback around the linear part;
* a static nonlinearity: tanh, a cubic, a dead zone, a saturation at +-0.8, an exponential, an absolute value;
* stable linear parts of order 1 to 3 (and 1 to 2 after a Wiener-Hammerstein's nonlinearity), poles of radius
  0.5 to 0.97, about half of them complex, unit static gain;
* an excitation: band-limited Gaussian noise, steps of random levels held a random number of samples (5 to
  39), or a multisine of 199 lines over a period of 1024 samples;
* 1500, 4000 or 10 000 training samples (80 % training, 20 % validation) with 0, 1 or 5 % white output noise;
* a test recording of 4000 samples of its own, noise-free, from a fresh draw of the same excitation (held
  steps: another hold time too, so that the test is not a replay of the training conditions).

Printed per case: the test NMSE (%) of ``family: auto`` (default budget) and of the narx, esn and (when it is
installed) the example arx defaults, the model auto chose and its wall time. Asserts nothing; the data come
from fixed seeds (docs/auto.md, "A random population").
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from auto_small_data import fit_series, run_generated
from scipy import signal

DEFAULTS = ("narx", "esn", "arx")
SYSTEMS = 24

NONLINEARITIES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "tanh": np.tanh,
    "cubic": lambda x: x + 0.3 * x**3,
    "deadzone": lambda x: np.sign(x) * np.maximum(np.abs(x) - 0.3, 0.0),
    "sat": lambda x: np.clip(x, -0.8, 0.8),
    "exp": lambda x: np.exp(0.7 * x) - 1.0,
    "abs": np.abs,
}


def _linear(rng: np.random.Generator, order: int) -> tuple[np.ndarray, np.ndarray]:
    """A stable filter (b, a) of ``order`` with unit static gain and a delay of 0 or 1 sample."""
    poles: list[complex] = []
    while len(poles) < order:
        r = rng.uniform(0.5, 0.97)
        if order - len(poles) >= 2 and rng.random() < 0.6:
            angle = rng.uniform(0.05, 1.2)
            poles += [r * np.exp(1j * angle), r * np.exp(-1j * angle)]
        else:
            poles.append(r)
    a = np.real(np.poly(poles))
    b = np.zeros(order + 1)
    b[rng.integers(0, 2)] = 1.0
    return b * np.sum(a) / np.sum(b), a


def _excitation(rng: np.random.Generator, kind: str, n: int) -> np.ndarray:
    if kind == "noise":
        x = signal.lfilter(*signal.butter(2, rng.uniform(0.1, 0.5)), rng.standard_normal(n))
        return x / x.std()
    if kind == "steps":
        hold = int(rng.integers(5, 40))
        return np.repeat(rng.uniform(-1.7, 1.7, n // hold + 2), hold)[:n]
    lines = np.arange(1, 200)
    phases = rng.uniform(0, 2 * np.pi, lines.size)
    x = np.cos(2 * np.pi * np.outer(np.arange(n), lines) / 1024 + phases).sum(axis=1)
    return x / x.std()


def _feedback(b: np.ndarray, a: np.ndarray, f: Callable, u: np.ndarray) -> np.ndarray:
    """y = L (u - 0.5 f(y[t-1])), sample by sample (the loop has a delay of one sample)."""
    y, e = np.zeros(len(u)), np.zeros(len(u))
    for t in range(len(u)):
        e[t] = u[t] - 0.5 * f(y[t - 1] if t else 0.0)
        acc = sum(b[i] * e[t - i] for i in range(len(b)) if t >= i)
        acc -= sum(a[i] * y[t - i] for i in range(1, len(a)) if t >= i)
        y[t] = acc / a[0]
    return y


#: a drawn system is drawn again (from seed + REDRAW) when its series are not finite or reach this magnitude
#: (a nonlinear feedback loop that diverges: an exponential inside it, seed 302)
DIVERGED = 1e6
REDRAW = 1000


def system(k: int, first_seed: int = 100) -> tuple[str, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """System ``sysK`` drawn from seed ``first_seed + k`` (again from ``+ REDRAW`` while its series diverge): its
    description, training series and test series (columns u, y)."""
    seed = first_seed + k
    while True:
        with np.errstate(all="ignore"):
            description, train, test = _draw(seed)
        if all(np.isfinite(v).all() and np.abs(v).max() < DIVERGED for s in (train, test) for v in s.values()):
            return description, train, test
        seed += REDRAW


def _draw(seed: int) -> tuple[str, dict[str, np.ndarray], dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    structure = str(rng.choice(["wiener", "hammerstein", "wh", "feedback"]))
    name = str(rng.choice(list(NONLINEARITIES)))
    f = NONLINEARITIES[name]
    first = _linear(rng, int(rng.integers(1, 4)))
    second = _linear(rng, int(rng.integers(1, 3)))
    kind = str(rng.choice(["noise", "steps", "multisine"]))
    n = int(rng.choice([1500, 4000, 10000]))
    noise = float(rng.choice([0.0, 0.01, 0.05]))

    def output(u: np.ndarray) -> np.ndarray:
        if structure == "wiener":
            return f(signal.lfilter(*first, u))
        if structure == "hammerstein":
            return signal.lfilter(*first, f(u))
        if structure == "wh":
            return signal.lfilter(*second, f(signal.lfilter(*first, u)))
        return _feedback(*first, f, u)

    u, u_test = _excitation(rng, kind, n), _excitation(rng, kind, 4000)
    y = output(u)
    y = y + noise * y.std() * rng.standard_normal(n)
    return (
        f"{structure} {name} {kind} n={n} noise={noise:g}",
        {"u": u, "y": y},
        {"u": u_test, "y": output(u_test)},
    )


CASES = [f"sys{k}" for k in range(SYSTEMS)]


def run_case(name: str, folder: Path, args) -> dict[str, Any]:
    description, train, test = system(int(name[3:]), args.first_seed)
    row = fit_series(name, folder, args, train, test, list(DEFAULTS))
    row["case"] = f"{name} {description}"
    return row


def main() -> None:
    run_generated(
        __doc__,
        CASES,
        run_case,
        list(DEFAULTS),
        "test NMSE % on a recording of its own (noise-free)",
        options=lambda ap: ap.add_argument(
            "--first-seed", type=int, default=100, help="draw system K from seed FIRST_SEED + K (default 100)"
        ),
    )


if __name__ == "__main__":
    main()
