"""Conditional Lyapunov exponents along driven trajectories (thesis 4.2, eq. 4.20; 4.4.1).

Tangent vectors are pushed through the Jacobian products Df(x_{t-1}, v_t) and re-orthonormalised
by a QR decomposition every step; the logs of |diag R| averaged over the run (after a discarded
first quarter) are the exponents. A positive largest exponent means two replicas that start
arbitrarily close separate: the response depends on the initial state and the system is not
reliable for that input. Exponents are per step; for flows divided by the sampling time
(per time unit) when reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..family import Progress
from .system import DrivenSystem

#: |lambda| below this (per step) is "about zero"
LYAP_TOL = 1e-3
BLOCKS = 10


@dataclass
class Exponents:
    """Exponents (per step) of ``k`` tangent directions for one trajectory, with a standard error
    of the largest one from block means."""

    values: np.ndarray
    stderr: float

    @property
    def largest(self) -> float:
        return float(self.values[0])

    def sign(self) -> str:
        """'positive', 'negative' or 'zero' (within LYAP_TOL and three standard errors)."""
        lam = self.largest
        if not np.isfinite(lam):
            return "undefined"
        margin = max(LYAP_TOL, 3 * self.stderr)
        if lam > margin:
            return "positive"
        if lam < -margin:
            return "negative"
        return "zero"


def _orthonormal(rng: np.random.Generator, rows: int, m: int, k: int) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.standard_normal((rows, m, k)))
    return np.ascontiguousarray(Q)


def exponents(
    system: DrivenSystem,
    V: np.ndarray,
    X0: np.ndarray,
    k: int,
    rng: np.random.Generator,
    discard: float = 0.25,
    progress: Progress | None = None,
    label: str = "lyapunov",
) -> list[Exponents]:
    """Exponents along the trajectories from each row of X0 under per-row drives.

    ``V`` has shape (n, rows, d): the drive of every row at every step.
    """
    n, rows, _ = V.shape
    m = system.state_dim
    k = max(1, min(k, m))
    X = np.ascontiguousarray(X0, dtype=np.float64)
    E = _orthonormal(rng, rows, m, k)
    n0 = int(discard * n)
    sums = np.zeros((rows, k))
    block_len = max(1, (n - n0) // BLOCKS)
    blocks = np.zeros((rows, BLOCKS))
    every = max(1, n // 10)
    for t in range(n):
        X, E = system.tangent(X, V[t], E)
        if k == 1:
            norms = np.sqrt((E[:, :, 0] ** 2).sum(axis=1))
            logs = np.log(np.maximum(norms, 1e-300))[:, None]
            E = E / np.where(norms > 1e-300, norms, 1.0)[:, None, None]
        else:
            Q, Rm = np.linalg.qr(E)
            logs = np.log(np.maximum(np.abs(np.diagonal(Rm, axis1=1, axis2=2)), 1e-300))
            E = np.ascontiguousarray(Q)
        dead = ~np.isfinite(E).all(axis=(1, 2)) | (np.abs(E).sum(axis=(1, 2)) == 0)
        if dead.any():
            E[dead] = _orthonormal(rng, int(dead.sum()), m, k)
        if t >= n0:
            sums += logs
            b = min(BLOCKS - 1, (t - n0) // block_len)
            blocks[:, b] += logs[:, 0]
        if progress is not None and t % every == 0:
            progress(label, t / n, f"tangent dynamics of {rows} trajectories, step {t + 1}/{n}")
    lam = sums / max(1, n - n0)
    finite = np.isfinite(X).all(axis=1)
    lam[~finite] = np.nan
    counts = np.array(
        [
            min(block_len, max(0, (n - n0) - b * block_len)) if b < BLOCKS - 1 else (n - n0) - (BLOCKS - 1) * block_len
            for b in range(BLOCKS)
        ],
        dtype=np.float64,
    )
    valid = counts > 0
    means = blocks[:, valid] / counts[valid]
    se = means.std(axis=1, ddof=1) / np.sqrt(valid.sum()) if valid.sum() > 1 else np.full(rows, np.inf)
    return [Exponents(lam[r], float(se[r])) for r in range(rows)]


def to_json(e: Exponents, dt: float, continuous: bool) -> dict[str, Any]:
    scale = 1.0 / dt if continuous else 1.0
    return {
        "largest": e.largest * scale,
        "exponents": [float(v) * scale for v in e.values],
        "stderr": e.stderr * scale,
        "unit": "per time unit" if continuous else "per step",
        "sign": e.sign(),
    }
