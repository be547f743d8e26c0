"""Optimality criteria of a measurement plan: Table 1, the test-pose criterion O_t (eq. 16), its
reference O_t* (eq. 17) and the accuracy gain chi (eq. 27).

Every criterion is evaluated on a batch of plans given by their stacked observation matrices
``A``: (..., r, n) with r = m d rows (m poses, d coordinates each). Each returns its natural value
(the quantity in Table 1) and is registered with a sense ('min' or 'max'); :func:`loss` turns it into a
quantity to minimise, ``+inf`` where the plan is singular for a criterion that needs an inverse.

Singular values of A are the square roots of the eigenvalues of the information matrix ``A^T A``, so
the SVD-based observability indices O1-O4 are computed from the same eigen-decomposition.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .stiffness import covariance_diagonal, functional_variance, spectral


def _inv_trace(M):
    return np.sum(covariance_diagonal(M), axis=-1)


def _leverage_max(A, M):
    """max diag of the hat matrix H = A M^-1 A^T (inf for a singular plan)."""
    r = A.shape[-2]
    return np.max(functional_variance(M, A), axis=-1) if r else np.inf


def _singular_values(M):
    w, _, null = spectral(M)
    return np.sqrt(np.where(null, 0.0, np.maximum(w, 0.0)))  # ascending


@dataclass(frozen=True)
class Criterion:
    """One optimality criterion: ``key`` (CLI name), ``label`` (as in the paper), ``sense``,
    ``value(A, M, m)`` -> (...,) and the paper's formula for documentation."""

    key: str
    label: str
    sense: str
    value: Callable
    formula: str


def _o1(A, M, m):
    s = _singular_values(M)
    n = s.shape[-1]
    return np.prod(s, axis=-1) ** (1.0 / n) / np.sqrt(m)


#: Table 1, in the paper's order. O2 is the inverse condition number sigma_s / sigma_1: the formula
#: printed in Table 1 (sigma_s^2 / sigma_1^3) is not scale invariant and is taken as a typesetting slip;
#: see the report for the comparison of both readings with Table 2.
TABLE1: dict[str, Criterion] = {
    c.key: c
    for c in [
        Criterion("a", "A-optimality", "min", lambda A, M, m: _inv_trace(M), "trace((A^T A)^-1) -> min"),
        Criterion("t", "T-optimality", "max", lambda A, M, m: np.trace(M, axis1=-2, axis2=-1),
                  "trace(A^T A) -> max"),
        Criterion("d", "D-optimality", "max", lambda A, M, m: np.linalg.det(M), "det(A^T A) -> max"),
        Criterion("g", "G-optimality", "min", lambda A, M, m: _leverage_max(A, M),
                  "max d[H], H = A (A^T A)^-1 A^T -> min"),
        Criterion("mdc", "MDC", "min", lambda A, M, m: np.max(covariance_diagonal(M), axis=-1),
                  "max d[(A^T A)^-1] -> min"),
        Criterion("o1", "O1", "max", _o1, "(sigma_1 ... sigma_s)^(1/s) / sqrt(m) -> max"),
        Criterion("o2", "O2", "max",
                  lambda A, M, m: (lambda s: s[..., 0] / np.where(s[..., -1] > 0, s[..., -1], 1.0))(
                      _singular_values(M)), "sigma_s / sigma_1 -> max"),
        Criterion("o3", "O3", "max", lambda A, M, m: _singular_values(M)[..., 0], "sigma_s -> max"),
        Criterion("o4", "O4", "max",
                  lambda A, M, m: (lambda s: s[..., 0] ** 2 / np.where(s[..., -1] > 0, s[..., -1], 1.0))(
                      _singular_values(M)), "sigma_s^2 / sigma_1 -> max"),
    ]
}

CRITERIA_KEYS = ("ot",) + tuple(TABLE1)


def o_t(M: np.ndarray, At: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    """O_t of eq. 16: ``sigma^2 trace(A_t M^-1 A_t^T)``, the mean squared compensation error at the
    test pose.

    M: (..., n, n) information matrix of the plan; At: (d, n) observation matrix at the test pose.
    Returns (...,) [m^2 for sigma in m]. ``inf`` when the deflection at the test pose is not estimable
    from the plan; finite when M is singular only in directions the test pose does not see.
    """
    return np.sum(functional_variance(M, At, sigma), axis=-1)


def o_t_star(n: int, m: int, sigma: float = 1.0) -> float:
    """O_t* of eq. 17: ``n sigma^2 / m``, O_t when all m measurements are taken at the test pose
    (valid when A_t has full column rank)."""
    return n * sigma**2 / m


def chi(ot: np.ndarray, n: int, m: int, sigma: float = 1.0) -> np.ndarray:
    """chi of eq. 27: ``O_t* / O_t`` (0 where O_t is inf)."""
    return o_t_star(n, m, sigma) / np.asarray(ot, float)


def evaluate(key: str, A: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0):
    """Natural value of criterion ``key`` for stacked observation matrices A: (..., m d, n)."""
    M = np.einsum("...ri,...rj->...ij", A, A)
    if key == "ot":
        return o_t(M, At, sigma)
    return TABLE1[key].value(A, M, m)


def sense(key: str) -> str:
    """'min' or 'max'."""
    return "min" if key == "ot" else TABLE1[key].sense


def label(key: str) -> str:
    return "O_t" if key == "ot" else TABLE1[key].label


#: criteria built on the inverse of the information matrix: +inf for a singular plan when optimising
NEEDS_INVERSE = frozenset({"a", "g", "mdc", "ot"})


def loss(key: str, A: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0) -> np.ndarray:
    """Criterion as a quantity to minimise: the value for 'min' criteria, minus it for 'max' ones.

    Never NaN. A plan whose information matrix is singular (a compliance cannot be identified) gets
    +inf for the criteria that invert it (A, G, MDC, O_t), as the paper's T-optimality row shows inf.
    For O_t this also excludes plans that identify only what the test pose needs: e.g. for the paper's
    test pose, poses with link 2 parallel to the force (q1 + q2 = +-90 deg) leave k2 unidentified yet reach
    the same O_t; a calibration plan must identify every compliance, so they are not candidates.
    """
    M = np.einsum("...ri,...rj->...ij", A, A)
    v = np.asarray(evaluate(key, A, m, At, sigma), float)
    v = v if sense(key) == "min" else -v
    if key in NEEDS_INVERSE:
        v = np.where(np.any(spectral(M)[2], axis=-1), np.inf, v)
    return np.where(np.isnan(v), np.inf, v)
