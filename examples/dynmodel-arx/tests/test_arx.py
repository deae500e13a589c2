"""Tests of the example family, as its author would write them: the dynmodel contract, then the family's
own promise (output error is unbiased under output noise where least squares on the equation error is not)."""

from __future__ import annotations

import numpy as np
import pytest
from dynmodel_arx import Arx
from scipy.signal import lfilter

from dynmodel.testing import check_family


@pytest.mark.parametrize("cost", ["mse1", "mse_inf"])
def test_contract(cost, tmp_path):
    check_family(Arx, fit_options={"cost": cost}, tmp_path=tmp_path)


def test_output_error_is_unbiased_under_output_noise_where_arx_is_not():
    """y = B(q)/A(q) u + e with A = 1 - 1.5 q^-1 + 0.7 q^-2, B = q^-1 + 0.5 q^-2 and white e of half the
    output's std: the noise enters the ARX regressors y(t-i) and biases least squares; the output-error
    estimate recovers A."""
    rng = np.random.default_rng(7)
    u, ut = rng.standard_normal(4000), rng.standard_normal(2000)
    x, xt = (lfilter([0.0, 1.0, 0.5], [1.0, -1.5, 0.7], v) for v in (u, ut))
    y = x + 0.5 * x.std() * rng.standard_normal(len(x))
    arx = Arx().fit(u, y, cost="mse1", scaling="none")
    oe = Arx().fit(u, y, cost="mse_inf", scaling="none")
    np.testing.assert_allclose(oe.a_[0], [1.5, -0.7], atol=0.02)
    assert abs(arx.a_[0, 0] - 1.5) > 0.5  # measured: 0.59
    assert oe.score(ut, xt) > 0.999 and arx.score(ut, xt) < 0.8  # measured: 0.9997 and 0.715
