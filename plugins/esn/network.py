"""Random sparse networks of tanh elements and their algebraic properties (thesis 5.2.3, 5.3.1)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import cast

import numpy as np
import scipy.sparse as sp

from dynmodel.reliability.evidence import largest_singular_value, spectral_radius

from .params import EsnParams

__all__ = [
    "Network",
    "build_network",
    "element_gain",
    "largest_singular_value",
    "spectral_radius",
    "stack_networks",
]


def element_gain(a: np.ndarray, relaxation_gain: bool) -> np.ndarray:
    """g of the elements: 1 - |a| (eq. 6.21) when ``relaxation_gain``, else 1 (eq. 6.27)."""
    return 1.0 - np.abs(a) if relaxation_gain else np.ones_like(a)


@dataclass(frozen=True)
class Network:
    """x_t = a x_{t-1} + g tanh(C x_{t-1} + c0 + B_in u_t + B_back f_t).

    The one description of a tanh network in the plugins: the `esn` family builds it at random,
    `annealed-rnn` edits it (with C dense while the moves act on it, :meth:`dense`) and both run
    it through the compiled kernels (:meth:`kernel_args`, C in CSR form). Immutable: a change
    makes a new network (``dataclasses.replace``)."""

    C: sp.csr_matrix | np.ndarray  # (M, M): CSR, or dense while an annealing search edits it
    B_in: np.ndarray  # (M, n_inputs)
    B_back: np.ndarray  # (M, n_outputs); no columns in internal mode
    c0: np.ndarray
    a: np.ndarray
    g: np.ndarray

    @property
    def size(self) -> int:
        return self.c0.shape[0]

    @property
    def B(self) -> np.ndarray:
        return np.hstack([self.B_in, self.B_back])

    def sparse(self) -> Network:
        """The same network with C in CSR form (sorted indices), as the fitted models keep it."""
        if sp.issparse(self.C):
            return self
        C = sp.csr_matrix(self.C)
        C.sort_indices()
        return replace(self, C=C)

    def dense(self) -> Network:
        """The same network with C as a dense array (the form the annealing moves edit)."""
        return replace(self, C=self.C.toarray()) if sp.issparse(self.C) else self

    def kernel_args(self) -> tuple:
        """(indptr, indices, data, B, c0, a, g) for :mod:`dynmodel.kernels`. Unsigned indices:
        they spare the compiled gather numba's check for negative indices (20 - 30 % of a step)."""
        C = cast(sp.csr_matrix, self.sparse().C)
        return (
            C.indptr.astype(np.uint64),
            C.indices.astype(np.uint64),
            C.data.astype(np.float64),
            np.ascontiguousarray(self.B, dtype=np.float64),
            np.ascontiguousarray(self.c0, dtype=np.float64),
            np.ascontiguousarray(self.a, dtype=np.float64),
            np.ascontiguousarray(self.g, dtype=np.float64),
        )


def _sparse_normal(
    rng: np.random.Generator, shape: tuple[int, int], p: float, std: float, every_column: bool
) -> np.ndarray:
    """Entries nonzero with probability p, values N(0, std^2); optionally at least one per column."""
    mask = rng.random(shape) < p
    values = std * rng.standard_normal(shape)
    if every_column and shape[0] > 0:
        for j in np.flatnonzero(~mask.any(axis=0)):
            mask[rng.integers(shape[0]), j] = True
    return np.where(mask, values, 0.0)


def _as_matrix(v, rows: int, cols: int, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.shape != (rows, cols):
        raise ValueError(f"weights.{what} has shape {a.shape}; expected ({rows}, {cols})")
    return a


def build_network(p: EsnParams, n_inputs: int, n_outputs: int, rng: np.random.Generator) -> Network:
    """A random network as in thesis 5.3.2 (or the explicit matrices of ``p.weights``)."""
    m = p.size
    n_back = n_outputs if p.mode == "external" else 0
    if p.weights is not None:
        w = p.weights
        C = np.asarray(w.C, dtype=np.float64)
        B_in = (
            _as_matrix(w.b, m, n_inputs, "b")
            if w.b is not None
            else _sparse_normal(rng, (m, n_inputs), p.input_connectivity, p.input_scale, True)
        )
        B_back = (
            _as_matrix(w.b_back, m, n_back, "b_back")
            if (w.b_back is not None and n_back)
            else _sparse_normal(rng, (m, n_back), p.input_connectivity, p.feedback_scale, True)
        )
        c0 = np.asarray(w.c0, dtype=np.float64) if w.c0 is not None else np.zeros(m)
        a = np.asarray(w.relaxation, dtype=np.float64) if w.relaxation is not None else None
    else:
        assert p.connectivity is not None  # set by EsnParams' validator
        C = _sparse_normal(rng, (m, m), p.connectivity, 1.0, False)
        B_in = _sparse_normal(rng, (m, n_inputs), p.input_connectivity, p.input_scale, True)
        B_back = _sparse_normal(rng, (m, n_back), p.input_connectivity, p.feedback_scale, True)
        c0 = _sparse_normal(rng, (m, 1), p.bias_connectivity, p.bias_scale, False)[:, 0]
        a = None
    if a is None:
        if isinstance(p.relaxation, tuple):
            a = rng.uniform(p.relaxation[0], p.relaxation[1], m)
        else:
            a = np.full(m, float(p.relaxation))
    g = element_gain(a, p.relaxation_gain)
    Cs = sp.csr_matrix(C)
    assert p.scale is not None
    if p.scale.by == "singular":
        s = largest_singular_value(Cs)
        if s > 0:
            Cs = Cs * (p.scale.value / s)
    elif p.scale.by == "spectral":
        warnings.warn(
            "scaling C by its spectral radius does not guarantee a reliable network "
            "(thesis 5.3.1, eq. 5.28); scale.by: singular does",
            stacklevel=2,
        )
        r = spectral_radius(Cs)
        if r > 0:
            Cs = Cs * (p.scale.value / r)
    Cs.sort_indices()
    return Network(Cs.tocsr(), B_in, B_back, c0, a, g)


def stack_networks(nets: list[Network]) -> Network:
    """The networks side by side and unconnected, as one: C block-diagonal, each block driven by the inputs (and
    fed-back outputs) as before, the state the stack of theirs. sigma(C) is the largest of theirs, so a stack of
    reliable networks is reliable (thesis 5.3.1)."""
    C = sp.csr_matrix(sp.block_diag([n.sparse().C for n in nets], format="csr"))
    C.sort_indices()
    return Network(
        C,
        np.vstack([n.B_in for n in nets]),
        np.vstack([n.B_back for n in nets]),
        np.concatenate([n.c0 for n in nets]),
        np.concatenate([n.a for n in nets]),
        np.concatenate([n.g for n in nets]),
    )
