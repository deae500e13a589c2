"""Speed of the compiled friction kernels against plain numpy loops (same arithmetic, elements
vectorized with numpy), and of `dynmodel control`.

    python benchmarks/friction_speed.py

GMS with 10 elements. Best of 3; the plain loops run on fewer steps (per-step times compared).
Prints figures; asserts nothing.
"""

from __future__ import annotations

import numpy as np
from timing import best_of

from dynmodel_plugins.friction.laws import GmsFields
from dynmodel_plugins.friction.plant import Plant, PlantParams, TrackingTask
from dynmodel_plugins.friction.response import friction_force
from dynmodel_plugins.friction.trajectories import Trajectory, TrajectoryParams


def gms_plain(law: GmsFields, x: np.ndarray, h: float) -> np.ndarray:
    """The prescribed-trajectory GMS update of kernels.gms_substep, numpy over the elements."""
    k, nu, C = law.k(), law.nu(), law.attraction
    F, mode = np.zeros(law.elements), np.zeros(law.elements)
    out = np.empty(len(x))
    out[0] = 0.0
    for j in range(len(x) - 1):
        dx = x[j + 1] - x[j]
        g = law.coulomb + (law.static - law.coulomb) * np.exp(-((dx / h / law.stribeck_velocity) ** 2))
        slip = (mode != 0) & (dx * mode > 0)
        target = mode * nu * g
        F = np.where(slip, target + (F - target) * np.exp(-C * h / (nu * g)), F)
        mode = np.where(slip, mode, 0.0)
        Fn = F + k * dx
        brk = ~slip & (Fn * dx > 0) & (np.abs(Fn) >= nu * g) & (dx != 0)
        F = np.where(slip, F, np.where(brk, np.sign(dx) * nu * g, np.clip(Fn, -nu * g, nu * g)))
        mode = np.where(brk, np.sign(dx), mode)
        out[j + 1] = F.sum()
    return out


def plant_plain(params: PlantParams, ref: np.ndarray, dref: np.ndarray, noise: np.ndarray, n: int) -> np.ndarray:
    """RK4 of the GMS plant with frozen modes, numpy over the elements (no feed-forward)."""
    law = params.law
    k, nu, C, m, kp = law.k(), law.nu(), law.attraction, params.mass, params.kp
    s = params.substeps
    h = params.sampling_time / s
    P, V = ref[0], dref[0]
    S, mode = np.zeros(law.elements), np.zeros(law.elements)

    def g(v):
        return law.coulomb + (law.static - law.coulomb) * np.exp(-((v / law.stribeck_velocity) ** 2))

    def rates(V, S, i, r):
        dS = np.where(mode == 0, k * V, C * (mode - S / (nu * g(V))))
        u = kp * (ref[i] - P_stage[0])
        return (u - S.sum() - law.viscous * V - r) / m, dS

    out = np.empty(n)
    P_stage = [P]
    for j in range(n):
        out[j] = P
        r = noise[j]
        for q in range(s):
            i0 = 2 * s * j + 2 * q
            P_stage[0] = P
            a1, d1 = rates(V, S, i0, r)
            P_stage[0] = P + 0.5 * h * V
            a2, d2 = rates(V + 0.5 * h * a1, S + 0.5 * h * d1, i0 + 1, r)
            P_stage[0] = P + 0.5 * h * (V + 0.5 * h * a1)
            a3, d3 = rates(V + 0.5 * h * a2, S + 0.5 * h * d2, i0 + 1, r)
            P_stage[0] = P + h * (V + 0.5 * h * a2)
            a4, d4 = rates(V + h * a3, S + h * d3, i0 + 2, r)
            P, V = (
                P + h / 6 * (V + 2 * (V + 0.5 * h * a1) + 2 * (V + 0.5 * h * a2) + (V + h * a3)),
                V + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4),
            )
            S = S + h / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
            lim = nu * g(V)
            mode = np.where((mode != 0) & (V * mode <= 0), 0.0, mode)
            hit = (mode == 0) & (np.abs(S) >= lim)
            mode = np.where(hit & (S * V > 0), np.sign(S), mode)
            S = np.where(hit, np.sign(S) * lim, S)
    return out


def main() -> None:
    law = GmsFields()
    tr = Trajectory(TrajectoryParams(std=5e-6, band=(0.02, 1.0)), np.random.default_rng(1))
    h = 4e-4
    x, _, _ = tr.grid(0.0, h, 240001)
    v = np.zeros(240001)
    friction_force(law, x[:100], v[:100], h, 1)  # compile
    t_fast = best_of(lambda: friction_force(law, x, v, h, 1))
    n_plain = 20000
    t_plain = best_of(lambda: gms_plain(law, x[:n_plain], h), 1)
    diff = np.max(np.abs(gms_plain(law, x[:n_plain], h) - friction_force(law, x[:n_plain], v[:n_plain], h, 1)))
    print(
        f"GMS along a trajectory (10 elements): compiled {1e9 * t_fast / (len(x) - 1):.1f} ns/substep, "
        f"plain numpy {1e9 * t_plain / (n_plain - 1):.0f} ns/substep ({t_plain / (n_plain - 1) / (t_fast / (len(x) - 1)):.0f}x); "
        f"largest difference {diff:.1e} N"
    )

    params = PlantParams()
    plant = Plant(params)
    n = 100000
    task = TrackingTask(plant, n, np.random.default_rng(0))
    task.start(100, np.random.default_rng(1))  # compile
    t_fast = best_of(lambda: task.start(n, np.random.default_rng(1)))
    n_plain = 300
    noise = plant.noise(n, np.random.default_rng(1))
    t_plain = best_of(lambda: plant_plain(params, task.ref_grid, task.dref_grid, noise, n_plain), 1)
    fast = task.start(n_plain, np.random.default_rng(1)).position
    diff = np.max(np.abs(plant_plain(params, task.ref_grid, task.dref_grid, noise, n_plain) - fast))
    steps = params.substeps
    print(
        f"plant, RK4 with {steps} substeps per 1 ms sample: compiled {1e6 * t_fast / n:.2f} us/sample "
        f"({1e9 * t_fast / n / steps:.0f} ns/RK4 step), plain numpy {1e6 * t_plain / n_plain:.0f} us/sample "
        f"({t_plain / n_plain / (t_fast / n):.0f}x); largest position difference {diff:.1e} m"
    )
    t_ref = best_of(lambda: TrackingTask(plant, n, np.random.default_rng(0)))
    t_perf = best_of(lambda: task.perfect_feedforward())
    print(f"100 s reference (2 x 10 x 1e5 points): {t_ref:.2f} s; perfect feed-forward: {t_perf:.2f} s")


if __name__ == "__main__":
    main()
