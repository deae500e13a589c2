"""The embedding step (thesis 3.1.1) and the monomial pool (eq. 3.8 - 3.11).

A *regressor* is one data column at one lag: an input ``u[t-k]`` (k >= 0) or a past output
``y[t-k]`` (k >= 1), eq. 3.5 / 3.6. A *term* is a monomial of the regressors, stored as a row
of exponents (eq. 3.10); the all-zero row is the constant. Terms are written as text the way
the summary prints them: ``1``, ``u[t]``, ``y[t-2]^3``, ``y[t-1] * u[t-1]^2``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

INPUT, OUTPUT = 0, 1
#: the default embedding: every input at lags 0 .. L, every output at 1 .. L, with L the largest of
#: DEFAULT_MAX_LAG .. 1 whose pool holds at most DEFAULT_POOL monomials
DEFAULT_MAX_LAG = 6
DEFAULT_POOL = 600

_FACTOR = re.compile(r"^(?P<name>.+?)\[\s*t\s*(?:-\s*(?P<lag>\d+)\s*)?\](?:\s*\^\s*(?P<pow>\d+))?$")


@dataclass(frozen=True)
class Regressor:
    source: int  # INPUT or OUTPUT
    channel: int  # column in the model inputs or outputs
    lag: int
    name: str  # the column's name

    @property
    def label(self) -> str:
        return f"{self.name}[t]" if self.lag == 0 else f"{self.name}[t-{self.lag}]"


@dataclass
class Embedding:
    """The regressors of a NARX model, inputs first, each column's lags ascending."""

    regressors: list[Regressor]

    @property
    def size(self) -> int:
        return len(self.regressors)

    @property
    def max_lag(self) -> int:
        return max((r.lag for r in self.regressors), default=0)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(source, channel, lag) as int64 arrays, for the kernels and the model file."""
        return (
            np.array([r.source for r in self.regressors], dtype=np.int64),
            np.array([r.channel for r in self.regressors], dtype=np.int64),
            np.array([r.lag for r in self.regressors], dtype=np.int64),
        )

    def matrix(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Regressor values (n, size) of one recording; values before its first sample are 0
        (zero padding, 3.1.1; callers drop those rows when asked to)."""
        n = u.shape[0]
        X = np.zeros((n, self.size))
        for j, r in enumerate(self.regressors):
            src = u if r.source == INPUT else y
            if r.lag < n:
                X[r.lag :, j] = src[: n - r.lag, r.channel]
        return X

    def label_of(self, exponents: np.ndarray) -> str:
        return term_label(exponents, [r.label for r in self.regressors])

    @property
    def inputs(self) -> np.ndarray:
        """Which regressors are inputs (bool, per regressor)."""
        return np.array([r.source == INPUT for r in self.regressors], dtype=bool)


def _lag_error(name: str, what: str) -> ValueError:
    return ValueError(f"lags.{name}: {what}")


def default_lag_table(
    input_names: list[str],
    output_names: list[str],
    degree: int,
    constant: bool = True,
    linear_inputs: bool = False,
) -> dict[str, list[int]]:
    """The default embedding: inputs at 0 .. L and outputs at 1 .. L (eq. 3.5 / 3.6), L the largest
    of ``DEFAULT_MAX_LAG`` .. 1 whose pool of degree ``degree`` holds at most ``DEFAULT_POOL``
    monomials (the Gram matrix costs N K^2; FOS then keeps the lags that matter). One input and
    one output at degree 3: L = 6 (13 regressors, 560 monomials), the embedding that models
    Silverbox and Bouc-Wen best; two inputs: L = 3; degree 5: L = 2 (the thesis's 3.2.4 pool).
    ``linear_inputs``: the inputs enter only as linear terms (``input_terms: linear``), a smaller pool."""
    n_in, n_out = len(input_names), len(output_names)
    L = 1
    for lag in range(DEFAULT_MAX_LAG, 0, -1):
        n_lin = n_in * (lag + 1) if linear_inputs else 0
        if pool_size(n_in * (lag + 1) + n_out * lag, degree, constant, n_lin) <= DEFAULT_POOL:
            L = lag
            break
    table = {n: list(range(0, L + 1)) for n in input_names}
    table.update({n: list(range(1, L + 1)) for n in output_names})
    return table


def build_embedding(
    lags: dict[str, list[int]] | None,
    input_names: list[str],
    output_names: list[str],
    extra: Sequence[tuple[str, int]] = (),
    degree: int = 3,
    constant: bool = True,
    linear_inputs: bool = False,
) -> Embedding:
    """Regressors from ``{column: [lags]}`` (None: :func:`default_lag_table` for this ``degree``)
    plus the (column, lag) pairs in ``extra`` (from explicit terms)."""
    table: dict[str, set[int]]
    if lags is None:
        default = default_lag_table(input_names, output_names, degree, constant, linear_inputs)
        table = {n: set(v) for n, v in default.items()}
    else:
        table = {n: set(v) for n, v in lags.items()}
    for name, lag in extra:
        table.setdefault(name, set()).add(lag)
    known = list(input_names) + list(output_names)
    for name, values in table.items():
        if name not in known:
            raise _lag_error(
                name,
                f"'{name}' is not a column of the data; the model inputs are {list(input_names)} "
                f"and the outputs {list(output_names)}",
            )
        if name in output_names and 0 in values:
            raise _lag_error(name, f"output '{name}' at lag 0 is the value being predicted; output lags start at 1")
    regs = [Regressor(INPUT, c, lag, n) for c, n in enumerate(input_names) for lag in sorted(table.get(n, ()))]
    regs += [Regressor(OUTPUT, c, lag, n) for c, n in enumerate(output_names) for lag in sorted(table.get(n, ()))]
    if not regs:
        raise ValueError("lags: the embedding is empty; give at least one lag, e.g. {u: [0, 1], y: [1]}")
    return Embedding(regs)


# ---------------------------------------------------------------- terms as text


def parse_term(text: str) -> list[tuple[str, int, int]]:
    """``'y[t-1]^2 * u[t]'`` -> [(name, lag, power), ...]; ``'1'`` -> [] (the constant)."""
    s = str(text).strip()
    if s == "1":
        return []
    factors = []
    for part in s.split("*"):
        m = _FACTOR.match(part.strip())
        if not m:
            raise ValueError(f"terms: cannot read '{text}'; write monomials such as 'u[t]', 'y[t-1]^2 * u[t-2]' or '1'")
        power = int(m.group("pow") or 1)
        if power < 1:
            raise ValueError(f"terms: '{text}' has a zero power; leave that factor out")
        factors.append((m.group("name").strip(), int(m.group("lag") or 0), power))
    return factors


def term_label(exponents: np.ndarray, labels: list[str]) -> str:
    parts = [labels[j] + (f"^{int(p)}" if p > 1 else "") for j, p in enumerate(exponents) if p > 0]
    return " * ".join(parts) if parts else "1"


def exponents_of(terms: list[str], emb: Embedding) -> np.ndarray:
    """Exponent rows (len(terms), emb.size) of textual terms; duplicates are refused."""
    index = {(r.name, r.lag): j for j, r in enumerate(emb.regressors)}
    rows = np.zeros((len(terms), emb.size), dtype=np.int64)
    for i, text in enumerate(terms):
        for name, lag, power in parse_term(text):
            rows[i, index[(name, lag)]] += power
    seen: dict[bytes, str] = {}
    for i, text in enumerate(terms):
        key = rows[i].tobytes()
        if key in seen:
            raise ValueError(f"terms: '{text}' repeats '{seen[key]}'")
        seen[key] = text
    return rows


# ---------------------------------------------------------------- the pool


def pool_size(n_regressors: int, degree: int, constant: bool, linear: int = 0) -> int:
    """Number of monomials of total degree 1..degree in n variables, plus the constant; ``linear`` of the
    variables enter only as terms of their own (x, never x^2 nor x * z)."""
    return math.comb(n_regressors - linear + degree, degree) - (0 if constant else 1) + (linear if degree else 0)


def pool_exponents(n_regressors: int, degree: int, constant: bool, linear: np.ndarray | None = None) -> np.ndarray:
    """Every monomial up to ``degree`` (eq. 3.10 / 3.11), by degree, constant first. ``linear`` (bool per
    regressor): those regressors appear only as linear terms of their own, the pool of a model
    y[t] = f(y[t-1], ...) + sum_k b_k u[t-k] (``input_terms: linear``)."""
    lin = np.zeros(n_regressors, dtype=bool) if linear is None else np.asarray(linear, dtype=bool)
    rows = [np.zeros(n_regressors, dtype=np.int64)] if constant else []
    for d in range(1, degree + 1):
        for combo in itertools.combinations_with_replacement(range(n_regressors), d):
            if d > 1 and lin[list(combo)].any():
                continue
            row = np.zeros(n_regressors, dtype=np.int64)
            np.add.at(row, list(combo), 1)
            rows.append(row)
    return np.array(rows, dtype=np.int64).reshape(len(rows), n_regressors)


def factor_lists(exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sparse form of exponent rows for the kernels: term i has factors ptr[i]:ptr[i+1] of
    regressor ``reg`` to power ``pw``."""
    E = np.asarray(exponents, dtype=np.int64)
    nz = E > 0
    ptr = np.zeros(E.shape[0] + 1, dtype=np.int64)
    ptr[1:] = np.cumsum(nz.sum(axis=1))
    rows, cols = np.nonzero(nz)
    return ptr, cols.astype(np.int64), E[rows, cols].astype(np.int64)
