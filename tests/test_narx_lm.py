"""The narx family's Levenberg-Marquardt (plugins/narx/lm.py) against MINPACK's lmder (scipy)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from dynmodel_plugins.narx import lm


def test_blocked_r_factor_is_the_r_of_the_thin_qr():
    rng = np.random.default_rng(0)
    n, p = 2 * lm.BLOCK_ROWS + 321, 9  # three blocks, the last one short
    J = rng.standard_normal((n, p)) * np.logspace(0, 4, p)
    r = rng.standard_normal(n)
    R, q = lm.r_factor(J, r)
    assert np.allclose(np.tril(R, -1), 0.0)
    # R^T R = J^T J and R^T q = J^T r: the normal equations, whatever the signs of R's rows
    assert np.allclose(R.T @ R, J.T @ J, rtol=1e-10, atol=0)
    assert np.allclose(R.T @ q, J.T @ r, rtol=1e-10, atol=1e-8 * np.abs(J.T @ r).max())
    R_numpy = np.linalg.qr(J, mode="r")
    assert np.allclose(np.abs(R), np.abs(R_numpy), rtol=1e-9, atol=1e-9 * np.abs(R_numpy).max())


def test_fewer_rows_than_weights_gives_a_square_r():
    J, r = np.arange(6.0).reshape(2, 3), np.array([1.0, -1.0])
    R, q = lm.r_factor(J, r)
    assert R.shape == (3, 3) and q.shape == (3,)
    assert np.allclose(R.T @ R, J.T @ J)


def _damped_sine(n: int):
    t = np.linspace(0.0, 20.0, n)
    truth = np.array([1.5, 0.2, 2.0, 0.3])
    noise = 0.05 * np.random.default_rng(1).standard_normal(n)

    def model(x):
        return x[0] * np.exp(-x[1] * t) * np.sin(x[2] * t + x[3])

    y = model(truth) + noise

    def fun(x):
        return model(x) - y

    def jac(x):
        e, s, c = np.exp(-x[1] * t), np.sin(x[2] * t + x[3]), np.cos(x[2] * t + x[3])
        return np.column_stack([e * s, -x[0] * t * e * s, x[0] * t * e * c, x[0] * e * c])

    return fun, jac, truth


@pytest.mark.parametrize("n", [500, 3 * lm.BLOCK_ROWS + 7])
def test_same_solution_and_path_as_minpack_lmder(n):
    fun, jac, truth = _damped_sine(n)
    x0 = np.array([1.0, 0.1, 1.8, 0.0])
    tol = 1e-10
    ours = lm.levenberg_marquardt(fun, jac, x0, max_nfev=200, ftol=tol, xtol=tol, gtol=tol)
    ref = least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", ftol=tol, xtol=tol, gtol=tol, max_nfev=200)
    assert ours.status > 0 and ref.status > 0
    assert np.allclose(ours.x, ref.x, rtol=1e-12, atol=0)
    assert ours.cost == pytest.approx(ref.cost, rel=1e-12)
    # the same iterations, not only the same optimum; the factorizations round differently, so at the
    # end one may take its last Jacobian (and stop on the gradient test) where the other stopped on ftol
    assert ours.nfev == ref.nfev and abs(ours.njev - ref.njev) <= 1
    assert np.allclose(ours.x, truth, atol=0.02)


def test_rosenbrock_from_the_classic_start():
    def fun(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    def jac(x):
        return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])

    res = lm.levenberg_marquardt(fun, jac, np.array([-1.2, 1.0]), max_nfev=200, ftol=1e-12, xtol=1e-12, gtol=0.0)
    assert np.allclose(res.x, [1.0, 1.0], atol=1e-10)
    assert res.cost < 1e-20


def test_max_nfev_stops_with_status_0_and_never_increases_the_cost():
    fun, jac, _ = _damped_sine(500)
    x0 = np.array([1.0, 0.1, 1.8, 0.0])
    res = lm.levenberg_marquardt(fun, jac, x0, max_nfev=3, ftol=1e-15, xtol=1e-15, gtol=1e-15)
    assert res.status == 0 and res.nfev <= 3
    assert res.cost <= 0.5 * float(fun(x0) @ fun(x0))


def test_a_jacobian_that_is_not_finite_stops_at_the_last_good_weights():
    """A free run near divergence can overflow its sensitivities while its clipped residuals stay finite;
    the LAPACK least squares then failed ('SVD did not converge'), reported as a spec error with exit 2
    (the narx default on a LuGre friction record). Now the solve stops and keeps the weights it had."""
    fun, jac, _ = _damped_sine(200)
    x0 = np.array([1.0, 0.1, 1.8, 0.0])

    def overflowing(x):
        J = jac(x)
        if np.linalg.norm(x - x0) > 0:  # finite at the start, overflowed after the first accepted step
            J[3, 1] = np.inf
        return J

    res = lm.levenberg_marquardt(fun, overflowing, x0, max_nfev=50, ftol=1e-12, xtol=1e-12, gtol=1e-12)
    assert res.status == -1 and "not finite" in res.message
    assert np.isfinite(res.x).all() and res.cost < 0.5 * float(fun(x0) @ fun(x0))
