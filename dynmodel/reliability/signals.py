"""The battery of test inputs (thesis 4.4.1 and figure 5.5): a reliable system must forget its
initial state under *every* input, so the check tries several kinds of them.

* the recorded training input, started at several offsets;
* white noise at the training scale (two realizations);
* constants at the low end, the mean and the high end of the range;
* sines spanning the range, seven periods from 4 samples to a tenth of the run, each started
  at phase 0, 90 and 270 degrees (zero, maximum and minimum amplitude first);
* figure 5.5: a small sine (0.15 of the half range, period a fifth of the run) held at the mean
  from 60 % of the run on, started at the same three phases. The tails are identical, so a
  reliable system ends in the same state whatever the phase;
* sines the system declares (e.g. 27 sin(1.4 t) for the Duffing oscillator) and the user's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .system import DrivenSystem, InputDomain, Sine

PHASES = (0.0, 90.0, 270.0)
HOLD_AMPLITUDE = 0.15  # figure 5.5, as a fraction of the half range
HOLD_SWITCH = 0.6


@dataclass
class TestSignal:
    """One input sequence (n, channels) in the system's input space."""

    __test__ = False
    base: str  # what the signal is
    variant: str  # which start (phase, offset, realization); "" if only one
    kind: str
    u: np.ndarray
    family: str | None = None  # signals of one family share the tail from ``tail_from`` on
    tail_from: int | None = None

    @property
    def name(self) -> str:
        return f"{self.base}, {self.variant}" if self.variant else self.base


def _fmt(v: np.ndarray) -> str:
    return ", ".join(f"{x:.4g}" for x in np.atleast_1d(v))


def _period_name(p: float, dt: float, continuous: bool) -> str:
    return f"P={p * dt:.4g} ({p:g} samples)" if continuous else f"P={p:g}"


def sine_periods(n: int) -> list[float]:
    """Seven periods (samples), geometric from 4 to a tenth of the run."""
    hi = max(8.0, n / 10.0)
    return [float(p) for p in np.unique(np.round(np.geomspace(4.0, hi, 7)))]


def _wave(dom: InputDomain, t: np.ndarray, frac: float, omega: float, phase: float, centre: np.ndarray) -> np.ndarray:
    half = 0.5 * dom.width
    return centre[None, :] + frac * half[None, :] * np.sin(omega * t + phase)[:, None]


def declared_sine(dom: InputDomain, s: Sine, n: int, dt: float) -> np.ndarray:
    """A sine with absolute amplitude on the first channel, the other channels at their mean."""
    t = np.arange(n) * dt
    u = np.tile(dom.mean, (n, 1))
    off = 0.5 * (dom.low[0] + dom.high[0]) if s.offset is None else s.offset
    u[:, 0] = off + s.amplitude * np.sin(s.omega * t + s.phase)
    return u


def training_segments(system: DrivenSystem, n: int) -> list[tuple[int, np.ndarray]]:
    """Up to three windows (offset, u) of the longest recorded segment."""
    u = system.training_input
    if u is None or len(u) == 0:
        return []
    u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
    lengths = system.training_lengths
    bounds = (
        np.cumsum(np.concatenate([[0], lengths])) if lengths is not None and len(lengths) else np.array([0, len(u)])
    )
    k = int(np.argmax(np.diff(bounds)))
    seg = u[bounds[k] : bounds[k + 1]]
    m = min(n, len(seg))
    offsets = sorted({0, (len(seg) - m) // 2, len(seg) - m})
    return [(o, seg[o : o + m]) for o in offsets]


def battery(system: DrivenSystem, n: int, rng: np.random.Generator, extra: Sequence[Sine] = ()) -> list[TestSignal]:
    """The test inputs for a replica test of ``n`` steps."""
    dom = system.inputs
    dt = system.sampling_time
    cont = system.continuous
    mid = 0.5 * (dom.low + dom.high)
    steps = np.arange(n, dtype=np.float64)
    out: list[TestSignal] = []
    for off, seg in training_segments(system, n):
        out.append(TestSignal("training input", f"from sample {off}", "training", seg))
    for k in range(2):
        noise = dom.mean + dom.std * rng.standard_normal((n, dom.n))
        out.append(TestSignal(f"white noise (mean {_fmt(dom.mean)}, std {_fmt(dom.std)})", f"#{k + 1}", "noise", noise))
    for label, c in (("low end", dom.low), ("mean", dom.mean), ("high end", dom.high)):
        out.append(TestSignal(f"constant {_fmt(c)} ({label})", "", "constant", np.tile(c, (n, 1))))
    for p in sine_periods(n):
        for ph in PHASES:
            u = _wave(dom, steps, 1.0, 2 * np.pi / p, np.deg2rad(ph), mid)
            out.append(TestSignal(f"sine, {_period_name(p, dt, cont)}", f"phase {ph:g}", "sine", u))
    p_hold = max(4.0, round(n / 5))
    switch = int(HOLD_SWITCH * n)
    for ph in PHASES:
        u = _wave(dom, steps, HOLD_AMPLITUDE, 2 * np.pi / p_hold, np.deg2rad(ph), dom.mean)
        u[switch:] = dom.mean
        out.append(
            TestSignal(
                f"small sine {_period_name(p_hold, dt, cont)}, then mean from {switch} (fig. 5.5)",
                f"phase {ph:g}",
                "sine-hold",
                u,
                family="fig-5.5",
                tail_from=switch,
            )
        )
    for s in [*system.signals(), *extra]:
        out.append(TestSignal(s.name(), "", "declared", declared_sine(dom, s, n, dt)))
    return out


def constant_levels(dom: InputDomain, levels: int) -> list[np.ndarray]:
    """Constant inputs for the scan of eq. 4.39: each channel swept over its range (the others at
    their mean), all channels together along the diagonal, plus the zero input when in range."""
    out: list[np.ndarray] = []
    grid = np.linspace(0.0, 1.0, max(2, levels))
    if dom.n == 1:
        out = [dom.low + q * dom.width for q in grid]
    else:
        k = max(2, levels // 2)
        for j in range(dom.n):
            for q in np.linspace(0.0, 1.0, k):
                c = dom.mean.copy()
                c[j] = dom.low[j] + q * dom.width[j]
                out.append(c)
        out += [dom.low + q * dom.width for q in np.linspace(0.0, 1.0, k)]
    zero = np.zeros(dom.n)
    if np.all(dom.low <= 0) and np.all(dom.high >= 0):
        out.append(zero)
    out.append(dom.mean.copy())
    uniq: list[np.ndarray] = []
    for c in out:
        if not any(np.allclose(c, d, rtol=0, atol=1e-12 * (1 + np.abs(d).max())) for d in uniq):
            uniq.append(np.asarray(c, dtype=np.float64))
    uniq.sort(key=lambda c: tuple(c))
    return uniq
