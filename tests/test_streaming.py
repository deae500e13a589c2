"""Network fits from moments accumulated chunk by chunk equal the fits from stored states."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from conftest import narx

import dynmodel.moments as moments_mod
from dynmodel import kernels, readout, regression
from dynmodel.data.training import Series, TrainingData
from dynmodel.engine import family_rng
from dynmodel.moments import GramMoments, Moments, split_blocks
from dynmodel_plugins.annealed_rnn import AnnealedRnn
from dynmodel_plugins.annealed_rnn.search import GRAM_CUTOFF, Evaluator
from dynmodel_plugins.esn import EchoStateNetwork
from dynmodel_plugins.esn.network import build_network
from dynmodel_plugins.esn.streaming import RunBuffers, free_run_moments, free_runs
from dynmodel_plugins.lorenz_net.elements import simulate_network
from dynmodel_plugins.lorenz_net.params import LorenzNetParams
from dynmodel_plugins.lorenz_net.search import initial_state
from dynmodel_plugins.lorenz_net.streaming import outputs, readout_moments

#: a small network whose states are well conditioned (condition number ~1e3), so that the
#: streamed and the stored readouts must agree to rounding (random 200-element networks are
#: conditioned beyond 1e15, where any reordering of the arithmetic moves the readout)
SMALL = dict(size=20, connectivity=0.3, input_connectivity=1.0, bias_scale=0.5, tune_in=30)


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of 256 rows: several per series, cut across the split boundaries."""
    monkeypatch.setattr(moments_mod, "CHUNK_ELEMENTS", 1)


def _data(validation_first: bool = False) -> TrainingData:
    """Two recordings of the NARX system; in the first one a transient, and the validation rows
    before (or after) the training rows."""
    series = []
    for seed, n in ((1, 1800), (2, 900)):
        u, y = narx(n, seed)
        series.append(Series(u[:, None], y[:, None]))
    if validation_first:
        segments = {"validation": [(0, 100, 500)], "train": [(0, 500, 1800), (1, 0, 700)]}
    else:
        segments = {"train": [(0, 100, 1300), (1, 0, 700)], "validation": [(0, 1300, 1800)]}
    return TrainingData(series, segments, ["u"], ["y"], 1.0)


def _stored_features(fam, net, data, drives=None):
    drives = drives if drives is not None else fam.training_drives(data)
    return [np.hstack([kernels.drive(*net.kernel_args(), d, np.zeros(net.size)), d]) for d in drives]


def _assert_same_fit(new, ref, tol=1e-9):
    scale = max(1.0, float(np.abs(ref.coef).max()))
    np.testing.assert_allclose(new.coef, ref.coef, rtol=0, atol=tol * scale)
    np.testing.assert_allclose(new.intercept, ref.intercept, rtol=0, atol=tol * scale)


def test_moments_hold_the_centred_gram_matrix_whatever_the_chunking():
    rng = np.random.default_rng(0)
    F = rng.standard_normal((3000, 6)) * [1, 10, 0.1, 1, 5, 1] + [1e4, -3, 0, 7, 1e3, 2]  # large offsets
    Y = F[:, :2] @ [[1.0], [-2.0]] + rng.standard_normal((3000, 1))
    A = np.hstack([F, Y])
    Ac = A - A.mean(axis=0)
    for cls in (Moments, GramMoments):
        for cuts in ([3000], [1, 999, 2000], [7] * 428 + [4]):
            m, start = cls(6, 1), 0
            for c in cuts:
                m.add(F[start : start + c], Y[start : start + c])
                start += c
            gram = m.gram() if cls is Moments else m.G
            assert m.n == 3000
            np.testing.assert_allclose(m.mean, A.mean(axis=0), rtol=1e-13)
            np.testing.assert_allclose(gram, Ac.T @ Ac, rtol=0, atol=1e-11 * np.abs(Ac.T @ Ac).max())
    m = Moments(6, 1)
    m.add(F, Y)
    W, b = rng.standard_normal((6, 1)), np.array([0.3])
    np.testing.assert_allclose(m.residual_ss(W, b), [np.sum((Y - F @ W - b) ** 2)], rtol=1e-10)
    S, Z = m.pool_factor("first")
    P = np.hstack([np.ones((3000, 1)), F])
    np.testing.assert_allclose(S.T @ S, P.T @ P, rtol=1e-11, atol=1e-9)
    np.testing.assert_allclose(S.T @ Z, P.T @ Y, rtol=1e-11, atol=1e-9)
    bad = Moments(6, 1)
    bad.add(np.full((3, 6), np.nan), np.zeros((3, 1)))
    assert not bad.finite


def test_split_blocks_cover_each_series_up_to_its_last_scored_sample():
    data = _data(validation_first=True)
    blocks = split_blocks(data, 0, 300)
    assert blocks[0] == (0, 100, None) and blocks[-1][1] == 1800
    assert all(b - a <= 300 for a, b, _ in blocks)
    assert all(a == prev_b for (a, _, _), (_, prev_b, _) in zip(blocks[1:], blocks[:-1]))
    assert {label for a, b, label in blocks if a >= 500} == {"train"}
    assert split_blocks(data, 1, 300, ("validation",)) == []


@pytest.mark.parametrize("mode", ["internal", "external"])
@pytest.mark.parametrize(
    "readout_params",
    [
        {"solver": "lstsq"},
        {"solver": "ridge", "ridge": 0.5},
        {"solver": "ridge", "ridge": "auto"},
        {"solver": "fos", "patience": 3},
        {"solver": "fos", "patience": 3, "direct": False},
    ],
)
def test_streamed_readout_equals_the_stored_states_readout(small_chunks, mode, readout_params):
    data = _data()
    fam = EchoStateNetwork(**SMALL, mode=mode, readout=readout_params)
    fam.fit(data, rng=family_rng(3))
    net = build_network(fam.params, 1, 1, family_rng(3))
    feats = _stored_features(fam, net, data)
    if not fam.params.readout.direct:
        feats = [F[:, : net.size] for F in feats]
    F, Y = data.stack("train", feats), data.targets("train")
    Fv, Yv = data.stack("validation", feats), data.targets("validation")
    r = fam.params.readout
    if r.solver == "lstsq":
        ref = regression.lstsq(F, Y)
    elif r.solver == "ridge":
        ref = regression.ridge(F, Y, r.ridge, Fv, Yv)
    else:
        ref = regression.fos(F, Y, Fv=Fv, Yv=Yv, patience=r.patience)
        assert fam.selected_[0].tolist() == ref.selected[0].tolist()
        assert len(ref.selected[0]) > 2  # a real selection
    m = net.size
    np.testing.assert_allclose(fam.W_[0], ref.coef[:m, 0], rtol=0, atol=1e-9 * np.abs(ref.coef).max())
    np.testing.assert_allclose(fam.w0_, ref.intercept, rtol=0, atol=1e-9 * max(1, np.abs(ref.intercept).max()))
    if r.direct:
        np.testing.assert_allclose(fam.D_[0], ref.coef[m:, 0], rtol=0, atol=1e-9 * np.abs(ref.coef).max())
    # the fitted network predicts as the stored states do
    sim = fam.simulate(data.series[1].u, data.series[1].y)
    if mode == "internal":
        np.testing.assert_allclose(sim.y, ref.predict(feats[1]), rtol=0, atol=1e-10)


def test_streamed_free_run_moments_equal_the_stored_free_run(small_chunks):
    data = _data()
    fam = EchoStateNetwork(**SMALL, mode="external", readout={"solver": "lstsq"})
    fam.fit(data, rng=family_rng(4))
    lo, hi = data.output_bounds()
    clip_lo, clip_hi = fam._clip
    args = dict(
        tune_in=30, W=fam.W_, D=fam.D_, w0=fam.w0_, y_rest=fam.y_rest_, lo=lo, hi=hi, clip_lo=clip_lo, clip_hi=clip_hi
    )
    for mix in (0.0, 0.4):
        mom = free_run_moments(fam.network_, data, mix, True, ("train", "validation"), RunBuffers(data), **args)
        feats = []
        for s in data.series:
            X, _, fb, div = kernels.free_run_clipped(
                *fam.network_.kernel_args(), s.u, s.y, 30, mix, fam.W_, fam.D_, fam.w0_, fam.y_rest_, lo, hi,
                np.zeros(fam.network_.size), True, clip_lo, clip_hi,
            )  # fmt: skip
            assert div == -1
            feats.append(np.hstack([X, s.u, fb]))
        _assert_same_fit(
            readout.lstsq(mom["train"]), regression.lstsq(data.stack("train", feats), data.targets("train"))
        )
        val = data.stack("validation", feats)
        np.testing.assert_allclose(mom["validation"].mean[:-1], val.mean(axis=0), rtol=0, atol=1e-12)
    # a run that leaves the band gives no moments
    far = dict(args, lo=np.array([-0.01]), hi=np.array([0.01]))
    assert free_run_moments(fam.network_, data, 0.0, True, ("train",), RunBuffers(data), **far) is None


def test_refined_fit_equals_the_refinement_on_stored_states(small_chunks, monkeypatch):
    """cost mse_inf: one refinement iteration from the streamed free run, checked against the
    same iteration computed from stored free-run states."""
    data = _data()
    params = dict(SMALL, mode="external", readout={"solver": "lstsq"}, refinement={"max_iter": 1, "alpha": 0.5})
    one_step = EchoStateNetwork(**params).fit(data, rng=family_rng(5))
    refined = EchoStateNetwork(**params).fit(data, cost="mse_inf", rng=family_rng(5))
    assert len(refined.refinement_) == 2 and refined.refinement_[1]["mix"] == 0.0  # the one-step model runs free
    lo, hi = data.output_bounds()
    feats = []
    for s in data.series:
        X, _, fb, _ = kernels.free_run_clipped(
            *one_step.network_.kernel_args(), s.u, s.y, 30, 0.0, one_step.W_, one_step.D_, one_step.w0_,
            one_step.y_rest_, lo, hi, np.zeros(20), True, *one_step._clip,
        )  # fmt: skip
        feats.append(np.hstack([X, s.u, fb]))
    fit = regression.lstsq(data.stack("train", feats), data.targets("train"))
    new = 0.5 * one_step._readout_vector() + 0.5 * np.concatenate([fit.coef[:20, 0], fit.coef[20:, 0], fit.intercept])
    if refined.refinement_[1]["validation_nmse"] < refined.refinement_[0]["validation_nmse"]:
        np.testing.assert_allclose(refined._readout_vector(), new, rtol=0, atol=1e-9 * np.abs(new).max())
    else:
        np.testing.assert_array_equal(refined._readout_vector(), one_step._readout_vector())


def _loop_free_run(net, s, tune_in, mix, W, D, w0, y_rest, clip_lo, clip_hi, settle=0):
    """The external-mode run with the output clip as a plain numpy loop: the clipped output is the
    one recorded and fed back, from the state ``settle`` steps of the first input and output held leave
    (rest for 0). Returns states, outputs and fed-back values."""
    C, B = net.C.toarray(), net.B
    x = np.zeros(net.size)
    for _ in range(settle):
        x = net.a * x + net.g * np.tanh(C @ x + net.c0 + B @ np.concatenate([s.u[0], s.y[0]]))
    X, yhat, fb = np.empty((s.n, net.size)), np.empty((s.n, W.shape[0])), np.empty((s.n, W.shape[0]))
    for t in range(s.n):
        if tune_in and t <= tune_in:
            f = s.y[t - 1] if t > 0 else s.y[0]
        else:
            f = yhat[t - 1] if t > 0 else y_rest
            if mix > 0:
                f = mix * (s.y[t - 1] if t > 0 else s.y[0]) + (1 - mix) * f
        v = np.concatenate([s.u[t], f])
        x = net.a * x + net.g * np.tanh(C @ x + net.c0 + B @ v)
        X[t], fb[t] = x, f
        yhat[t] = np.clip(W @ x + D @ v + w0, clip_lo, clip_hi)
    return X, yhat, fb


def test_streamed_clipped_free_run_equals_a_plain_loop(small_chunks):
    """The output clip (esn ``bounds``) inside the chunked external run: the model's free run, the
    refinement's free-run outputs and its streamed moments equal a plain loop that clips the output
    and feeds the clipped value back, with a clip that is active."""
    data = _data()
    fam = EchoStateNetwork(**SMALL, mode="external", readout={"solver": "lstsq"})
    fam.fit(data, rng=family_rng(6))
    y = data.targets("train")[:, 0]
    fam.clip_lo_, fam.clip_hi_ = np.quantile(y, [0.2]), np.quantile(y, [0.8])  # tighter than the data: active
    clip = fam._clip
    run = fam._run_args()
    for mix in (0.0, 0.4):
        loops = [
            _loop_free_run(fam.network_, s, 30, mix, fam.W_, fam.D_, fam.w0_, fam.y_rest_, *clip, settle=200)
            for s in data.series
        ]
        assert any((yl[31:] == clip[1]).any() and (yl[31:] == clip[0]).any() for _, yl, _ in loops)
        buffers = RunBuffers(data)
        mom = free_run_moments(
            fam.network_, data, mix, True, ("train", "validation"), buffers, **run, starts=fam._run_starts(data)
        )
        assert mom is not None
        feats = []
        for k, ((X, yl, fl), s, yb, fbb) in enumerate(zip(loops, data.series, buffers.yhat, buffers.fb)):
            end = max(b for segs in data.segments.values() for kk, _, b in segs if kk == k)  # rows the fit runs
            np.testing.assert_allclose(yb[:end], yl[:end], rtol=0, atol=1e-10)
            np.testing.assert_allclose(fbb[1:end], fl[1:end], rtol=0, atol=1e-10)
            feats.append(np.hstack([X, s.u, fl]))
        _assert_same_fit(
            readout.lstsq(mom["train"]), regression.lstsq(data.stack("train", feats), data.targets("train"))
        )
        np.testing.assert_allclose(
            mom["validation"].mean[:-1], data.stack("validation", feats).mean(axis=0), rtol=0, atol=1e-10
        )
    # the pure free run (mix 0): the refinement's runs and the model's simulate
    buffers = RunBuffers(data)
    assert free_runs(fam.network_, data, 0.0, buffers, **run, starts=fam._run_starts(data))
    for s, yb in zip(data.series, buffers.yhat):
        _, yl, _ = _loop_free_run(fam.network_, s, 30, 0.0, fam.W_, fam.D_, fam.w0_, fam.y_rest_, *clip, settle=200)
        np.testing.assert_allclose(yb, yl, rtol=0, atol=1e-10)
        sim = fam.simulate(s.u, s.y[:30])
        assert sim.diverged_at is None
        np.testing.assert_allclose(sim.y, yl, rtol=0, atol=1e-10)


def test_chunked_kernels_equal_one_long_run():
    net = build_network(EchoStateNetwork(**SMALL, mode="external").params, 2, 1, np.random.default_rng(0))
    args = net.kernel_args()
    rng = np.random.default_rng(1)
    V = rng.standard_normal((700, 3))
    X = kernels.drive(*args, V, np.zeros(20))
    F, x = np.empty((700, 23)), np.zeros(20)
    for a, b in ((0, 1), (1, 300), (300, 300), (300, 700)):
        kernels.drive_chunk(*args, V[a:b], x, True, F[a:b])
    np.testing.assert_array_equal(F[:, :20], X)
    np.testing.assert_array_equal(F[:, 20:], V)
    np.testing.assert_array_equal(x, X[-1])
    W, D, w0 = rng.standard_normal((2, 20)), rng.standard_normal((2, 3)), np.array([0.5, -1.0])
    out = np.empty((700, 2))
    kernels.drive_output(*args, V, np.zeros(20), W, D, w0, out)
    np.testing.assert_allclose(out, X @ W.T + V @ D.T + w0, rtol=0, atol=1e-12)
    U, Y = V[:, :2].copy(), V[:, 2:].copy()
    W1, D1 = 0.05 * W[:1], 0.1 * D[:1]
    lo, hi = np.array([-1e9]), np.array([1e9])
    for tune, mix, clip in ((0, 0.0, np.inf), (40, 0.0, np.inf), (40, 0.3, np.inf), (0, 0.0, 0.3), (40, 0.3, 0.3)):
        clip_lo, clip_hi = np.array([-clip]), np.array([clip])
        Xr, yr, fr, div = kernels.free_run_clipped(
            *args, U, Y, tune, mix, W1, D1, w0[:1], np.zeros(1), lo, hi, np.zeros(20), True, clip_lo, clip_hi
        )
        if clip == np.inf:  # no clip: the unclipped kernel
            Xu, yu, fu, _ = kernels.free_run(
                *args, U, Y, tune, mix, W1, D1, w0[:1], np.zeros(1), lo, hi, np.zeros(20), True
            )
            np.testing.assert_array_equal(yu, yr)
            np.testing.assert_array_equal(Xu, Xr)
        else:
            assert (np.abs(yr) == clip).any()  # the clip is active
        yhat, fb, Xs, x = np.empty((700, 1)), np.empty((700, 1)), np.empty((700, 20)), np.zeros(20)
        for a, b in ((0, 41), (41, 42), (42, 700)):
            d = kernels.free_run_span(
                *args, U, Y, tune, mix, W1, D1, w0[:1], np.zeros(1), lo, hi, clip_lo, clip_hi, x, a, b, yhat, fb,
                Xs[a:b],
            )  # fmt: skip
            assert d == -1
        np.testing.assert_array_equal(yhat, yr)
        np.testing.assert_array_equal(fb, fr)
        np.testing.assert_array_equal(Xs, Xr)


def _stored_annealing_score(ev: Evaluator, state) -> float:
    """The annealing objective computed from stored features (the evaluator before issue 20)."""
    data, p = ev.data, ev.p
    feats = [np.hstack([kernels.drive(*state.kernel_args(), d, np.zeros(state.size)), d]) for d in ev.drives]
    if not p.readout.direct:
        feats = [F[:, : state.size] for F in feats]
    F, Y = data.stack("train", feats), data.targets("train")
    if p.readout.solver == "fos":
        fit = regression.fos(
            F, Y, Fv=data.stack("validation", feats), Yv=ev.Yv, patience=p.readout.patience, weights="recursion"
        )
        W = np.vstack([fit.coef, fit.intercept])
    else:
        mean, y_mean = F.mean(axis=0), Y.mean(axis=0)
        Fc = F - mean
        lam, V = np.linalg.eigh(Fc.T @ Fc)
        keep = lam > GRAM_CUTOFF * lam[-1]
        w = V[:, keep] @ ((V[:, keep].T @ (Fc.T @ (Y - y_mean))) / lam[keep, None])
        W = np.vstack([w, y_mean - mean @ w])
    if p.mode == "internal":
        pred = data.stack("validation", feats) @ W[:-1] + W[-1]
    else:
        m, nv = state.size, ev.n_drive
        Wd = W[m : m + nv].T if p.readout.direct else np.zeros((1, nv))
        runs = [
            kernels.free_run(
                *state.kernel_args(), s.u, s.y, p.tune_in, 0.0, np.ascontiguousarray(W[:m].T),
                np.ascontiguousarray(Wd), W[-1], ev.y_rest, ev.lo, ev.hi, np.zeros(m), False,
            )[1]
            for s in data.series
        ]  # fmt: skip
        pred = data.stack("validation", runs)
    return float(np.mean(np.mean((ev.Yv - pred) ** 2, axis=0) / ev.var_v))


@pytest.mark.parametrize(
    "params",
    [
        {},
        {"mode": "external", "tune_in": 30},
        {"readout": {"solver": "fos", "direct": False, "patience": 3}},
        {"readout": {"solver": "lstsq", "direct": True}},
    ],
)
@pytest.mark.parametrize("validation_first", [False, True])
def test_annealing_objective_equals_the_stored_states_objective(small_chunks, params, validation_first):
    data = _data(validation_first)
    fam = AnnealedRnn(size=12, connectivity=0.3, input_connectivity=1.0, **params)
    fam._prepare(data)
    ev = Evaluator(data, fam.params, fam.training_drives(data))
    rng = np.random.default_rng(7)
    for _ in range(3):
        state = fam._initial_state(data, rng)
        new, ref = ev.score(state), _stored_annealing_score(ev, state)
        assert 0 < ref < 1
        assert new == pytest.approx(ref, rel=1e-9, abs=0)


def test_lorenz_readout_and_prediction_stream_exactly(small_chunks):
    data = _data()
    p = LorenzNetParams(size=6, layers=2, extra_links=3)
    st = initial_state(p, 1, np.random.default_rng(2))
    full = [simulate_network(st.params, st.C, st.B, s.u, 0.1, 2)[0].reshape(s.n, -1) for s in data.series]
    mom = readout_moments(st.params, st.C, st.B, 0.1, 2, data)
    new = readout.lstsq(mom["train"]).predict(full[0])
    ref = regression.lstsq(data.stack("train", full), data.targets("train")).predict(full[0])
    np.testing.assert_allclose(new, ref, rtol=0, atol=1e-9 * np.std(ref))
    W, w0 = np.random.default_rng(3).standard_normal((1, 18)), np.array([0.2])
    y = outputs(st.params, st.C, st.B, 0.1, 2, data.series[0].u, W, w0)
    np.testing.assert_allclose(y, full[0] @ W.T + w0, rtol=0, atol=1e-10)


def test_a_long_fit_never_holds_the_state_matrix(monkeypatch):
    """50 000 samples x 200 elements: stored states would take 80 MB; the streamed fit allocates
    a few chunks of 500 rows."""
    monkeypatch.setattr(moments_mod, "CHUNK_ELEMENTS", 100_000)
    u, y = narx(50_000, 8)
    data = TrainingData([Series(u[:, None], y[:, None])], {"train": [(0, 200, 50_000)]}, ["u"], ["y"], 1.0)
    fam = EchoStateNetwork(size=200, readout={"solver": "lstsq"})
    fam.fit(data, rng=family_rng(0))  # compile outside the measurement
    tracemalloc.start()
    fam.fit(data, rng=family_rng(0))
    fam.simulate(data.series[0].u)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 20e6, f"{peak / 1e6:.0f} MB"


def test_lorenz_annealing_objective_without_the_cache_equals_the_cached_one(small_chunks, monkeypatch):
    """Recordings too long to cache: every candidate integrated again, error from the moments."""
    import dynmodel_plugins.lorenz_net.search as search

    data = _data()
    p = LorenzNetParams(size=6, layers=2, extra_links=3)
    cached = search.Evaluator(data, p, 0.1)
    monkeypatch.setattr(search, "CACHE_BYTES", 0)
    streamed = search.Evaluator(data, p, 0.1)
    assert cached.cache and not streamed.cache
    rng = np.random.default_rng(6)
    for _ in range(3):
        st = initial_state(p, 1, rng)
        ref = cached.score(st)
        assert 0 < ref < 1
        assert streamed.score(st) == pytest.approx(ref, rel=1e-9, abs=0)
