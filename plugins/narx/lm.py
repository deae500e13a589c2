"""Levenberg-Marquardt for the free-running least-squares problem (eq. 3.15): many residuals, few weights.

MINPACK's ``lmder`` (scipy's ``least_squares(method="lm")``) factors the whole N x p Jacobian with an
unblocked, column-pivoted Householder QR at every iteration. On a long record with many terms that is most
of the fit: on 52 000 Silverbox samples and 258 terms, 2.96 s per Jacobian with lmder, 0.81 s here, with the
same 115 Jacobians and the same weights (``benchmarks/narx_refine_speed.py``).
This is the same method, Moré's trust-region Levenberg-Marquardt (J. J. Moré, *The Levenberg-Marquardt
algorithm: implementation and theory*, 1978; the algorithm of ``lmder`` and ``lmpar``), with the factorization
done by LAPACK in row blocks (a tall-skinny QR: the R of [J  r] block after block, never Q):

    [J  r] = Q [[R, q], [0, rho]]            q = Q^T r

and every trial step is the solution of the small problem

    min_d || R d + q ||^2 + lam || D d ||^2     (D: running maximum of the Jacobian's column norms),

lam chosen (``lmpar``) so that ||D d|| is the trust radius within 10 %. The radius and the stopping tests are
``lmder``'s: relative reductions (actual and predicted) of the cost below ``ftol``, the radius below
``xtol`` times the scaled weights, the scaled gradient below ``gtol``, or ``max_nfev`` residual evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

#: rows of J factored at a time (the R of the rows so far is stacked on the next block)
BLOCK_ROWS = 8192
#: the initial trust radius in units of ||D x0|| (lmder's ``factor``)
FACTOR = 100.0
_DWARF = np.finfo(float).tiny


@dataclass
class LMResult:
    """The solution and how it was reached (the fields of scipy's OptimizeResult that the family reads)."""

    x: np.ndarray
    cost: float  # 0.5 ||r(x)||^2, as scipy reports it
    nfev: int
    njev: int
    status: int  # as scipy's: 0 max_nfev, 1 gtol, 2 ftol, 3 xtol, 4 ftol and xtol; -1 a Jacobian not finite
    message: str


def r_factor(J: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, Q^T r) of the thin QR of J, computed block by block on [J r] (Q never formed)."""
    p = J.shape[1]
    Rb: np.ndarray | None = None
    for k in range(0, J.shape[0], BLOCK_ROWS):
        block = np.column_stack([J[k : k + BLOCK_ROWS], r[k : k + BLOCK_ROWS]])
        stacked = block if Rb is None else np.vstack([Rb, block])
        Rb = scipy.linalg.qr(stacked, mode="r", check_finite=False)[0][: p + 1]
    assert Rb is not None
    if Rb.shape[0] < p + 1:  # fewer rows than weights + 1
        Rb = np.vstack([Rb, np.zeros((p + 1 - Rb.shape[0], p + 1))])
    return Rb[:p, :p], Rb[:p, p]


def _damped_step(R: np.ndarray, q: np.ndarray, D: np.ndarray, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """(d, S): d minimises ||R d + q||^2 + lam ||D d||^2; S is the R factor of [R; sqrt(lam) D]."""
    p = R.shape[0]
    A = np.vstack([R, np.sqrt(lam) * np.diag(D)])
    rhs = np.concatenate([-q, np.zeros(p)])
    S = scipy.linalg.qr(np.column_stack([A, rhs]), mode="r", check_finite=False)[0][:p]
    d = scipy.linalg.solve_triangular(S[:, :p], S[:, p], check_finite=False)
    return d, S[:, :p]


def lmpar(R: np.ndarray, q: np.ndarray, D: np.ndarray, delta: float, lam: float) -> tuple[float, np.ndarray]:
    """Moré's ``lmpar``: lam >= 0 and the step d with ||D d|| within 10 % of ``delta`` (lam = 0 when the
    Gauss-Newton step already lies inside), starting from the previous ``lam``."""
    p = R.shape[0]
    d, _, rank, _ = np.linalg.lstsq(R, -q, rcond=None)
    dxnorm = float(np.linalg.norm(D * d))
    fp = dxnorm - delta
    if fp <= 0.1 * delta:
        return 0.0, d
    parl = 0.0
    if rank == p:
        wa = D * (D * d) / dxnorm
        z = scipy.linalg.solve_triangular(R, wa, trans="T", check_finite=False)
        parl = fp / delta / float(z @ z)
    gnorm = float(np.linalg.norm((R.T @ q) / D))
    paru = gnorm / delta
    if paru == 0.0:
        paru = _DWARF / min(delta, 0.1)
    lam = min(max(lam, parl), paru)
    if lam == 0.0:
        lam = gnorm / dxnorm
    for it in range(10):
        if lam == 0.0:
            lam = max(_DWARF, 0.001 * paru)
        d, S = _damped_step(R, q, D, lam)
        dxnorm = float(np.linalg.norm(D * d))
        temp, fp = fp, dxnorm - delta
        if abs(fp) <= 0.1 * delta or (parl == 0.0 and fp <= temp and temp < 0.0) or it == 9:
            break
        wa = D * (D * d) / dxnorm
        z = scipy.linalg.solve_triangular(S, wa, trans="T", check_finite=False)
        correction = fp / delta / float(z @ z)
        if fp > 0.0:
            parl = max(parl, lam)
        elif fp < 0.0:
            paru = min(paru, lam)
        lam = max(parl, lam + correction)
    return lam, d


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    *,
    max_nfev: int,
    ftol: float,
    xtol: float,
    gtol: float,
) -> LMResult:
    """Minimise 0.5 ||fun(x)||^2 from ``x0`` (``jac(x)``: the N x p Jacobian of ``fun``); see the module text."""
    x = np.asarray(x0, dtype=np.float64).copy()
    r = fun(x)
    nfev, njev = 1, 0
    fnorm = float(np.linalg.norm(r))
    D: np.ndarray | None = None
    delta = xnorm = 0.0
    lam = 0.0
    status, message = 0, "the number of function evaluations reached max_nfev"
    first = True
    while status == 0 and nfev < max_nfev:
        R, q = r_factor(jac(x), r)
        njev += 1
        if not (np.isfinite(R).all() and np.isfinite(q).all()):
            # the free run's sensitivities overflowed (a run near divergence): no step can be computed, keep x
            status, message = -1, "the Jacobian is not finite at the current weights"
            break
        norms = np.linalg.norm(R, axis=0)  # = the Jacobian's column norms (J = QR, Q orthonormal)
        if D is None:
            D = np.where(norms > 0, norms, 1.0)
            xnorm = float(np.linalg.norm(D * x))
            delta = FACTOR * xnorm if xnorm > 0 else FACTOR
        if fnorm == 0.0:
            status, message = 1, "gtol: the residuals are zero"
            break
        gscaled = np.abs(R.T @ q) / np.where(norms > 0, norms, np.inf) / fnorm
        if float(np.max(gscaled, initial=0.0)) <= gtol:
            status, message = 1, "gtol: the scaled gradient is below tolerance"
            break
        D = np.maximum(D, norms)
        while nfev < max_nfev:
            lam, d = lmpar(R, q, D, delta, lam)
            pnorm = float(np.linalg.norm(D * d))
            if first:
                delta = min(delta, pnorm)
            x_new = x + d
            r_new = fun(x_new)
            nfev += 1
            fnorm1 = float(np.linalg.norm(r_new))
            actred = 1.0 - (fnorm1 / fnorm) ** 2 if np.isfinite(fnorm1) and 0.1 * fnorm1 < fnorm else -1.0
            t1 = float(np.linalg.norm(R @ d)) / fnorm
            t2 = np.sqrt(lam) * pnorm / fnorm
            prered = t1**2 + t2**2 / 0.5
            dirder = -(t1**2 + t2**2)
            ratio = actred / prered if prered != 0.0 else 0.0
            if ratio <= 0.25:
                temp = 0.5 if actred >= 0.0 else 0.5 * dirder / (dirder + 0.5 * actred)
                if not np.isfinite(fnorm1) or 0.1 * fnorm1 >= fnorm or temp < 0.1:
                    temp = 0.1
                delta = temp * min(delta, pnorm / 0.1)
                lam = lam / temp
            elif lam == 0.0 or ratio >= 0.75:
                delta = pnorm / 0.5
                lam = 0.5 * lam
            if ratio >= 1e-4:
                x, r, fnorm = x_new, r_new, fnorm1
                xnorm = float(np.linalg.norm(D * x))
                first = False
            small_gain = abs(actred) <= ftol and prered <= ftol and 0.5 * ratio <= 1.0
            small_radius = delta <= xtol * xnorm
            if small_gain and small_radius:
                status, message = 4, "ftol and xtol: both tests are satisfied"
            elif small_gain:
                status, message = 2, "ftol: the relative reduction of the cost is below tolerance"
            elif small_radius:
                status, message = 3, "xtol: the trust region is below tolerance"
            if status != 0 or ratio >= 1e-4:
                break
    return LMResult(x, 0.5 * fnorm**2, nfev, njev, status, message)
