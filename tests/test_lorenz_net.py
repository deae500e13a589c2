"""The `lorenz-net` family: driven Lorenz elements (eq. 4.52), networks (4.58 / 4.59), annealing."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ROOT, make_spec
from scipy.integrate import solve_ivp

import dynmodel
from dynmodel import engine
from dynmodel.spec import load_spec
from dynmodel_plugins.lorenz_net.elements import descendants, integrate_element, simulate_network, step_elements
from dynmodel_plugins.lorenz_net.params import LorenzNetParams
from dynmodel_plugins.lorenz_net.search import initial_state, make_moves
from dynmodel_plugins.lorenz_net.streaming import DelayLine, delayed


def test_element_integration_matches_an_adaptive_solver():
    rng = np.random.default_rng(0)
    v = rng.uniform(0, 3, 150)
    s, r, b, a = 10.0, 28.0, 8 / 3, 1.1
    out = np.empty((150, 3))
    assert integrate_element(s, r, b, a, v, 0.1, 20, np.zeros(3), out) == -1
    x, ref = np.zeros(3), []
    for t in range(150):  # zero-order hold of the drive over each interval

        def rhs(_, x, vt=v[t]):
            return [a * s * (vt - x[0]), a * (r * x[0] - x[1] - x[0] * x[2]), a * (x[0] * x[1] - b * x[2])]

        x = solve_ivp(rhs, (0, 0.1), x, rtol=1e-11, atol=1e-12).y[:, -1]
        ref.append(x)
    np.testing.assert_allclose(out, ref, atol=1e-6)


def test_every_element_forgets_its_initial_state():
    """Replicas from far-apart states, same input: they converge (eq. 4.44 / 4.45 Lyapunov function)."""
    rng = np.random.default_rng(1)
    p = LorenzNetParams(size=12, strategy="feed-forward", layers=3, extra_links=6)
    st = initial_state(p, 1, rng)
    X = rng.uniform(-30, 30, (8, 12, 3))
    u = rng.uniform(0, 4, 600)
    out = np.empty_like(X)
    for t in range(600):
        step_elements(st.params, st.C, st.B, X, np.full((8, 1), u[t]), 0.1, 4, out)
        X, out = out, X
    assert np.max(np.abs(X - X[0])) < 1e-6


def test_batched_step_equals_the_network_simulation():
    rng = np.random.default_rng(2)
    st = initial_state(LorenzNetParams(size=10, strategy="feed-forward", layers=2, extra_links=5), 2, rng)
    U = rng.uniform(-1, 2, (80, 2))
    X, bad = simulate_network(st.params, st.C, st.B, U, 0.1, 3)
    assert bad == -1
    state, out = np.zeros((1, 10, 3)), np.empty((1, 10, 3))
    for t in range(80):
        step_elements(st.params, st.C, st.B, state, U[t : t + 1], 0.1, 3, out)
        state, out = out, state
        np.testing.assert_allclose(state[0], X[t], atol=1e-12)


def test_feed_forward_structure_follows_the_thesis():
    st = initial_state(LorenzNetParams(size=32, strategy="feed-forward"), 1, np.random.default_rng(3))
    C = st.C
    assert np.all(np.triu(C) == 0)  # strictly lower triangular: no loops
    assert list(np.bincount(st.layer)) == [8, 8, 8, 8]
    for i in np.flatnonzero(st.layer > 0):
        assert np.any(C[i, st.layer < st.layer[i]] != 0)  # linked to a previous layer
    assert np.count_nonzero(C) == 24 + 30
    w = np.abs(C[C != 0])
    assert np.all((w >= 0.5) & (w <= 1.5))
    assert np.all(st.B[st.layer == 0] == 1) and np.all(st.B[st.layer > 0] == 0)
    par = initial_state(LorenzNetParams(size=32, strategy="parallel"), 1, np.random.default_rng(3))
    assert not par.C.any() and np.all(par.B == 1)
    lo = np.array([0, 0, 0, 0.8])
    assert np.all(par.params >= np.maximum(lo, 1e-3)) and np.all(par.params[:, 3] <= 1.2)


@pytest.mark.parametrize("strategy", ["parallel", "feed-forward"])
def test_input_scale_is_the_gain_of_the_drive_and_changes_nothing_else(strategy):
    """input_scale g: the input-driven elements see x1' = alpha sigma (g u - x1); the random draws (element
    parameters, couplings) are those of g = 1, and driving with g u equals scaling the input by g."""
    base = LorenzNetParams(size=12, strategy=strategy, layers=3, extra_links=6)
    scaled = base.model_copy(update={"input_scale": 1.5})
    a, b = (initial_state(p, 1, np.random.default_rng(7)) for p in (base, scaled))
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_array_equal(a.C, b.C)
    np.testing.assert_array_equal(b.B, 1.5 * a.B)
    assert np.all(b.B[b.layer == 0] == 1.5) and np.all(b.B[b.layer > 0] == 0)
    u = np.random.default_rng(8).uniform(0.2, 6, (300, 1))
    Xa, _ = simulate_network(a.params, a.C, a.B, 1.5 * u, 0.1, 2)
    Xb, _ = simulate_network(b.params, b.C, b.B, u, 0.1, 2)
    np.testing.assert_allclose(Xb, Xa, rtol=1e-12, atol=1e-12)


def test_moves_keep_the_network_loop_free_and_parameters_positive():
    p = LorenzNetParams(size=16, strategy="feed-forward", layers=4, extra_links=10)
    rng = np.random.default_rng(4)
    st = initial_state(p, 1, rng)
    moves = make_moves(p)
    for k in range(400):
        name, _, fn = moves[k % len(moves)]
        new = fn(st, rng, 1.0)
        if new is not None:
            st = new
        assert np.all(np.triu(st.C) == 0) and np.all(st.params > 0)
        assert all(np.count_nonzero(st.C[i]) >= 1 for i in np.flatnonzero(st.layer > 0))


def test_cached_trajectories_equal_a_full_recomputation():
    p = LorenzNetParams(size=20, strategy="feed-forward", layers=4, extra_links=12)
    rng = np.random.default_rng(5)
    st = initial_state(p, 1, rng)
    U = rng.uniform(0, 3, (300, 1))
    cache, _ = simulate_network(st.params, st.C, st.B, U, 0.1, 2)
    params = st.params.copy()
    params[6, 0] *= 1.5
    todo = descendants(st.C, {6})
    assert todo[0] == 6 and all(i > 6 for i in todo[1:])
    simulate_network(params, st.C, st.B, U, 0.1, 2, out=cache, only=todo)
    full, _ = simulate_network(params, st.C, st.B, U, 0.1, 2)
    np.testing.assert_array_equal(cache, full)


def _raw(strategy="feed-forward", steps=40, **params):
    return {
        "data": {
            "generator": "rossler-cross",
            "n": 3000,
            "seed": 1,
            "split": {"train": [0, 2000], "validation": [2000, 3000]},
            "test": {"seed": 2, "n": 2000},
            "transient": 300,
            "transient_at": "recording",
            "scaling": "none",
        },
        "model": {
            "family": "lorenz-net",
            "params": {"size": 12, "layers": 3, "extra_links": 6, "strategy": strategy, "steps": steps, **params},
        },
        "seed": 0,
    }


def test_fit_is_reproducible_saved_exactly_and_annealing_helps(tmp_path):
    a, b = engine.fit(make_spec(_raw())), engine.fit(make_spec(_raw()))
    np.testing.assert_array_equal(a.family.element_params_, b.family.element_params_)
    run = a.family.search_["restarts"][0]
    assert run["validation_nmse"] < run["initial_validation_nmse"]
    assert run["element_integrations"] < run["steps"] * 12  # only touched elements are integrated again
    loaded = dynmodel.load(dynmodel.save(a, tmp_path / "l.h5"))
    u = np.random.default_rng(9).uniform(0.3, 8, 400)
    np.testing.assert_array_equal(loaded.predict(u), a.predict(u))
    assert loaded.family.summary()["couplings"] == np.count_nonzero(a.family.C_)


def test_trained_networks_pass_the_reliability_check():
    from dynmodel.reliability import check_model

    for strategy in ("parallel", "feed-forward"):
        m = engine.fit(make_spec(_raw(strategy=strategy, steps=20)))
        report = check_model(m)
        assert report.verdict.verdict == "reliable", report.verdict.reasons
        assert max(e.largest for e in report.exponents.values()) < 0  # every drive contracts


def test_delay_line_over_chunks_equals_the_delayed_states_of_one_run():
    """Readout rows [xi_t, xi_(t-d), ...] built chunk by chunk (streamed fit and prediction) equal those of
    the whole recording, with the network at rest (zeros) before the first sample."""
    X = np.random.default_rng(3).standard_normal((700, 5))
    delays = (1, 10, 37)
    whole = delayed(X, delays)
    assert whole.shape == (700, 20)
    np.testing.assert_array_equal(whole[:, :5], X)
    np.testing.assert_array_equal(whole[37:, 15:], X[:-37])
    assert np.all(whole[:37, 15:] == 0) and np.all(whole[:10, 10:15] == 0)
    line = DelayLine(5, delays)
    chunks = np.vstack([line(X[a:b]) for a, b in [(0, 3), (3, 40), (40, 41), (41, 500), (500, 700)]])
    np.testing.assert_array_equal(chunks, whole)
    np.testing.assert_array_equal(delayed(X, ()), X)
    with pytest.raises(ValueError, match="readout_delays"):
        LorenzNetParams(readout_delays=(10, 0))


def test_delayed_readout_is_streamed_exactly_and_gives_the_readout_memory(tmp_path):
    """On the Rossler task (output 10 time units ahead) states 1 - 3 time units old lower the error of the
    same random networks (no annealing); the fitted model's streamed prediction equals the readout of the
    whole run's delayed states."""
    plain = engine.fit(make_spec(_raw(strategy="parallel", steps=0)))
    lagged = engine.fit(make_spec(_raw(strategy="parallel", steps=0, readout_delays=[10, 20, 30])))
    np.testing.assert_array_equal(plain.family.element_params_, lagged.family.element_params_)
    assert lagged.family.W_.shape == (1, 4 * 3 * 12)
    nm = plain.metrics["validation"]["nmse"], lagged.metrics["validation"]["nmse"]
    assert nm[1] < 0.8 * nm[0], nm
    f = lagged.family
    u = np.random.default_rng(9).uniform(0.3, 8, (900, 1))
    X, _ = simulate_network(f.element_params_, f.C_, f.B_, u, f.dt_, f.params.substeps)
    expected = delayed(X.reshape(900, -1), (10, 20, 30)) @ f.W_.T + f.w0_
    np.testing.assert_allclose(f.simulate(u).y, expected, rtol=1e-10, atol=1e-10)
    loaded = dynmodel.load(dynmodel.save(lagged, tmp_path / "delays.h5"))
    assert loaded.family.params.readout_delays == (10, 20, 30)
    np.testing.assert_array_equal(loaded.predict(u[:, 0]), lagged.predict(u[:, 0]))


def test_anneal_delays_false_anneals_the_thesis_readout_and_adds_the_delays_after():
    """anneal_delays: false scores the candidates with the current states only: the annealed network is the
    one without delays (same seed), and only the final readout sees the delayed states."""
    plain = engine.fit(make_spec(_raw(steps=15)))
    after = engine.fit(make_spec(_raw(steps=15, readout_delays=[10, 20], anneal_delays=False)))
    during = engine.fit(make_spec(_raw(steps=15, readout_delays=[10, 20])))
    np.testing.assert_array_equal(after.family.element_params_, plain.family.element_params_)
    np.testing.assert_array_equal(after.family.C_, plain.family.C_)
    assert after.family.W_.shape == during.family.W_.shape == (1, 3 * 3 * 12)
    assert after.family.search_ == plain.family.search_
    assert (
        during.family.search_["restarts"][0]["validation_nmse"]
        != plain.family.search_["restarts"][0]["validation_nmse"]
    )


def test_a_validation_split_is_required():
    raw = _raw()
    raw["data"]["split"] = {"train": 1.0}
    with pytest.raises(dynmodel.DynmodelError, match="validation split"):
        engine.fit(make_spec(raw))


def _spec_runs(name: str, seeds: range) -> np.ndarray:
    values = []
    for seed in seeds:
        spec = load_spec(ROOT / f"specs/{name}.yaml")
        spec.seed = seed
        values.append(engine.fit(spec).metrics["test"]["nmse"])
    print(f"\n{name}: mean {np.mean(values):.3f} std {np.std(values):.3f}")
    return np.array(values)


@pytest.fixture(scope="module")
def thesis_4_4_2():
    """Test NMSE (%) of both thesis specs (the thesis's readout) over the family seeds 0 - 4."""
    return {s: _spec_runs(f"thesis-4.4.2-{s}", range(5)) for s in ("parallel", "feed-forward")}


@pytest.fixture(scope="module")
def thesis_4_4_2_delays():
    """Test NMSE (%) of the specs with delayed states in the readout over the family seeds 0 - 4."""
    return {s: _spec_runs(f"thesis-4.4.2-{s}-delays", range(5)) for s in ("parallel", "feed-forward")}


@pytest.mark.slow
def test_thesis_4_4_2_feed_forward_beats_parallel(thesis_4_4_2):
    """Both strategies over 5 runs on the rossler-cross task with the thesis's readout (docs/ablations.md,
    5 runs: parallel 15.9 ± 0.5 %, feed-forward 9.2 ± 1.3 %; the thesis's 1.9 % / 0.9 % are not reached)."""
    results = thesis_4_4_2
    assert results["feed-forward"].mean() < results["parallel"].mean()
    assert np.median(results["feed-forward"]) < np.median(results["parallel"])
    assert results["parallel"].mean() < 18.0 and results["feed-forward"].mean() < 12.0


@pytest.mark.slow
def test_thesis_4_4_2_delayed_states_in_the_readout_cut_the_error(thesis_4_4_2, thesis_4_4_2_delays):
    """The ablation's finding: the readout lacks memory of the drive. The same annealed networks (anneal_delays:
    false: seed for seed the network of the thesis's readout) read out over their states every 0.3 (parallel) /
    0.5 (feed-forward) time units up to 6 / 5 back cut each seed's error by more than 4x (the worst: 9.71 ->
    1.94 %). Seeds 0 - 4: parallel 1.68 / 1.59 %, feed-forward 0.77 / 0.95 % on two CPUs, whose compiled kernels
    round otherwise (docs/ablations.md, "Figures and the machine"); thesis readout 15.9 / 9.2 %."""
    plain, lagged = thesis_4_4_2, thesis_4_4_2_delays
    for strategy in ("parallel", "feed-forward"):
        assert (lagged[strategy] < 0.25 * plain[strategy]).all(), strategy
    assert lagged["parallel"].mean() < 2.0 and lagged["feed-forward"].mean() < lagged["parallel"].mean()


@pytest.mark.slow
@pytest.mark.xfail(
    strict=False,
    reason="thesis 4.4.2 feed-forward (0.9 %) not reached robustly: the mean over seeds 0 - 4 is 0.77 % on one "
    "machine and 0.95 % on another (kernels compiled for the host CPU round otherwise), and 1.26 % over seeds "
    "0 - 9 on the second (seed 6: 4.3 %); docs/ablations.md",
)
def test_thesis_4_4_2_feed_forward_reaches_the_thesis_figure(thesis_4_4_2_delays):
    """Thesis 4.4.2, feed-forward: mean test NMSE over runs 0.9 %, with delayed states in the readout (not the
    thesis's readout). Its seeds spread from 0.30 to 4.3 % (seeds 0 - 9), so five of them do not settle the
    mean below or above 0.9 %: an expected failure that passes on some machines (the seeds 0 - 4 figure above)."""
    assert thesis_4_4_2_delays["feed-forward"].mean() <= 0.9


@pytest.mark.slow
def test_thesis_4_4_2_parallel_reaches_the_thesis_figure(thesis_4_4_2_delays):
    """Thesis 4.4.2, parallel: mean test NMSE over runs 1.9 %; measured 1.68 ± 0.20 % over seeds 0 - 4 with
    the states every 0.3 time units up to 6 back in the readout (not the thesis's readout; seed 1 alone: 1.99 %),
    1.59 ± 0.24 % on a machine whose kernels round otherwise, and 1.79 % there over seeds 0 - 9."""
    assert thesis_4_4_2_delays["parallel"].mean() <= 1.9
