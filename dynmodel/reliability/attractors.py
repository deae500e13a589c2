"""Constant-input scan (thesis eq. 4.39): for a constant input a reliable system settles on one
stable fixed point from every initial state.

For each constant level many replicas run until they settle; their end states are grouped into
*responses* (replicas within the tolerance of each other). Each response is classified by how it
continues: back to itself after p steps (a fixed point for p = 1, else a p-cycle, whose points are
listed) or not within ``MAX_PERIOD`` steps (non-periodic: chaotic if its conditional Lyapunov
exponent is positive, a limit cycle / quasi-periodic motion if it is about zero, still converging
if negative). Responses on the same cycle are that cycle in different *phases* (the regular and
the anti-cycle of figure 5.4): they too give different outputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..family import Progress
from ..kernels import group_spread, row_distances
from . import lyapunov
from .replicas import max_pairwise
from .system import DrivenSystem

MAX_PERIOD = 32
#: responses whose points are closer than this fraction of the scale are "not settled", not distinct
NEAR = 1e-3
EXTRA_ROUNDS = 2
LYAP_STEPS = 600
SETTLE_CHECK = 100
#: a level counts as settled early when its replicas agree and moved less than this times the tolerance
SETTLE_MOVE = 1e-3


@dataclass
class Attractor:
    kind: str  # "fixed point", "cycle", "non-periodic"
    replicas: int
    phases: int
    period: int | None = None
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    lyapunov: float | None = None  # largest exponent per step (non-periodic only)
    label: str = ""

    def to_json(self, dt: float, continuous: bool) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": self.kind,
            "label": self.label,
            "replicas": self.replicas,
            "phases": self.phases,
            "period": self.period,
        }
        if self.kind != "non-periodic":
            out["points"] = self.points.tolist()
        else:
            out["largest_lyapunov"] = None if self.lyapunov is None else self.lyapunov / (dt if continuous else 1.0)
            out["sample_point"] = self.points[0].tolist() if len(self.points) else None
        return out


@dataclass
class LevelResult:
    """``status``: 'fixed point' (eq. 4.39 holds), 'several responses', 'no fixed point',
    'not settled', 'diverged'."""

    input: np.ndarray
    attractors: list[Attractor]
    responses: int
    status: str
    spread: float = 0.0  # largest distance between the replicas' end states

    def to_json(self, dt: float, continuous: bool) -> dict[str, Any]:
        return {
            "input": self.input.tolist(),
            "status": self.status,
            "responses": self.responses,
            "spread": self.spread,
            "attractors": [a.to_json(dt, continuous) for a in self.attractors],
        }


def _clusters(F: np.ndarray, tol: float) -> list[list[int]]:
    """Greedy grouping of rows of F within ``tol`` of a group's first row."""
    reps: list[int] = []
    groups: list[list[int]] = []
    for r in range(len(F)):
        for g, rep in enumerate(reps):
            if np.sqrt(((F[r] - F[rep]) ** 2).sum()) <= tol:
                groups[g].append(r)
                break
        else:
            reps.append(r)
            groups.append([r])
    return groups


def _periods(system: DrivenSystem, X: np.ndarray, V: np.ndarray, tol: float) -> np.ndarray:
    """Smallest p <= MAX_PERIOD with ||x_{T+p} - x_T|| <= tol per row (0: none)."""
    per = np.zeros(len(X), dtype=np.int64)
    d = np.empty(len(X))
    Y = X
    for p in range(1, MAX_PERIOD + 1):
        Y = system.step(Y, V)
        row_distances(Y, X, d)
        new = (per == 0) & (d <= tol)
        per[new] = p
    return per


def _orbit(system: DrivenSystem, x: np.ndarray, v: np.ndarray, p: int) -> np.ndarray:
    pts = [x]
    y = x[None, :]
    for _ in range(p - 1):
        y = system.step(y, v[None, :])
        pts.append(y[0])
    return np.array(pts)


def _settle(
    system: DrivenSystem,
    X: np.ndarray,
    V: np.ndarray,
    R: int,
    steps: int,
    tol: float,
    progress: Progress,
    done: float,
    share: float,
) -> np.ndarray:
    """Run every level ``steps`` steps; a level stops early once all its replicas sit within
    ``tol`` of each other and hardly moved in the last step (one fixed point, located well within
    the tolerance even when the contraction is slow)."""
    X = X.copy()
    live = np.arange(len(X) // R)
    spread = np.empty(len(live))
    t = 0
    while t < steps and len(live):
        rows = (live[:, None] * R + np.arange(R)[None, :]).ravel()
        Xl, Vl = np.ascontiguousarray(X[rows]), np.ascontiguousarray(V[rows])
        chunk = min(SETTLE_CHECK, steps - t)
        prev = Xl
        bufs = [np.empty_like(Xl), np.empty_like(Xl)]
        for k in range(chunk):
            prev = Xl
            Xl = system.step(Xl, Vl, bufs[k % 2])
        X[rows] = Xl
        t += chunk
        move = np.empty(len(rows))
        row_distances(Xl, prev, move)
        group_spread(Xl, len(live), R, spread[: len(live)])
        settled = (spread[: len(live)] <= tol) & (move.reshape(-1, R).max(axis=1) <= SETTLE_MOVE * tol)
        live = live[~settled]
        progress("constant scan", done + share * t / steps, f"{len(live) * R} replicas unsettled, step {t}/{steps}")
    return X


def _analyse(
    system: DrivenSystem,
    level: np.ndarray,
    F: np.ndarray,
    per: np.ndarray,
    v: np.ndarray,
    tol: float,
    near: float,
    rng: np.random.Generator,
) -> LevelResult:
    if not np.isfinite(F).all():
        return LevelResult(level, [], 0, "diverged", float("inf"))
    groups = _clusters(F, tol)
    periodic: list[tuple[list[int], int]] = []
    nonper: list[list[int]] = []
    for g in groups:
        p = int(per[g[0]])
        (periodic.append((g, p)) if p > 0 else nonper.append(g))
    attractors: list[Attractor] = []
    # group periodic responses into cycles: same period, rep on the other's orbit
    orbits: list[tuple[int, np.ndarray, list[list[int]]]] = []
    for g, p in periodic:
        x = F[g[0]]
        for entry in orbits:
            if entry[0] == p and np.min(np.sqrt(((entry[1] - x) ** 2).sum(axis=1))) <= max(tol, 1e-9):
                entry[2].append(g)
                break
        else:
            orbits.append((p, _orbit(system, x, v, p), [g]))
    for p, pts, gs in orbits:
        kind = "fixed point" if p == 1 else "cycle"
        label = "fixed point" if p == 1 else f"{p}-cycle"
        attractors.append(Attractor(kind, sum(len(g) for g in gs), len(gs), p, pts, None, label))
    if nonper:
        reps = [g[0] for g in nonper[:2]]
        n = LYAP_STEPS
        Vt = np.broadcast_to(v, (n, len(reps), v.shape[0]))
        ex = lyapunov.exponents(system, Vt, F[reps], 1, rng)
        lam = max((e.largest for e in ex), default=np.nan)
        sign = max((e.sign() for e in ex), key=["undefined", "negative", "zero", "positive"].index)
        label = {
            "positive": "chaotic",
            "zero": "limit cycle or quasi-periodic",
            "negative": "not settled (still converging)",
            "undefined": "undefined",
        }[sign]
        attractors.append(
            Attractor(
                "non-periodic",
                sum(len(g) for g in nonper),
                len(nonper),
                None,
                F[[g[0] for g in nonper[:1]]],
                float(lam),
                label,
            )
        )
    responses = len(groups)
    # distinct "attractors" closer than `near` to each other are one slowly converging attractor
    close = False
    pts_all = [a.points for a in attractors if a.kind != "non-periodic"]
    for i in range(len(pts_all)):
        for j in range(i + 1, len(pts_all)):
            dmin = np.min(np.sqrt(((pts_all[i][:, None, :] - pts_all[j][None, :, :]) ** 2).sum(axis=2)))
            if dmin < near:
                close = True
    unsettled = any(a.kind == "non-periodic" and a.label.startswith("not settled") for a in attractors)
    if responses == 1 and attractors and attractors[0].kind == "fixed point":
        status = "fixed point"
    elif close or unsettled:
        status = "not settled"
    elif responses > 1:
        status = "several responses"
    else:
        status = "no fixed point"
    return LevelResult(level, attractors, responses, status, max_pairwise(F))


def scan(
    system: DrivenSystem,
    levels: list[np.ndarray],
    X0: np.ndarray,
    steps: int,
    tol: float,
    rng: np.random.Generator,
    progress: Progress,
) -> list[LevelResult]:
    """Settle ``len(X0)`` replicas at every constant level and name what they reach."""
    R, M = X0.shape
    L = len(levels)
    drives = np.stack([system.drive(np.tile(c, (2, 1)))[-1] for c in levels])  # (L, d)
    near = NEAR * system.scale()
    active = list(range(L))
    X = np.ascontiguousarray(np.tile(X0, (L, 1)))
    results: dict[int, LevelResult] = {}
    rounds = 1 + EXTRA_ROUNDS
    for rnd in range(rounds):
        rows = np.concatenate([np.arange(i * R, (i + 1) * R) for i in active])
        V = np.ascontiguousarray(np.repeat(drives[active], R, axis=0))
        X[rows] = _settle(system, X[rows], V, R, steps, tol, progress, rnd / rounds, 1.0 / rounds)
        per = _periods(system, X[rows], V, tol)
        still: list[int] = []
        for k, i in enumerate(active):
            res = _analyse(
                system, levels[i], X[i * R : (i + 1) * R], per[k * R : (k + 1) * R], drives[i], tol, near, rng
            )
            results[i] = res
            if res.status == "not settled" or any(a.label.startswith("limit cycle") for a in res.attractors):
                still.append(i)  # slow convergence looks like either: give it more time
        active = still
        if not active:
            break
    return [results[i] for i in range(L)]
