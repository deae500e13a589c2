"""Compiled integrators of the friction laws (thesis 6.1) and of the friction plant (6.4.2).

Prescribed trajectory (cross-prediction position -> force): the position is known at every substep
boundary and taken as linear in between (constant velocity dx / h). The stiff first-order
states then have exact updates: Dahl and LuGre relax exponentially, in displacement, towards
sign(dx) F_c / sigma resp. sign(dx) g / sigma0; a sticking GMS element moves by k_i dx, and one
that reaches its limit nu_i g switches to slipping at the limit, where the symmetric slip law
relaxes exponentially, in time, towards sign(v) nu_i g. No substep can overshoot, so modes never
chatter.

Plant (mass, controller, friction, noise): classical RK4 on (P, V, law states) with the GMS modes
frozen within a substep (the right-hand side is smooth there); the modes switch between substeps:
slip -> stick when the velocity has changed sign, stick -> slip (force set onto the limit) when a
loaded element reaches nu_i g(v).

Law parameters arrive packed (see ``laws.pack``): p = [sigma0, sigma1, sigma2, F_c, F_s, v_s,
delta, v_d, C]. GMS modes: 0 sticking, +1 / -1 slipping in that direction.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dynmodel.kernels.tanh import FASTMATH

_JIT = dict(cache=True, nogil=True, fastmath=FASTMATH, error_model="numpy")


@njit(inline="always", **_JIT)
def stribeck(v: float, p: np.ndarray) -> float:
    """g(v) = F_c + (F_s - F_c) exp(-|v / v_s|^delta) (eq. 6.11)."""
    r = abs(v) / p[5]
    if p[6] == 2.0:
        e = r * r
    else:
        e = r ** p[6]
    if e > 745.0:  # exp(-e) underflows to 0 (double precision)
        return p[3]
    return p[3] + (p[4] - p[3]) * math.exp(-e)


@njit(inline="always", **_JIT)
def _sign(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


# ----------------------------------------------------------------------------- prescribed trajectory
@njit(**_JIT)
def gms_substep(
    F: np.ndarray, mode: np.ndarray, k: np.ndarray, nu: np.ndarray, dx: float, h: float, g: float, C: float
) -> None:
    """Advance every GMS element over one substep of displacement dx (constant velocity dx / h)."""
    for i in range(F.shape[0]):
        if mode[i] != 0.0:
            if dx * mode[i] > 0.0:  # still moving the way it slips: relax towards sign(v) nu_i g
                target = mode[i] * nu[i] * g
                F[i] = target + (F[i] - target) * math.exp(-C * h / (nu[i] * g))
                continue
            mode[i] = 0.0  # the velocity went through zero: the element sticks
        if dx == 0.0:
            continue
        lim = nu[i] * g
        Fn = F[i] + k[i] * dx
        if Fn * dx > 0.0 and abs(Fn) >= lim:
            # loaded in the direction of motion up to the limit: slips from there on; starting on the
            # limit, the slip law keeps it there for the rest of the substep (g is constant in it)
            s = 1.0 if dx > 0.0 else -1.0
            mode[i] = s
            F[i] = s * lim
        else:
            if abs(Fn) > lim:  # unloading while the limit shrinks (Stribeck): stay within it
                Fn = lim if Fn > 0.0 else -lim
            F[i] = Fn


@njit(**_JIT)
def law_force(
    kind: int,
    p: np.ndarray,
    k: np.ndarray,
    nu: np.ndarray,
    x: np.ndarray,
    v: np.ndarray,
    substeps: int,
    h: float,
    state: np.ndarray,
    mode: np.ndarray,
) -> np.ndarray:
    """Friction force at the n samples of a prescribed trajectory.

    ``x``: positions at the (n - 1) * substeps + 1 substep boundaries (x[j * substeps] is sample j);
    ``v``: velocities at the samples (viscous term, LuGre damping); ``h``: substep length.
    ``state`` (z, or the element forces) and ``mode`` (GMS) are updated in place, so a run can go on.
    """
    n = v.shape[0]
    out = np.empty(n)
    sigma0, sigma1, sigma2, fc, vd, C = p[0], p[1], p[2], p[3], p[7], p[8]
    for j in range(n):
        vj = v[j]
        if kind == 0:
            f = sigma0 * state[0]
        elif kind == 1:
            g = stribeck(vj, p)
            zdot = vj - sigma0 * abs(vj) * state[0] / g
            s1 = sigma1 * math.exp(-((vj / vd) ** 2)) if vd > 0.0 else sigma1
            f = sigma0 * state[0] + s1 * zdot
        else:
            f = 0.0
            for i in range(state.shape[0]):
                f += state[i]
        out[j] = f + sigma2 * vj
        if j == n - 1:
            break
        base = j * substeps
        for s in range(substeps):
            dx = x[base + s + 1] - x[base + s]
            if kind == 0:
                if dx != 0.0:
                    zs = (fc / sigma0) * _sign(dx)
                    state[0] = zs + (state[0] - zs) * math.exp(-sigma0 * abs(dx) / fc)
            elif kind == 1:
                if dx != 0.0:
                    g = stribeck(dx / h, p)
                    zs = (g / sigma0) * _sign(dx)
                    state[0] = zs + (state[0] - zs) * math.exp(-sigma0 * abs(dx) / g)
            else:
                gms_substep(state, mode, k, nu, dx, h, stribeck(dx / h, p), C)
    return out


# ----------------------------------------------------------------------------- plant
@njit(inline="always", **_JIT)
def _rates(
    kind: int,
    p: np.ndarray,
    k: np.ndarray,
    inv_nu: np.ndarray,
    mode: np.ndarray,
    V: float,
    S: np.ndarray,
    dS: np.ndarray,
) -> float:
    """dS/dt of the law states at velocity V (into dS); returns the law's force (without sigma2 v).
    ``inv_nu`` = 1 / nu_i."""
    sigma0, sigma1, fc, vd, C = p[0], p[1], p[3], p[7], p[8]
    if kind == 0:
        dS[0] = V - sigma0 * abs(V) * S[0] / fc
        return sigma0 * S[0]
    if kind == 1:
        g = stribeck(V, p)
        zdot = V - sigma0 * abs(V) * S[0] / g
        dS[0] = zdot
        s1 = sigma1 * math.exp(-((V / vd) ** 2)) if vd > 0.0 else sigma1
        return sigma0 * S[0] + s1 * zdot
    cg = C / stribeck(V, p)
    f = 0.0
    for i in range(S.shape[0]):
        f += S[i]
        if mode[i] == 0.0:
            dS[i] = k[i] * V
        else:
            dS[i] = C * mode[i] - cg * S[i] * inv_nu[i]
    return f


@njit(**_JIT)
def _switch_modes(S: np.ndarray, mode: np.ndarray, nu: np.ndarray, V: float, p: np.ndarray) -> None:
    """GMS mode changes between substeps (eq. 6.13 - 6.15)."""
    g = stribeck(V, p)
    for i in range(S.shape[0]):
        if mode[i] != 0.0:
            if V * mode[i] <= 0.0:
                mode[i] = 0.0  # the velocity went through zero
            continue
        lim = nu[i] * g
        if abs(S[i]) >= lim:
            if S[i] * V > 0.0:
                mode[i] = 1.0 if S[i] > 0.0 else -1.0
            S[i] = lim if S[i] > 0.0 else -lim


@njit(**_JIT)
def plant_run(
    kind: int,
    p: np.ndarray,
    k: np.ndarray,
    nu: np.ndarray,
    mass: float,
    kp: float,
    kd: float,
    ref: np.ndarray,
    dref: np.ndarray,
    ff: np.ndarray,
    hold: int,
    noise: np.ndarray,
    substeps: int,
    h: float,
    xv: np.ndarray,
    S: np.ndarray,
    mode: np.ndarray,
    start: int,
    stop: int,
    position: np.ndarray,
    force: np.ndarray,
    friction: np.ndarray,
) -> int:
    """Closed loop m P'' = kp (P_r - P) + kd (P_r' - V) + F_ff - F_law - sigma2 V - r over samples
    [start, stop), recording at each sample before stepping on; returns the first non-finite sample or -1.

    ``ref`` / ``dref``: reference position / velocity every half substep (index 2 substeps k + m);
    ``ff``: feed-forward at the samples (n + 1 values), held linearly (hold 1) or constant (hold 0);
    ``noise``: internal friction noise r_k, constant over [t_k, t_k+1); ``xv`` = [P, V], ``S``, ``mode``:
    the state, updated in place so the run can resume.
    """
    sigma2 = p[2]
    m_inv = 1.0 / mass
    ns = S.shape[0]
    inv_nu = 1.0 / nu
    k1 = np.empty(ns)
    k2 = np.empty(ns)
    k3 = np.empty(ns)
    k4 = np.empty(ns)
    St = np.empty(ns)
    dummy = np.empty(ns)
    P = xv[0]
    V = xv[1]
    two_s = 2 * substeps
    for j in range(start, stop):
        base = j * two_s
        r = noise[j]
        flaw = _rates(kind, p, k, inv_nu, mode, V, S, dummy)
        u = kp * (ref[base] - P) + kd * (dref[base] - V) + ff[j]
        position[j] = P
        force[j] = u
        friction[j] = flaw + sigma2 * V + r
        if not (math.isfinite(P) and math.isfinite(V)):
            xv[0] = P
            xv[1] = V
            return j
        f0 = ff[j]
        df = (ff[j + 1] - ff[j]) if hold == 1 else 0.0
        for s in range(substeps):
            i0 = base + 2 * s
            a0 = s / substeps
            a1 = (s + 0.5) / substeps
            a2 = (s + 1.0) / substeps
            # stage 1
            fl = _rates(kind, p, k, inv_nu, mode, V, S, k1)
            u = kp * (ref[i0] - P) + kd * (dref[i0] - V) + f0 + a0 * df
            dP1 = V
            dV1 = (u - fl - sigma2 * V - r) * m_inv
            # stage 2
            P2 = P + 0.5 * h * dP1
            V2 = V + 0.5 * h * dV1
            for i in range(ns):
                St[i] = S[i] + 0.5 * h * k1[i]
            fl = _rates(kind, p, k, inv_nu, mode, V2, St, k2)
            u = kp * (ref[i0 + 1] - P2) + kd * (dref[i0 + 1] - V2) + f0 + a1 * df
            dP2 = V2
            dV2 = (u - fl - sigma2 * V2 - r) * m_inv
            # stage 3
            P3 = P + 0.5 * h * dP2
            V3 = V + 0.5 * h * dV2
            for i in range(ns):
                St[i] = S[i] + 0.5 * h * k2[i]
            fl = _rates(kind, p, k, inv_nu, mode, V3, St, k3)
            u = kp * (ref[i0 + 1] - P3) + kd * (dref[i0 + 1] - V3) + f0 + a1 * df
            dP3 = V3
            dV3 = (u - fl - sigma2 * V3 - r) * m_inv
            # stage 4
            P4 = P + h * dP3
            V4 = V + h * dV3
            for i in range(ns):
                St[i] = S[i] + h * k3[i]
            fl = _rates(kind, p, k, inv_nu, mode, V4, St, k4)
            u = kp * (ref[i0 + 2] - P4) + kd * (dref[i0 + 2] - V4) + f0 + a2 * df
            dP4 = V4
            dV4 = (u - fl - sigma2 * V4 - r) * m_inv
            P += (h / 6.0) * (dP1 + 2.0 * dP2 + 2.0 * dP3 + dP4)
            V += (h / 6.0) * (dV1 + 2.0 * dV2 + 2.0 * dV3 + dV4)
            for i in range(ns):
                S[i] += (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            if kind == 2:
                _switch_modes(S, mode, nu, V, p)
    xv[0] = P
    xv[1] = V
    return -1
