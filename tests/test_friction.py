"""Friction simulators (thesis 6.1 - 6.4): analytic limits of the laws, pre-sliding memory, switching
without chatter, the closed-loop plant, the control criteria and `dynmodel control`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import write_csv, write_yaml

import dynmodel
from dynmodel import control as ctl
from dynmodel_plugins.friction.laws import DahlFields, GmsFields, GmsLaw, LuGreFields, initial_stiffness, steady_force
from dynmodel_plugins.friction.plant import Plant, PlantParams, TrackingTask, simulate
from dynmodel_plugins.friction.response import LawState, friction_force
from dynmodel_plugins.friction.sources import FrictionPlant
from dynmodel_plugins.friction.trajectories import Trajectory, TrajectoryParams


def ramp(v: float, n: int, h: float, x0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Positions at n substep boundaries of a constant-velocity move, and the sample velocities."""
    return x0 + v * h * np.arange(n), np.full(n, v)


def path(points: list[float], dx: float) -> np.ndarray:
    """Piecewise-linear positions through the turning points, every step exactly dx long
    (points are multiples of dx, so every path visits the same grid of positions)."""
    out = [points[0]]
    for a, b in zip(points, points[1:]):
        k = int(round(abs(b - a) / dx))
        out.extend(a + np.sign(b - a) * dx * np.arange(1, k + 1))
    return np.asarray(out)


# ----------------------------------------------------------------------------- laws: analytic limits
@pytest.mark.parametrize("v", [0.05, -0.05, 0.3, -1e-3])
def test_dahl_steady_state_is_the_coulomb_force(v):
    law = DahlFields(sigma=1e6, coulomb=7.5)
    x, vs = ramp(v, 20000, 1e-4)
    F = friction_force(law, x, vs, 1e-4, 1)
    assert F[-1] == pytest.approx(7.5 * np.sign(v), rel=1e-9)  # eq. 6.9


@pytest.mark.parametrize("damping", ["standard", "olsson"])
@pytest.mark.parametrize("v", [1e-3, -4e-3, 0.02, -0.2])
def test_lugre_steady_state_is_stribeck_plus_viscous(v, damping):
    law = LuGreFields(
        sigma0=1e6,
        sigma1=300.0,
        viscous=0.4,
        coulomb=10.0,
        static=14.0,
        stribeck_velocity=5e-3,
        damping=damping,
        damping_velocity=2e-3,
    )
    x, vs = ramp(v, 40000, 1e-4)
    F = friction_force(law, x, vs, 1e-4, 1)
    g = 10.0 + 4.0 * np.exp(-((v / 5e-3) ** 2))  # eq. 6.11
    assert F[-1] == pytest.approx(np.sign(v) * g + 0.4 * v, rel=1e-9)
    assert steady_force(law, v) == pytest.approx(F[-1], rel=1e-9)


@pytest.mark.parametrize("v", [5e-4, -2e-3, 0.01, -0.5])
def test_gms_total_sliding_force(v):
    """Every element ends slipping at sign(v) nu_i g(v); with sum nu_i = 1 the total is g(v) sign(v) + sigma2 v."""
    law = GmsFields(
        elements=6,
        fractions=[0.3, 0.25, 0.2, 0.1, 0.1, 0.05],
        viscous=0.7,
        coulomb=12.0,
        static=15.0,
        stribeck_velocity=3e-3,
        attraction=2e3,
    )
    x, vs = ramp(v, 60000, 1e-4)
    st = LawState(law)
    F = friction_force(law, x, vs, 1e-4, 1, st)
    g = 12.0 + 3.0 * np.exp(-((v / 3e-3) ** 2))
    assert F[-1] == pytest.approx(np.sign(v) * g + 0.7 * v, rel=1e-9)
    assert np.all(st.mode == np.sign(v))


@pytest.mark.parametrize(
    "law", [DahlFields(sigma=3e6), LuGreFields(sigma0=2e6, sigma1=0.0), GmsFields()], ids=["dahl", "lugre", "gms"]
)
def test_presliding_initial_stiffness(law):
    """From the virgin state, the first nanometre gives dF/dx = sigma, sigma0, or sum k_i."""
    x, vs = ramp(1e-6, 11, 1e-3)  # 1 nm per step, at 1 um/s (negligible viscous and Stribeck effects)
    F = friction_force(law, x, vs, 1e-3, 1)
    slope = (F[1] - F[0]) / (x[1] - x[0])
    assert slope == pytest.approx(initial_stiffness(law), rel=2e-3)
    if isinstance(law, GmsFields):
        assert initial_stiffness(law) == pytest.approx(np.sum(law.k()))
        assert slope == pytest.approx(np.sum(law.k()), rel=1e-9)  # every element sticks: exactly linear


# ----------------------------------------------------------------------------- pre-sliding memory
@pytest.mark.parametrize("static", [20.0, 22.0])
def test_gms_non_local_memory_inner_loop_returns_onto_the_outer_loop(static):
    """Fig. 6.2 / 6.5: after the inner loop (a -> b -> a) is closed, the force follows the outer branch
    again, as if the inner loop had never happened (Maxwell-slip return-point memory)."""
    law = GmsFields(static=static)
    dx, h = 1e-8, 1e-2  # 10 nm per substep at 1 um/s: deep in pre-sliding, g(v) is the same everywhere
    X, a, b = 2e-5, 6e-6, -4e-6
    outer = path([0.0, X, -X, X], dx)
    inner = path([0.0, X, -X, a, b, X], dx)
    Fo = friction_force(law, outer, np.full(len(outer), 1e-6), h, 1)
    Fi = friction_force(law, inner, np.full(len(inner), 1e-6), h, 1)
    up_o = Fo[-int(round((X - a) / dx)) - 1 :]  # the last rise from a to X on either path
    up_i = Fi[-int(round((X - a) / dx)) - 1 :]
    np.testing.assert_allclose(up_i, up_o, rtol=0, atol=1e-9 * static)
    # and inside the inner loop the force did differ (the memory is non-local, not a function of x)
    k_b = len(path([0.0, X, -X, a, b], dx)) - 1
    k_same = len(path([0.0, X, -X], dx)) - 1 + int(round((b + X) / dx))
    assert abs(Fi[k_b] - Fo[k_same]) > 1.0


def test_gms_hysteresis_loop_is_closed_and_symmetric():
    law = GmsFields()
    x = path([0.0, 3e-5, -3e-5, 3e-5, -3e-5], 1e-8)
    F = friction_force(law, x, np.full(len(x), 1e-6), 1e-2, 1)
    m = int(round(6e-5 / 1e-8))
    np.testing.assert_allclose(F[-1], -F[-1 - m], atol=1e-6)  # the branches are point-symmetric
    np.testing.assert_allclose(F[-1 - 2 * m], F[-1], atol=1e-9)  # a repeated cycle retraces the loop


# ----------------------------------------------------------------------------- no chatter
def test_no_spurious_switching_in_steady_or_slowly_varying_sliding():
    """Sliding at a speed that sweeps the Stribeck range (g(v) changes, v > 0): after the break-away
    every element keeps slipping; a mode never flips back and forth."""
    law = GmsFields()
    st = LawState(law)
    h, n, chunks = 1e-4, 4000, 20
    v = 0.004 + 0.0035 * np.sin(np.linspace(0, 6 * np.pi, chunks * n + 1))
    x = np.concatenate([[0.0], np.cumsum(v[1:] * h)])
    history = []
    for c in range(chunks):
        seg = slice(c * n, (c + 1) * n + 1)
        friction_force(law, x[seg], v[seg], h, 1, st)
        history.append(st.mode.copy())
    history = np.array(history)
    assert np.all(history == 1.0)


def test_plant_steady_sliding_has_no_mode_chatter_and_tracks_with_the_expected_lag():
    """A long move at nearly constant speed under PD control: after the break-away no element
    switches again, and the tracking error settles at (g(v) + sigma2 v) / kp (quasi-static)."""
    law = GmsLaw(viscous=0.2)
    params = PlantParams(
        kd=250.0, noise=0.0, law=law, reference={"kind": "reversals", "points": [0.0, 1.0], "speed": 0.05}
    )
    plant = Plant(params)
    traj = Trajectory(params.reference, np.random.default_rng(0))
    n = 30000
    ref, dref = plant.reference_grid(traj, n)
    state = plant.initial_state(ref[0], dref[0])
    ff, noise = np.zeros(n + 1), np.zeros(n)
    modes, pos = [], []
    for start in range(0, n, 250):
        rec = plant.run(ref, dref, ff, noise, state, start, start + 250)
        modes.append(state.mode.copy())
        pos.append(rec.position)
    modes = np.array(modes)
    assert np.all(modes[8:] == 1.0)  # every element broke away within 2 s (one by one) and keeps slipping
    assert np.sum(modes[1:] != modes[:-1]) == 10  # ten switches in all: one break-away per element
    mid = 15708  # t = 15.708 s: the peak of the half-cosine move (31.4 s long): v = 0.05 m/s, a = 0
    P = np.concatenate(pos)
    e = ref[:: 2 * params.substeps][:n] - P
    v = 0.05
    assert e[mid] * params.kp == pytest.approx(law.g(v) + 0.2 * v, rel=2e-3)


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    "params, message",
    [
        ({"fractions": [0.5, 0.4]}, "fractions has 2 values but elements is 10"),
        ({"elements": 2, "fractions": [0.5, 0.4]}, "the fractions nu_i add up to 0.9; they must sum to 1 (eq. 6.14)"),
        ({"elements": 2, "stiffness": [1e5, -1.0]}, "every stiffness k_i must be positive"),
        ({"viscous": -0.2}, "viscous = -0.2 is negative: a negative damping feeds energy into the motion"),
        ({"static": 0.0}, "static = 0 must be positive"),
        ({"trajectory": {"kind": "reversals"}}, "kind reversals needs points"),
        ({"trajectory": {"band": [2.0, 1.0]}}, "band = [2, 1] must satisfy 0 < low <= high"),
    ],
)
def test_parameter_errors_are_one_clear_line(cli, tmp_path, params, message):
    spec = {"data": {"generator": "gms", "params": params, "n": 100}, "model": {"family": "esn"}}
    r = cli("validate", write_yaml(tmp_path / "s.yaml", spec))
    assert r.exit_code == 2
    line = r.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert "data.params" in line and message in line, line


def test_plant_validation_names_the_problem(cli, tmp_path):
    r = cli("generate", "friction-plant", "--n", 10, "--out", tmp_path / "x.csv", "-p", "law={type: lugre, sigma1: -3}")
    assert r.exit_code == 2 and "sigma1 = -3 is negative" in r.stderr and "\n" not in r.stderr.strip()
    r = cli("generate", "friction-plant", "--n", 10, "--out", tmp_path / "x.csv", "-p", "substeps=1")
    assert r.exit_code == 2 and "substeps = 1 is too coarse" in r.stderr and "use substeps >=" in r.stderr


# ----------------------------------------------------------------------------- trajectories
def test_random_trajectory_std_derivatives_and_start_from_rest():
    tp = TrajectoryParams(kind="random", std=2e-3, band=(0.1, 2.0), fade_in=1.0)
    tr = Trajectory(tp, np.random.default_rng(3))
    dt = 1e-3
    x, v, a = tr.grid(0.0, dt, 400001)
    assert np.std(x[1000:]) == pytest.approx(2e-3, rel=0.15)
    assert x[0] == 0 and v[0] == 0
    np.testing.assert_allclose(np.gradient(x, dt)[1:-1], v[1:-1], atol=1e-4 * np.abs(v).max())
    np.testing.assert_allclose(np.gradient(v, dt)[1:-1], a[1:-1], atol=1e-4 * np.abs(a).max())
    # a longer record starts with the same samples as a shorter one (the rotated phasors stay exact)
    x2, _, _ = Trajectory(tp, np.random.default_rng(3)).grid(0.0, dt, 1000)
    np.testing.assert_allclose(x2, x[:1000], rtol=0, atol=1e-15)
    spec = np.abs(np.fft.rfft(x[2000:] * np.hanning(len(x) - 2000)))
    f = np.fft.rfftfreq(len(x) - 2000, dt)
    assert spec[(f > 3.0)].max() < 1e-3 * spec.max()  # band-limited


def test_multisine_is_periodic():
    tp = TrajectoryParams(kind="multisine", std=1e-5, band=(0.1, 1.0), period=10.0, fade_in=0.0)
    x, _, _ = Trajectory(tp, np.random.default_rng(0)).grid(0.0, 0.01, 2001)
    np.testing.assert_allclose(x[:1000], x[1000:2000], atol=1e-12 * np.abs(x).max() + 1e-20)


# ----------------------------------------------------------------------------- compiled vs plain
def _gms_plain(law: GmsFields, x: np.ndarray, h: float) -> np.ndarray:
    """Plain-numpy twin of the prescribed-trajectory GMS update (vectorized over elements)."""
    k, nu = law.k(), law.nu()
    F, mode = np.zeros(law.elements), np.zeros(law.elements)
    out = [F.sum()]
    for j in range(len(x) - 1):
        dx = x[j + 1] - x[j]
        g = law.coulomb + (law.static - law.coulomb) * np.exp(-(np.abs(dx / h / law.stribeck_velocity) ** 2))
        slip = (mode != 0) & (dx * mode > 0)
        target = mode * nu * g
        F = np.where(slip, target + (F - target) * np.exp(-law.attraction * h / (nu * g)), F)
        mode = np.where(slip, mode, 0.0)
        stick = ~slip
        Fn = F + k * dx
        brk = stick & (Fn * dx > 0) & (np.abs(Fn) >= nu * g) & (dx != 0)
        Fn = np.clip(Fn, -nu * g, nu * g)
        F = np.where(stick, np.where(brk, np.sign(dx) * nu * g, Fn), F)
        mode = np.where(brk, np.sign(dx), mode)
        out.append(F.sum())
    return np.asarray(out)


def test_compiled_gms_matches_a_plain_numpy_loop():
    law = GmsFields()
    tr = Trajectory(TrajectoryParams(std=2e-5, band=(0.5, 3.0)), np.random.default_rng(1))
    h = 1e-3
    x, v, _ = tr.grid(0.0, h, 3001)
    F = friction_force(law, x, np.zeros(3001), h, 1)
    np.testing.assert_allclose(F, _gms_plain(law, x, h), rtol=0, atol=1e-10)


# ----------------------------------------------------------------------------- plant
def test_plant_rk4_converges_and_records_consistent_forces():
    base = dict(noise=0.0, reference={"std": 0.02, "band": [0.1, 1.0]})
    _, coarse = simulate(PlantParams(substeps=10, **base), 3000, np.random.default_rng(2))
    ref, fine = simulate(PlantParams(substeps=40, **base), 3000, np.random.default_rng(2))
    assert np.max(np.abs(coarse.position - fine.position)) < 1e-4 * np.std(ref)
    assert np.max(np.abs(coarse.force - fine.force)) < 1e-3 * np.std(fine.force)
    np.testing.assert_allclose(fine.force, 4000.0 * (ref - fine.position), rtol=1e-12, atol=1e-12)


def test_generator_columns_and_p_control_tracking():
    params = PlantParams()
    u, y = FrictionPlant.generate(params, 20000, np.random.default_rng(1))
    position, reference = u[:, 0], u[:, 1]
    force, friction = y[:, 0], y[:, 1]
    e = position - reference
    # the P-controller keeps the position at the reference within a few per cent of its spread ...
    assert 0.002 < np.sqrt(np.mean(e[2000:] ** 2)) / np.std(reference) < 0.2
    # ... with the control force kp (P_r - P); friction is bounded by F_s + sigma2 |v| + noise
    np.testing.assert_allclose(force, -4000.0 * e, rtol=1e-12, atol=1e-9)
    assert np.max(np.abs(friction)) < 22.0 + 0.2 * 1.0 + 0.05


def test_perfect_feedforward_removes_nearly_all_tracking_error():
    """The plant's own law as the feed-forward model (fig. 6.23): alpha and beta near 100 %;
    no feed-forward at all: alpha near 0."""
    plant = Plant(PlantParams())
    n, switch, skip = 16000, 8000, 3000
    task = TrackingTask(plant, n, np.random.default_rng(4))
    run = task.start(switch, np.random.default_rng(5))
    pos, _ = run.resume(task.perfect_feedforward())
    perfect = ctl.criteria(task.reference, np.concatenate([run.position, pos]) - task.reference, switch, skip)
    pos0, _ = run.resume(np.zeros(n))
    none = ctl.criteria(task.reference, np.concatenate([run.position, pos0]) - task.reference, switch, skip)
    assert perfect["alpha"] > 99.99 and perfect["beta"] > 99.0
    assert abs(none["alpha"]) < 30 and none["nmse_p"] == perfect["nmse_p"]


# ----------------------------------------------------------------------------- control criteria
def test_control_criteria_by_hand():
    ref = np.array([1.0, -1.0] * 10)  # var 1, std 1
    e = np.zeros(20)
    e[2:10] = [0.1, -0.1, 0.1, -0.1, 0.1, -0.1, 0.1, -0.3]  # before the switch (scored from 2 to 9)
    e[12:] = [0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.03]  # after it (scored from 12)
    c = ctl.criteria(ref, e, switch=10, skip=2)
    nmse_p = 100 * (7 * 0.01 + 0.09) / 8
    nmse_ff = 100 * (0.0001 + 0.0009) / 8
    assert c["nmse_p"] == pytest.approx(nmse_p) and c["nmse_ff"] == pytest.approx(nmse_ff)
    assert c["max_p"] == pytest.approx(0.3) and c["max_ff"] == pytest.approx(0.03)
    assert c["alpha"] == pytest.approx(100 * (nmse_p - nmse_ff) / nmse_p)
    assert c["beta"] == pytest.approx(90.0)
    with pytest.raises(ValueError):
        ctl.criteria(ref, e, switch=10, skip=10)


# ----------------------------------------------------------------------------- CLI
@pytest.fixture(scope="module")
def small_plant_model(tmp_path_factory):
    """A quickly fitted feed-forward model of a short closed-loop recording (not a good one)."""
    d = tmp_path_factory.mktemp("ctl")
    spec = {
        "name": "tiny",
        "output": str(d / "tiny.h5"),
        "data": {
            "generator": "friction-plant",
            "n": 6000,
            "seed": 1,
            "input": ["position"],
            "output": ["force"],
            "split": {"train": 0.8, "validation": 0.2},
            "delay_lines": [50, 100],
        },
        "model": {"family": "esn", "params": {"size": 50, "relaxation": [0.0, 0.95]}},
    }
    model = dynmodel.fit(dynmodel.load_spec(write_yaml(d / "tiny.yaml", spec)))
    dynmodel.save(model, d / "tiny.h5")
    return d / "tiny.h5"


def test_cli_control_table_json_plot(cli, tmp_path, small_plant_model):
    r = cli(
        "control",
        small_plant_model,
        "--duration",
        10,
        "--switch",
        5,
        "--skip",
        2,
        "--realizations",
        2,
        "--json",
        tmp_path / "c.json",
        "--plot",
        tmp_path / "c.png",
        "-q",
    )
    assert r.exit_code == 0, r.stderr
    for word in ("NMSE_P %", "NMSE_ff %", "MAX_P", "MAX_ff", "alpha %", "beta %", "perfect model", "friction-plant"):
        assert word in r.stdout
    report = json.loads((tmp_path / "c.json").read_text())
    assert set(report) >= {"model", "perfect", "realizations", "plant", "settings"}
    assert len(report["realizations"]) == 2 and report["settings"]["samples"] == 10000
    assert report["plant"]["params"]["law"]["elements"] == 10 and report["plant"]["generator"] == "friction-plant"
    assert report["perfect"]["alpha"]["mean"] > 99.9
    assert (tmp_path / "c.png").stat().st_size > 20000
    # the same seed gives the same figures
    r2 = cli(
        "control",
        small_plant_model,
        "--duration",
        10,
        "--switch",
        5,
        "--skip",
        2,
        "--realizations",
        2,
        "--json",
        tmp_path / "d.json",
        "-q",
    )
    assert r2.exit_code == 0, r2.stderr
    again = json.loads((tmp_path / "d.json").read_text())["model"]
    for c in ctl.CRITERIA:  # equal up to summation order (numpy's SIMD reductions depend on alignment)
        assert again[c]["mean"] == pytest.approx(report["model"][c]["mean"], rel=1e-12)


def test_cli_control_plant_override_and_spec_file(cli, tmp_path, small_plant_model):
    plant = write_yaml(tmp_path / "plant.yaml", {"generator": "friction-plant", "params": {"noise": 0.0}})
    r = cli(
        "control",
        small_plant_model,
        "--plant",
        plant,
        "-p",
        "law.viscous=1.0",
        "--duration",
        4,
        "--switch",
        2,
        "--skip",
        0.5,
        "--realizations",
        1,
        "--json",
        tmp_path / "c.json",
        "-q",
    )
    assert r.exit_code == 0, r.stderr
    params = json.loads((tmp_path / "c.json").read_text())["plant"]["params"]
    assert params["noise"] == 0.0 and params["law"]["viscous"] == 1.0 and params["law"]["type"] == "gms"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--hold", "cubic"], "--hold cubic is not linear or zero"),
        (["--switch", "200"], "need 0 < skip"),
        (["-p", "law.fractions=[1, 2]"], "fractions has 2 values but elements is 10"),
        (["-p", "mass=-1"], "mass: Input should be greater than 0"),
    ],
)
def test_cli_control_usage_errors_are_one_line(cli, small_plant_model, args, message):
    r = cli("control", small_plant_model, *args, "-q")
    assert r.exit_code == 2 and message in r.stderr and "\n" not in r.stderr.strip() and "Traceback" not in r.stderr


def test_cli_control_refuses_models_and_plants_it_cannot_use(cli, tmp_path, small_plant_model):
    r = cli("control", tmp_path / "missing.h5")
    assert r.exit_code == 2 and "missing.h5" in r.stderr
    # a plant description whose generator has no plant to control
    other = write_yaml(tmp_path / "p.yaml", {"generator": "narx-system"})
    r = cli("control", small_plant_model, "--plant", other)
    assert r.exit_code == 2 and "generator 'narx-system' describes no controllable plant" in r.stderr
    assert "friction-plant" in r.stderr
    # a model fitted on recorded data needs --plant
    u, y = np.random.default_rng(0).standard_normal((2, 3000))
    csv = write_csv(tmp_path / "d.csv", {"position": u, "force": y})
    spec = write_yaml(
        tmp_path / "f.yaml",
        {
            "data": {"path": str(csv), "input": ["position"], "output": ["force"], "sampling_time": 0.001},
            "model": {"family": "esn", "params": {"size": 20}},
            "output": str(tmp_path / "f.h5"),
        },
    )
    assert cli("fit", spec, "-q").exit_code == 0
    r = cli("control", tmp_path / "f.h5")
    assert r.exit_code == 2 and "fitted on recorded data" in r.stderr and "--plant" in r.stderr
    # ... and with --plant it runs (the file model's input is called position)
    plant = write_yaml(tmp_path / "plant.yaml", {"generator": "friction-plant"})
    r = cli(
        "control",
        tmp_path / "f.h5",
        "--plant",
        plant,
        "--duration",
        4,
        "--switch",
        2,
        "--skip",
        0.5,
        "--realizations",
        1,
        "-q",
    )
    assert r.exit_code == 0, r.stderr


def test_cli_generate_plot_shows_the_hysteresis(cli, tmp_path):
    r = cli(
        "generate",
        "gms",
        "--n",
        3000,
        "--out",
        tmp_path / "g.csv",
        "--plot",
        tmp_path / "g.png",
        "-p",
        "position_unit=um",
    )
    assert r.exit_code == 0, r.stderr
    data = np.loadtxt(tmp_path / "g.csv", delimiter=",", skiprows=1)
    assert (tmp_path / "g.csv").read_text().splitlines()[0] == "t,position,force"
    # the unit changes the recorded position column only: same run in metres, same forces
    assert cli("generate", "gms", "--n", 3000, "--out", tmp_path / "m.csv").exit_code == 0
    metres = np.loadtxt(tmp_path / "m.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 1], 1e6 * metres[:, 1], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(data[:, 2], metres[:, 2])
    assert np.std(metres[:, 1]) == pytest.approx(5e-6, rel=0.05)  # the default drive: std 5 um
    assert (tmp_path / "g.png").stat().st_size > 20000


def test_cli_control_tunes_external_models_in_on_the_p_controlled_force(cli, tmp_path):
    spec = {
        "name": "ext",
        "output": str(tmp_path / "ext.h5"),
        "cost": "mse_inf",
        "data": {
            "generator": "friction-plant",
            "n": 6000,
            "seed": 1,
            "input": ["position"],
            "output": ["force"],
            "split": {"train": 0.8, "validation": 0.2},
            "delay_lines": [50, 100],
        },
        "model": {"family": "esn", "params": {"size": 50, "mode": "external", "tune_in": 20}},
    }
    assert cli("fit", write_yaml(tmp_path / "ext.yaml", spec), "-q").exit_code == 0
    r = cli(
        "control",
        tmp_path / "ext.h5",
        "--duration",
        6,
        "--switch",
        3,
        "--skip",
        1,
        "--realizations",
        2,
        "--json",
        tmp_path / "c.json",
        "-q",
    )
    assert r.exit_code == 0, r.stderr
    assert "tunes in on its first 20 outputs" in r.stdout
    assert len(json.loads((tmp_path / "c.json").read_text())["realizations"]) == 2
