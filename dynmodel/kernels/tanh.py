"""A branch-free, vectorisable tanh accurate to a few ulp.

numba compiles ``np.tanh`` to a scalar libm call (about 8 ns), which dominates a network step.
Here ``tanh(x) = m / (m + 2)`` with ``m = expm1(2|x|)``, computed as ``expm1(2|x| / 64)`` by a
degree-15 Taylor polynomial (|arg| <= 0.61, truncation < 2e-17) followed by six exact
doublings ``m <- m (m + 2)`` (that is ``e^{2s} - 1 = (e^s - 1)(e^s + 1)``), so there is no
cancellation near zero. ``|x| > 19.5`` saturates to +-1 exactly as in float64. Measured error
against ``numpy.tanh``: below 6 ulp on [-25, 25]; NaN propagates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: fast-math flags without 'nnan'/'ninf', so divergence checks (isfinite) stay valid
FASTMATH = {"nsz", "arcp", "contract", "reassoc"}


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def tanh1(x: float) -> float:
    ax = abs(x)
    ax = 19.5 if ax > 19.5 else ax
    s = ax * (2.0 / 64.0)
    m = s * (
        1.0
        + s
        * (
            1.0 / 2
            + s
            * (
                1.0 / 6
                + s
                * (
                    1.0 / 24
                    + s
                    * (
                        1.0 / 120
                        + s
                        * (
                            1.0 / 720
                            + s
                            * (
                                1.0 / 5040
                                + s
                                * (
                                    1.0 / 40320
                                    + s
                                    * (
                                        1.0 / 362880
                                        + s
                                        * (
                                            1.0 / 3628800
                                            + s
                                            * (
                                                1.0 / 39916800
                                                + s
                                                * (
                                                    1.0 / 479001600
                                                    + s
                                                    * (
                                                        1.0 / 6227020800
                                                        + s * (1.0 / 87178291200 + s * (1.0 / 1307674368000))
                                                    )
                                                )
                                            )
                                        )
                                    )
                                )
                            )
                        )
                    )
                )
            )
        )
    )
    m = m * (m + 2.0)
    m = m * (m + 2.0)
    m = m * (m + 2.0)
    m = m * (m + 2.0)
    m = m * (m + 2.0)
    m = m * (m + 2.0)
    t = m / (m + 2.0)
    return t if x >= 0.0 else -t


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def tanh_vec(x: np.ndarray, out: np.ndarray) -> None:
    """out[i] = tanh(x[i]) for 1-D arrays."""
    for i in range(x.shape[0]):
        out[i] = tanh1(x[i])
