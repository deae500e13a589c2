"""Algebraic reliability evidence for sigmoid networks x_t = a x_{t-1} + g tanh(C x_{t-1} + c0 + B v_t).

* eq. 4.51 / 5.21: if the map is a contraction the network is reliable. With tanh 1-Lipschitz the
  Jacobian diag(a) + diag(g tanh') C has norm <= max|a| + sigma(diag(g) C); for a = 0, g = 1 that
  is sigma(C) < 1.
* eq. 5.24: rho(C) > 1 (more generally rho(diag(a) + diag(g) C) > 1) makes x = 0 an unstable
  fixed point for zero drive when the biases are zero: unreliable. With biases it proves nothing.
* rho < 1 alone does not guarantee reliability (the 2-element network of eq. 5.28).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .system import Evidence

_DENSE_LIMIT = 2000


def largest_singular_value(C) -> float:
    """sigma(C), the matrix 2-norm (dense below 2000 rows, else Lanczos)."""
    C = sp.csr_matrix(C)
    if C.nnz == 0:
        return 0.0
    if C.shape[0] <= _DENSE_LIMIT:
        return float(np.linalg.norm(C.toarray(), 2))
    return float(spla.svds(C.astype(np.float64), k=1, return_singular_vectors=False)[0])


def spectral_radius(C) -> float:
    """rho(C), the largest eigenvalue modulus (dense below 2000 rows, else Arnoldi)."""
    C = sp.csr_matrix(C)
    if C.nnz == 0:
        return 0.0
    if C.shape[0] <= _DENSE_LIMIT:
        return float(np.max(np.abs(np.linalg.eigvals(C.toarray()))))
    return float(np.abs(spla.eigs(C.astype(np.float64), k=1, which="LM", return_eigenvectors=False)[0]))


def tanh_network_evidence(C, a: np.ndarray, g: np.ndarray, c0: np.ndarray) -> list[Evidence]:
    """sigma(C), rho(C) and, for leaky elements, the general contraction bound and rho of the
    Jacobian at the origin; each with what it implies."""
    C = sp.csr_matrix(C)
    a = np.asarray(a, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    leaky = bool(np.any(a != 0) or np.any(g != 1))
    zero_bias = bool(np.all(np.asarray(c0) == 0))
    sigma = largest_singular_value(C)
    rho = spectral_radius(C)
    out: list[Evidence] = []
    if not leaky:
        if sigma < 1:
            out.append(
                Evidence(
                    "sigma(C)",
                    sigma,
                    "reliable",
                    "sigma(C) < 1: the network is a contraction, every input gives one response (eq. 4.51)",
                )
            )
        else:
            out.append(
                Evidence(
                    "sigma(C)", sigma, "undecided", "sigma(C) >= 1: the contraction proof of eq. 4.51 does not apply"
                )
            )
    else:
        out.append(
            Evidence("sigma(C)", sigma, "undecided", "largest singular value of C (leaky elements: see the bound)")
        )
        bound = float(np.max(np.abs(a))) + largest_singular_value(sp.diags(g) @ C)
        out.append(
            Evidence(
                "max|a| + sigma(diag(g) C)",
                bound,
                "reliable" if bound < 1 else "undecided",
                "< 1: the leaky network is a contraction (eq. 4.51 generalised)"
                if bound < 1
                else ">= 1: the contraction bound does not apply",
            )
        )
    if leaky:
        out.append(Evidence("rho(C)", rho, "undecided", "spectral radius of C"))
        rho_name, rho0 = "rho(diag(a) + diag(g) C)", spectral_radius(sp.diags(a) + sp.diags(g) @ C)
    else:
        rho_name, rho0 = "rho(C)", rho
    proved = any(e.implies == "reliable" for e in out)
    if rho0 > 1 and zero_bias:
        out.append(
            Evidence(
                rho_name,
                rho0,
                "unreliable",
                "> 1 with zero biases: for zero drive the rest state x = 0 is an unstable fixed point (eq. 5.24)",
            )
        )
    elif rho0 > 1:
        out.append(
            Evidence(
                rho_name,
                rho0,
                "undecided",
                "> 1: the linearisation at x = 0 expands; with nonzero biases this is no proof (numerical tests decide)",
            )
        )
    else:
        out.append(
            Evidence(
                rho_name,
                rho0,
                "undecided",
                "<= 1 does not guarantee reliability (eq. 5.28 has rho 0.79 and two attractors); numerical tests decide"
                if not proved
                else "<= 1, as implied by the contraction bound",
            )
        )
    return out
