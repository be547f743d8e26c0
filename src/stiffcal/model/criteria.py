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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .stiffness import ESTIMABLE_RTOL, functional_variance, spectral


@dataclass(frozen=True)
class Criterion:
    """One optimality criterion, an entry of the registry :data:`CRITERIA`: ``key`` (the CLI's and the config's
    name), ``label`` (as in the paper), ``sense`` ('min' or 'max'), ``formula`` (the paper's, for the docs);
    ``value(M, m, s, smax, At, sigma, A, spec)`` its natural value from information matrices M (..., n, n) of
    m-pose plans, their singular values s (..., n) ascending (the square roots of M's eigenvalues; smax the
    largest, 1 where zero), the test pose's rows At, the noise sigma, the stacked rows A and M's
    eigen-decomposition ``spec`` (:func:`stiffcal.model.stiffness.spectral`); ``needs_inverse``: built on M^-1 (+inf
    for a singular plan when optimising); ``nonsmooth``: a max over poses or eigenvalues (polished by
    Nelder-Mead); ``exchange``: the fast exchange's form for it in :mod:`stiffcal.planning.plans` (``"linear"``: a
    linear functional tr(C M^-1), L-optimality; ``"closed"``: det or trace in closed form; None: the generic
    exchange)."""

    key: str
    label: str
    sense: str
    formula: str
    value: Callable
    needs_inverse: bool = False
    nonsmooth: bool = False
    exchange: str | None = None


def _eye_variance(M, spec):
    return functional_variance(M, np.eye(M.shape[-1]), 1.0, spec)


def _g(M, m, s, smax, At, sigma, A, spec):
    if A is None:
        raise ValueError("G-optimality needs the stacked observation rows A")
    return np.max(functional_variance(M, A, 1.0, spec), axis=-1)


#: Every criterion: the test-pose criterion O_t (eq. 16) and Table 1, in the paper's order. O1 is the geometric
#: mean of the singular values over sqrt(m) (the paper's sqrt(sigma_1 sigma_2)/sqrt(m) for two parameters). O2 is
#: the inverse condition number sigma_s / sigma_1, as Table 1 names it; the formula Table 1 prints,
#: sigma_s^2 / sigma_1^3, is not scale invariant (it changes with the units of A), so we keep the name's form. For
#: the paper's arm both forms have the same global maximisers, the isotropic poses (sigma_s = sigma_1) of Table 2,
#: so either gives the pose and accuracies printed there (tests/test_paper.py compares both with a brute force).
CRITERIA: dict[str, Criterion] = {
    c.key: c
    for c in [
        Criterion("ot", "O_t", "min", "sigma^2 trace(A_t (A^T A)^-1 A_t^T) -> min (eq. 16)",
                  lambda M, m, s, smax, At, sigma, A, spec: o_t(M, At, sigma, spec), needs_inverse=True,
                  exchange="linear"),
        Criterion("a", "A-optimality", "min", "trace((A^T A)^-1) -> min",
                  lambda M, m, s, smax, At, sigma, A, spec: np.sum(_eye_variance(M, spec), axis=-1),
                  needs_inverse=True, exchange="linear"),
        Criterion("t", "T-optimality", "max", "trace(A^T A) -> max",
                  lambda M, m, s, smax, At, sigma, A, spec: np.trace(M, axis1=-2, axis2=-1), exchange="closed"),
        Criterion("d", "D-optimality", "max", "det(A^T A) -> max",
                  lambda M, m, s, smax, At, sigma, A, spec: np.linalg.det(M), exchange="closed"),
        Criterion("g", "G-optimality", "min", "max d[H], H = A (A^T A)^-1 A^T -> min", _g,
                  needs_inverse=True, nonsmooth=True),
        Criterion("mdc", "MDC", "min", "max d[(A^T A)^-1] -> min",
                  lambda M, m, s, smax, At, sigma, A, spec: np.max(_eye_variance(M, spec), axis=-1),
                  needs_inverse=True, nonsmooth=True),
        Criterion("o1", "O1", "max", "(sigma_1 ... sigma_s)^(1/s) / sqrt(m) -> max",
                  lambda M, m, s, smax, At, sigma, A, spec: np.prod(s, axis=-1) ** (1.0 / M.shape[-1]) / np.sqrt(m)),
        Criterion("o2", "O2", "max", "sigma_s / sigma_1 -> max",
                  lambda M, m, s, smax, At, sigma, A, spec: s[..., 0] / smax),
        Criterion("o3", "O3", "max", "sigma_s -> max", lambda M, m, s, smax, At, sigma, A, spec: s[..., 0]),
        Criterion("o4", "O4", "max", "sigma_s^2 / sigma_1 -> max",
                  lambda M, m, s, smax, At, sigma, A, spec: s[..., 0] ** 2 / smax),
    ]
}
#: Table 1 of the paper (every criterion but O_t), in its order
TABLE1: dict[str, Criterion] = {k: c for k, c in CRITERIA.items() if k != "ot"}

CRITERIA_KEYS = tuple(CRITERIA)
#: the paper's criteria in the order of Table 2's rows
TABLE2_ORDER = ("t", "a", "d", "g", "mdc", "o1", "o2", "o3", "o4")
#: the config's default ``study.criteria`` (the order of the tables' rows): Table 2's order, any other registered
#: criterion after them, O_t last
STUDY_DEFAULT = (*TABLE2_ORDER, *(k for k in CRITERIA if k not in (*TABLE2_ORDER, "ot")), "ot")

#: criteria built on the inverse of the information matrix: +inf for a singular plan when optimising
NEEDS_INVERSE = frozenset(k for k, c in CRITERIA.items() if c.needs_inverse)


def o_t(M: np.ndarray, At: np.ndarray, sigma: float = 1.0, spec=None) -> np.ndarray:
    """O_t of eq. 16: ``sigma^2 trace(A_t M^-1 A_t^T)``, the mean squared compensation error at the
    test pose.

    M: (..., n, n) information matrix of the plan; At: (d, n) observation matrix at the test pose.
    Returns (...,) [m^2 for sigma in m]. ``inf`` when the deflection at the test pose is not estimable
    from the plan; finite when M is singular only in directions the test pose does not see.
    """
    return np.sum(functional_variance(M, At, sigma, spec), axis=-1)


def o_t_of_rows(A: np.ndarray, At: np.ndarray, sigma: float = 1.0) -> float:
    """O_t of eq. 16 from a plan's stacked rows A (r, n) instead of its information A^T A:
    ``sigma^2 trace(A_t (A^T A)^+ A_t^T) = sigma^2 ||A_t A^+||_F^2``, A^+ by the singular value decomposition of A,
    which resolves a direction whose singular value is below the square root of round-off relative to the largest
    (a component of the deflection the load barely makes: each measured direction counts in full however small, as
    in ``trace(A_t (A_t^T A_t)^+ A_t^T) = rank A_t``), where A^T A cannot. At: (d, n). Returns [m^2 for sigma in m];
    inf when A_t has a part outside A's row space (beyond ``ESTIMABLE_RTOL`` of its norm: not estimable)."""
    A, At = np.asarray(A, float), np.asarray(At, float)
    Z = At @ np.linalg.pinv(A)
    leak = At - Z @ A
    if np.sum(leak**2) > ESTIMABLE_RTOL**2 * max(float(np.sum(At**2)), np.finfo(float).tiny):
        return float("inf")
    return float(sigma**2 * np.sum(Z**2))


def o_t_star(n: int, m: int, sigma: float = 1.0) -> float:
    """O_t* of eq. 17: ``n sigma^2 / m``, O_t when all m measurements are taken at the test pose, with n the
    number of parameters they identify (``trace(A_t (A_t^T A_t)^+ A_t^T) = rank A_t``): the number of
    compliances when A_t has full column rank, the number of measured coordinates for an arm with more joints
    than that (:meth:`stiffcal.planning.problem.Problem.ot_star`)."""
    return n * sigma**2 / m


def chi(ot: np.ndarray, n: int, m: int, sigma: float = 1.0) -> np.ndarray:
    """chi of eq. 27: ``O_t* / O_t`` (0 where O_t is inf)."""
    return o_t_star(n, m, sigma) / np.asarray(ot, float)


def from_info(key: str, M: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0,
              A: np.ndarray | None = None, spec=None) -> np.ndarray:
    """Natural value of criterion ``key`` from information matrices M: (..., n, n) of m-pose plans.

    Singular values of the stacked A are the square roots of the eigenvalues of M, so O1-O4 come from
    the same eigen-decomposition. G needs the stacked rows A: (..., r, n) themselves.
    """
    spec = spectral(M) if spec is None else spec
    w, _, null = spec
    s = np.sqrt(np.where(null, 0.0, np.maximum(w, 0.0)))  # ascending
    smax = np.where(s[..., -1] > 0, s[..., -1], 1.0)
    if key not in CRITERIA:
        raise KeyError(key)
    return CRITERIA[key].value(M, m, s, smax, At, sigma, A, spec)


def evaluate(key: str, A: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0):
    """Natural value of criterion ``key`` for stacked observation matrices A: (..., m d, n)."""
    return from_info(key, np.einsum("...ri,...rj->...ij", A, A), m, At, sigma, A)


def sense(key: str) -> str:
    """'min' or 'max'."""
    return CRITERIA[key].sense


def label(key: str) -> str:
    return CRITERIA[key].label


def loss_from_info(key: str, M: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0,
                   A: np.ndarray | None = None) -> np.ndarray:
    """Criterion as a quantity to minimise, from information matrices M: (..., n, n).

    The value for 'min' criteria, minus it for 'max' ones. Never NaN. A plan whose information matrix is
    singular (a compliance cannot be identified) gets +inf for the criteria that invert it (A, G, MDC,
    O_t), as the paper's T-optimality row shows inf. For O_t this also excludes plans that identify only
    what the test pose needs: e.g. for the paper's test pose, poses with link 2 parallel to the force
    (q1 + q2 = +-90 deg) leave k2 unidentified yet reach the same O_t; a calibration plan must identify
    every compliance, so they are not candidates.
    """
    spec = spectral(M)
    v = np.asarray(from_info(key, M, m, At, sigma, A, spec), float)
    v = v if sense(key) == "min" else -v
    if key in NEEDS_INVERSE:
        v = np.where(np.any(spec[2], axis=-1), np.inf, v)
    return np.where(np.isnan(v), np.inf, v)


def loss(key: str, A: np.ndarray, m: int, At: np.ndarray | None = None, sigma: float = 1.0) -> np.ndarray:
    """:func:`loss_from_info` for stacked observation matrices A: (..., m d, n)."""
    return loss_from_info(key, np.einsum("...ri,...rj->...ij", A, A), m, At, sigma, A)
