"""The one check for NaN and inf in the data a user gives (files, generators, arrays, prediction inputs)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import DataError

FILL = "remove, interpolate or fill those samples before fitting"


def non_finite(a: np.ndarray, names: Sequence[str]) -> str | None:
    """What is wrong with the first non-finite value of the 2-D array ``a`` (columns ``names``), e.g.
    "column 'y' has NaN at sample 17 (2 non-finite values in that column)"; None when all are finite."""
    bad = ~np.isfinite(a)
    if not bad.any():
        return None
    rows, cols = np.nonzero(bad)
    row, col = int(rows[0]), int(cols[0])
    kind = "NaN" if np.isnan(a[row, col]) else "inf"
    count = int(bad[:, col].sum())
    return (
        f"column '{names[col]}' has {kind} at sample {row} ({count} non-finite value"
        f"{'s' if count > 1 else ''} in that column)"
    )


def check_finite(a: np.ndarray, names: Sequence[str], where: str, fix: str = FILL) -> None:
    """DataError (what, ``where``, ``fix``) at the first non-finite value of ``a``."""
    problem = non_finite(a, names)
    if problem is not None:
        raise DataError(problem, where, fix)
