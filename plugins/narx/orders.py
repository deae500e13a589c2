"""Lags and degree chosen on the validation split (the defaults ``lags: null``, ``degree: null``).

Thesis 3.1.1 and 3.1.4: the embedding decides what a static model can learn, and choosing it is
trial and error. Here the trials are cheap. The pool of the largest embedding (inputs at lags
0 .. L_max, outputs at 1 .. L_max, degree d_max) contains the pool of every smaller one (lags
0 .. L / 1 .. L, degree d <= d_max): its monomials are those that use only regressors of lag <= L
and have degree <= d, and their Gram matrix (eq. 3.13, what FOS needs, A.2.2) is a sub-block of
the large one. So one Gram matrix serves every candidate (L, d); FOS runs on each sub-block, the
number of terms is chosen by the free-run validation error (``stop_on: free_run``), and the
candidate whose free run validates best wins. Its terms are then written on its own, smaller
embedding (the free run needs only L measured outputs to start) and re-estimated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .embedding import OUTPUT, Embedding


@dataclass
class Candidate:
    """A sub-pool of the largest pool: the embedding with lags <= ``lag`` and monomials of degree <= ``degree``."""

    lag: int | None  # None: the user's lag table, as given
    degree: int
    rows: np.ndarray  # indices of its monomials in the large pool (the constant first)


def memory_lags(emb: Embedding) -> np.ndarray:
    """Each regressor's lag counted from its column's first one (inputs from 0, outputs from 1): its lag, on the
    default table; on a table whose input starts at its dead time d, input lags d .. d + L count as 0 .. L."""
    first: dict[tuple[int, int], int] = {}
    for r in emb.regressors:
        first[(r.source, r.channel)] = min(first.get((r.source, r.channel), r.lag), r.lag)
    return np.array(
        [r.lag - first[(r.source, r.channel)] + (1 if r.source == OUTPUT else 0) for r in emb.regressors],
        dtype=np.int64,
    )


def candidates(emb: Embedding, E: np.ndarray, lags: list[int | None], degrees: list[int]) -> list[Candidate]:
    """Every (L, d) of the search, smallest first, as rows of the large pool E (L on :func:`memory_lags`)."""
    reg_lag = memory_lags(emb)
    total = E.sum(axis=1)
    out = []
    for L in lags:
        allowed = np.ones(emb.size, dtype=bool) if L is None else reg_lag <= L
        inside = ~(E[:, ~allowed] > 0).any(axis=1)
        for d in degrees:
            rows = np.flatnonzero(inside & (total <= d))
            out.append(Candidate(L, d, rows))
    return out


def lag_tables(emb: Embedding, lag: int) -> dict[str, list[int]]:
    """The lag table of the embedding restricted to :func:`memory_lags` <= ``lag`` (every column keeps its lags
    up to it)."""
    table: dict[str, list[int]] = {}
    for r, m in zip(emb.regressors, memory_lags(emb)):
        if m <= lag:
            table.setdefault(r.name, []).append(r.lag)
    return table


def remap(exponents: np.ndarray, source: Embedding, target: Embedding) -> np.ndarray:
    """Exponent rows written on ``source``'s regressors, rewritten on ``target``'s (which must hold
    every regressor the rows use)."""
    index = {(r.source, r.channel, r.lag): j for j, r in enumerate(target.regressors)}
    out = np.zeros((exponents.shape[0], target.size), dtype=np.int64)
    for j, r in enumerate(source.regressors):
        used = exponents[:, j] > 0
        if used.any():
            out[:, index[(r.source, r.channel, r.lag)]] = exponents[:, j]
    return out


def score(info: dict[str, Any]) -> float:
    """The candidate's validation error: the mean over outputs of the kept size's free-run NMSE (inf
    when an output has none, e.g. it diverged at every size)."""
    kept = [entry.get("validation_free_run_nmse_kept") for entry in info["path"]]
    return float(np.mean(kept)) if all(k is not None for k in kept) else np.inf


def uses_inputs(emb: Embedding, exponents: np.ndarray) -> bool:
    src, _, _ = emb.arrays()
    return bool((exponents[:, src != OUTPUT] > 0).any())
