"""The elasto-static model: deflection (eq. 2), observation matrix (eqs. 3-4), information matrix and
covariance (eq. 11), least-squares identification (eq. 6).

Shapes: ``d`` measured coordinates per pose, ``n`` joints (= compliances), ``m`` measurement poses.
Units: Jacobian [m/rad], force [N], compliance k [rad/(N m)], deflection [m]; A [m^2 N/rad].

Singular plans
--------------
When the information matrix ``M = sum_i A_i^T A_i`` is singular, some linear functions ``c^T k`` of the
compliances cannot be estimated at all; their variance is reported as ``inf`` (never NaN, never a huge
finite number from round-off). Functions that ARE estimable (``c`` orthogonal to the null space of M)
keep their finite variance ``sigma^2 c^T M^+ c``, which is what least squares actually achieves for them.
An eigenvalue of M counts as zero when it is below ``n * eps * max eigenvalue`` (round-off in forming
``A^T A``; the same rule as ``numpy.linalg.matrix_rank(M, hermitian=True)``).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

EPS = np.finfo(float).eps
#: relative size of the null-space component below which a functional counts as estimable
ESTIMABLE_RTOL = np.sqrt(EPS)


def observation_matrix(J: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Observation matrix A of eq. 4: column j is ``J_j (J_j^T F)``, so that ``dp = A k`` (eq. 3).

    J: (..., d, n) [m/rad]; F: (..., d) or (d,) [N]. Returns A: (..., d, n) [m^2 N/rad].
    """
    JtF = np.einsum("...dj,...d->...j", J, F)
    return J * JtF[..., None, :]


def deflection(J: np.ndarray, k: np.ndarray, F: np.ndarray) -> np.ndarray:
    """End-effector deflection of eq. 2, ``dp = J diag(k) J^T F``.

    J: (..., d, n) [m/rad]; k: (n,) [rad/(N m)]; F: (..., d) [N]. Returns (..., d) [m].
    """
    return np.einsum("...dn,...n->...d", observation_matrix(J, F), k)


def information_matrix(A: np.ndarray) -> np.ndarray:
    """Information matrix ``sum_i A_i^T A_i`` (eq. 11) of a plan.

    A: (..., m, d, n), the observation matrices of m poses. Returns (..., n, n).
    """
    return np.einsum("...mdi,...mdj->...ij", A, A)


def pose_information(A: np.ndarray) -> np.ndarray:
    """Information contributed by single poses, ``A^T A``. A: (..., d, n). Returns (..., n, n)."""
    return np.einsum("...di,...dj->...ij", A, A)


def spectral(M: np.ndarray):
    """Eigen-decomposition of a batch of information matrices with the zero-eigenvalue rule.

    M: (..., n, n) symmetric PSD. Returns ``(w, V, null)``: eigenvalues (..., n) ascending, eigenvectors
    (..., n, n) as columns, and a boolean mask (..., n) of eigenvalues that count as zero.
    """
    w, V = np.linalg.eigh(M)
    n = M.shape[-1]
    tol = n * EPS * np.maximum(w[..., -1:], 0.0)
    null = w <= tol
    return w, V, null


def functional_variance(M: np.ndarray, C: np.ndarray, sigma: float = 1.0, spec=None) -> np.ndarray:
    """Variances of the least-squares estimates of ``C k`` for a plan with information matrix M (eq. 11).

    Returns ``sigma^2 diag(C M^+ C^T)`` with ``inf`` for every row of C that is not estimable.
    M: (..., n, n); C: (..., r, n) or (r, n); spec: ``spectral(M)`` if already computed. Returns (..., r).
    """
    w, V, null = spectral(M) if spec is None else spec
    inv_w = np.where(null, 0.0, 1.0 / np.where(null, 1.0, w))
    P = np.einsum("...rn,...nk->...rk", np.broadcast_to(C, M.shape[:-2] + np.shape(C)[-2:]), V)
    var = sigma**2 * np.einsum("...rk,...k->...r", P**2, inv_w)
    leak = np.einsum("...rk,...k->...r", P**2, null.astype(float))
    scale = np.sum(np.asarray(C, float) ** 2, axis=-1)
    not_estimable = leak > (ESTIMABLE_RTOL**2) * np.maximum(scale, np.finfo(float).tiny)
    return np.where(not_estimable, np.inf, var)


def covariance_diagonal(M: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    """``E[dk_i^2]`` of eq. 11, the diagonal of ``sigma^2 M^-1``, with inf for non-identifiable k_i.

    M: (..., n, n). Returns (..., n) [rad^2/(N m)^2 times sigma^2 units].
    """
    n = M.shape[-1]
    return functional_variance(M, np.eye(n), sigma)


def covariance(M: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    """Full covariance ``sigma^2 M^-1`` (eq. 11) for a nonsingular plan; raises for a singular one.

    M: (n, n). Returns (n, n).
    """
    _, _, null = spectral(M)
    if np.any(null):
        raise InputError("the plan's information matrix is singular: some compliances cannot be "
                         "identified from these poses and forces")
    return sigma**2 * np.linalg.inv(M)


def identify(A: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """Least-squares compliances of eq. 6, ``k = (sum A_i^T A_i)^-1 sum A_i^T dp_i``.

    Solved with an orthogonal factorisation of the stacked system (same solution as eq. 6, better
    conditioned). A: (m, d, n); dp: (m, d) [m]. Returns k: (n,). Raises :class:`InputError` when the plan
    is singular (a compliance cannot be identified).
    """
    A = np.asarray(A, float)
    m, d, n = A.shape
    rows = A.reshape(m * d, n)
    _, _, null = spectral(rows.T @ rows)
    if np.any(null):
        raise InputError(f"singular plan: {int(null.sum())} of {n} compliances cannot be identified "
                         "from these poses and forces")
    k, *_ = np.linalg.lstsq(rows, np.asarray(dp, float).reshape(m * d), rcond=None)
    return k


def identify_batch(A: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """Eq. 6 for many independent data sets on the same plan (Monte Carlo).

    A: (m, d, n); dp: (s, m, d). Returns (s, n).
    """
    m, d, n = A.shape
    rows = A.reshape(m * d, n)
    k, *_ = np.linalg.lstsq(rows, dp.reshape(-1, m * d).T, rcond=None)
    return k.T


def random_directions(rng: np.random.Generator, count: int, d: int) -> np.ndarray:
    """``count`` unit vectors uniformly distributed on the circle (d = 2) or the sphere (d = 3): (count, d)."""
    if d == 2:
        ang = rng.uniform(-np.pi, np.pi, count)
        return np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    v = rng.normal(size=(count, d))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)
