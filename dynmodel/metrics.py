"""Quality measures of free-running predictions (thesis 6.2.2).

NMSE = 100 % * mean((y - yhat)^2) / var(y)        (eq. 5.48 / 6.17)
MAX  = max |y - yhat| / std(y)                     (eq. 6.18)
RMSE = sqrt(mean((y - yhat)^2))                    (in the output's units; benchmark reporting)
FIT  = 100 % * (1 - RMSE / std(y))                 (the "fit" of the nonlinear benchmarks)

Both are computed per output channel over the scored samples of a split, pooled over
recordings; ``var(y)`` and ``std(y)`` are those of the measured output on the same samples.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal, get_args

import numpy as np

#: the metric names a spec's ``evaluation.metrics`` accepts (this module is their one home)
MetricName = Literal["nmse", "max", "rmse", "fit"]
METRIC_NAMES: tuple[MetricName, ...] = get_args(MetricName)
#: what a spec without ``evaluation.metrics`` reports
DEFAULT_METRICS: tuple[MetricName, ...] = ("nmse", "max")
#: metrics where a larger value is better (the others are errors)
HIGHER_IS_BETTER: tuple[MetricName, ...] = ("fit",)
#: column headings of tables
METRIC_LABELS: dict[str, str] = {"nmse": "NMSE %", "max": "MAX", "rmse": "RMSE", "fit": "fit %"}


def split_label(split: str, entry: Mapping[str, Any]) -> str:
    """How a split's scores are named to the user: ``validation (fitted)`` when its samples were fitted (family
    auto's refit on every sample: ``fitted`` in its metrics), else the split's name."""
    return f"{split} (fitted)" if entry.get("fitted") else split


#: the costs a family is fitted with: mse1, the one-step error; mse_inf, the free-run error (thesis 5.1)
CostName = Literal["mse1", "mse_inf"]
COSTS: tuple[CostName, ...] = get_args(CostName)


def nmse(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """Normalised mean squared error in percent, per output column."""
    y, yhat = np.atleast_2d(y.T).T, np.atleast_2d(yhat.T).T
    return 100.0 * np.mean((y - yhat) ** 2, axis=0) / np.maximum(np.var(y, axis=0), np.finfo(float).tiny)


def max_error(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """Largest absolute error in units of the output's standard deviation, per output column."""
    y, yhat = np.atleast_2d(y.T).T, np.atleast_2d(yhat.T).T
    return np.max(np.abs(y - yhat), axis=0) / np.maximum(np.std(y, axis=0), np.finfo(float).tiny)


def rmse(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """Root mean squared error in the output's units, per output column."""
    y, yhat = np.atleast_2d(y.T).T, np.atleast_2d(yhat.T).T
    return np.sqrt(np.mean((y - yhat) ** 2, axis=0))


def fit_percent(y: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """100 % (1 - RMSE / std(y)) per output column (100 % is perfect, 0 % the mean's level)."""
    y = np.atleast_2d(y.T).T
    return 100.0 * (1.0 - rmse(y, yhat) / np.maximum(np.std(y, axis=0), np.finfo(float).tiny))


METRICS: dict[str, Callable[[np.ndarray, np.ndarray], np.ndarray]] = {
    "nmse": nmse,
    "max": max_error,
    "rmse": rmse,
    "fit": fit_percent,
}
assert set(METRICS) == set(METRIC_NAMES)
