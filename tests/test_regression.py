"""Least squares, ridge and Fast Orthogonal Search (thesis A.2.1, A.2.2, A.3)."""

from __future__ import annotations

import numpy as np
import pytest

from dynmodel.regression import fos, fos_select, lstsq, ridge, ridge_path


@pytest.fixture
def sparse_problem():
    rng = np.random.default_rng(4)
    F = rng.standard_normal((2000, 15))
    F[:, 9] = 2 * F[:, 3] - F[:, 4]  # exactly redundant candidate
    y = 0.5 + 3 * F[:, 1] - 2 * F[:, 6] + 0.5 * F[:, 12] + 0.05 * rng.standard_normal(2000)
    Fv = rng.standard_normal((800, 15))
    Fv[:, 9] = 2 * Fv[:, 3] - Fv[:, 4]
    yv = 0.5 + 3 * Fv[:, 1] - 2 * Fv[:, 6] + 0.5 * Fv[:, 12] + 0.05 * rng.standard_normal(800)
    return F, y, Fv, yv


def test_lstsq_matches_numpy_and_handles_tall_chunks(sparse_problem):
    F, y, _, _ = sparse_problem
    F = np.vstack([F] * 15)  # 30000 rows: several TSQR chunks
    y = np.concatenate([y] * 15)
    fit = lstsq(F, y)
    A = np.hstack([F, np.ones((len(F), 1))])
    ref, *_ = np.linalg.lstsq(A, y, rcond=None)
    np.testing.assert_allclose(fit.predict(F)[:, 0], A @ ref, atol=1e-10)
    assert fit.info["rank"] == 15  # 16 columns, one redundant


def test_ridge_equals_the_closed_form_and_auto_picks_on_validation(sparse_problem):
    F, y, Fv, yv = sparse_problem
    fit = ridge(F, y, 3.0)
    Fc, yc = F - F.mean(0), y - y.mean()
    w = np.linalg.solve(Fc.T @ Fc + 3.0 * np.eye(15), Fc.T @ yc)
    np.testing.assert_allclose(fit.coef[:, 0], w, atol=1e-9)
    auto = ridge(F, y, "auto", Fv, yv)
    assert auto.info["validation_mse"] < 0.05**2 * 1.2


def test_fos_finds_the_true_terms_and_stops_on_validation(sparse_problem):
    F, y, Fv, yv = sparse_problem
    fit = fos(F, y, Fv=Fv, Yv=yv, patience=3)
    assert fit.selected[0].tolist() == [1, 6, 12]
    np.testing.assert_allclose(fit.coef[[1, 6, 12], 0], [3, -2, 0.5], atol=0.01)
    assert abs(fit.intercept[0] - 0.5) < 0.01


def test_fos_recursion_weights_agree_with_least_squares(sparse_problem):
    F, y, _, _ = sparse_problem
    for k in (2, 4, 8):
        rec = fos(F, y, max_terms=k, weights="recursion")
        ls = fos(F, y, max_terms=k, weights="lstsq")
        assert rec.selected[0].tolist() == ls.selected[0].tolist()
        np.testing.assert_allclose(rec.coef, ls.coef, atol=1e-9)
        np.testing.assert_allclose(rec.intercept, ls.intercept, atol=1e-9)


def test_fos_with_every_term_equals_least_squares_and_skips_redundant_ones(sparse_problem):
    F, y, _, _ = sparse_problem
    full = fos(F, y, weights="recursion")
    assert full.info["terms"] == [15]  # constant + 14 independent columns; the redundant one is never picked
    np.testing.assert_allclose(full.predict(F), lstsq(F, y).predict(F), atol=1e-9)


def test_fos_error_reductions_sum_to_the_explained_energy(sparse_problem):
    F, y, _, _ = sparse_problem
    P = np.hstack([np.ones((len(F), 1)), F])
    path = fos_select(P.T @ P, P.T @ y, float(y @ y), forced=(0,), max_terms=4)
    coef = path.coef_path[-1]
    resid = y - P[:, path.order] @ coef
    assert np.isclose(y @ y - path.error_reduction.sum(), resid @ resid, rtol=1e-9)
    thr = fos(F, y, threshold=1e-3)
    assert thr.selected[0].tolist() == [1, 6, 12]


def test_ridge_path_without_intercept_equals_the_closed_form(sparse_problem):
    F, y, _, _ = sparse_problem
    alphas = [0.0, 1.0, 100.0]
    for a, fit in zip(alphas, ridge_path(F[:, :9], y, alphas, fit_intercept=False)):
        w = np.linalg.solve(F[:, :9].T @ F[:, :9] + a * np.eye(9), F[:, :9].T @ y)
        np.testing.assert_allclose(fit.coef[:, 0], w, rtol=1e-9, atol=1e-12)
        assert fit.intercept[0] == 0.0 and fit.info["alpha"] == a
    assert len(ridge_path(F, y)) == 29  # the grid of alpha='auto'


def test_fos_ties_prefer_the_first_candidate_in_pool_order():
    rng = np.random.default_rng(1)
    x = rng.standard_normal(500)
    P = np.column_stack([np.ones(500), 3.0 * x, x, rng.standard_normal(500)])  # columns 1 and 2 are the same direction
    y = 2.0 * x + 0.01 * rng.standard_normal(500)
    G, c = P.T @ P, P.T @ y
    plain = fos_select(G, c, float(y @ y), forced=(0,), max_terms=2)
    tied = fos_select(G, c, float(y @ y), forced=(0,), max_terms=2, ties=1e-9)
    assert plain.order[1] in (1, 2) and tied.order[1] == 1
    assert fos_select(G[::-1, ::-1], c[::-1], float(y @ y), forced=(3,), max_terms=2, ties=1e-9).order[1] == 1
