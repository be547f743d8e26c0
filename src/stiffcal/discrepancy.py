"""From measured deflections: what the stiffness model (eq. 2) gets wrong, why, the extended model, the gain.

The nominal model is linear in the joint compliances k: dp = A(q, F) k + e (eqs. 3-4), fitted by least
squares (eq. 6). Each candidate cause is a physically derived extension, linear in its own parameters,
so every question is a comparison of nested linear models:

- ``link_compliance``: Euler-Bernoulli links loaded at their distal end by the force F and the moment
  M it transmits; with P the force across link i, L its length, r the lever from its distal end to the end
  effector, the end effector moves by c_i [(P L^3/3 + M L^2/2) n_i + (P L^2/2 + M L) z x r], c_i = 1/(E I_i).
- ``joint_coupling``: off-diagonal joint compliances, dq_i = sum_j k_ij tau_j: columns J_i tau_j + J_j tau_i.
- ``nonlinear_joint_stiffness``: a compliance that changes with the torque, dq_i = k_i tau_i + g_i tau_i^3
  (the first odd term of any symmetric law): columns J_i tau_i^3.
- ``backlash``: a deflection of fixed size whose sign follows the torque: columns J_i sign(tau_i).
- ``measurement_offset``: a constant bias of the measuring system: one column per axis.

Statistics. The noise variance comes from replicates (pure error) when there are any, else from the
residuals of the union of all extensions (said in ``sigma_source``). Each extension is an F-test against
the nominal model; the family-wise false-alarm rate over the catalogue is held at ``alpha`` by Holm's
procedure. Gross blunders are found first, one at a time, by their residual from the union model against
a robust scale (Bonferroni threshold), and are left out of everything else.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from .errors import InputError
from .measurements import Measurements
from .robot import Robot, as_xyz
from .design import is_sampled, sample_joint_space
from .stiffness import observation_matrix, random_directions

CAUSES = ("link_compliance", "joint_coupling", "nonlinear_joint_stiffness", "backlash", "measurement_offset")
#: relative singular value below which a direction of a design matrix counts as absent
RANK_RTOL = 1e-9


# --- regressors ----------------------------------------------------------------------------------------

def torques(robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """tau = J^T F (N, n) [N m]."""
    return np.einsum("ndj,nd->nj", robot.jacobian(q), force)


def nominal_columns(robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """(N, d, n): the observation matrices A of eq. 4, one per measurement (the model's parameters:
    a joint that never moves the measured point is left out, see :attr:`Robot.params`)."""
    return observation_matrix(robot.model_jacobian(q), force)


def _link_columns(robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """(N, d, segments): per link segment (consecutive ``robot.link_points``), the end-effector displacement
    per unit 1/(E I) of a cantilever loaded at its distal end by the force F and the moment M = r x F it
    transmits (bending only): tip deflection (L^3/3) F_perp + (L^2/2) M_perp x u, tip rotation
    (L^2/2) u x F_perp + L M_perp, carried to the end effector by the lever r."""
    pts = as_xyz(robot.link_points(q))
    F = as_xyz(force)
    pe = pts[:, -1, :]
    cols = []
    for i in range(pts.shape[1] - 1):
        seg = pts[:, i + 1, :] - pts[:, i, :]
        L = np.linalg.norm(seg, axis=-1)
        u = seg / np.where(L > 0, L, 1.0)[:, None]
        r = pe - pts[:, i + 1, :]
        F_perp = F - np.einsum("nd,nd->n", F, u)[:, None] * u
        M = np.cross(r, F)
        M_perp = M - np.einsum("nd,nd->n", M, u)[:, None] * u
        tip = (L**3 / 3)[:, None] * F_perp + (L**2 / 2)[:, None] * np.cross(M_perp, u)
        turn = (L**2 / 2)[:, None] * np.cross(u, F_perp) + L[:, None] * M_perp
        cols.append(tip + np.cross(turn, r))
    return np.stack(cols, axis=-1)[:, : robot.task_dim, :]


def cause_columns(cause: str, robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """(N, d, p_cause): the regressors of one extension (module docstring) [m per unit parameter]."""
    J = robot.jacobian(q)
    tau = torques(robot, q, force)
    n, d = robot.n_joints, robot.task_dim
    if cause == "link_compliance":
        return _link_columns(robot, q, force)
    if cause == "joint_coupling":
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        return np.stack([J[:, :, i] * tau[:, j, None] + J[:, :, j] * tau[:, i, None] for i, j in pairs], axis=-1)
    if cause == "nonlinear_joint_stiffness":
        return J * (tau**3)[:, None, :]
    if cause == "backlash":
        return J * np.sign(tau)[:, None, :]
    if cause == "measurement_offset":
        return np.broadcast_to(np.eye(d), (len(q), d, d)).copy()
    raise ValueError(f"unknown cause {cause!r}")


def _stack(X: np.ndarray) -> np.ndarray:
    """(N, d, p) -> (N d, p), rows ordered measurement by measurement."""
    return X.reshape(-1, X.shape[-1])


# --- linear models -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Fit:
    """Least-squares fit: beta (p,), rss, rank, df (rows - rank), cov_unscaled (p, p) = (X^T X)^+."""
    beta: np.ndarray
    rss: float
    rank: int
    df: int
    cov_unscaled: np.ndarray


def fit(X: np.ndarray, y: np.ndarray) -> Fit:
    """Least squares (eq. 6) with columns scaled to unit norm for a well-conditioned rank decision."""
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    Xs = X / scale
    U, s, Vt = np.linalg.svd(Xs, full_matrices=False)
    keep = s > RANK_RTOL * s[0] if s.size else np.zeros(0, bool)
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    beta_s = Vt.T @ (inv * (U.T @ y))
    resid = y - Xs @ beta_s
    cov_s = (Vt.T * inv**2) @ Vt
    rank = int(keep.sum())
    return Fit(beta_s / scale, float(resid @ resid), rank, len(y) - rank, cov_s / np.outer(scale, scale))


def pure_error(y: np.ndarray, groups: np.ndarray) -> tuple[float, int]:
    """(SS, df) of the replicates: the spread of each coordinate about its group mean."""
    ss, df = 0.0, 0
    for g in np.unique(groups):
        rows = y[groups == g]
        if len(rows) > 1:
            ss += float(((rows - rows.mean(axis=0)) ** 2).sum())
            df += rows.size - rows.shape[1]
    return ss, df


def f_test(rss0: float, df0: int, rss1: float, df1: int, s2: float, df_s2: int) -> float:
    """p-value of the F-test of a nested extension (df0 - df1 extra parameters) against the error
    variance estimate s2 on df_s2 degrees of freedom."""
    extra = df0 - df1
    if extra <= 0 or s2 <= 0:
        return 1.0
    F = max(rss0 - rss1, 0.0) / extra / s2
    return float(stats.f.sf(F, extra, df_s2))


def holm(pvalues: dict[str, float]) -> dict[str, float]:
    """Holm-adjusted p-values (family-wise error control)."""
    keys = sorted(pvalues, key=lambda k: pvalues[k])
    m, out, running = len(keys), {}, 0.0
    for i, k in enumerate(keys):
        running = max(running, min(1.0, (m - i) * pvalues[k]))
        out[k] = running
    return out


# --- the analysis --------------------------------------------------------------------------------------

@dataclass
class Design:
    """The stacked regressors of one data set: X0 (N d, n), per-cause blocks, y (N d,), groups (N d... per row)."""
    X0: np.ndarray
    blocks: dict[str, np.ndarray]
    y: np.ndarray
    d: int

    def rows(self, keep: np.ndarray) -> "Design":
        r = np.repeat(keep, self.d)
        return Design(self.X0[r], {k: v[r] for k, v in self.blocks.items()}, self.y[r], self.d)

    def union(self) -> np.ndarray:
        return np.hstack([self.X0, *self.blocks.values()])


def build_design(robot: Robot, meas: Measurements) -> Design:
    X0 = _stack(nominal_columns(robot, meas.q, meas.force))
    blocks = {c: _stack(cause_columns(c, robot, meas.q, meas.force)) for c in CAUSES}
    return Design(X0, blocks, meas.dp.ravel(), robot.task_dim)


def find_blunders(des: Design, n_rows: int, alpha: float, max_fraction: float = 0.1) -> list[int]:
    """Rows whose residual from the union model exceeds a Bonferroni threshold on a robust scale, removed
    one at a time (largest first) and refitted."""
    keep = np.ones(n_rows, bool)
    out = []
    X = des.union()
    if X.shape[0] <= 2 * X.shape[1]:
        X = des.X0  # too few measurements for the union model: judge against the nominal one
    for _ in range(int(max_fraction * n_rows)):
        r = np.repeat(keep, des.d)
        f = fit(X[r], des.y[r])
        resid = des.y[r] - X[r] @ f.beta
        scale = 1.4826 * np.median(np.abs(resid)) * np.sqrt(len(resid) / max(f.df, 1))
        if scale <= 0:
            break
        per_row = np.abs(resid).reshape(-1, des.d).max(axis=1) / scale
        threshold = stats.norm.isf(alpha / (2 * len(resid))) + 2.0
        worst = int(np.argmax(per_row))
        if per_row[worst] <= threshold:
            break
        row = int(np.flatnonzero(keep)[worst])
        keep[row] = False
        out.append(row)
    return sorted(out)


def _spans_within(a: np.ndarray, b: np.ndarray) -> bool:
    """True when every column of a lies in the span of b (to RANK_RTOL)."""
    return fit(b, np.zeros(len(b))).rank == fit(np.hstack([b, a]), np.zeros(len(b))).rank


def check_identifiable(robot: Robot, meas: Measurements) -> None:
    """Enough equations for the compliances and a nonsingular plan, or one clear error."""
    n, d, N = robot.n_params, robot.task_dim, meas.n_rows
    if N * d < n:
        raise InputError(f"expected at least {n} equations for the {n} joint compliances, got {N * d} "
                         f"({N} measurements of {d} coordinates)", source=meas.source)
    f = fit(_stack(nominal_columns(robot, meas.q, meas.force)), meas.dp.ravel())
    if f.rank < n:
        raise InputError(f"the measurement plan cannot identify the {n} joint compliances: its information "
                         f"matrix has rank {f.rank} (the poses and forces load too few joints; measure other "
                         f"poses or force directions)", source=meas.source)


def analyse(robot: Robot, meas: Measurements, alpha: float = 0.01, test_pose=None, test_force=None) -> dict:
    """The verdict of DESIGN.md for one data set (module docstring). test_pose [rad] and test_force [N]
    (optional) give the compensation error at the study's test pose under both models."""
    check_identifiable(robot, meas)
    des_all = build_design(robot, meas)
    blunders = find_blunders(des_all, meas.n_rows, alpha)
    keep = np.ones(meas.n_rows, bool)
    keep[blunders] = False
    m = meas.subset(keep)
    check_identifiable(robot, m)
    des = des_all.rows(keep)
    ss_pe, df_pe = pure_error(m.dp, m.group)

    f0 = fit(des.X0, des.y)
    fu = fit(des.union(), des.y)
    if df_pe > 0:
        s2, df_s2, source = ss_pe / df_pe, df_pe, "replicates (pure error)"
    elif fu.df > 0:
        s2, df_s2, source = fu.rss / fu.df, fu.df, "residuals of the union of all extensions"
    else:
        s2, df_s2, source = f0.rss / max(f0.df, 1), max(f0.df, 1), "residuals of the nominal model"

    def lack_of_fit(f: Fit, used: list[str]) -> float | None:
        if df_pe > 0:
            return None if f.df <= df_pe else f_test(f.rss, f.df, ss_pe, df_pe, s2, df_pe)
        # no replicates: structure left in the residuals (rank correlations, Bonferroni) stands in
        return structure_p_value(robot, m, des, f, used)

    fits, raw, extra = {}, {}, {}
    for c in CAUSES:
        fc = fit(np.hstack([des.X0, des.blocks[c]]), des.y)
        fits[c] = fc
        extra[c] = fc.rank - f0.rank
        raw[c] = f_test(f0.rss, f0.df, fc.rss, fc.df, s2, df_s2) if extra[c] > 0 else 1.0
    testable = {c: p for c, p in raw.items() if extra[c] > 0}
    lof_nominal = lack_of_fit(f0, [])
    family = {**testable, **({"lack_of_fit": lof_nominal} if lof_nominal is not None else {})}
    adjusted = holm(family)  # one family: the false-alarm rate of any verdict but 'none' is <= alpha
    significant = [c for c in testable if adjusted[c] < alpha]

    if not significant:
        unexplained = adjusted.get("lack_of_fit", 1.0) < alpha
        cause = "unexplained" if unexplained else "none"
        best, p_value = None, (adjusted["lack_of_fit"] if unexplained else min(adjusted.values(), default=1.0))
    else:
        rss_min = min(fits[c].rss for c in significant)
        # equal fits (coinciding spans) go to the first cause of the catalogue; both are named
        best = min(significant, key=lambda c: (round(fits[c].rss / rss_min, 9), CAUSES.index(c)))
        # parsimony: a significant cause whose span lies inside the best one's, and which the best one does
        # not significantly improve on, explains the data as well with fewer parameters
        smaller = [c for c in significant if c != best and extra[c] < extra[best]
                   and _spans_within(des.blocks[c], np.hstack([des.X0, des.blocks[best]]))
                   and f_test(fits[c].rss, fits[c].df, fits[best].rss, fits[best].df, s2, df_s2) >= alpha]
        if smaller:
            best = min(smaller, key=lambda c: (extra[c], fits[c].rss))
        p_value = adjusted[best]
        left = lack_of_fit(fits[best], [best])
        if df_pe <= 0:  # no replicates: also, does the union explain significantly more than the best cause?
            left = min(1.0, 2 * min(left, f_test(fits[best].rss, fits[best].df, fu.rss, fu.df, s2, df_s2)))
        cause = "unexplained" if left < alpha else best
    indistinct = []
    if best is not None:
        Xb = np.hstack([des.X0, des.blocks[best]])
        for c in CAUSES:
            if c == best or extra[c] == 0:
                continue
            Xc = np.hstack([des.X0, des.blocks[c]])
            nested = _spans_within(des.blocks[c], Xb) or _spans_within(des.blocks[best], Xc)
            both = fit(np.hstack([Xb, des.blocks[c]]), des.y)
            equal = (c in significant
                     and f_test(fits[best].rss, fits[best].df, both.rss, both.df, s2, df_s2) >= alpha
                     and f_test(fits[c].rss, fits[c].df, both.rss, both.df, s2, df_s2) >= alpha)
            if nested or equal:
                indistinct.append(c)
    absorbed = [c for c in CAUSES if extra[c] == 0]
    advice = {c: separation_advice(robot, best, c, meas) for c in indistinct}

    sigma = float(np.sqrt(s2))
    t = stats.t.isf(0.025, df_s2)
    k_ci = t * sigma * np.sqrt(np.diag(f0.cov_unscaled))
    nominal = {"k": f0.beta.tolist(), "k_ci95": k_ci.tolist(), "k_joints": [int(j) + 1 for j in robot.params],
               "not_identifiable_joints": [j + 1 for j in robot.inert_joints], "sigma_m": sigma, "sigma_source": source,
               "sigma_df": int(df_s2), "rss": f0.rss, "df": f0.df, "lack_of_fit_p": lof_nominal,
               "n_rows": int(m.n_rows), "n_poses": int(len(np.unique(m.group)))}
    tests = {c: {"extra_parameters": int(extra[c]), "p_value": raw[c],
                 "holm_p_value": adjusted.get(c), "significant": c in significant} for c in CAUSES}
    out = {"cause": cause, "indistinguishable_from": indistinct, "p_value": p_value, "alpha": alpha,
           "nominal": nominal, "tests": tests, "absorbed_by_nominal": absorbed,
           "outlier_rows": [int(r) for r in blunders], "separation": advice}
    ext_cause = best
    out["extended"] = None if ext_cause is None else _extended(des, fits[ext_cause], ext_cause, sigma, t, robot)
    out["gain"] = None if ext_cause is None else _gain(robot, m, des, ext_cause, s2, test_pose, test_force)
    if cause == "unexplained":
        out["residual_structure"] = residual_structure(robot, m, des, fits[best] if best else f0,
                                                       [best] if best else [])
    return out


def separation_advice(robot: Robot, a: str, b: str, meas: Measurements, n_probe: int = 400) -> str:
    """Why causes a and b cannot be told apart here, and what measurement would separate them.

    On a random probe of poses within the joint limits and forces in every direction, if one span still
    lies inside the other for any end-effector position measurement, no choice of poses can separate them:
    another measured quantity is needed. Otherwise the probe pose where b's extra regressors are farthest
    from the span of a's model is the one to measure.
    """
    rng = np.random.default_rng(0)
    lims = robot.joint_limits_rad
    q = rng.uniform(lims[:, 0], lims[:, 1], (n_probe, robot.n_joints))
    f = random_directions(rng, n_probe, robot.task_dim) * np.median(np.linalg.norm(meas.force, axis=1))
    X0 = _stack(nominal_columns(robot, q, f))
    A, B = (_stack(cause_columns(c, robot, q, f)) for c in (a, b))
    if _spans_within(B, np.hstack([X0, A])) or _spans_within(A, np.hstack([X0, B])):
        return (f"for this robot every end-effector position measurement sees {a} and {b} (with the joint "
                f"compliances) through the same directions, so no choice of poses or forces separates them; "
                f"measure another quantity, e.g. the position of an intermediate joint or the end-effector "
                f"orientation")
    Xa = np.hstack([X0, A])
    P = B - Xa @ np.linalg.lstsq(Xa, B, rcond=None)[0]
    per_pose = np.linalg.norm(P.reshape(n_probe, -1, P.shape[1]), axis=(1, 2))
    i = int(np.argmax(per_pose))
    u = f[i] / np.linalg.norm(f[i])
    where = (f"at {np.degrees(np.arctan2(u[1], u[0])):.0f} deg" if len(u) == 2 else
             f"along ({', '.join(f'{c:.2f}' for c in u)})")
    return (f"these data do not separate {a} from {b}; a measurement at q = "
            f"{np.round(np.degrees(q[i]), 1).tolist()} deg with the force {where} "
            f"would (it is where their predictions differ most)")


def _extended(des: Design, f: Fit, cause: str, sigma: float, t: float, robot: Robot) -> dict:
    n = des.X0.shape[1]
    ci = t * sigma * np.sqrt(np.diag(f.cov_unscaled))
    return {"cause": cause, "k": f.beta[:n].tolist(), "k_ci95": ci[:n].tolist(),
            "parameters": f.beta[n:].tolist(), "parameters_ci95": ci[n:].tolist(),
            "parameter_names": parameter_names(cause, robot), "rss": f.rss, "df": f.df}


def parameter_names(cause: str, robot: Robot) -> list[str]:
    n = robot.n_joints
    return {"link_compliance": [f"c{i + 1}_1/(N m^2)" for i in range(robot.n_segments)],
            "joint_coupling": [f"k{i + 1}{j + 1}_rad/(N m)" for i in range(n) for j in range(i + 1, n)],
            "nonlinear_joint_stiffness": [f"g{i + 1}_rad/(N m)^3" for i in range(n)],
            "backlash": [f"b{i + 1}_rad" for i in range(n)],
            "measurement_offset": [f"o{a}_m" for a in "xyz"[: robot.task_dim]]}[cause]


def _design_of(robot: Robot, q, force, cause: str | None) -> np.ndarray:
    X = nominal_columns(robot, q, force)
    if cause:
        X = np.concatenate([X, cause_columns(cause, robot, q, force)], axis=-1)
    return X


def lopo_rms(robot: Robot, meas: Measurements, cause: str | None) -> float:
    """RMS prediction error [m] of held-out poses: each group of replicates left out in turn."""
    X = _design_of(robot, meas.q, meas.force, cause)
    err = []
    for g in np.unique(meas.group):
        test = meas.group == g
        f = fit(_stack(X[~test]), meas.dp[~test].ravel())
        err.append((meas.dp[test] - np.einsum("ndp,p->nd", X[test], f.beta)).ravel())
    e = np.concatenate(err)
    return float(np.sqrt(np.mean(e**2)))


def _gain(robot, meas, des, cause, s2, test_pose, test_force) -> dict:
    nom, ext = lopo_rms(robot, meas, None), lopo_rms(robot, meas, cause)
    out = {"lopo_rms_nominal_m": nom, "lopo_rms_extended_m": ext, "lopo_ratio": nom / ext if ext > 0 else None}
    if test_pose is not None and test_force is not None:
        qt = np.atleast_2d(test_pose)
        ft = np.atleast_2d(test_force)
        Xt0 = nominal_columns(robot, qt, ft)[0]
        Xt1 = _design_of(robot, qt, ft, cause)[0]
        X1 = np.hstack([des.X0, des.blocks[cause]])
        f0, f1 = fit(des.X0, des.y), fit(X1, des.y)
        bias = Xt1 @ f1.beta - Xt0 @ f0.beta  # the extended model taken as the truth
        var0 = s2 * np.trace(Xt0 @ f0.cov_unscaled @ Xt0.T)
        var1 = s2 * np.trace(Xt1 @ f1.cov_unscaled @ Xt1.T)
        out.update({"test_pose_rms_nominal_m": float(np.sqrt(bias @ bias + var0)),
                    "test_pose_rms_extended_m": float(np.sqrt(var1)),
                    "test_pose_model_error_m": float(np.linalg.norm(bias))})
        plan, ot_ext = optimal_plan(robot, cause, qt[0], ft[0])
        plan_nom, _ = optimal_plan(robot, None, qt[0], ft[0], m=len(plan))
        Xt = _design_of(robot, qt, ft, cause)[0]
        F = np.broadcast_to(ft[0], (len(plan), ft.shape[1]))
        ot_nom_plan = _ot_of(_design_of(robot, np.radians(plan_nom), F, cause), Xt)
        out.update({"optimal_plan_extended_deg": plan.round(3).tolist(),
                    "optimal_plan_extended_rms_m": float(np.sqrt(s2 * ot_ext)),
                    "nominal_plan_deg": plan_nom.round(3).tolist(),
                    "nominal_plan_under_extended_rms_m": float(np.sqrt(s2 * ot_nom_plan))
                    if np.isfinite(ot_nom_plan) else None})
    return out


def structure_p_value(robot: Robot, meas: Measurements, des: Design, f: Fit, used: list[str]) -> float:
    """Bonferroni-adjusted smallest p-value of the rank correlations of the residuals with row order,
    force, pose and torque (:func:`residual_structure`): a lack-of-fit test that needs no replicates."""
    found = residual_structure(robot, meas, des, f, used, keep=None)
    return min(1.0, min(r["p_value"] for r in found.values()) * len(found)) if found else 1.0


def residual_structure(robot: Robot, meas: Measurements, des: Design, f: Fit, used: list[str],
                       keep: int | None = 5) -> dict:
    """What is left: the rank correlations of the residual components with row order, force, pose and
    torque, strongest first (the ``keep`` strongest; all with keep=None)."""
    X = np.hstack([des.X0, *[des.blocks[c] for c in used]])
    resid = (des.y - X @ f.beta).reshape(-1, des.d)
    tau = torques(robot, meas.q, meas.force)
    features = {"row order (drift?)": np.arange(meas.n_rows), "force magnitude": np.linalg.norm(meas.force, axis=1),
                "force direction": np.arctan2(meas.force[:, 1], meas.force[:, 0]),
                **{f"q{i + 1}": meas.q[:, i] for i in range(robot.n_joints)},
                **{f"tau{i + 1}": tau[:, i] for i in range(robot.n_joints)}}
    out = {}
    for axis in range(des.d):
        for name, v in features.items():
            rho, p = stats.spearmanr(v, resid[:, axis])
            out[f"{'xyz'[axis]} vs {name}"] = {"spearman": float(rho), "p_value": float(p)}
    ranked = sorted(out.items(), key=lambda kv: kv[1]["p_value"])
    return dict(ranked if keep is None else ranked[:keep])


def residual_features(robot: Robot, meas: Measurements) -> dict[str, np.ndarray]:
    """The quantities residuals are plotted against: joint angles [deg], |F| [N], F direction [deg], tau [N m]."""
    tau = torques(robot, meas.q, meas.force)
    return {**{f"q{i + 1} [deg]": np.degrees(meas.q[:, i]) for i in range(robot.n_joints)},
            "|F| [N]": np.linalg.norm(meas.force, axis=1),
            "force direction [deg]": np.degrees(np.arctan2(meas.force[:, 1], meas.force[:, 0])),
            **{f"tau{i + 1} [N m]": tau[:, i] for i in range(robot.n_joints)}}


def nominal_residuals(robot: Robot, meas: Measurements, keep: np.ndarray) -> np.ndarray:
    """(N, d) residuals [m] of the nominal fit made on the rows ``keep`` (all rows get a residual)."""
    X = nominal_columns(robot, meas.q, meas.force)
    f = fit(_stack(X[keep]), meas.dp[keep].ravel())
    return meas.dp - np.einsum("ndp,p->nd", X, f.beta)


def run(robot: Robot, data_path: str, out_dir: str, alpha: float = 0.01, test_pose=None, test_force=None,
        label: str | None = None) -> dict:
    """Read, analyse, and write ``out_dir/verdict.json`` and ``out_dir/residuals.{png,svg}``; everything is
    computed before anything is written, so bad data leave no partial output."""
    import json
    from pathlib import Path

    from . import plots
    from .measurements import read_measurements

    if not 0 < alpha < 1:
        raise InputError(f"expected 0 < alpha < 1, got {alpha}", field="--alpha")
    meas = read_measurements(data_path, robot)
    verdict = analyse(robot, meas, alpha, test_pose, test_force)
    verdict = {"data": str(data_path), "robot": robot.source, **verdict}
    keep = np.ones(meas.n_rows, bool)
    keep[verdict["outlier_rows"]] = False
    resid = nominal_residuals(robot, meas, keep)
    fig = plots.fig_residuals(residual_features(robot, meas.subset(keep)), resid[keep],
                              verdict["nominal"]["sigma_m"], f"Nominal-model residuals: {label or Path(data_path).name}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots.save(fig, out / "residuals")
    text = json.dumps(verdict, indent=2, default=float, allow_nan=False)
    (out / "verdict.json").write_text(text + "\n", encoding="utf-8")
    return verdict


# --- the paper's method applied to the model that fits --------------------------------------------------

def _ot_of(Xs: np.ndarray, Xt: np.ndarray) -> float:
    """O_t / sigma^2 = tr(X_t M^-1 X_t^T) of a plan with regressors Xs (m, d, p); inf when singular."""
    M = np.einsum("mdi,mdj->ij", Xs, Xs)
    try:
        return float(np.trace(Xt @ np.linalg.solve(M, Xt.T))) if np.linalg.cond(M) < 1e12 else np.inf
    except np.linalg.LinAlgError:
        return np.inf


def optimal_plan(robot: Robot, cause: str | None, test_pose: np.ndarray, test_force: np.ndarray,
                 m: int | None = None, step_deg: float = 10.0, passes: int = 10):
    """O_t-optimal plan of m poses (default: the fewest that identify every parameter, plus one) for the
    model nominal + ``cause``, the test force used in every measurement (as in the paper): Fedorov exchange
    over a step_deg grid of poses within the joint limits. Returns (poses [deg] (m, n), O_t / sigma^2)."""
    if is_sampled(robot, step_deg):
        pool = sample_joint_space(robot, 12, seed=0)  # a grid would be too large: 4096 quasi-random poses
    else:
        lims = np.degrees(robot.joint_limits_rad)
        axes = [np.arange(lo, hi + 1e-9, step_deg) for lo, hi in lims]
        pool = np.radians(np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, robot.n_joints))
    F = np.broadcast_to(test_force, (len(pool), len(test_force)))
    Xp = _design_of(robot, pool, F, cause)
    Xt = _design_of(robot, np.atleast_2d(test_pose), np.atleast_2d(test_force), cause)[0]
    p, d = Xp.shape[2], Xp.shape[1]
    m = m or int(np.ceil(p / d)) + 1
    info = np.einsum("kdi,kdj->kij", Xp, Xp)
    ridge = 1e-9 * np.trace(info.mean(axis=0)) * np.eye(p)
    chosen: list[int] = []
    for _ in range(m):  # greedy start on a slightly regularised information matrix
        base = sum((info[i] for i in chosen), ridge)
        vals = np.einsum("ij,kji->k", Xt.T @ Xt, np.linalg.inv(base + info))
        chosen.append(int(np.argmin(vals)))
    best = _ot_of(Xp[chosen], Xt)
    for _ in range(passes):
        improved = False
        for i in range(m):
            rest = sum((info[j] for k, j in enumerate(chosen) if k != i), np.zeros((p, p)))
            cand = rest + info
            ok = np.linalg.cond(cand) < 1e12
            vals = np.full(len(pool), np.inf)
            vals[ok] = np.einsum("ij,kji->k", Xt.T @ Xt, np.linalg.inv(cand[ok]))
            k = int(np.argmin(vals))
            if vals[k] < best * (1 - 1e-12):
                chosen[i], best, improved = k, float(vals[k]), True
        if not improved:
            break
    return np.degrees(pool[chosen]), best
