"""Compiled kernels agree with plain numpy recurrences."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from dynmodel.kernels import drive, free_run, step_batch, tanh_vec


def test_fast_tanh_matches_numpy_to_a_few_ulp():
    x = np.concatenate(
        [
            np.linspace(-30, 30, 600001),
            np.random.default_rng(0).standard_normal(100000) * 1e-4,
            [0.0, -0.0, 1e-300, -5e-324, 19.5, -19.5, 20.0],
        ]
    )
    out = np.empty_like(x)
    tanh_vec(x, out)
    ref = np.tanh(x)
    ulps = np.abs(out - ref) / np.spacing(np.maximum(np.abs(ref), np.finfo(float).tiny))
    assert ulps.max() <= 8
    assert np.all(np.abs(out) <= 1.0) and out[-1] == 1.0 and out[-2] == -1.0
    nan = np.empty(1)
    tanh_vec(np.array([np.nan]), nan)
    assert np.isnan(nan[0])


def _network(m=40, n_drive=3, seed=0):
    rng = np.random.default_rng(seed)
    C = sp.random(m, m, density=0.1, random_state=seed, data_rvs=rng.standard_normal, format="csr")
    C = C * (0.9 / np.linalg.norm(C.toarray(), 2))
    B = rng.standard_normal((m, n_drive))
    c0 = rng.standard_normal(m)
    a = rng.uniform(0, 0.8, m)
    g = 1 - np.abs(a)
    return C.tocsr(), B, c0, a, g


def _args(C, B, c0, a, g):
    return C.indptr.astype(np.int64), C.indices.astype(np.int64), C.data, B, c0, a, g


def test_drive_equals_numpy_loop():
    C, B, c0, a, g = _network()
    V = np.random.default_rng(1).standard_normal((500, 3))
    X = drive(*_args(C, B, c0, a, g), V, np.zeros(40))
    x, Cd = np.zeros(40), C.toarray()
    for t in range(500):
        x = a * x + g * np.tanh(Cd @ x + c0 + B @ V[t])
        np.testing.assert_allclose(X[t], x, rtol=0, atol=1e-13)


def test_step_batch_advances_every_replica():
    C, B, c0, a, g = _network()
    rng = np.random.default_rng(2)
    X0, V = rng.uniform(-1, 1, (7, 40)), rng.standard_normal((7, 3))
    out = np.empty_like(X0)
    step_batch(*_args(C, B, c0, a, g), X0, V, out)
    ref = a * X0 + g * np.tanh(X0 @ C.toarray().T + c0 + V @ B.T)
    np.testing.assert_allclose(out, ref, atol=1e-13)


def _numpy_free_run(C, B, c0, a, g, U, Y, tune_in, W, D, w0, y_rest):
    x, Cd = np.zeros(len(c0)), C.toarray()
    yhat = np.zeros((len(U), W.shape[0]))
    for t in range(len(U)):
        if tune_in and t <= tune_in:
            f = Y[t - 1] if t > 0 else Y[0]
        else:
            f = yhat[t - 1] if t > 0 else y_rest
        v = np.concatenate([U[t], f])
        x = a * x + g * np.tanh(Cd @ x + c0 + B @ v)
        yhat[t] = W @ x + D @ v + w0
    return yhat


def test_free_run_with_tune_in_equals_numpy_loop():
    C, B, c0, a, g = _network(n_drive=3)  # two inputs, one fed-back output
    rng = np.random.default_rng(3)
    U, Y = rng.standard_normal((300, 2)), rng.standard_normal((300, 1))
    W, D, w0 = 0.05 * rng.standard_normal((1, 40)), 0.1 * rng.standard_normal((1, 3)), np.array([0.2])
    for tune in (0, 25):
        _, yhat, fb, div = free_run(
            *_args(C, B, c0, a, g),
            U,
            Y,
            tune,
            0.0,
            W,
            D,
            w0,
            np.array([0.1]),
            np.array([-1e9]),
            np.array([1e9]),
            np.zeros(40),
            False,
        )
        ref = _numpy_free_run(C, B, c0, a, g, U, Y, tune, W, D, w0, np.array([0.1]))
        assert div == -1
        np.testing.assert_allclose(yhat, ref, atol=1e-12)
        if tune:
            np.testing.assert_array_equal(fb[1 : tune + 1], Y[:tune])
            np.testing.assert_array_equal(fb[tune + 1 :], yhat[tune:-1])


def test_free_run_reports_the_sample_where_it_leaves_the_band():
    C, B, c0, a, g = _network(n_drive=2)
    U = np.ones((200, 1))
    W = np.full((1, 40), 0.0)
    D = np.array([[0.0, 1.05]])  # yhat_t = 1.05 yhat_{t-1} + 1: grows geometrically
    _, yhat, _, div = free_run(
        *_args(C, B, c0, a, g),
        U,
        np.zeros((0, 1)),
        0,
        0.0,
        W,
        D,
        np.array([1.0]),
        np.array([0.0]),
        np.array([-50.0]),
        np.array([50.0]),
        np.zeros(40),
        False,
    )
    k = int(np.ceil(np.log(1 + 50 * 0.05) / np.log(1.05)))  # first t with sum_{j<=t} 1.05^j > 50
    assert div == k - 1 or div == k
    assert np.isnan(yhat[div:]).all() and np.isfinite(yhat[:div]).all()
