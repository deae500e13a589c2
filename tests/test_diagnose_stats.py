"""The statistics behind the detectors: correlation bounds, spectral peaks, the out-of-sample dependence
test, block bootstrap, merge patches. Calibration is checked on data where the null holds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from dynmodel.diagnose.bootstrap import batch_means_test, paired_nmse
from dynmodel.diagnose.correlation import (
    ar_coefficients,
    ar_filter,
    autocorr,
    bartlett_sd,
    crosscorr,
    integrated_time,
    sidak_z,
)
from dynmodel.diagnose.dependence import holdout_share, partial_share
from dynmodel.diagnose.patch import merge
from dynmodel.diagnose.spectrum import refine_peak, welch


def test_crosscorr_pools_segments_and_never_pairs_across_them():
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal(300), rng.standard_normal(300)
    r = crosscorr([a], [b], 5)
    ac, bc = a - a.mean(), b - b.mean()
    direct = [np.mean(ac[k:] * bc[: 300 - k]) / (a.std() * b.std()) for k in range(6)]
    np.testing.assert_allclose(r, direct, rtol=1e-10)
    # two segments: lag 3 pairs come only from inside each segment
    r2 = crosscorr([a[:150], a[150:]], [b[:150], b[150:]], 3)
    assert np.isfinite(r2).all() and not np.allclose(r2, r[:4])


def test_prewhitening_recovers_an_ar2_input_and_whitens_it():
    rng = np.random.default_rng(1)
    u = signal.lfilter([1.0], [1.0, -1.2, 0.5], rng.standard_normal(20000))
    phi = ar_coefficients([u])
    np.testing.assert_allclose(phi[:2], [1.2, -0.5], atol=0.03)
    w = ar_filter([u], phi)
    assert np.max(np.abs(autocorr(w, 10)[1:])) < 0.03


def test_bartlett_bounds_hold_their_level_for_independent_series():
    """Max |r(k)| / s over 300 lags beyond the Sidak bound in about alpha of the runs (prewhitened AR inputs)."""
    hits, runs, alpha = 0, 200, 0.05
    z = sidak_z(alpha, 300)
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        u = signal.lfilter([1.0], [1.0, -0.8], rng.standard_normal(3000))
        e = signal.lfilter([1.0], [1.0, -0.6], rng.standard_normal(3000))  # a coloured residual, independent of u
        phi = ar_coefficients([u])
        uw, ew = ar_filter([u], phi), ar_filter([e], phi)
        r = crosscorr(ew, uw, 300)
        sd = bartlett_sd(ew, uw, 300)
        hits += bool(np.max(np.abs(r[1:]) / sd[1:]) > z)
    assert hits / runs < 2.5 * alpha  # 0.05 nominal; binomial sd 0.015


def test_integrated_time_of_an_ar1_process():
    rng = np.random.default_rng(2)
    x = signal.lfilter([1.0], [1.0, -0.9], rng.standard_normal(50000))
    assert integrated_time([x]) == pytest.approx((1 + 0.9) / (1 - 0.9), rel=0.15)


def test_spectrum_finds_a_line_and_its_frequency():
    rng = np.random.default_rng(3)
    n, f0 = 8000, 0.0731
    x = 0.3 * np.sin(2 * np.pi * f0 * np.arange(n)) + rng.standard_normal(n)
    spec = welch([x])
    k = int(np.argmax(spec.ratio()))
    assert spec.p_values()[k] * spec.testable.sum() < 1e-6
    assert refine_peak(spec, k, [x]) == pytest.approx(f0, rel=0.01)


def test_spectral_test_is_calibrated_on_coloured_noise():
    """No line: the Bonferroni-corrected minimum p-value falls below 0.05 in at most about 5 % of the runs."""
    hits, runs = 0, 100
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        x = signal.lfilter([1.0], [1.0, -0.7], rng.standard_normal(6000))
        spec = welch([x])
        p = spec.p_values()[spec.testable]
        hits += bool(p.min() * p.size < 0.05)
    assert hits <= 8


def test_holdout_share_separates_dependence_from_independence():
    rng = np.random.default_rng(4)
    n = 4000
    u = rng.standard_normal(n)
    check = np.arange(n) >= 3000
    e = 0.7 * u**2 + 0.5 * rng.standard_normal(n)
    dep = holdout_share(e, u[:, None], (u**2)[:, None], check)
    assert dep.p_value < 1e-4 and dep.share == pytest.approx(0.98 / (0.98 + 0.25), abs=0.05)
    # independent: p roughly uniform, so rarely small
    small = 0
    for seed in range(60):
        r = np.random.default_rng(100 + seed)
        x = r.standard_normal(n)
        e = signal.lfilter([1.0], [1.0, -0.9], r.standard_normal(n))  # slow, autocorrelated residual
        small += holdout_share(e, x[:, None], np.column_stack([x**2, x**3]), check).p_value < 0.01
    assert small <= 3


def test_partial_share_is_an_in_sample_partial_r2():
    rng = np.random.default_rng(5)
    x, z = rng.standard_normal(2000), rng.standard_normal(2000)
    e = x + z
    assert partial_share(e, x[:, None], z[:, None]) == pytest.approx(0.5, abs=0.05)
    assert partial_share(e, np.column_stack([x, z]), (x + z)[:, None]) == pytest.approx(0.0, abs=1e-9)


def test_paired_block_bootstrap_of_nmse():
    rng = np.random.default_rng(6)
    y = rng.standard_normal(3000)
    e1 = 0.5 * rng.standard_normal(3000)
    out = paired_nmse(y, e1, 0.5 * e1, rng, 300)
    assert out["relative_reduction"]["std"] < 1e-12  # the same blocks for both: exactly 75 %
    assert out["relative_reduction"]["mean"] == pytest.approx(0.75)
    assert out["test_nmse_before"]["interval_95"][0] < 25.0 < out["test_nmse_before"]["interval_95"][1]


def test_batch_means_test_signs():
    rng = np.random.default_rng(7)
    z, p, k = batch_means_test(1.0 + rng.standard_normal(2000))
    assert p < 1e-6 and k == 40 and z > 10
    assert batch_means_test(-1.0 + rng.standard_normal(2000))[1] > 0.99
    slow = signal.lfilter([1.0], [1.0, -0.98], rng.standard_normal(2000))
    assert batch_means_test(slow)[2] < 20  # long batches for a slowly varying d


def test_merge_patch_follows_rfc_7396():
    target = {"a": 1, "b": {"c": [1, 2], "d": 4}, "e": "x"}
    assert merge(target, {"b": {"c": [3], "d": None}, "e": None, "f": {"g": 1}}) == {
        "a": 1,
        "b": {"c": [3]},
        "f": {"g": 1},
    }
    assert target["b"]["c"] == [1, 2]  # the target is not modified
