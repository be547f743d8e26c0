"""Every result number the seed paper prints (Tables 2-5 and its text, 113) beside ours: each reproduces to
its printed digits, or it differs for a reason that holds for its whole row. Everything is checked here
with the test's own numpy code from the paper's equations (eqs. 4, 11, 16, 17, 27 and Table 1), not with
the code that computed the comparison."""

import copy
import re

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import minimize, minimize_scalar

from stiffcal.model import criteria
from stiffcal.planning import maps
from stiffcal.paper import reproduction
from stiffcal.paper import tables
from stiffcal.planning.study import study_from_config

L = np.array([0.6, 0.4])
F = np.array([0.0, -1.0])
QT_DEG = np.array([60.0, 30.0])
RTOL = reproduction.FLAT_RTOL  # the definition of an optimal pose the reasons use


# --- the paper's equations, our own code ---------------------------------------------------------------

def A_of(q_deg):
    """Observation matrix of eq. 4 for the paper's arm: (..., 2) [deg] -> (..., 2, 2)."""
    q = np.radians(np.asarray(q_deg, float))
    c = np.cumsum(q, -1)
    x, y = L * np.cos(c), L * np.sin(c)
    J = np.stack([-np.flip(np.cumsum(np.flip(y, -1), -1), -1), np.flip(np.cumsum(np.flip(x, -1), -1), -1)], -2)
    return J * np.einsum("...dj,d->...j", J, F)[..., None, :]


AT = A_of(QT_DEG)


def summary(plan_deg):
    """O_t (eq. 16), chi (eq. 27), E[dk_i^2] (eq. 11) and dk_i of plans (..., m, 2) [deg], sigma = 1."""
    plan = np.asarray(plan_deg, float)
    A = A_of(plan)
    M = np.einsum("...mdi,...mdj->...ij", A, A)
    det = M[..., 0, 0] * M[..., 1, 1] - M[..., 0, 1] ** 2
    ok = det > 1e-12 * (M[..., 0, 0] + M[..., 1, 1]) ** 2
    adj = np.stack([np.stack([M[..., 1, 1], -M[..., 0, 1]], -1), np.stack([-M[..., 0, 1], M[..., 0, 0]], -1)], -2)
    Minv = adj / np.where(ok, det, 1.0)[..., None, None]
    ot = np.where(ok, np.einsum("ij,...jk,ik->...", AT, Minv, AT), np.inf)
    e1, e2 = np.where(ok, Minv[..., 0, 0], np.inf), np.where(ok, Minv[..., 1, 1], np.inf)
    m = plan.shape[-2]
    return {"O_t": ot, "chi": (2.0 / m) / ot, "E_dk1": e1, "E_dk2": e2, "dk1": np.sqrt(e1), "dk2": np.sqrt(e2)}


def loss(key, pose_deg):
    """Table 1 criteria (and O_t) of single poses (..., 2) [deg], as quantities to minimise."""
    A = A_of(pose_deg)
    s = np.linalg.svd(A, compute_uv=False)  # descending
    sm = summary(np.asarray(pose_deg, float)[..., None, :])
    return {"a": sm["E_dk1"] + sm["E_dk2"], "d": -(s[..., 0] * s[..., 1]) ** 2, "mdc": np.maximum(sm["E_dk1"], sm["E_dk2"]),
            "o1": -np.sqrt(s[..., 0] * s[..., 1]), "o2": -s[..., 1] / s[..., 0], "o4": -s[..., 1] ** 2 / s[..., 0],
            "o3": -s[..., 1], "ot": sm["O_t"]}[key]


def rounds(value, printed):
    """Our own rounding test: value rounds to the printed string at its printed decimals."""
    if printed == "inf":
        return bool(np.isinf(value))
    if printed.startswith("<"):
        return value < float(printed[1:])
    dec = len(printed.split(".")[1]) if "." in printed else 0
    return bool(np.isfinite(value)) and abs(value - float(printed)) <= 0.5 * 10.0 ** -dec * (1 + 1e-9)


def parse(text):
    text = re.sub(r"\s*\(.*\)$", "", str(text))
    return np.array([[float(v) for v in p.split()] for p in text.split(";")])


def half(pose):
    return 0.5 * 10.0 ** -max(len(v.split(".")[1]) if "." in v else 0 for v in pose)


def wrap(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


# --- the comparison --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def results(paper_study, paper_config, root):
    t2 = tables.table2(paper_study)
    t3 = tables.table3(paper_study, t2)
    t4 = tables.plans_table(paper_study, 2, seed=0)
    t5 = tables.plans_table(paper_study, 3, seed=0)
    printed = reproduction.load_printed(root / "paper/printed_values.yaml")
    cfg = copy.deepcopy(paper_config)  # a coarse map of the paper's arm, for the Figure 6 numbers
    cfg["maps"].update(step_deg=15.0, statistics_steps_deg=[30.0, 15.0])
    study7 = [s for s in maps.map_studies(cfg, root) if s.figure == 7]
    mp = maps.solve_map(study7[0].link_ratio, study7[0].force_deg, 15.0)
    stats = maps.statistics_table({study7[0].name: mp}, study7, [30.0, 15.0],
                                  {k: float(v) for k, v in printed["figure6"].items()})
    cmp = reproduction.comparison_table(paper_study, t2, t3, t4, t5, printed, stats, seed=0)
    return {"t2": t2.set_index("criterion"), "t3": t3.set_index("row"), "t4": t4.set_index("plan"),
            "t5": t5.set_index("plan"), "printed": printed, "cmp": cmp, "stats": stats}


def test_every_printed_number_is_compared_once(results):
    """113 numbers as the paper prints them: Table 2 has 7 rows of 4 (the row "O2, O4" once), Table 3 6 rows
    of 4, Tables 4-5 O_t, E[dk1^2], E[dk2^2] and every pose angle (22 and 24), and 15 in the text."""
    pr, cmp = results["printed"], results["cmp"]
    expected = {("table2", r, q) for r, e in pr["table2"].items() for q in e if q != "criteria"}
    expected |= {("table3", r, q) for r, e in pr["table3"].items() for q in e if q != "criteria"}
    for t in ("table4", "table5"):
        for r, e in pr[t].items():
            expected |= {(t, r, q) for q in ("O_t", "E_dk1", "E_dk2")}
            expected |= {(t, r, f"pose{k + 1}_q{j + 1}") for k, p in enumerate(e["poses_deg"]) for j in range(len(p))}
    expected |= {("text", k, "value") for k in pr["text"]}
    got = list(map(tuple, cmp[["table", "row", "quantity"]].to_numpy()))
    assert len(got) == len(set(got)) == 113 and set(got) == expected
    assert cmp.table.value_counts().to_dict() == {"table2": 28, "table3": 24, "table4": 22, "table5": 24, "text": 15}
    s = reproduction.summary(cmp)
    assert s["total"] == 113 and s["reproduced"] + s["differs"] == 113
    assert (cmp.status == "reproduced").sum() == s["reproduced"]


#: the printed numbers that do not reproduce to their printed digits, each with its reason
DIFFERS = {
    ("table2", "a", "E_dk1"): "flat-optimum", ("table2", "a", "E_dk2"): "flat-optimum",
    ("table2", "d", "q1_deg"): "last-digit", ("table2", "d", "E_dk2"): "last-digit",
    ("table2", "mdc", "q1_deg"): "flat-optimum", ("table2", "mdc", "q2_deg"): "flat-optimum",
    ("table2", "o1", "q1_deg"): "last-digit", ("table2", "o1", "E_dk2"): "last-digit",
    ("table2", "o2_o4", "q2_deg"): "last-digit",
    ("table2", "o3", "E_dk1"): "flat-optimum", ("table2", "o3", "E_dk2"): "flat-optimum",
    ("table3", "ot_star", "dk1"): "table3_ot_star_dk1",
    ("table3", "a", "chi"): "table3_a", ("table3", "a", "O_t"): "table3_a",
    ("table3", "a", "dk1"): "flat-optimum", ("table3", "a", "dk2"): "flat-optimum",
    ("table3", "d", "chi"): "table3_d_chi", ("table3", "d", "dk2"): "last-digit",
    **{("table3", "o3", q): "flat-optimum" for q in ("chi", "dk1", "dk2", "O_t")},
    ("table3", "ot", "dk2"): "printed-pose",
    ("table4", "i", "E_dk2"): "flat-optimum", ("table5", "i", "E_dk2"): "flat-optimum",
    ("table5", "iii", "E_dk2"): "flat-optimum",
    **{(t, "ii", q): "flat-family" for t in ("table4", "table5") for q in ("pose1_q1", "E_dk2")},
    ("text", "fig6_mean", "value"): "figure6_mean", ("text", "fig6_max", "value"): "figure6_max",
}


def test_statuses_and_reasons(results):
    cmp = results["cmp"]
    got = {tuple(r[:3]): r[4] for r in cmp[cmp.status != "reproduced"][["table", "row", "quantity", "status",
                                                                           "reason"]].to_numpy()}
    assert got == DIFFERS
    assert set(cmp.status) == {"reproduced", "differs"}
    notes = results["printed"]["notes"]
    assert all(r in notes or r in ("flat-optimum", "last-digit", "printed-pose", "flat-family") for r in got.values())


def test_reproduced_numbers_of_tables_2_3_are_the_equations_at_our_poses(results):
    """Every reproduced non-pose number of Tables 2-3, recomputed at our pose with our own numpy."""
    cmp, pr = results["cmp"], results["printed"]
    for _, r in cmp[(cmp.status == "reproduced") & cmp.table.isin(["table2", "table3"])].iterrows():
        if r.quantity.endswith("_deg"):
            assert rounds(float(r.ours), r.printed)
            continue
        keys = pr[r.table][r.row].get("criteria", [r.row])
        for key in keys:
            if r.table == "table3" and r.row == "ot_star":
                pose = QT_DEG
            else:
                pose = results["t2"].loc[key, ["q1_deg", "q2_deg"]].to_numpy(float)
            v = summary(pose[None])[r.quantity]
            if r.table == "table3" and r.row == "ot_star" and r.quantity in ("O_t", "chi"):
                v = {"O_t": 2.0, "chi": 1.0}[r.quantity]  # eq. 17: O_t* = n sigma^2 / m; chi = O_t*/O_t*
            assert rounds(float(v), r.printed), (r.table, r.row, r.quantity, v)
            if key == keys[0]:  # ours is the first criterion's (the others' are checked to round alike)
                assert np.isinf(v) and np.isinf(r.ours) or v == pytest.approx(float(r.ours), rel=1e-9)


def test_reproduced_numbers_of_tables_4_5_are_the_equations_for_our_plans(results):
    cmp = results["cmp"]
    for _, r in cmp[(cmp.status == "reproduced") & cmp.table.isin(["table4", "table5"])].iterrows():
        plan = parse(results["t4" if r.table == "table4" else "t5"].loc[r.row, "poses_deg"])
        if r.quantity.startswith("pose"):
            continue  # the poses: below
        v = float(summary(plan)[r.quantity])
        assert rounds(v, r.printed) and v == pytest.approx(float(r.ours), rel=1e-5), (r.table, r.row, r.quantity)


def _copies(q):
    """The symmetric copies of pose q [deg] for the paper's force (phi = -90 deg): half-turn of the arm
    (q1 + 180: the force reversed relative to the arm, same A^T A) and mirror about the force line."""
    out = []
    for a in (q, [q[0] + 180, q[1]]):
        out += [a, [2 * -90.0 - a[0], -a[1]]]
    return wrap(np.array(out, float))


def test_printed_poses_of_tables_4_5_are_our_poses_or_copies_with_the_same_information(results):
    """A reproduced printed pose rounds to one of our poses or to a copy of one, and our own numpy confirms
    that copy has exactly the information of our pose (the same A^T A)."""
    cmp, pr = results["cmp"], results["printed"]
    for t in ("table4", "table5"):
        for key, e in pr[t].items():
            plan = parse(results["t" + t[-1]].loc[key, "poses_deg"])
            for k, pose in enumerate(e["poses_deg"]):
                st = cmp[(cmp.table == t) & (cmp.row == key) & cmp.quantity.str.startswith(f"pose{k + 1}_")]
                if (st.status != "reproduced").any():
                    continue
                p = np.array([float(v) for v in pose])
                found = False
                for q in plan:
                    Mq = np.einsum("di,dj->ij", A_of(q), A_of(q))
                    for c in _copies(q):
                        if np.all(np.abs(wrap(c - p)) <= half(pose) + 1e-4):  # the CSV rounds ours to 1e-4
                            Mc = np.einsum("di,dj->ij", A_of(c), A_of(c))
                            assert np.abs(Mc - Mq).max() < 1e-12 * np.abs(Mq).max()
                            found = True
                assert found, (t, key, pose)


# --- every reason holds for its whole row ---------------------------------------------------------------

#: the paper's lines: the printed rows computed at one pose, the criteria that pose is optimal for, the pose
LINES = {
    "a": (["table2/a", "table3/a"], ["a"]),
    "d": (["table2/d", "table2/o1", "table3/d"], ["d", "o1"]),
    "mdc": (["table2/mdc", "table3/mdc"], ["mdc"]),
    "o2_o4": (["table2/o2_o4"], ["o2", "o4"]),
    "o3": (["table2/o3", "table3/o3"], ["o3"]),
    "ot": (["table3/ot"], ["ot"]),
}


def _line_pose(pr, name):
    src = pr["ot_pose_deg"] if name == "ot" else pr["table2"][name]
    return [src["q1_deg"], src["q2_deg"]]


def _line_numbers(pr, rows):
    """(quantity, printed) of every number of the line that no note explains."""
    out = []
    for tr in rows:
        t, r = tr.split("/")
        for q, v in pr[t][r].items():
            if q != "criteria" and not q.endswith("_deg") and f"{t}/{r}/{q}" not in pr["explain"]:
                out.append((q, v))
    return out


def _own_optimum(key, pose):
    """Our own optimum of criterion key, polished from ``pose`` (Nelder-Mead on our own formula)."""
    f = lambda x: float(loss(key, x))  # noqa: E731
    r = minimize(f, pose, method="Nelder-Mead", options=dict(xatol=1e-11, fatol=1e-16, maxiter=4000))
    return min(r.fun, f(pose))


@pytest.mark.parametrize("name", sorted(LINES))
def test_line_witness_gives_every_printed_number_of_the_row(name, results):
    """The differing numbers of a line share one witness pose; with our own numpy it gives every printed
    number of the line (all rows, less the noted ones) together, rounds to the printed pose (last-digit: one
    angle one unit off) and is within FLAT_RTOL of the optimum of every criterion of the line."""
    pr, cmp = results["printed"], results["cmp"]
    rows, keys = LINES[name]
    mine = cmp[cmp.apply(lambda r: f"{r.table}/{r.row}" in rows, axis=1)]
    explained = mine[(mine.status == "differs") & mine.reason.isin(["flat-optimum", "last-digit", "printed-pose"])]
    if explained.empty:
        pytest.skip(f"line {name}: every number reproduces or is noted")
    assert explained.witness_deg.nunique() == 1 and explained.reason.nunique() == 1
    reason, text = explained.reason.iloc[0], explained.witness_deg.iloc[0]
    w = parse(text)[0]
    vals = summary(w[None, None])
    for q, v in _line_numbers(pr, rows):
        assert rounds(float(vals[q][0]), v), (name, q, float(vals[q][0]), v)
    pose = _line_pose(pr, name)
    target = np.array([float(v) for v in pose])
    if reason == "last-digit":
        j, sign = re.search(r"printed q(\d) ([+-])1 unit", text).groups()
        target[int(j) - 1] += (1 if sign == "+" else -1) * 2 * half(pose)
    else:
        assert "printed" not in text
    assert np.all(np.abs(w - target) < half(pose)), (w, target)
    if reason == "printed-pose":
        np.testing.assert_allclose(w, target)
    for key in keys:
        ours = results["t2"].loc[key if key != "ot" else "ot", ["q1_deg", "q2_deg"]].to_numpy(float)
        best = _own_optimum(key, ours)
        assert (float(loss(key, w)) - best) / abs(best) <= RTOL, key


def _no_pose_in_box_gives(constraints, pose, points=201, safety=2.0):
    """True when, provably, no pose of the rounding box of ``pose`` gives every (quantity, printed) together:
    on a grid of cell centres, each cell is ruled out by a constraint that misses its printed interval by
    more than a bound of the change across the cell (the largest finite-difference slope on the grid times
    ``safety``)."""
    p = np.array([float(v) for v in pose])
    h = half(pose)
    ax = (np.arange(points) + 0.5) / points * 2 * h - h
    Q = np.stack(np.meshgrid(p[0] + ax, p[1] + ax, indexing="ij"), -1)
    vals = summary(Q[..., None, :])
    step = 2 * h / points
    possible = np.ones(Q.shape[:2], bool)
    for q, v in constraints:
        f = vals[q]
        slope = max(np.abs(np.diff(f, axis=0)).max(), np.abs(np.diff(f, axis=1)).max()) / step
        change = safety * slope * step / np.sqrt(2)
        dec = len(v.split(".")[1]) if "." in v else 0
        possible &= np.abs(f - float(v)) <= 0.5 * 10.0 ** -dec + change
    return not possible.any()


@pytest.mark.parametrize("name", ["d", "o2_o4"])
def test_last_digit_rows_have_no_pose_in_the_printed_box(name, results):
    """For a last-digit line, no pose that rounds to the printed pose gives the row's printed numbers
    together (proved on a grid with a slope bound), while the witness one unit off does (test above):
    e.g. no pose that prints as (-43.72, 62.93) gives E[dk1^2] = 5.3208 with E[dk2^2] = 113.3093."""
    pr = results["printed"]
    assert _no_pose_in_box_gives(_line_numbers(pr, LINES[name][0]), _line_pose(pr, name))
    if name == "d":
        pose = _line_pose(pr, "d")
        assert _no_pose_in_box_gives([("E_dk1", "5.3208"), ("E_dk2", "113.3093")], pose)


def test_rounding_box_alone_no_longer_explains_the_d_row(results):
    """Number by number the D row's E[dk2^2] lies within the range over the printed rounding box (the old,
    per-number reason), but that is not a reason for the row: the joint check above fails there."""
    cmp = results["cmp"]
    r = cmp[(cmp.table == "table2") & (cmp.row == "d") & (cmp.quantity == "E_dk2")].iloc[0]
    assert r.range_low <= float(r.printed) <= r.range_high and r.reason == "last-digit"


@pytest.mark.parametrize("table", ["table4", "table5"])
@pytest.mark.parametrize("key", ["i", "ii", "iii"])
def test_plan_witness_gives_every_printed_number_of_the_row(table, key, results):
    """A plan row's witness has the row's structure, its printed poses round to the paper's, it gives every
    printed number of the row together and its O_t is within FLAT_RTOL of ours (our own numpy)."""
    cmp, pr = results["cmp"], results["printed"]
    mine = cmp[(cmp.table == table) & (cmp.row == key) & (cmp.status == "differs")]
    if mine.empty:
        pytest.skip("the row reproduces")
    assert mine.witness_deg.nunique() == 1
    w = parse(mine.witness_deg.iloc[0])
    m = 2 if table == "table4" else 3
    assert w.shape == (m, 2)
    vals = summary(w[None])
    for q in ("O_t", "E_dk1", "E_dk2"):
        assert rounds(float(vals[q][0]), pr[table][key][q]), (q, float(vals[q][0]))
    for pose in pr[table][key]["poses_deg"]:
        p = np.array([float(v) for v in pose])
        assert np.any(np.all(np.abs(wrap(w - p)) < half(pose), axis=-1)), pose
    ours = float(summary(parse(results["t" + table[-1]].loc[key, "poses_deg"])[None])["O_t"][0])
    assert (float(vals["O_t"][0]) - ours) / ours <= RTOL
    structure = {"i": np.ptp(w, axis=0).max(), "ii": np.ptp(w[:, 1]), "iii": np.ptp(w[:, 0])}[key]
    assert structure < 1e-9


def test_flat_family_of_plan_ii(results):
    """Plan (ii), m = 2, scanned with our own numpy: pin one pose's q1 on a grid, optimise the other's (q2
    at the single optimum). A whole family reaches the optimal O_t; over it E[dk2^2] is never below ours
    (the range's low end) and grows without bound toward the pose with link 2 parallel to the force, which
    cannot identify k2 yet has the same O_t; the printed 78.8330 lies within the range."""
    cmp = results["cmp"]
    q1o, q2 = results["t2"].loc["ot", ["q1_deg", "q2_deg"]].to_numpy(float)
    opt = float(summary(np.array([[[q1o, q2]]]))["O_t"][0]) / 2

    def ot_pair(a, b):
        return float(summary(np.array([[[a, q2], [b, q2]]]))["O_t"][0])

    members = []
    grid = np.arange(-180.0, 180.0, 0.1)
    for a in np.arange(-90.0, 90.0, 1.0):
        ot = summary(np.stack([np.broadcast_to([a, q2], (len(grid), 2)), np.column_stack([grid, np.full_like(grid, q2)])], 1))["O_t"]
        b0 = grid[np.argmin(ot)]
        r = minimize_scalar(lambda b: ot_pair(a, b), bounds=(b0 - 0.2, b0 + 0.2), method="bounded",
                            options=dict(xatol=1e-10))
        if r.fun <= opt * (1 + 1e-9):
            members.append(float(summary(np.array([[[a, q2], [r.x, q2]]]))["E_dk2"][0]))
    row = cmp[(cmp.table == "table4") & (cmp.row == "ii") & (cmp.quantity == "E_dk2")].iloc[0]
    assert len(members) > 30  # a family, not one plan
    assert min(members) >= row.range_low * (1 - 1e-6)
    assert min(members) <= row.range_low * 1.01
    assert max(members) > 3 * row.range_low and np.isinf(row.range_high)
    assert row.range_low <= float(row.printed) <= max(members)
    # the family's far end: link 2 parallel to the force (q1 + q2 = 90 deg) identifies k1 alone, same O_t
    qs = 90.0 - q2
    A = A_of([qs, q2])
    assert np.abs(A[:, 1]).max() < 1e-12
    ot_s = np.sum(AT[:, 0] ** 2) / (2 * np.sum(A[:, 0] ** 2))
    assert ot_s == pytest.approx(opt, rel=1e-9)


# --- the notes ----------------------------------------------------------------------------------------

def _edk1_to_chi(e):
    """chi of eq. 27 from E[dk1^2] at this test pose, where A_t's second column is zero."""
    assert np.abs(AT[:, 1]).max() < 1e-15
    return 2.0 / (np.sum(AT[:, 0] ** 2) * np.asarray(e, float))


def test_table3_a_row_is_inconsistent_with_itself_and_with_table2(results):
    """O_t = |a_t1|^2 E[dk1^2] at every plan: the row's dk1 (3.7056, any value that rounds to it) and Table
    2's E[dk1^2] (13.7315) give O_t in intervals that exclude the printed 1.1736 (and chi 1.7041)."""
    pr = results["printed"]
    c = np.sum(AT[:, 0] ** 2)
    for e_lo, e_hi in ((3.70555 ** 2, 3.70565 ** 2), (13.73145, 13.73155)):
        assert not c * e_lo - 0.00005 <= float(pr["table3"]["a"]["O_t"]) <= c * e_hi + 0.00005
        lo, hi = sorted(_edk1_to_chi([e_lo, e_hi]))
        assert not lo - 0.00005 <= float(pr["table3"]["a"]["chi"]) <= hi + 0.00005
    assert float(pr["table3"]["a"]["chi"]) == pytest.approx(2 / float(pr["table3"]["a"]["O_t"]), abs=1e-4)


def test_table3_d_chi_contradicts_table2(results):
    """Table 2's E[dk1^2] = 5.3208 (any value rounding to it) gives chi from 4.46348 to 4.46356 (ours,
    4.4635, among them), never the printed 4.4632, which needs E[dk1^2] >= 5.3211."""
    lo, hi = sorted(_edk1_to_chi([5.32075, 5.32085]))
    assert 4.46347 < lo < 4.46349 and 4.46355 < hi < 4.46357
    assert lo > 4.46325
    e_needed = 2.0 / (np.sum(AT[:, 0] ** 2) * 4.46325)
    assert e_needed > 5.32105
    assert rounds(float(results["cmp"].set_index(["table", "row", "quantity"]).loc[("table3", "d", "chi"), "ours"]), "4.4635")


def test_table3_ot_star_dk1_is_the_force_direction_component_only(results):
    """The printed 11.1111 is 1/|a_t1,y|: the std of k1 fitted from the y displacement alone; ours is
    1/|a_t1| from both measured coordinates."""
    assert rounds(1.0 / abs(AT[1, 0]), results["printed"]["table3"]["ot_star"]["dk1"])
    ours = results["t3"].loc["ot_star", "dk1"]
    assert ours == pytest.approx(1.0 / np.linalg.norm(AT[:, 0]), rel=1e-9)


def test_figure6_chi_is_unbounded_and_its_mean_diverges(results):
    """Next to the test pose (90, 0) (arm along the force line, A_t = 0), chi >= 2 / O_t of any fixed
    measurement pose grows like 1/r^2, also where A_t has full rank (q2* != 0): chi has no maximum (10 is
    exceeded a thousand times over) and its integral over the plane diverges. The grid means of the map
    statistics grow with the resolution."""
    x = results["t2"].loc["ot", ["q1_deg", "q2_deg"]].to_numpy(float)
    A = A_of(x)
    Minv = np.linalg.inv(A.T @ A)
    for theta in np.radians([20, 60, 90, 160, 200, 300]):  # not along q1 + q2 = 90 deg (rank one)
        scaled = []
        for r in (1e-1, 1e-2, 1e-3):
            At = A_of([90 + r * np.cos(theta), r * np.sin(theta)])
            assert np.linalg.matrix_rank(At) == 2
            chi_lb = 2.0 / np.trace(At @ Minv @ At.T)
            scaled.append(chi_lb * r ** 2)
        assert chi_lb > 1e4
        assert max(scaled) / min(scaled) < 1.01  # chi >= c / r^2
    cmp = results["cmp"].set_index(["table", "row", "quantity"])
    mean = cmp.loc[("text", "fig6_mean", "value")]
    st = results["stats"]
    means = st[(st.statistic == "mean") & st.paper.notna()].sort_values("grid_deg")
    assert means.ours.is_monotonic_decreasing  # finer grids, larger means
    assert mean.range_low == pytest.approx(means.ours.min()) and mean.range_high == pytest.approx(means.ours.max())


# --- the text -----------------------------------------------------------------------------------------

def _own_value(results, ref, source):
    table, row, qty = ref.split("/")
    if source == "paper":
        return float(results["printed"][table][row][qty])
    if table == "table3":
        pose = results["t2"].loc[row, ["q1_deg", "q2_deg"]].to_numpy(float)[None, None]
    else:
        pose = parse(results["t" + table[-1]].loc[row, "poses_deg"])[None]
    return float(summary(pose)[qty][0])


def _own_text(kind, x):
    return {"chi": lambda: x[0], "rms_ratio": lambda: np.sqrt(x[0] / x[1]),
            "rms_reduction": lambda: 100 * (1 - np.sqrt(x[1] / x[0])), "ms_ratio": lambda: x[0] / x[1],
            "rms": lambda: np.sqrt(x[0])}[kind]()


def test_text_numbers_are_the_stated_quantities_of_our_plans(results):
    """Each text number recomputed with our own numpy from our plans (and from the paper's printed table
    numbers): ours agrees with the comparison, and the printed number is what it rounds to. Where the text
    states a ratio of RMS errors, the ratio of mean squares does not round to it (shown beside)."""
    cmp = results["cmp"].set_index(["table", "row", "quantity"])
    rms_only = []
    for key, e in results["printed"]["text"].items():
        r = cmp.loc[("text", key, "value")]
        if e["kind"] == "map_statistic":
            continue
        ours = _own_text(e["kind"], [_own_value(results, ref, "ours") for ref in e["of"]])
        paper = _own_text(e["kind"], [_own_value(results, ref, "paper") for ref in e["of"]])
        assert ours == pytest.approx(float(r.ours), rel=1e-5, abs=1e-4) and paper == pytest.approx(float(r.from_paper), rel=1e-9)
        assert rounds(ours, e["value"]) and r.status == "reproduced", key
        if e["kind"] in ("rms_ratio", "rms_reduction") and not rounds(float(r.ours_ms), e["value"]):
            rms_only.append(key)
    assert set(rms_only) == {"iv_8pc", "m2_factor", "m2_usual", "iv_10pc", "m3_factor", "m3_usual"}


def test_text_numbers_against_other_plans(results):
    """'by 8 % with regard to all other cases' holds against every other plan of Table 4; Table 5's 'by 10 %
    with regard to other cases' only against (i) and (ii): against (iii) the RMS error is 6.6 % lower."""
    cmp = results["cmp"].set_index(["table", "row", "quantity"])
    for key, table, holds in (("iv_8pc", "t4", True), ("iv_10pc", "t5", False)):
        ot = {k: float(summary(parse(results[table].loc[k, "poses_deg"])[None])["O_t"][0]) for k in ("i", "ii", "iii", "iv")}
        red = [100 * (1 - np.sqrt(ot["iv"] / ot[k])) for k in ("i", "ii", "iii")]
        r = cmp.loc[("text", key, "value")]
        assert min(red) == pytest.approx(r.range_low, rel=1e-5) and max(red) == pytest.approx(r.range_high, rel=1e-5)
        assert all(rounds(v, results["printed"]["text"][key]["value"]) for v in red) == holds


# --- O2 -----------------------------------------------------------------------------------------------

def test_o2_both_forms_peak_at_the_same_pose(results):
    """Table 1 names O2 the inverse condition number (sigma_s / sigma_1) and prints sigma_s^2 / sigma_1^3.
    A brute force over the joint space (0.5 deg, then polished) finds the same global maximisers for both:
    the isotropic poses, which are our O2 pose and its symmetric copies."""
    g = np.arange(-180.0, 180.0, 0.5)
    Q = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    s = np.linalg.svd(A_of(Q), compute_uv=False)
    ours = results["t2"].loc["o2", ["q1_deg", "q2_deg"]].to_numpy(float)
    copies = [ours, [-ours[0], -ours[1]], [180 - ours[0], -ours[1]], [ours[0] - 180, ours[1]]]
    copies += [[2 * -90 - c[0], -c[1]] for c in copies]  # mirrors about the force line (phi = -90 deg)
    copies = wrap(np.array(copies, float))
    for form in (lambda s: s[..., 1] / s[..., 0], lambda s: s[..., 1] ** 2 / s[..., 0] ** 3):
        v = np.nan_to_num(form(s), nan=-1.0)
        start = Q[np.argmax(v)]
        f = lambda x: -float(np.nan_to_num(form(np.linalg.svd(A_of(x), compute_uv=False)), nan=1.0))  # noqa: E731
        best = minimize(f, start, method="Nelder-Mead", options=dict(xatol=1e-10, fatol=1e-15)).x
        assert np.min(np.max(np.abs(wrap(copies - best)), axis=-1)) < 1e-3, best
        assert -f(ours) >= v.max() and -f(ours) == pytest.approx(-f(best), rel=1e-9)
        top = Q[v >= v.max() * (1 - 1e-3)]  # every near-maximal grid pose is next to a copy of ours
        assert np.all(np.min(np.max(np.abs(wrap(top[:, None] - copies[None])), -1), 1) < 2.0)
    sv = np.linalg.svd(A_of(ours), compute_uv=False)
    assert sv[1] / sv[0] == pytest.approx(1.0, abs=1e-9)  # isotropic


# --- eq. 27 and determinism -----------------------------------------------------------------------------

def test_table3_chi_is_eq27_of_o_t(results):
    t3 = results["t3"]
    np.testing.assert_allclose(t3.chi, np.where(np.isinf(t3.O_t), 0, criteria.o_t_star(2, 1) / t3.O_t))


def test_comparison_columns(results, tmp_path):
    """The CSV has the documented columns (the byte-identical rerun is checked by tests/test_workflow.py)."""
    tables.write_csv(results["cmp"], tmp_path / "a.csv")
    assert list(pd.read_csv(tmp_path / "a.csv").columns) == reproduction.COLUMNS


def test_a_study_with_fewer_criteria_compares_what_it_computed(paper_config, root, results):
    """A fresh user's config with `study.criteria: [a, ot]` crashed the paper comparison (KeyError 'd': a number
    of the paper's text rests on the D row). Every printed number is still listed once; those resting on rows this
    configuration did not compute are 'not computed' with the reason, and every number the full comparison
    reproduced from the rows kept is reproduced here too."""
    cfg = copy.deepcopy(paper_config)
    cfg["study"]["criteria"] = ["a", "ot"]
    study = study_from_config(cfg, root)
    t2 = tables.table2(study)
    t3 = tables.table3(study, t2)
    t4, t5 = (results[k].reset_index() for k in ("t4", "t5"))
    cmp = reproduction.comparison_table(study, t2, t3, t4, t5, results["printed"], results["stats"], seed=0)
    full = results["cmp"]
    assert len(cmp) == len(full) and list(cmp.columns) == reproduction.COLUMNS
    gone = cmp.status == "not computed"
    assert gone.any() and (cmp[gone].table == "text").any()
    assert cmp[gone & (cmp.table == "text")].reason.str.contains("study.criteria").all()
    kept = cmp.status != "not computed"
    same = cmp[kept].merge(full, on=["table", "row", "quantity"], suffixes=("", "_full"))
    assert (same.status == same.status_full).all()
