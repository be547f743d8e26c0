"""The paper's tables as data frames: Table 2 (optimal single pose per criterion), Table 3 (those plans
judged at the test pose), and the Monte Carlo checks of eqs. 11 and 16.

Every column name carries its unit where it has one. CSVs are written by :func:`write_csv` with a fixed
float format so that reruns are byte-identical.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..model import criteria
from ..csvtext import FLOAT_FORMAT, numeric_csv
from ..planning.problem import optimal_single_pose, plan_observations, plan_summary  # noqa: F401 (tables.plan_summary)
from ..model.stiffness import covariance_diagonal, identify_batch, information_matrix
from ..planning.study import Study



def write_csv(df: pd.DataFrame, path: str | Path) -> None:
    """Write a table deterministically (fixed float format, no index, '\\n' line ends) and atomically (a
    temporary file moved into place when complete). Tables of float64 and int64 columns only (the maps, 10^5
    rows and more) are formatted by :func:`_numeric_csv`, byte for byte what ``DataFrame.to_csv`` writes, three
    times faster; any other table by pandas."""
    from ..integrity import atomic_path

    text = _numeric_csv(df)
    with atomic_path(path) as tmp:
        if text is None:
            df.to_csv(tmp, index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        else:
            tmp.write_text(text, encoding="utf-8")


def _numeric_csv(df: pd.DataFrame) -> str | None:
    """``df.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator='\\n')`` as text for a table whose
    columns are all float64 or int64 and whose column names need no quoting
    (:func:`stiffcal.csvtext.numeric_csv`); None for any other table."""
    if not len(df.columns) or not df.columns.is_unique:
        return None
    return numeric_csv({str(c): df[c].to_numpy() for c in df.columns})


def _pose_cols(robot) -> list[str]:
    """The joint-angle columns of a robot's tables: q1_deg..qn_deg, or q_<name>_deg for named joints."""
    return robot.joint_columns("q", "_deg")


def table2(study: Study) -> pd.DataFrame:
    """Table 2: the optimal single measurement pose for every criterion of the study, with the
    identification accuracy ``E[dk_i^2]`` (eq. 11) at that pose.

    Columns: criterion, label, q1_deg..qn_deg, E_dk1..E_dkn, value (the criterion's own value),
    n_optimal (size of the optimal set), optimal_set_deg ('q1 q2; ...'), degenerate.
    """
    rows = []
    for key in study.criteria:
        res = optimal_single_pose(study.problem(key), step_deg=study.search_step_deg)
        summ = plan_summary(study, res.pose_deg[None, :])
        row = {"criterion": key, "label": criteria.label(key)}
        row.update(dict(zip(_pose_cols(study.robot), res.pose_deg)))
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
    cols = _pose_cols(study.robot)
    dks = study.robot.joint_columns("dk")
    test_deg = np.degrees(study.test_pose)
    prob = study.problem("ot")
    M_t = information_matrix(prob.At[None])
    ref = {"row": "ot_star", "label": "O_t* (eq. 17)", **dict(zip(cols, test_deg)), "chi": 1.0}
    ref.update({dk: float(np.sqrt(c)) for dk, c in zip(dks, covariance_diagonal(M_t, study.sigma))})
    ref["O_t"] = prob.ot_star(1)
    ref["O_t_lsq"] = float(criteria.o_t(M_t, prob.At, study.sigma))
    rows = [ref]
    for _, r in t2[~t2["degenerate"].astype(bool)].iterrows():
        summ = plan_summary(study, r[cols].to_numpy(float)[None, :])
        row = {"row": r["criterion"], "label": r["label"], **{c: r[c] for c in cols},
               "chi": float(summ["chi"])}
        row.update({dk: float(summ[dk]) for dk in dks})
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
    chi = prob.ot_star(1) / ot
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
    E_dk = study.robot.joint_columns("E_dk")
    prob = study.problem("ot")
    for name, plan_deg in plans.items():
        plan = np.radians(np.atleast_2d(plan_deg))
        A = prob.rows(plan)  # (m, r, p): every row with the noise sigma (weighted least squares)
        k_p = k_true[prob.params]
        dp = np.einsum("mdn,n->md", A, k_p)
        noisy = dp[None] + rng.normal(0.0, study.sigma, size=(samples,) + dp.shape)
        dk = identify_batch(A, noisy) - k_p  # (s, p)
        err_t = dk @ prob.At.T  # (s, d): compensation error at the test pose (eq. 13)
        summ = plan_summary(study, np.atleast_2d(plan_deg))
        quantities = [(E_dk[j], "eq. 11", float(summ[E_dk[j]]), dk[:, i] ** 2) for i, j in enumerate(prob.params)]
        quantities.append(("O_t", "eq. 16", float(summ["O_t"]), np.sum(err_t**2, axis=1)))
        for q, eq, formula, draws in quantities:
            mean, se = float(draws.mean()), float(draws.std(ddof=1) / np.sqrt(samples))
            rows.append({"plan": name, "quantity": q, "equation": eq, "formula": formula,
                         "monte_carlo": mean, "mc_std_error": se, "z": (mean - formula) / se})
    return pd.DataFrame(rows)


# ---------------------------------------------------------------------------------------------------
# plans of several poses (Tables 4-5), the approximate design and the certificate

PLAN_VARIANTS = {
    "i": "single optimum repeated",
    "ii": "q1 free, other joints at the single optimum",
    "iii": "q1 at the single optimum, other joints free",
    "iv": "all joints free (global)",
}


def format_plan(poses_deg: np.ndarray) -> str:
    """(m, n) poses -> 'q1 q2; q1 q2' with 4 decimals (the CSV form of a plan)."""
    rounded = np.round(np.atleast_2d(poses_deg), 4) + 0.0  # + 0.0: no "-0.0000"
    return "; ".join(" ".join(f"{a:.4f}" for a in p) for p in rounded)


def parse_plan(text: str) -> np.ndarray:
    """Inverse of :func:`format_plan`."""
    return np.array([[float(v) for v in p.split()] for p in str(text).split(";")])


def plans_long(plans: dict, robot, clearances: dict | None = None) -> pd.DataFrame:
    """Plans in long form, one row per pose: columns plan, m, pose (1-based), q1_deg..qn_deg (q_<name>_deg
    for named joints). plans: (plan label, m) -> (m, n) poses [deg]; clearances: the same keys -> (the poses'
    smallest distances [m] to the cell and to the robot itself, the pair of each), which add the columns
    clearance_m and closest (a robot in a cell)."""
    from ..model.robot import round_within

    cols = _pose_cols(robot)
    rows = []
    for key, poses in plans.items():
        label, m = key
        # to 1e-4 deg, never past a joint limit (a Panda's -176.001176 printed as -176.0012 lay outside it)
        for i, q in enumerate(round_within(np.atleast_2d(poses), robot.limits_deg, 4)):
            row = {"plan": label, "m": m, "pose": i + 1, **dict(zip(cols, np.asarray(q, float) + 0.0))}
            if clearances is not None:
                c, closest = clearances[key]
                row |= {"clearance_m": round(float(c[i]), 6), "closest": closest[i]}
            rows.append(row)
    return pd.DataFrame(rows)


def single_ot_pose(study: Study) -> np.ndarray:
    """The O_t-optimal single measurement pose [deg] (the representative of Table 2)."""
    return optimal_single_pose(study.problem("ot"), step_deg=study.search_step_deg).pose_deg


def plan_variants(study: Study, m: int, seed: int, design=None, single_deg=None) -> dict[str, np.ndarray]:
    """The paper's four m-pose plans (i)-(iv), each (m, n) [deg].

    (i) the single-pose optimum repeated m times; (ii) every pose keeps joints 2..n at the single-pose
    optimum and q1 is optimised for each pose; (iii) every pose keeps q1 at the single-pose optimum and
    joints 2..n are optimised; (iv) the global optimum over all joints of all poses (this is our reading
    of the paper's loosely described plans; see the report). Deterministic for a seed.
    """
    from ..planning.certificate import approximate_design, default_pool_step
    from ..planning.problem import joint_grids
    from ..planning.plans import design_starts, optimise_plan

    n = study.robot.n_joints
    single = single_ot_pose(study) if single_deg is None else np.asarray(single_deg, float)
    prob = study.problem("ot", m)
    repeat = np.repeat(single[None], m, axis=0)
    out = {"i": repeat}
    fine = joint_grids(study.robot, 0.5)
    base = np.radians(single)
    free_first = np.zeros(n, bool)
    free_first[0] = True
    pool_ii = np.tile(base, (len(fine[0]), 1))
    pool_ii[:, 0] = fine[0]
    out["ii"] = optimise_plan(prob, pool=pool_ii, free=free_first, starts=[repeat], seed=seed,
                              canonical=False).poses_deg
    rest = joint_grids(study.robot, 0.5 if n == 2 else default_pool_step(n))[1:]
    grid_rest = np.stack(np.meshgrid(*rest, indexing="ij"), -1).reshape(-1, n - 1)
    pool_iii = np.column_stack([np.full(len(grid_rest), base[0]), grid_rest])
    out["iii"] = optimise_plan(prob, pool=pool_iii, free=~free_first, starts=[repeat], seed=seed,
                               canonical=False).poses_deg
    design = design or approximate_design(prob)
    out["iv"] = optimise_plan(prob, starts=[*design_starts(prob, design, m), repeat], seed=seed).poses_deg
    return out


def plans_table(study: Study, m: int, seed: int, design=None, single_deg=None) -> pd.DataFrame:
    """Table 4 (m = 2) / Table 5 (m = 3): plans (i)-(iv) with O_t, chi, the poses, E[dk_i^2], the
    certified lower bound on O_t for any m-pose plan and the gap O_t / bound - 1."""
    from ..planning.certificate import approximate_design

    design = design or approximate_design(study.problem("ot", m))
    bound = design.lower_bound(m, study.sigma)
    rows = []
    for key, plan in plan_variants(study, m, seed, design, single_deg).items():
        summ = plan_summary(study, plan)
        row = {"plan": key, "variables": PLAN_VARIANTS[key], "m": m, "O_t": float(summ["O_t"]),
               "chi": float(summ["chi"]), "poses_deg": format_plan(plan)}
        row.update({e: float(summ[e]) for e in study.robot.joint_columns("E_dk")})
        row.update({"lower_bound": bound, "gap": float(summ["O_t"]) / bound - 1.0})
        rows.append(row)
    return pd.DataFrame(rows)


def design_table(design, robot) -> pd.DataFrame:
    """The optimal approximate design: support poses [deg] (columns as :func:`plans_long`) and weights."""
    df = pd.DataFrame(design.support_deg, columns=_pose_cols(robot))
    df["weight"] = design.weights
    return df


def certificate_table(design, sigma: float, continuum=None) -> pd.DataFrame:
    """The certificate's numbers: Phi(xi), max_x phi(x, xi), the equivalence gap and Phi* bound, and whether
    the design converged (gap within :data:`stiffcal.planning.certificate.EQUIVALENCE_TOL`; else the bound is labelled
    as not converged). In a cell (``continuum``: the design without the cell) two rows with a ``region``
    column: ``joint space`` (that design: its bound holds for every plan, so for every feasible one) and
    ``feasible candidates`` (the design over the poses the cell allows: its bound is exact over those)."""
    def row(d):
        return {"Phi": d.phi, "max_phi": d.max_phi, "equivalence_gap": d.equivalence_gap, "Phi_lower": d.phi_lower,
                "sigma": sigma, "multiplicative_iterations": d.iterations, "converged": d.converged}
    if continuum is None:
        return pd.DataFrame([row(design)])
    return pd.DataFrame([row(continuum) | {"region": continuum.region}, row(design) | {"region": design.region}])


def study_plan_row(study: Study, m: int, seed: int, design, pool=None, continuum=None) -> dict:
    """A design study's best plan of m poses (:func:`stiffcal.planning.plans.best_plan`, the function ``stiffcal
    design`` uses: one answer for one input) as one row: m, O_t (eq. 16), rms_m = sqrt(O_t), chi (eq. 27), lower_bound
    and gap (in a cell from ``continuum``, the design without the cell: valid for every plan), E_dk1.. (eq. 11),
    within_limits, poses_deg; in a cell also feasible_lower_bound and feasible_gap (exact over the feasible
    candidates and the plan's own poses), feasible (every pose checked again at the printed digits), min_clearance_m
    and clearance_m (each printed pose's smallest distance [m], space-separated) with closest (the pair of each,
    ';'-separated)."""
    from ..planning.plans import best_plan
    from ..model.workcell import clearance

    prob = study.problem("ot", m)
    plan = best_plan(prob, design, seed, pool)
    summ = plan_summary(study, plan.poses_deg)
    ot = float(summ["O_t"])
    bound = (continuum or design).lower_bound(m, study.sigma)
    row = {"m": m, "O_t": ot, "rms_m": float(np.sqrt(ot)), "chi": float(summ["chi"]), "lower_bound": bound,
           "gap": ot / bound - 1.0}
    q = np.radians(plan.poses_deg)
    if study.robot.cell is not None:
        fb = design.bound_with(study.problem("ot"), q, m, study.sigma)
        fb = fb if continuum is None else max(fb, bound)  # the joint-space bound holds for these plans too (api)
        row |= {"feasible_lower_bound": fb, "feasible_gap": ot / fb - 1.0}
    row |= {e: float(summ[e]) for e in study.robot.joint_columns("E_dk")}
    row["within_limits"] = not study.robot.outside_limits(q).any()
    if study.robot.cell is not None:  # checked again at the printed digits: the poses a lab sends the robot to
        q = np.radians(parse_plan(format_plan(plan.poses_deg)))
        c, closest = clearance(study.robot, q)
        row |= {"feasible": bool(prob.feasible(q).all()), "min_clearance_m": float(np.min(c)),
                "clearance_m": " ".join(f"{v:.6f}" for v in c), "closest": ";".join(closest)}
    row["poses_deg"] = format_plan(plan.poses_deg)
    return row


def best_plan_row(study: Study, m: int, seed: int, design, extra_starts=(), pool=None) -> dict:
    """The best m-pose plan for O_t (plan (iv)) with its criteria and the certified bound, as one row:
    m, O_t (eq. 16), rms_m = sqrt(O_t) (the RMS compensation error at the test pose, in the unit of sigma),
    chi (eq. 27), lower_bound, gap, E_dk1.. (eq. 11), within_limits, poses_deg. Any robot. pool: the candidate
    poses (N, n) [rad] of the exchange (default: :func:`stiffcal.planning.plans.optimise_plan`'s own)."""
    from ..planning.plans import design_starts, optimise_plan

    prob = study.problem("ot", m)
    plan = optimise_plan(prob, pool=pool, starts=[*design_starts(prob, design, m), *extra_starts], seed=seed)
    summ = plan_summary(study, plan.poses_deg)
    bound = design.lower_bound(m, study.sigma)
    row = {"m": m, "O_t": plan.loss, "rms_m": float(np.sqrt(plan.loss)), "chi": float(summ["chi"]),
           "lower_bound": bound, "gap": plan.loss / bound - 1.0}
    row |= {e: float(summ[e]) for e in study.robot.joint_columns("E_dk")}
    row["within_limits"] = not study.robot.outside_limits(np.radians(plan.poses_deg)).any()
    row["poses_deg"] = format_plan(plan.poses_deg)
    return row


def ot_versus_m(study: Study, ms, seed: int, design=None) -> pd.DataFrame:
    """Best O_t (plan (iv)) for each number of poses m, beside the certified bound and the repeated
    single optimum (plan (i), O_t(1)/m). Columns: m, O_t, lower_bound, gap, O_t_repeat, gain_vs_repeat."""
    from ..planning.certificate import approximate_design

    design = design or approximate_design(study.problem("ot", 1))
    single = single_ot_pose(study)
    ot1 = float(plan_summary(study, single[None])["O_t"])
    rows = []
    for m in ms:
        r = best_plan_row(study, m, seed, design, [np.repeat(single[None], m, 0)])
        rows.append({"m": m, "O_t": r["O_t"], "lower_bound": r["lower_bound"], "gap": r["gap"],
                     "O_t_repeat": ot1 / m, "gain_vs_repeat": (ot1 / m) / r["O_t"], "poses_deg": r["poses_deg"]})
    return pd.DataFrame(rows)


def phi_map(study: Study, design, step_deg: float = 2.0) -> pd.DataFrame:
    """phi(x, xi) / Phi(xi) over the (q1, q2) plane for the approximate design xi (2-joint robots).

    design: a :class:`stiffcal.planning.certificate.ApproximateDesign`. Columns q1_deg, q2_deg, ratio.
    """
    g = np.arange(-180.0, 180.0, step_deg)
    Q1, Q2 = np.meshgrid(g, g, indexing="ij")
    prob = study.problem("ot")
    X = np.radians(design.support_deg)
    M = np.einsum("k,kij->ij", design.weights, information_matrix(prob.rows(X)[:, None]))
    C = np.linalg.inv(M) @ prob.At.T
    A = prob.rows(np.radians(np.stack([Q1, Q2], -1)))
    ratio = np.sum((A @ C) ** 2, axis=(-2, -1)) / design.phi
    return pd.DataFrame({"q1_deg": Q1.ravel(), "q2_deg": Q2.ravel(), "ratio": ratio.ravel()})
