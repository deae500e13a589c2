"""`dynmodel reliability-check`: thesis 4.4.1 / 5.3.1 examples, esn models, the protocol's numerics, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import make_spec, narx_spec

import dynmodel
from dynmodel import engine, registry
from dynmodel.reliability import DrivenSystem, InputDomain, Settings, check, check_model, lyapunov
from dynmodel.reliability.networks import SigmoidNetwork
from dynmodel.reliability.replicas import APART
from dynmodel.reliability.signals import declared_sine

EQ_5_28 = [[0.34, 2.31], [-0.56, -1.93]]


def _system(name: str, **params):
    return registry.system(name)(**params)


def _level(report, value: float):
    return next(lv for lv in report.levels if np.allclose(lv.input, value))


def _evidence(report, name: str):
    return next(e for e in report.evidence if e.name == name)


def assert_consistent(report) -> None:
    """The verdict follows from the evidence the report carries (whatever it is)."""
    v = report.verdict.verdict
    tol, apart = report.tolerance, APART * report.scale
    apart_signals = [s for s in report.signals if s.status in ("apart", "diverged")]
    bad_levels = [lv for lv in report.levels if lv.status in ("several responses", "no fixed point", "diverged")]
    positive = [n for n, e in report.exponents.items() if e.sign() == "positive"]
    proof = [e.implies for e in report.evidence]
    if v == "reliable":
        assert not apart_signals and not bad_levels and not report.verdict.counterexamples
        assert all(s.final_distance <= 2 * tol for s in report.signals) or "reliable" in proof
        assert not positive and "unreliable" not in proof
    elif v == "unreliable":
        assert report.verdict.counterexamples or "unreliable" in proof
        assert apart_signals or bad_levels or positive or "unreliable" in proof
        for s in apart_signals:
            assert s.status == "diverged" or s.final_distance >= apart
    else:
        assert report.verdict.unsettled or (report.verdict.counterexamples and "reliable" in proof)


# ---------------------------------------------------------------------------------------- thesis 5.3.1
def test_eq_5_28_network_is_unreliable_and_its_attractors_are_named():
    r = check(_system("tanh-network"), Settings(seed=0))
    assert abs(_evidence(r, "sigma(C)").value - 3.07) < 0.01
    assert abs(_evidence(r, "rho(C)").value - 0.79) < 0.01
    assert r.verdict.verdict == "unreliable" and r.exit_code == 1
    zero = _level(r, 0.0)
    assert zero.status == "several responses" and zero.responses == 3
    fixed = [a for a in zero.attractors if a.kind == "fixed point"]
    cycles = [a for a in zero.attractors if a.kind == "cycle"]
    assert len(fixed) == 1 and np.abs(fixed[0].points[0]).max() < 1e-8
    assert len(cycles) == 1 and cycles[0].period == 2 and cycles[0].phases == 2
    pts = cycles[0].points
    z2a = np.array([0.864, -0.694])
    assert min(np.abs(pts - z2a).max(axis=1)) < 2e-3 and min(np.abs(pts + z2a).max(axis=1)) < 2e-3
    # figure 5.5: the same small sine started at three phases, then zero input: the end depends on the phase
    assert [f.status for f in r.families] == ["apart"]
    assert any("u = 0: fixed point (0, 0)" in c for c in r.verdict.counterexamples)
    assert_consistent(r)


def test_eq_5_28_matrix_rescaled_to_sigma_095_is_reliable():
    r = check(_system("tanh-network", sigma=0.95))
    ev = _evidence(r, "sigma(C)")
    assert abs(ev.value - 0.95) < 1e-12 and ev.implies == "reliable"
    assert r.verdict.verdict == "reliable" and r.exit_code == 0
    assert all(s.status == "converged" for s in r.signals)
    assert all(lv.status == "fixed point" for lv in r.levels)
    assert all(e.largest < 0 for e in r.exponents.values())
    assert r.washout is not None and r.washout < 200
    assert_consistent(r)


def test_rho_below_one_rescaling_keeps_the_eq_5_28_network_unreliable():
    r = check(_system("tanh-network", rho=0.95), Settings(replicas=8, scan_replicas=16, length=1000))
    assert abs(_evidence(r, "rho(C)").value - 0.95) < 1e-9 and _evidence(r, "sigma(C)").value > 3
    assert r.verdict.verdict == "unreliable"


# ---------------------------------------------------------------------------------------- thesis 4.4.1
def test_driven_gaussian_map_is_unreliable_with_cycles_and_chaos():
    r = check(_system("gaussian-map"))
    assert r.verdict.verdict == "unreliable"
    kinds = {a.label for lv in r.levels for a in lv.attractors}
    assert "chaotic" in kinds and {"2-cycle", "3-cycle", "4-cycle"} <= kinds
    chaotic = [lv for lv in r.levels if any(a.label == "chaotic" for a in lv.attractors)]
    assert all(a.lyapunov > 0.1 for lv in chaotic for a in lv.attractors if a.label == "chaotic")
    assert any(np.isclose(lv.input[0], 0.0) for lv in chaotic)  # u = 0 (fig. 4.8)
    two = _level(r, 0.5)
    assert two.attractors[0].period == 2 and two.attractors[0].phases == 2
    assert _level(r, 1.0).status == "fixed point"
    assert_consistent(r)


def test_duffing_has_one_fixed_point_per_constant_input_yet_is_unreliable_under_a_sine():
    s = _system("duffing")
    r = check(s)
    # the necessary criterion of eq. 4.39 holds: a single stable fixed point for every constant input ...
    assert len(r.levels) >= 21 and all(lv.status == "fixed point" for lv in r.levels)
    for lv in r.levels:
        x1, x2 = lv.attractors[0].points[0]
        c = lv.input[0]
        assert abs(x1 + x1**3 - c) < 1e-4 * max(1, abs(c)) and abs(x2) < 1e-4
    assert not any(c.startswith("constant input") for c in r.verdict.counterexamples)
    # ... yet u = 27 sin(1.4 t) leaves the replicas apart with a positive conditional exponent
    thesis = next(x for x in r.signals if x.name.startswith("27 sin(1.4 t)"))
    assert thesis.status == "apart" and thesis.final_distance > 1.0
    assert r.exponents[thesis.name].largest / s.sampling_time > 0.05
    assert r.verdict.verdict == "unreliable"
    # the generic battery finds it without the thesis drive as well
    generic = [x for x in r.signals if x.kind == "sine" and x.status == "apart"]
    assert len(generic) >= 3
    assert_consistent(r)


@pytest.mark.parametrize("coupling", ["4.52", "4.46", "4.43"])
def test_driven_lorenz_couplings_are_reliable(coupling):
    s = _system("lorenz-driven", coupling=coupling)
    r = check(s, Settings(replicas=12, scan_replicas=16))
    assert r.verdict.verdict == "reliable", r.verdict.reasons
    assert all(x.status == "converged" for x in r.signals)
    assert all(e.largest < 0 for e in r.exponents.values())
    assert all(lv.status == "fixed point" for lv in r.levels)
    if coupling == "4.52":  # fixed point x1 = c, x2 = r c / (1 + c^2 / b), x3 = x1 x2 / b (fig. 4.10)
        for lv in r.levels:
            c = lv.input[0]
            x2 = 28.0 * c / (1 + c * c / 2.666)
            np.testing.assert_allclose(lv.attractors[0].points[0], [c, x2, c * x2 / 2.666], atol=1e-5)
    assert_consistent(r)


def test_duffing_scan_and_tangent_agree_with_finite_differences():
    s = _system("duffing")
    rng = np.random.default_rng(3)
    X = s.sample_states(rng, 5)
    V = s.drive(np.array([[3.0], [-7.0]]))[1:].repeat(5, axis=0)
    E = rng.standard_normal((5, 2, 2))
    _, JE = s.tangent(X, V, E)
    h = 1e-6
    for j in range(2):
        num = np.stack([(s.step(X + h * E[:, :, j], V) - s.step(X - h * E[:, :, j], V)) / (2 * h)], axis=2)[:, :, 0]
        np.testing.assert_allclose(JE[:, :, j], num, rtol=1e-6, atol=1e-6)


# ---------------------------------------------------------------------------------------- numerics
def test_network_step_and_tangent_match_numpy_sparse_and_dense():
    rng = np.random.default_rng(0)
    for density in (0.03, 1.0):
        m = 80
        C = sp.random(m, m, density=density, random_state=1, data_rvs=rng.standard_normal).toarray() * 0.3
        B, c0 = rng.standard_normal((m, 2)), rng.standard_normal(m)
        a = rng.uniform(0, 0.5, m)
        g = 1 - a
        net = SigmoidNetwork(C, B, c0, a, g)
        assert (net._dense is not None) == (density == 1.0)
        X, V, E = rng.uniform(-1, 1, (6, m)), rng.standard_normal((6, 2)), rng.standard_normal((6, m, 3))
        Z = X @ C.T + V @ B.T + c0
        J = a[None, :, None] * np.eye(m)[None] + (g * (1 - np.tanh(Z) ** 2))[:, :, None] * C[None]
        out, JE = net.tangent(X, V, E)
        np.testing.assert_allclose(net.step(X, V), a * X + g * np.tanh(Z), atol=1e-14)
        np.testing.assert_allclose(out, a * X + g * np.tanh(Z), atol=1e-14)
        np.testing.assert_allclose(JE, J @ E, atol=1e-13)


class _Linear(DrivenSystem):
    """x_t = A x_{t-1} + b u_t: a third-party system through the protocol; CLEs = log |eig(A)|."""

    name = "linear"

    def __init__(self, A):
        self.A = np.asarray(A, dtype=float)
        self.state_dim = len(self.A)
        self.inputs = InputDomain.from_range(["u"], -1, 1)

    def step(self, X, V, out=None):
        return X @ self.A.T + V[:, :1]

    def tangent(self, X, V, E):
        return self.step(X, V), np.einsum("ij,rjk->rik", self.A, E)

    def state_box(self):
        return -np.ones(self.state_dim), np.ones(self.state_dim)


def test_lyapunov_spectrum_by_qr_of_a_linear_map():
    A = np.diag([0.5, 0.9, -0.2]) + np.triu(np.ones((3, 3)), 1) * 0.3
    s = _Linear(A)
    V = np.zeros((400, 2, 1))
    ex = lyapunov.exponents(s, V, s.sample_states(np.random.default_rng(0), 2), 3, np.random.default_rng(1))
    for e in ex:
        np.testing.assert_allclose(e.values, np.log([0.9, 0.5, 0.2]), atol=0.02)
        assert e.sign() == "negative"


def test_a_protocol_system_without_evidence_is_judged_numerically():
    r = check(_Linear([[0.5, 0.2], [0.0, 0.7]]), Settings(replicas=6, scan_replicas=8, length=400))
    assert r.verdict.verdict == "reliable" and not r.evidence
    assert "no algebraic proof" in r.verdict.reasons[0]
    r = check(_Linear([[1.0, 0.0], [0.0, 0.5]]), Settings(replicas=6, scan_replicas=8, length=400))
    assert r.verdict.verdict == "unreliable"  # a neutral direction never forgets its start
    assert_consistent(r)


def test_same_seed_same_report_other_seed_other_initial_states():
    s = _system("tanh-network")
    settings = Settings(replicas=6, scan_replicas=8, length=600, levels=5)
    a, b = check(s, settings).to_json(), check(s, settings).to_json()
    for d in (a, b):
        d.pop("timing_seconds")
    assert a == b
    c = check(s, Settings(replicas=6, scan_replicas=8, length=600, levels=5, seed=1)).to_json()
    assert c["replica_test"] != a["replica_test"]


# ---------------------------------------------------------------------------------------- esn models
def _fit(mode: str, seed: int, **params):
    raw = narx_spec(
        mode=mode,
        seed=seed,
        n=2500,
        test_n=500,
        transient=200,
        scaling="standard",
        split={"train": 0.8, "validation": 0.2},
        **params,
    )
    return engine.fit(make_spec(raw))


@pytest.mark.parametrize("mode,seed", [("internal", 0), ("internal", 1), ("external", 0), ("external", 2)])
def test_esn_with_default_singular_scaling_passes(mode, seed):
    m = _fit(mode, seed, size=150, connectivity=None, scale=None)
    r = check_model(m)
    assert abs(_evidence(r, "sigma(C)").value - 0.95) < 1e-9
    assert r.verdict.verdict == "reliable" and r.exit_code == 0
    assert all(s.status == "converged" for s in r.signals)
    assert all(lv.status == "fixed point" for lv in r.levels)
    assert max(e.largest for e in r.exponents.values()) < 0
    assert any(s.kind == "training" for s in r.signals)
    if mode == "external":
        assert [e.name for e in r.closed_loop] == ["sigma(C + b_back w^T)"]
        assert r.system["inputs"] == ["u", "y (fed back)"]
        ti = r.tune_in
        assert ti is not None and ti.required is not None and ti.required <= ti.configured == 100
        assert ti.deviations[0] > ti.tolerance  # without tune-in the free run starts on another trajectory
        # the tune-in it reports does put free runs on the reference trajectory
        k = ti.grid.index(ti.required)
        assert max(ti.deviations[k:]) <= ti.tolerance
    else:
        assert r.tune_in is None and r.closed_loop == []
    assert_consistent(r)


def test_esn_with_the_eq_5_28_weights_is_unreliable():
    raw = narx_spec(n=1500, test_n=300, transient=100, weights={"C": EQ_5_28, "b": [1, 1], "c0": [0, 0]})
    for key in ("size", "scale"):
        raw["model"]["params"].pop(key)
    m = engine.fit(make_spec(raw))
    r = check_model(m, Settings(replicas=8, scan_replicas=24, length=1500))
    assert abs(_evidence(r, "sigma(C)").value - 3.07) < 0.01 and abs(_evidence(r, "rho(C)").value - 0.79) < 0.01
    assert r.verdict.verdict == "unreliable"
    zero = _level(r, 0.0)
    assert {a.label for a in zero.attractors} == {"fixed point", "2-cycle"}
    raw["model"]["params"]["scale"] = {"by": "singular", "value": 0.95}
    r = check_model(engine.fit(make_spec(raw)), Settings(replicas=8, scan_replicas=16, length=1000))
    assert r.verdict.verdict == "reliable"


@pytest.mark.slow
def test_dense_esn_scaled_by_spectral_radius_is_reported_honestly():
    with pytest.warns(UserWarning, match="does not guarantee"):
        m = _fit("internal", 0, size=200, connectivity=1.0, scale={"by": "spectral", "value": 0.95})
    r = check_model(m)
    assert abs(_evidence(r, "rho(C)").value - 0.95) < 1e-9
    sigma = _evidence(r, "sigma(C)")
    assert sigma.value > 1 and sigma.implies == "undecided"  # no proof either way: numerics decide
    assert r.verdict.verdict in ("reliable", "unreliable", "inconclusive")
    assert_consistent(r)


# ---------------------------------------------------------------------------------------- CLI
def test_cli_system_verdicts_exit_codes_and_json(cli, tmp_path):
    r = cli("reliability-check", "--system", "tanh-network", "--json", tmp_path / "r.json", "-q")
    assert r.exit_code == 1 and "UNRELIABLE" in r.stdout and "fixed point (0, 0)" in r.stdout
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["verdict"] == "unreliable" and rep["test_system"] == "tanh-network"
    assert {a["name"] for a in rep["algebraic"]} == {"sigma(C)", "rho(C)"}
    zero = next(lv for lv in rep["constant_scan"]["levels"] if lv["input"] == [0.0])
    assert sorted(a["kind"] for a in zero["attractors"]) == ["cycle", "fixed point"]
    assert rep["replica_test"]["largest_final_distance"] > 1
    assert len(rep["replica_test"]["signals"]) == len({s["name"] for s in rep["replica_test"]["signals"]})

    r = cli(
        "reliability-check", "--system", "tanh-network", "--param", "sigma=0.95", "--json", tmp_path / "ok.json", "-q"
    )
    assert r.exit_code == 0 and "RELIABLE" in r.stdout and "washout" in r.stdout
    ok = json.loads((tmp_path / "ok.json").read_text())
    assert ok["verdict"] == "reliable" and ok["params"]["sigma"] == 0.95 and ok["washout_steps"] > 0


def test_cli_extra_sine_and_model_file(cli, tmp_path):
    r = cli(
        "reliability-check",
        "--system",
        "lorenz-driven",
        "--sine",
        "3:0.7",
        "--replicas",
        "4",
        "--scan-replicas",
        "4",
        "--length",
        "500",
        "--levels",
        "5",
        "-q",
        "--json",
        tmp_path / "l.json",
    )
    assert r.exit_code == 0, r.stdout
    names = [s["name"] for s in json.loads((tmp_path / "l.json").read_text())["replica_test"]["signals"]]
    assert "3 sin(0.7 t)" in names

    m = _fit("internal", 0, size=60, connectivity=None, scale=None)
    path = dynmodel.save(m, tmp_path / "m.h5")
    r = cli("reliability-check", path, "--json", tmp_path / "m.json", "-q", "--length", "600")
    assert r.exit_code == 0 and "RELIABLE" in r.stdout
    rep = json.loads((tmp_path / "m.json").read_text())
    assert rep["model"] == str(path) and rep["system"]["state_dim"] == 60 and rep["external_mode"] is None


@pytest.mark.parametrize(
    "args,needle",
    [
        ((), "give either a model file or --system"),
        (("m.h5", "--system", "duffing"), "not both"),
        (
            (
                "--system",
                "lorenz",
            ),
            "unknown test system 'lorenz'",
        ),
        (("--system", "duffing", "--param", "damping"), "is not key=value"),
        (("--system", "duffing", "--param", "dampng=0.1"), "invalid parameter (unknown key 'dampng')"),
        (("--system", "duffing", "--sine", "27"), "AMPLITUDE:OMEGA"),
        (("missing.h5",), "model file not found"),
    ],
)
def test_cli_usage_errors_are_one_line_exit_2(cli, tmp_path, args, needle):
    r = cli("reliability-check", *args)
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr
    if "lorenz" in args:
        assert "lorenz-driven" in lines[0] and "duffing" in lines[0] and "gaussian-map" in lines[0]


def test_cli_corrupt_model_and_family_without_view(cli, tmp_path, monkeypatch):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file at all")
    r = cli("reliability-check", bad)
    assert r.exit_code == 2 and len(r.stderr.strip().splitlines()) == 1 and "not a model file" in r.stderr

    m = _fit("internal", 0, size=30, connectivity=None, scale=None)
    path = dynmodel.save(m, tmp_path / "m.h5")
    from dynmodel_plugins.esn import EchoStateNetwork

    monkeypatch.setattr(EchoStateNetwork, "driven_system", lambda self: None)
    r = cli("reliability-check", path)
    assert r.exit_code == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "does not expose a driven-system view" in r.stderr


def test_plugins_lists_the_test_systems(cli):
    r = cli("plugins")
    assert r.exit_code == 0 and "dynmodel.systems" in r.stdout
    for name in ("gaussian-map", "duffing", "lorenz-driven", "tanh-network"):
        assert name in r.stdout


def test_declared_sine_is_the_thesis_drive():
    s = _system("duffing")
    u = declared_sine(s.inputs, s.signals()[0], 100, s.sampling_time)
    np.testing.assert_allclose(u[:, 0], 27 * np.sin(1.4 * 0.1 * np.arange(100)))


def test_external_model_file_without_outputs_falls_back_to_its_own_run(tmp_path):
    import h5py

    m = _fit("external", 0, size=80, connectivity=None, scale=None)
    path = dynmodel.save(m, tmp_path / "m.h5")
    with h5py.File(path, "a") as f:
        del f["data/train_output"]
    old = dynmodel.load(path)
    assert old.train_output is None
    r = check_model(old, Settings(replicas=6, scan_replicas=8, length=800))
    assert r.verdict.verdict == "reliable"  # the open loop: sigma(C) = 0.95
    assert any("own run" in n or "no training outputs" in n or "could not be measured" in n for n in r.notes)


def test_algebraic_evidence_for_leaky_and_expanding_networks():
    from dynmodel.reliability.evidence import tanh_network_evidence

    C = np.array([[0.0, 0.8], [0.3, 0.0]])
    ev = {e.name: e for e in tanh_network_evidence(C, a=[0.1, 0.1], g=[1, 1], c0=[0, 0])}
    assert (
        ev["max|a| + sigma(diag(g) C)"].implies == "reliable"
        and abs(ev["max|a| + sigma(diag(g) C)"].value - 0.9) < 1e-12
    )
    ev = {e.name: e for e in tanh_network_evidence(1.5 * np.eye(2), a=[0, 0], g=[1, 1], c0=[0, 0])}
    assert ev["rho(C)"].implies == "unreliable" and ev["sigma(C)"].implies == "undecided"
    ev = {e.name: e for e in tanh_network_evidence(1.5 * np.eye(2), a=[0, 0], g=[1, 1], c0=[0.3, 0])}
    assert ev["rho(C)"].implies == "undecided"  # with biases rho > 1 proves nothing
    # the numerical tests agree with the proof of eq. 5.24: u = 0 has the fixed points +-x* per element
    r = check(_system("tanh-network", C=[[1.5, 0], [0, 1.5]]), Settings(replicas=8, scan_replicas=16, length=600))
    assert r.verdict.verdict == "unreliable"
    assert _level(r, 0.0).responses == 4


def test_json_report_is_strict_json(tmp_path):
    class Blowup(_Linear):
        pass

    with np.errstate(over="ignore", invalid="ignore"):  # the test system's own overflow
        r = check(Blowup([[1.5, 0.0], [0.0, 0.2]]), Settings(replicas=4, scan_replicas=4, length=2000, levels=3))
    assert r.verdict.verdict == "unreliable"
    assert any("diverged" in c for c in r.verdict.counterexamples)
    text = json.dumps(r.to_json(), allow_nan=False)
    assert "diverged" in text


def test_slow_convergence_is_inconclusive_and_a_longer_run_settles_it():
    s = _Linear([[0.99]])
    r = check(s, Settings(replicas=6, scan_replicas=8, length=300, levels=5))
    assert r.verdict.verdict == "inconclusive" and r.exit_code == 1
    slow = [x for x in r.signals if x.status == "slow"]
    assert slow and all(abs(x.rate - np.log(0.99)) < 2e-3 for x in slow)
    need = max(x.steps_needed for x in slow)
    # 0.99^t from a spread of about 2 down to the tolerance 2e-6 takes about 1400 steps; the advice doubles it
    assert 2000 < need < 5000
    assert f"rerun with --length {need}" in " ".join(r.verdict.unsettled)
    assert r.length_needed >= need
    # what a user does: rerun once with the length the report asks for, and the test settles
    r = check(s, Settings(replicas=6, scan_replicas=8, length=r.length_needed, levels=5))
    assert r.verdict.verdict == "reliable"
    assert_consistent(r)


def test_lorenz_4_52_exponent_is_minus_one_per_time_unit_at_rest():
    """At u = 0, x1 -> 0 and the error of (x2, x3) decays as e2' = -e2, e3' = -b e3 (eq. 4.47): lambda = -1."""
    s = _system("lorenz-driven")
    V = s.drive(np.zeros((3000, 1)))
    Vr = np.ascontiguousarray(np.repeat(V[:, None, :], 2, axis=1))
    ex = lyapunov.exponents(s, Vr, s.sample_states(np.random.default_rng(0), 2), 2, np.random.default_rng(1))
    for e in ex:
        np.testing.assert_allclose(e.values / s.sampling_time, [-1.0, -2.666], atol=0.01)


@pytest.mark.parametrize("leak", [{"relaxation": 0.5, "relaxation_gain": True}, {"relaxation": [0.0, 0.9]}])
def test_leaky_esn_with_delay_lines(leak):
    raw = narx_spec(
        n=2500,
        test_n=500,
        transient=200,
        scaling="standard",
        split={"train": 0.8, "validation": 0.2},
        size=100,
        connectivity=None,
        scale=None,
        **leak,
    )
    raw["data"]["delay_lines"] = [5, 20]
    m = engine.fit(make_spec(raw))
    r = check_model(m)
    assert r.system["inputs"] == ["u"]  # delayed copies are made from the physical input
    bound = _evidence(r, "max|a| + sigma(diag(g) C)")
    if leak.get("relaxation_gain"):
        assert abs(bound.value - 0.975) < 1e-9 and bound.implies == "reliable"  # 0.5 + 0.5 * 0.95
    else:
        assert bound.value > 1 and bound.implies == "undecided"  # no proof: the numerics decide
    assert r.verdict.verdict == "reliable"
    assert all(s.status == "converged" for s in r.signals)
    assert_consistent(r)


def test_narx_models_are_checked_from_the_past_outputs_a_recording_presents():
    """A NARX model's state is its past outputs. Its view reproduces the free run exactly (step and tangent);
    a stable linear model forgets where it started (reliable); a double integrator never does (unreliable:
    its position remembers the start)."""
    from conftest import narx as narx_data

    from dynmodel_plugins.narx import Narx

    u, y = narx_data(3000, 1)
    stable = Narx(degree=1, lags={"u": [0], "y": [1, 2]}).fit(u, y)
    view = stable.driven_system()
    assert view.state_is_tune_in and view.state_dim == 2
    um = stable.model_.preprocessor.inputs(u[:, None])
    ym = stable.model_.preprocessor.outputs(y[:, None])
    sim = stable.simulate(um, ym[:2]).y[:, 0]
    X, V = np.array([[sim[1], sim[0]]]), view.drive(um)
    for t in range(2, 400):
        X = view.step(X, V[t : t + 1])
        assert X[0, 0] == pytest.approx(sim[t], abs=1e-12)
    assert check_model(stable.model_, Settings(replicas=8, scan_replicas=8, length=800)).verdict.verdict == "reliable"

    rng = np.random.default_rng(2)
    force = rng.standard_normal(3000)
    position = np.cumsum(np.cumsum(0.01 * force))  # a double integrator
    drift = Narx(degree=1, lags={"u": [1], "y": [1, 2]}).fit(force, position, validation=0.2)
    r = check_model(drift.model_, Settings(replicas=8, scan_replicas=8, length=800))
    assert r.verdict.verdict == "unreliable"


def test_narx_tangent_matches_finite_differences():
    from conftest import narx as narx_data

    from dynmodel_plugins.narx import Narx

    u, y = narx_data(2000, 3)
    view = Narx(degree=3, lags={"u": [0, 1], "y": [1, 2]}).fit(u, y).driven_system()
    rng = np.random.default_rng(0)
    X, V = 0.5 * rng.standard_normal((4, view.state_dim)), view.drive(0.5 * rng.standard_normal((4, 1)))
    E = np.repeat(np.eye(view.state_dim)[None], 4, axis=0)
    F, DE = view.tangent(X, V, E)
    h, J = 1e-6, np.zeros_like(DE)
    for m in range(view.state_dim):
        step = np.zeros(view.state_dim)
        step[m] = h
        J[:, :, m] = (view.step(X + step, V) - view.step(X - step, V)) / (2 * h)
    np.testing.assert_array_equal(F, view.step(X, V))
    np.testing.assert_allclose(DE, J, atol=1e-7)


def test_narx_step_is_the_polynomial_of_every_replica():
    """The reliability view's step computes every replica's monomials with the compiled kernel and weighs them in
    one product: the same polynomial as term by term, eq. 3.8, to rounding (35 s -> 2.8 s for the check of a
    122-term Silverbox model)."""
    from conftest import narx as narx_data

    from dynmodel_plugins.narx import Narx

    u, y = narx_data(2000, 3)
    view = Narx(degree=3, lags={"u": [0, 1], "y": [1, 2]}).fit(u, y).driven_system()
    R = np.random.default_rng(1).standard_normal((6, view.exponents.shape[1]))
    expected = np.zeros((6, view.n_out))
    for e, k, w in zip(view.exponents, view.term_output, view.weights):
        expected[:, k] += w * np.prod(R**e, axis=1)
    assert len(view.weights) >= 5 and view.exponents.max() >= 2
    np.testing.assert_allclose(view._outputs(R), expected, rtol=1e-12, atol=1e-14)
