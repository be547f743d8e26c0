"""The paper's tables as data frames: Table 2 (optimal single pose per criterion), Table 3 (those plans
judged at the test pose), and the Monte Carlo checks of eqs. 11 and 16.

Every column name carries its unit where it has one. CSVs are written by :func:`write_csv` with a fixed
float format so that reruns are byte-identical.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from . import criteria
from .design import optimal_single_pose, plan_observations
from .stiffness import covariance_diagonal, identify_batch, information_matrix, observation_matrix
from .study import Study

FLOAT_FORMAT = "%.10g"


def write_csv(df: pd.DataFrame, path: str | Path) -> None:
    """Write a table deterministically (fixed float format, no index, '\\n' line ends)."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False, float_format=FLOAT_FORMAT, lineterminator="\n")


def _pose_cols(n: int) -> list[str]:
    return [f"q{i + 1}_deg" for i in range(n)]


def plan_summary(study: Study, plan_deg: np.ndarray) -> dict:
    """O_t, chi, E[dk_i^2] and dk_i = sqrt(E[dk_i^2]) of plans, vectorised.

    plan_deg: (..., m, n) [deg]. Returns a dict of arrays of shape (...,): 'O_t' (eq. 16; inf when a
    compliance is not identifiable), 'chi' (eq. 27), 'E_dk1'.. (eq. 11), 'dk1'.. .
    """
    plan = np.radians(np.asarray(plan_deg, float))
    m, n = plan.shape[-2:]
    prob = study.problem("ot", m)
    M = information_matrix(observation_matrix(study.robot.jacobian(plan), study.force))
    cov = covariance_diagonal(M, study.sigma)
    ot = np.where(np.all(np.isfinite(cov), axis=-1), criteria.o_t(M, prob.At, study.sigma), np.inf)
    out = {"O_t": ot, "chi": criteria.chi(ot, n, m, study.sigma)}
    for i in range(n):
        out[f"E_dk{i + 1}"] = cov[..., i]
        out[f"dk{i + 1}"] = np.sqrt(cov[..., i])
    return out


def table2(study: Study) -> pd.DataFrame:
    """Table 2: the optimal single measurement pose for every criterion of the study, with the
    identification accuracy ``E[dk_i^2]`` (eq. 11) at that pose.

    Columns: criterion, label, q1_deg..qn_deg, E_dk1..E_dkn, value (the criterion's own value),
    n_optimal (size of the optimal set), optimal_set_deg ('q1 q2; ...'), degenerate.
    """
    rows = []
    n = study.robot.n_joints
    for key in study.criteria:
        res = optimal_single_pose(study.problem(key), step_deg=study.search_step_deg)
        summ = plan_summary(study, res.pose_deg[None, :])
        row = {"criterion": key, "label": criteria.label(key)}
        row.update(dict(zip(_pose_cols(n), res.pose_deg)))
        row.update({k: float(v) for k, v in summ.items() if k.startswith("E_dk")})
        row.update({"value": res.value, "n_optimal": len(res.optimal_set_deg),
                    "optimal_set_deg": "; ".join(" ".join(f"{a:.4f}" for a in p) for p in res.optimal_set_deg),
                    "degenerate": res.degenerate})
        rows.append(row)
    return pd.DataFrame(rows)


def table3(study: Study, t2: pd.DataFrame) -> pd.DataFrame:
    """Table 3: each criterion's optimal plan (from Table 2) judged at the test pose: chi (eq. 27),
    dk~_i = sqrt(E[dk_i^2]), O_t (eq. 16); first the reference row O_t* (eq. 17: measuring at the test
    pose itself).

    Columns: row, label, q1_deg.., chi, dk1.., O_t, O_t_lsq. ``O_t_lsq`` is the mean squared compensation
    error that least squares actually achieves with that plan (pseudo-inverse where the plan is singular
    but the test-pose deflection is estimable); it differs from O_t only in the O_t* row when A_t is
    rank deficient. Criteria that select no pose (degenerate, e.g. G for one experiment) have no row.
    """
    n = study.robot.n_joints
    cols = _pose_cols(n)
    test_deg = np.degrees(study.test_pose)
    prob = study.problem("ot")
    M_t = information_matrix(prob.At[None])
    ref = {"row": "ot_star", "label": "O_t* (eq. 17)", **dict(zip(cols, test_deg)), "chi": 1.0}
    ref.update({f"dk{i + 1}": float(np.sqrt(c)) for i, c in enumerate(covariance_diagonal(M_t, study.sigma))})
    ref["O_t"] = criteria.o_t_star(n, 1, study.sigma)
    ref["O_t_lsq"] = float(criteria.o_t(M_t, prob.At, study.sigma))
    rows = [ref]
    for _, r in t2[~t2["degenerate"].astype(bool)].iterrows():
        summ = plan_summary(study, r[cols].to_numpy(float)[None, :])
        row = {"row": r["criterion"], "label": r["label"], **{c: r[c] for c in cols},
               "chi": float(summ["chi"])}
        row.update({f"dk{i + 1}": float(summ[f"dk{i + 1}"]) for i in range(n)})
        row["O_t"] = row["O_t_lsq"] = float(summ["O_t"])
        rows.append(row)
    return pd.DataFrame(rows)


def chi_map(study: Study, step_deg: float | None = None) -> pd.DataFrame:
    """chi (eq. 27) of a single measurement pose over the (q1, q2) plane for the study's test pose
    (Figure 5). Planar 2-joint robots only. Columns q1_deg, q2_deg, O_t, chi (0 where singular)."""
    if study.robot.n_joints != 2:
        raise ValueError("the chi map over measurement poses is drawn for 2-joint robots")
    step = step_deg or study.fig5_step_deg
    g = np.arange(-180.0, 180.0, step)
    Q1, Q2 = np.meshgrid(g, g, indexing="ij")
    q = np.radians(np.stack([Q1, Q2], -1))[..., None, :]
    prob = study.problem("ot")
    ot = criteria.loss("ot", plan_observations(prob, q), 1, prob.At, study.sigma)
    chi = criteria.chi(ot, 2, 1, study.sigma)
    return pd.DataFrame({"q1_deg": Q1.ravel(), "q2_deg": Q2.ravel(), "O_t": ot.ravel(), "chi": chi.ravel()})


def monte_carlo_check(study: Study, plans: dict[str, np.ndarray], samples: int, seed: int) -> pd.DataFrame:
    """Check eq. 11 and eq. 16 against simulated calibrations (least squares, eq. 6, on noisy data).

    For each plan (name -> (m, n) poses [deg]): simulate ``samples`` calibrations with i.i.d. N(0, sigma^2)
    noise on every measured coordinate, identify k, and compare the empirical E[dk_i^2] and the empirical
    mean squared compensation error at the test pose with eqs. 11 and 16. Columns: plan, quantity,
    formula, monte_carlo, mc_std_error, z (difference in standard errors).
    """
    rng = np.random.default_rng(seed)
    rows = []
    n = study.robot.n_joints
    k_true = study.robot.compliances if study.robot.compliances is not None else np.full(n, 1e-6)
    prob = study.problem("ot")
    for name, plan_deg in plans.items():
        plan = np.radians(np.atleast_2d(plan_deg))
        A = observation_matrix(study.robot.jacobian(plan), study.force)  # (m, d, n)
        dp = np.einsum("mdn,n->md", A, k_true)
        noisy = dp[None] + rng.normal(0.0, study.sigma, size=(samples,) + dp.shape)
        dk = identify_batch(A, noisy) - k_true  # (s, n)
        err_t = dk @ prob.At.T  # (s, d): compensation error at the test pose (eq. 13)
        summ = plan_summary(study, np.atleast_2d(plan_deg))
        quantities = [(f"E_dk{i + 1}", "eq. 11", float(summ[f"E_dk{i + 1}"]), dk[:, i] ** 2) for i in range(n)]
        quantities.append(("O_t", "eq. 16", float(summ["O_t"]), np.sum(err_t**2, axis=1)))
        for q, eq, formula, draws in quantities:
            mean, se = float(draws.mean()), float(draws.std(ddof=1) / np.sqrt(samples))
            rows.append({"plan": name, "quantity": q, "equation": eq, "formula": formula,
                         "monte_carlo": mean, "mc_std_error": se, "z": (mean - formula) / se})
    return pd.DataFrame(rows)
