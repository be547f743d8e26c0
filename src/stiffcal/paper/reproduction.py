"""Our numbers beside every result number the paper prints, with a status per number.

The paper prints 113 result numbers (``paper/printed_values.yaml`` counts them): 98 in Tables 2-5 (the
row "O2, O4" of Table 2 once, each pose angle one number) and 15 in its text. A printed number is
*reproduced* when ours, rounded to the printed number of decimals, equals it (``inf`` matches ``inf``;
"less than 1 %" when ours is below 1). Otherwise it *differs*, and its reason holds for the whole row
it belongs to, never for the number alone:

* A *line* is every number the paper computed from one pose or plan: a row of Table 2 with the Table 3
  row of the same plan (the D and O1 rows of Table 2 share Table 3's "D-optimality (O1)" row; Table 3's
  O_t row is the pose printed in Table 4), or a row of Table 4 or 5. Numbers a note explains (below) are
  left out of their line.
* ``printed-pose`` -- the paper's own rounded pose (plan) gives every printed number of the line, and the
  criterion there is within ``FLAT_RTOL`` of our optimum.
* ``flat-optimum`` -- one pose (plan) that rounds to the printed one, with its criterion within
  ``FLAT_RTOL`` of our optimum (its O_t for Tables 4-5), gives every printed number of the line: the
  optimum is flat and the paper's optimiser stopped at another point of it than ours.
* ``last-digit`` -- no pose that rounds to the printed pose gives the line's numbers together, but one
  within ``FLAT_RTOL`` of the optimum whose pose prints one unit off in the last digit of one angle
  does: that printed angle is one unit off.
* ``flat-family`` (plan (ii)) -- at the paper's test pose O_t depends on k1 alone, and a whole family of
  plans with the same joints 2..n reaches the optimal O_t: a member of it whose first pose rounds to the
  printed one gives every printed number of the row, and E[dk2^2] runs over the family from ours (the
  repeated single optimum, its smallest) to infinity (:func:`q1_family`).
* a named note from ``printed_values.yaml`` (``notes:``), attached by ``explain:`` there, whose claim
  is checked numerically by ``tests/test_paper.py``;
* ``unexplained`` -- anything else (the tests require there be none).

Every computed reason comes with its *witness* (the pose or plan, and its criterion excess), so that it
can be checked independently; ``tests/test_paper.py`` re-evaluates each witness with its own code.
For the plans of Tables 4-5, a printed pose is *reproduced* when it rounds to one of our poses or to one
of its symmetric copies (``symmetric-copy``: same information, see :mod:`stiffcal.planning.plans`).
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd

from ..model import criteria
from ..planning.problem import plan_loss
from ..model.stiffness import covariance_diagonal
from ..planning.study import Study
from .tables import parse_plan, plan_summary
from ..validation import read_yaml

#: a pose whose criterion is within this relative excess of the optimum counts as optimal
FLAT_RTOL = 1e-6
#: points per joint of the grid that searches the rounding box of a printed pose for a witness
BOX_POINTS = 401
#: random plans searched in the rounding boxes of a printed plan of several poses
PLAN_SAMPLES = 20000

#: columns of the comparison table, in order
COLUMNS = ["table", "row", "quantity", "printed", "ours", "status", "reason", "meaning", "witness_deg",
           "witness_excess", "ours_at_printed_pose", "range_low", "range_high", "range_over",
           "criterion_excess_at_printed_pose", "ours_ms", "ours_rms", "from_paper"]

MEANING = {"E_dk1": "E[dk1^2] (eq. 11) [rad^2/N^2]", "E_dk2": "E[dk2^2] (eq. 11) [rad^2/N^2]",
           "dk1": "sqrt E[dk1^2] [rad/N]", "dk2": "sqrt E[dk2^2] [rad/N]", "chi": "chi = O_t*/O_t (eq. 27)",
           "O_t": "O_t (eq. 16)"}
BOX = "rounding box of the printed pose"


def load_printed(path: str | Path) -> dict:
    """Read the paper's printed values (strings as printed)."""
    return read_yaml(path)


def printed_decimals(text: str) -> int:
    """Number of decimals printed: '13.7315' -> 4, '0' -> 0, 'inf' -> 0, '<1' -> 0."""
    text = text.lstrip("<")
    exp = Decimal(text).as_tuple().exponent if text != "inf" else 0
    return max(0, -int(exp))


def half_unit(text: str) -> float:
    """Half a unit of the last printed digit: the rounding tolerance of a printed number."""
    return 0.5 * 10.0 ** -printed_decimals(text)


def matches(ours: float, printed: str) -> bool:
    """True when ``ours`` rounds to ``printed`` at the printed precision (half-unit tolerance); ``'<x'``
    when ours is below x."""
    if printed == "inf":
        return bool(np.isinf(ours))
    if not np.isfinite(ours):
        return False
    if printed.startswith("<"):
        return ours < float(printed[1:])
    return abs(ours - float(printed)) <= half_unit(printed) * (1 + 1e-9) + 1e-12


def violation(values: dict, printed: dict) -> np.ndarray:
    """How far values are from rounding to the printed numbers, in half units of each: the largest over
    quantities of |ours - printed| / half_unit (<= 1 when every one rounds to its printed number; 0 for inf
    against inf, inf for inf against a finite number). values: quantity -> (K,); printed: quantity -> str,
    or (quantity, str) pairs."""
    out = 0.0
    for q, p in (printed.items() if isinstance(printed, dict) else printed):
        v = np.asarray(values[q], float)
        if p == "inf":
            d = np.where(np.isinf(v), 0.0, np.inf)
        else:
            with np.errstate(invalid="ignore"):
                d = np.where(np.isfinite(v), np.abs(v - float(p)) / half_unit(p), np.inf)
        out = np.maximum(out, d)
    return np.broadcast_to(out, np.shape(out))


def rounding_box(pose_deg: np.ndarray, decimals: int = 2, points: int = BOX_POINTS) -> np.ndarray:
    """Poses that round to ``pose_deg`` at ``decimals``: a (points^n, n) grid of the centres of points^n
    equal cells of the +-half-unit box (none on its edge, where rounding is ambiguous; the printed pose
    itself when points is odd)."""
    half = 0.5 * 10.0 ** -decimals
    offsets = (np.arange(points) + 0.5) / points * 2 * half - half
    axes = [q + offsets for q in pose_deg]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(pose_deg))


def plan_text(plan_deg: np.ndarray, decimals: int = 8) -> str:
    """(m, n) [deg] -> 'q1 q2; q1 q2' with enough decimals to re-evaluate a witness."""
    return "; ".join(" ".join(f"{a:.{decimals}f}" for a in p) for p in np.atleast_2d(plan_deg))


def pose_decimals(pose: list[str]) -> int:
    """Decimals a printed pose is judged at: the most any of its angles prints ('0', '46.10' -> 2)."""
    return max(printed_decimals(v) for v in pose)


@dataclass(frozen=True)
class Witness:
    """A pose (plan) that gives every printed number of a line: ``reason`` (printed-pose, flat-optimum,
    last-digit, flat-family), ``plan_deg`` (m, n), ``excess`` (relative criterion excess over our
    optimum), ``violation`` (largest |ours - printed| in half units, <= 1), ``shift`` (for last-digit: the
    printed angle that is one unit off, e.g. 'q2 +1')."""

    reason: str
    plan_deg: np.ndarray
    excess: float
    violation: float
    shift: str = ""

    @property
    def text(self) -> str:
        return plan_text(self.plan_deg) + (f" (printed {self.shift} unit)" if self.shift else "")


def _first_witness(reason: str, plans: np.ndarray, viol: np.ndarray, excess: np.ndarray, shift: str = ""):
    ok = (viol <= 1.0) & (excess <= FLAT_RTOL)
    if not ok.any():
        return None
    i = int(np.argmin(np.where(ok, np.maximum(viol, excess / FLAT_RTOL), np.inf)))
    return Witness(reason, plans[i], float(excess[i]), float(viol[i]), shift)


# ---------------------------------------------------------------------------------------------------
# Tables 2-3: lines of one pose

@dataclass
class Line:
    """The printed numbers of one pose: ``criteria`` it is optimal for, the printed ``pose`` (strings;
    None for the test pose of the O_t* row) and ``numbers``: (table, row, quantity) -> printed string."""

    criteria: tuple
    pose: list | None
    numbers: dict


def _is_pose(q: str) -> bool:
    return q.endswith("_deg")


def table_lines(printed: dict, n: int) -> list[Line]:
    """Group the printed rows of Tables 2-3 into lines (module docstring)."""
    ot_pose = [printed["ot_pose_deg"][f"q{i + 1}_deg"] for i in range(n)]
    items = [Line(tuple(e.get("criteria", [key])), [e[f"q{i + 1}_deg"] for i in range(n)],
                  {("table2", key, q): v for q, v in e.items() if q != "criteria"})
             for key, e in printed["table2"].items()]
    items += [Line(tuple(e.get("criteria", [key])) if key != "ot_star" else (),
                   ot_pose if key == "ot" else None,
                   {("table3", key, q): v for q, v in e.items() if q != "criteria"})
              for key, e in printed["table3"].items()]
    lines: list[Line] = []
    for item in items:  # merge every line that shares a criterion with the item
        joined = [ln for ln in lines if set(ln.criteria) & set(item.criteria)]
        for ln in joined:
            lines.remove(ln)
            item = Line(tuple(dict.fromkeys(ln.criteria + item.criteria)), ln.pose or item.pose,
                        {**ln.numbers, **item.numbers})
        lines.append(item)
    return lines


def criterion_excess(study: Study, keys, plans_deg: np.ndarray, best_loss: dict) -> np.ndarray:
    """Largest relative excess over our optimum of the criteria ``keys`` at plans (K, m, n) [deg]:
    (loss - best) / |best| per criterion (the loss is the value for minimised criteria, minus it for
    maximised ones). best_loss: key -> our optimal loss. 0 for no criteria."""
    out = np.zeros(len(plans_deg))
    for key in keys:
        loss = plan_loss(study.problem(key, plans_deg.shape[1]), np.radians(plans_deg))
        out = np.maximum(out, (loss - best_loss[key]) / max(abs(best_loss[key]), 1e-300))
    return out


def _loss_of(t2: pd.DataFrame, key: str) -> float:
    return float(t2.loc[key, "value"]) * (1 if criteria.sense(key) == "min" else -1)


def line_witness(study: Study, pose: list[str], constraints, keys, best_loss: dict):
    """The first computed reason that holds for a line: its witness, or None (module docstring).

    pose: printed angles; constraints: (quantity of :func:`stiffcal.paper.tables.plan_summary`, printed) pairs;
    keys: criteria the pose is optimal for; best_loss: key -> our optimal loss. ``last-digit`` is tried
    only when no pose of the printed rounding box gives every constraint, whatever its criterion excess."""
    p = np.array([float(v) for v in pose])
    dec = pose_decimals(pose)

    def search(reason, poses, shift=""):
        plans = poses[:, None, :]
        viol = violation(plan_summary(study, plans), constraints)
        near = viol <= 1.0  # the criterion only where the numbers match
        excess = np.full(len(plans), np.inf)
        excess[near] = criterion_excess(study, keys, plans[near], best_loss)
        return _first_witness(reason, plans, viol, excess, shift), viol

    w, _ = search("printed-pose", p[None])
    if w is not None:
        return w
    w, viol = search("flat-optimum", rounding_box(p, dec))
    if w is not None or (viol <= 1.0).any():  # (a pose of the box gives the numbers, but not near the optimum)
        return w
    unit = 10.0 ** -dec
    for j in range(len(p)):
        for sign in (1, -1):
            shifted = p.copy()
            shifted[j] += sign * unit
            w, _ = search("last-digit", rounding_box(shifted, dec), f"q{j + 1} {'+' if sign > 0 else '-'}1")
            if w is not None:
                return w
    return None


def compare_tables(study: Study, t2: pd.DataFrame, t3: pd.DataFrame, printed: dict) -> pd.DataFrame:
    """Every printed number of Tables 2-3 beside ours, one row each (columns :data:`COLUMNS`)."""
    n = study.robot.n_joints
    explain = printed.get("explain", {})
    t2i, t3i = t2.set_index("criterion"), t3.set_index("row")
    best = {k: _loss_of(t2i, k) for k in t2i.index if not t2i.loc[k, "degenerate"]}
    out = []
    for line in table_lines(printed, n):
        keys = [k for k in line.criteria if k in best]
        rows = []
        for (table, row, qty), pr in line.numbers.items():
            crit = printed[table][row].get("criteria", [row])
            ours_df, idx = (t2i, crit) if table == "table2" else (t3i, [row])
            idx = [k for k in idx if k in ours_df.index]
            if not idx:  # a criterion this configuration did not optimise (study.criteria)
                out.append(dict(table=table, row=row, quantity=qty, printed=pr, status="not computed",
                                 reason="its criterion is not in this configuration's study.criteria",
                                 meaning=_table_meaning(table, qty, line.criteria)))
                continue
            ours = [float(ours_df.loc[k, qty]) for k in idx]
            ok = all(matches(v, pr) for v in ours)
            noted = explain.get(f"{table}/{row}/{qty}")
            rows.append(dict(table=table, row=row, quantity=qty, printed=pr, ours=ours[0],
                             status="reproduced" if ok else "differs", reason="" if ok else noted,
                             meaning=_table_meaning(table, qty, line.criteria), noted=noted))
        if not rows:
            continue
        at = box = None
        excess = np.nan
        witness = None
        if line.pose is not None:
            pose = np.array([float(v) for v in line.pose])
            at = plan_summary(study, pose[None, None, :])
            box = plan_summary(study, rounding_box(pose, pose_decimals(line.pose), 21)[:, None, :])
            excess = float(criterion_excess(study, keys, pose[None, None, :], best)[0])
            if any(r["status"] == "differs" and not r["noted"] for r in rows):
                witness = line_witness(study, line.pose, _constraints(line, explain), keys, best)
        for r in rows:
            qty = r["quantity"]
            _attach(r, witness)
            if at is not None and not _is_pose(qty):
                r["ours_at_printed_pose"] = float(at[qty][0])
                r["range_low"], r["range_high"] = float(np.min(box[qty])), float(np.max(box[qty]))
                r["range_over"] = BOX
            r["criterion_excess_at_printed_pose"] = excess
            r.pop("noted")
            out.append(r)
    order = {(t, row, q): i for i, (t, row, q) in enumerate(
        (t, row, q) for t in ("table2", "table3") for row, e in printed[t].items() for q in e)}
    out.sort(key=lambda r: order[(r["table"], r["row"], r["quantity"])])
    return pd.DataFrame(out).reindex(columns=COLUMNS)


def _attach(row: dict, witness: Witness | None) -> None:
    """A differing number that no note explains gets its line's reason and witness (else 'unexplained')."""
    if row["status"] == "differs" and not row["noted"]:
        row["reason"] = witness.reason if witness is not None else "unexplained"
        if witness is not None:
            row["witness_deg"], row["witness_excess"] = witness.text, witness.excess


def _constraints(line: Line, explain: dict) -> list:
    """The line's printed numbers a witness must give, as (quantity, printed) pairs (noted numbers and
    the pose left out)."""
    return [(q, pr) for (table, row, q), pr in line.numbers.items()
            if not _is_pose(q) and not explain.get(f"{table}/{row}/{q}")]


def _table_meaning(table: str, qty: str, keys) -> str:
    plan = "/".join(criteria.label(k) for k in keys) if keys else "test pose"
    if _is_pose(qty):
        return f"{qty[:2]} of the {plan}-optimal pose [deg]"
    return f"{MEANING.get(qty, qty)} of the {plan} plan" + (", at the test pose" if table == "table3" else "")


# ---------------------------------------------------------------------------------------------------
# Tables 4-5: plans of several poses

def _rot(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


@dataclass(frozen=True)
class Q1Family:
    """The plans of m poses of a planar arm that share joints 2..n (``rest_deg``) and differ in q1, under
    a fixed force F.

    Turning q1 turns the whole arm, so pose i sees the force ``g_i = R(-q1_i) F`` in the arm's frame and
    its information is ``G o (J0^T g_i g_i^T J0)`` (``o`` elementwise, ``J0`` the Jacobian at q1 = 0,
    ``G = J0^T J0``): a plan's information depends on its q1's only through ``P = sum_i g_i g_i^T``, and
    every P >= 0 with trace ``m |F|^2`` is reached by some m >= 2 poses. O_t is convex in the information
    matrix, so when the repeated optimum (``P0 = m g0 g0^T``) and the repeated pose whose link 2 is parallel
    to the force (``Ps``: k2 not identified, yet the same O_t at a test pose that does not see k2) reach the
    same O_t, every plan on the segment ``P(s) = (1 - s) P0 + s Ps`` does: E[dk2^2] runs along it from the
    repeated optimum to infinity at s = 1. :func:`q1_family` builds it; ``None`` when there is no such family.
    """

    study: Study
    m: int
    rest_deg: np.ndarray
    J0: np.ndarray
    P0: np.ndarray
    Ps: np.ndarray

    def information(self, P: np.ndarray) -> np.ndarray:
        """Information matrix (..., n, n) of the plans with force matrix P: (..., 2, 2)."""
        W = np.einsum("ai,...ab,bj->...ij", self.J0, P, self.J0)
        return W * (self.J0.T @ self.J0)

    def P(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)[..., None, None]
        return (1.0 - s) * self.P0 + s * self.Ps

    def e_dk(self, s: np.ndarray) -> np.ndarray:
        """E[dk_i^2] (..., n) along the segment."""
        return covariance_diagonal(self.information(self.P(s)), self.study.sigma)

    def _q1(self, g: np.ndarray) -> float:
        F = self.study.force
        return float(np.degrees(np.arctan2(F[1], F[0]) - np.arctan2(g[1], g[0])))

    def _split(self, R: np.ndarray, k: int) -> list[np.ndarray] | None:
        """k force vectors of norm |F| whose g g^T sum to R (2, 2), or None when there are none."""
        f2 = float(self.study.force @ self.study.force)
        lam, vec = np.linalg.eigh(R)
        if lam[0] < -1e-12 * f2:
            return None
        lam = np.maximum(lam, 0.0)
        v1, v2, l1 = vec[:, 1], vec[:, 0], lam[1]
        if k == 1:
            return [np.sqrt(l1) * v1] if lam[0] <= 1e-9 * f2 else None
        if l1 < (k - 2) * f2:
            return None
        c = np.sqrt(min(1.0, (l1 - (k - 2) * f2) / (2 * f2)))
        g = np.sqrt(f2) * np.array([c * v1 + np.sqrt(1 - c * c) * v2, c * v1 - np.sqrt(1 - c * c) * v2])
        return [np.sqrt(f2) * v1] * (k - 2) + list(g)

    def member(self, q1_first_deg: float, e_dk2: float) -> np.ndarray | None:
        """A plan (m, n) [deg] of the family whose first pose has q1 = q1_first_deg and whose E[dk2^2] is
        e_dk2 (for m = 2 the first pose fixes the plan, and e_dk2 only picks between the two that exist);
        None when there is none."""
        from scipy.optimize import brentq

        F = self.study.force
        g_a = _rot(-np.radians(q1_first_deg)) @ F
        Ga = np.outer(g_a, g_a)
        k = self.m - 1
        if k == 1:  # the rest is one pose: P(s) - Ga must have rank one
            R0, D = self.P0 - Ga, self.Ps - self.P0
            a, b = np.linalg.det(D), np.linalg.det(R0 + D) - np.linalg.det(R0) - np.linalg.det(D)
            roots = np.roots([a, b, np.linalg.det(R0)]) if abs(a) > 0 else np.array([-np.linalg.det(R0) / b])
            s_all = sorted(float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and 0 <= r.real < 1)
            if not s_all:
                return None
            s = min(s_all, key=lambda v: abs(self.e_dk(v)[1] - e_dk2))
        else:
            f = lambda v: self.e_dk(v)[1] - e_dk2  # noqa: E731
            hi = 1.0 - 1e-12
            if not (f(0.0) <= 0.0 < f(hi)):
                return None
            s = brentq(f, 0.0, hi, xtol=1e-15, rtol=1e-15)
        rest = self._split(self.P(s) - Ga, k)
        if rest is None:
            return None
        q1 = (np.array([q1_first_deg] + [self._q1(g) for g in rest]) + 180.0) % 360.0 - 180.0
        return np.column_stack([q1, np.tile(self.rest_deg, (self.m, 1))])

    def e_dk2_range(self, samples: int = 201) -> tuple[float, float]:
        """Smallest and largest E[dk2^2] over the segment (the largest is inf: s = 1 cannot identify k2)."""
        e = self.e_dk(np.linspace(0.0, 1.0, samples))[:, 1]
        return float(np.min(e)), float(np.max(e))


def q1_family(study: Study, optimum_deg: np.ndarray, m: int) -> Q1Family | None:
    """The family of optimal plans of m poses with joints 2..n of the single-pose optimum ``optimum_deg``
    (n,) [deg] and free q1's (plan (ii) of Tables 4-5), or None when the segment of :class:`Q1Family` is
    not optimal. Planar arms of two joints only (None otherwise)."""
    robot = study.robot
    if not robot.planar or m < 2 or robot.n_joints != 2 or robot.n_params != 2:
        return None
    q0 = np.radians(np.asarray(optimum_deg, float))
    J0 = robot.model_jacobian(np.concatenate([[0.0], q0[1:]]))
    F = study.force
    g0 = _rot(-q0[0]) @ F
    perp = np.array([-J0[1, 1], J0[0, 1]])
    gs = np.sqrt(F @ F) * perp / np.linalg.norm(perp)
    At = study.problem("ot", m).At
    fam = Q1Family(study, m, np.asarray(optimum_deg, float)[1:], J0, m * np.outer(g0, g0), m * np.outer(gs, gs))
    ot0, ots = (float(criteria.o_t(fam.information(P), At, study.sigma)) for P in (fam.P0, fam.Ps))
    return fam if ots <= ot0 * (1 + FLAT_RTOL) else None


def _matching_copy(study: Study, printed_pose: np.ndarray, plan_deg: np.ndarray, decimals: int):
    """Our pose (or symmetric copy of one) that rounds to the printed pose, else None."""
    from ..planning.plans import symmetric_copies

    half = 0.5 * 10.0 ** -decimals + 1e-9
    for pose in plan_deg:
        for copy in symmetric_copies(study.robot, pose, study.force):
            if np.all(_angle_gap(copy, printed_pose) <= half):
                return copy
    return None


def _angle_gap(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + 180.0) % 360.0 - 180.0)


def _prints_as(plans: np.ndarray, printed_poses: list, decimals: list[int]) -> np.ndarray:
    """(K,) True where every printed pose rounds to some pose of the plan (as it is, not a copy)."""
    ok = np.ones(len(plans), bool)
    for pose, dec in zip(printed_poses, decimals):
        p = np.array([float(v) for v in pose])
        ok &= np.any(np.all(_angle_gap(plans, p) <= 0.5 * 10.0 ** -dec * (1 + 1e-9), axis=-1), axis=-1)
    return ok


def plan_candidates(study: Study, key: str, ours_deg: np.ndarray, printed_poses: list,
                    e_dk2: float | None = None, seed: int = 0):
    """Plans of the structure of row ``key`` ((i)-(iv), see :func:`stiffcal.paper.tables.plan_variants`) whose
    printed poses round to the paper's: (candidates (K, m, n) [deg], reason, family or None).

    (i) the rounding box of the printed pose, repeated; (ii) members of the q1 family (:func:`q1_family`)
    whose first pose rounds to the printed one, with E[dk2^2] = ``e_dk2`` where the family leaves it free;
    (iii) q1 over the rounding box of the printed q1, the other joints of every pose re-optimised; (iv)
    random plans in the rounding boxes of the printed poses (``seed``)."""
    from ..planning.plans import polish

    m, n = ours_deg.shape
    p = [np.array([float(v) for v in pose]) for pose in printed_poses]
    dec = [pose_decimals(pose) for pose in printed_poses]
    half = [0.5 * 10.0 ** -d for d in dec]
    q1_box = np.linspace(p[0][0] - half[0], p[0][0] + half[0], 201 if key == "ii" else 21)
    if key == "i":
        return np.repeat(rounding_box(p[0], dec[0])[:, None, :], m, axis=1), "flat-optimum", None
    if key == "ii":
        fam = q1_family(study, ours_deg[0], m)
        if fam is None:
            return np.empty((0, m, n)), "flat-family", None
        target = fam.e_dk2_range()[0] if e_dk2 is None else e_dk2
        plans = [fam.member(q1, target) for q1 in q1_box]
        return np.array([x for x in plans if x is not None]).reshape(-1, m, n), "flat-family", fam
    if key == "iii":
        prob, free = study.problem("ot", m), np.arange(n) > 0
        starts = np.repeat(ours_deg[None], len(q1_box), 0)
        starts[:, :, 0] = q1_box[:, None]
        return np.array([np.degrees(polish(prob, np.radians(x), free)[0]) for x in starts]), "flat-optimum", None
    if len(p) != m:
        return np.empty((0, m, n)), "flat-optimum", None
    noise = np.random.default_rng(seed).uniform(-1, 1, (PLAN_SAMPLES, m, n)) * np.array(half)[None, :, None]
    return np.stack(p)[None] + np.concatenate([np.zeros((1, m, n)), noise]), "flat-optimum", None


def compare_plans(study: Study, table: pd.DataFrame, printed_rows: dict, name: str, explain: dict,
                  seed: int = 0, single_deg: np.ndarray | None = None) -> pd.DataFrame:
    """Every printed number of Table 4 or 5 beside ours, one row each (columns :data:`COLUMNS`; each pose
    angle is one number, quantity ``pose<k>_q<j>``).

    A printed pose is reproduced when it rounds to one of our poses or a symmetric copy of one; otherwise
    its angles are compared with the closest of our poses. A row with a number that differs is explained
    by a witness among :func:`plan_candidates` that gives every printed number of the row, with O_t within
    ``FLAT_RTOL`` of ours. single_deg: the single-pose optimum (n,) [deg] at full precision (the table's
    poses are rounded to 4 decimals), which plan (ii) keeps joints 2..n of; found when not given."""
    from .tables import single_ot_pose

    ours_df = table.set_index("plan")
    single_deg = single_ot_pose(study) if single_deg is None else np.asarray(single_deg, float)
    out = []
    for key, entry in printed_rows.items():
        plan = parse_plan(ours_df.loc[key, "poses_deg"])
        same = np.all(_angle_gap(plan, single_deg) <= 5e-5, axis=-1)  # the single optimum, at full precision
        plan[same] = single_deg
        m, n = plan.shape
        ot = float(ours_df.loc[key, "O_t"])
        rows = []
        for qty, pr in entry.items():
            if qty == "poses_deg":
                for k, pose in enumerate(pr):
                    rows += _pose_rows(study, name, key, k, pose, plan)
                continue
            ours = float(ours_df.loc[key, qty])
            ok = matches(ours, pr)
            noted = explain.get(f"{name}/{key}/{qty}")
            rows.append(dict(table=name, row=key, quantity=qty, printed=pr, ours=ours,
                             status="reproduced" if ok else "differs", reason="" if ok else noted, noted=noted,
                             meaning=f"{MEANING.get(qty, qty)} of plan ({key}), {m} poses"))
        constraints = [(r["quantity"], r["printed"]) for r in rows if not r["quantity"].startswith("pose")
                       and not r["noted"]]
        e2 = next((float(v) for q, v in constraints if q == "E_dk2"), None)
        base = np.repeat(single_deg[None], m, 0) if key == "ii" else plan
        cands, reason, fam = plan_candidates(study, key, base, entry["poses_deg"], e2, seed)
        cands = cands[_prints_as(cands, entry["poses_deg"], [pose_decimals(x) for x in entry["poses_deg"]])]
        vals = plan_summary(study, cands) if len(cands) else None
        witness = None
        if any(r["status"] == "differs" and not r["noted"] for r in rows) and vals is not None:
            excess = (np.asarray(vals["O_t"]) - ot) / ot
            witness = _first_witness(reason, cands, violation(vals, constraints), excess)
        for r in rows:
            qty = r["quantity"]
            _attach(r, witness)
            if vals is not None and not qty.startswith("pose"):
                r["range_low"], r["range_high"] = float(np.min(vals[qty])), float(np.max(vals[qty]))
                r["range_over"] = "plans of this row whose printed poses round to the paper's"
                if fam is not None and qty == "E_dk2":
                    r["range_low"], r["range_high"] = fam.e_dk2_range()
                    r["range_over"] = "the family of optimal plans (ii)"
            r.pop("noted")
            out.append(r)
    return pd.DataFrame(out).reindex(columns=COLUMNS)


def _pose_rows(study: Study, name: str, key: str, k: int, pose: list[str], plan: np.ndarray) -> list[dict]:
    """The printed angles of pose k of a plan beside ours: both reproduced when the pose rounds to one of
    ours or a symmetric copy (reason ``symmetric-copy`` for a copy); else each angle beside the closest of
    our poses."""
    p = np.array([float(v) for v in pose])
    dec = pose_decimals(pose)
    copy = _matching_copy(study, p, plan, dec)
    if copy is not None:
        as_is = bool(np.any(np.all(_angle_gap(plan, p) <= 0.5 * 10.0 ** -dec + 1e-9, axis=-1)))
        ours, ok, reason = copy, [True] * len(p), ("" if as_is else "symmetric-copy")
    else:
        ours = plan[int(np.argmin(np.max(_angle_gap(plan, p), axis=-1)))]
        ok, reason = list(_angle_gap(ours, p) <= 0.5 * 10.0 ** -dec * (1 + 1e-9)), ""
    return [dict(table=name, row=key, quantity=f"pose{k + 1}_q{j + 1}", printed=v, ours=float(ours[j]),
                 status="reproduced" if ok[j] else "differs", reason=reason if ok[j] else None, noted=None,
                 meaning=f"q{j + 1} of pose {k + 1} of plan ({key}) [deg]") for j, v in enumerate(pose)]


# ---------------------------------------------------------------------------------------------------
# The numbers in the text

#: how a text number is computed from table values x = (of[0], of[1]): (ours, mean-square form, RMS form)
TEXT_KINDS = {
    "chi": lambda x: (x[0], x[0], np.sqrt(x[0])),
    "rms_ratio": lambda x: (np.sqrt(x[0] / x[1]), x[0] / x[1], np.sqrt(x[0] / x[1])),
    "rms_reduction": lambda x: (100 * (1 - np.sqrt(x[1] / x[0])), 100 * (1 - x[1] / x[0]),
                                100 * (1 - np.sqrt(x[1] / x[0]))),
    "ms_ratio": lambda x: (x[0] / x[1], x[0] / x[1], np.sqrt(x[0] / x[1])),
    "rms": lambda x: (np.sqrt(x[0]), x[0], np.sqrt(x[0])),
}


def _ref_label(ref: str) -> str:
    table, row, qty = ref.split("/")
    if table == "table3":
        plan = f"the {criteria.label(row)}-optimal pose (Table 3)" if row in criteria.CRITERIA_KEYS else row
    else:
        plan = f"plan ({row}) of Table {table[-1]}"
    name = {"E_dk1": "E[dk1^2]", "E_dk2": "E[dk2^2]"}.get(qty, qty)
    return f"{name} of {plan}"


def text_meaning(kind: str, of: list[str]) -> str:
    """What a text number states, in words, from its kind and the table values it is computed from."""
    if kind == "map_statistic":
        stat = {"mean": "mean", "max_regular": "largest value (over test poses where A_t has full rank)"}
        name = of[0].split("/")[1]
        return f"the {stat.get(name, name)} of chi (eq. 27) over the test-pose plane of Figure 6"
    a = _ref_label(of[0])
    b = _ref_label(of[1]) if len(of) > 1 else ""
    return {
        "chi": f"{a} (eq. 27): a ratio of mean squares, O_t*/O_t; as a ratio of RMS errors it is sqrt(chi)",
        "rms_ratio": f"sqrt({a} / {b}): a ratio of RMS compensation errors (square roots of O_t)",
        "rms_reduction": f"100 (1 - sqrt({b} / {a})) %: how much lower the RMS compensation error (square root "
                         f"of O_t) is",
        "ms_ratio": f"{a} / {b}: a ratio of mean squares",
        "rms": f"sqrt({a}): a root mean square [rad/N]",
    }[kind]


def _figure6(statistics: pd.DataFrame | None, name: str):
    """(ours on the map's own grid, range over the grids, grids) of a Figure 6 statistic, or None."""
    if statistics is None or statistics.empty:
        return None
    fig = statistics[statistics["paper"].notna()]
    if fig.empty:
        return None
    study = fig["study"].iloc[0]
    own = statistics[(statistics.study == study) & (statistics.statistic == "cells")]["grid_deg"]
    rows = statistics[(statistics.study == study) & (statistics.statistic == name)]
    if rows.empty:
        return None
    grid = float(own.iloc[0]) if len(own) else float(rows.grid_deg.min())
    ours = float(rows[rows.grid_deg == grid]["ours"].iloc[0])
    return ours, float(rows.ours.min()), float(rows.ours.max()), sorted(rows.grid_deg.astype(float))


def _computed(frames: dict, refs) -> bool:
    """Whether every table row the references ('table/row/quantity') name is in our tables (a configuration with
    fewer criteria than the paper's has fewer rows)."""
    return all(r in frames[t].index for t, r, _ in (x.split("/") for x in refs))


def compare_text(frames: dict, printed: dict, statistics: pd.DataFrame | None = None) -> pd.DataFrame:
    """Every result number of the paper's text beside ours (columns :data:`COLUMNS`; table 'text', row the
    number's key in ``printed['text']``, quantity 'value').

    frames: 'table3', 'table4', 'table5' -> our tables indexed by row; statistics: the map statistics
    (``maps.statistics_table``), for the Figure 6 numbers; without it they are 'not computed'.
    ``ours`` is the quantity the number states; ``ours_ms`` and ``ours_rms`` give it as a ratio (or
    reduction) of mean squares and of RMS errors, and ``from_paper`` computes it from the paper's own
    printed table numbers."""
    explain = printed.get("explain", {})
    out = []
    for key, e in printed["text"].items():
        kind, of, pr = e["kind"], e["of"], e["value"]
        row = dict(table="text", row=key, quantity="value", printed=pr,
                   meaning=f'"{e.get("as_printed", pr)}": {text_meaning(kind, of)}')
        if kind == "map_statistic":
            got = _figure6(statistics, of[0].split("/")[1])
            if got is None:
                row.update(status="not computed", reason="no map of the paper's arm (config maps.studies)")
                out.append(row)
                continue
            ours, lo, hi, grids = got
            row.update(ours=ours, ours_ms=ours)
            if len(grids) > 1:
                row.update(range_low=lo, range_high=hi,
                           range_over="grids of " + ", ".join(f"{g:g}" for g in grids) + " deg")
        else:
            fn = TEXT_KINDS[kind]

            def ours_of(refs):
                return fn([float(frames[t].loc[r, q]) for t, r, q in (x.split("/") for x in refs)])

            if not _computed(frames, of):
                row.update(status="not computed", reason="a row it rests on is not in this configuration's tables "
                                                         "(study.criteria)")
                out.append(row)
                continue
            ours, ms, rms = ours_of(of)
            paper = fn([float(printed[t][r][q]) for t, r, q in (x.split("/") for x in of)])[0]
            row.update(ours=ours, ours_ms=ms, ours_rms=rms, from_paper=paper)
            others = [o for o in e.get("others") or () if _computed(frames, o)]
            if others:
                vals = [ours] + [ours_of(o)[0] for o in others]
                plans = [x[0].split("/")[1] for x in [of] + others]
                row.update(range_low=min(vals), range_high=max(vals),
                           range_over="against plans " + ", ".join(f"({p})" for p in plans))
        ok = matches(row["ours"], pr)
        row.update(status="reproduced" if ok else "differs",
                   reason="" if ok else explain.get(f"text/{key}/value", "unexplained"))
        out.append(row)
    return pd.DataFrame(out).reindex(columns=COLUMNS)


# ---------------------------------------------------------------------------------------------------
# All of it

def comparison_table(study: Study, t2: pd.DataFrame, t3: pd.DataFrame, t4: pd.DataFrame, t5: pd.DataFrame,
                     printed: dict, statistics: pd.DataFrame | None = None, seed: int = 0) -> pd.DataFrame:
    """Every result number the paper prints (Tables 2-5 and its text) beside ours: one row per printed
    number, columns :data:`COLUMNS` (see the module docstring for status and reason)."""
    explain = printed.get("explain", {})
    frames = {"table3": t3.set_index("row"), "table4": t4.set_index("plan"), "table5": t5.set_index("plan")}
    cols = [f"q{i + 1}_deg" for i in range(study.robot.n_joints)]
    single = t2.set_index("criterion").loc["ot", cols].to_numpy(float) if "ot" in set(t2.criterion) else None
    parts = [compare_tables(study, t2, t3, printed),
             compare_plans(study, t4, printed["table4"], "table4", explain, seed, single),
             compare_plans(study, t5, printed["table5"], "table5", explain, seed, single),
             compare_text(frames, printed, statistics)]
    return pd.concat(parts, ignore_index=True).reindex(columns=COLUMNS)


def summary(cmp: pd.DataFrame) -> dict:
    """Counts for the report's headline: total, reproduced, differs, not computed, the reasons, and the
    same per table ('table2'..'table5', 'text')."""
    def counts(df):
        return {"total": int(len(df)), "reproduced": int((df.status == "reproduced").sum()),
                "differs": int((df.status == "differs").sum()),
                "not_computed": int((df.status == "not computed").sum())}

    out = counts(cmp)
    out["reasons"] = {k: int(v) for k, v in cmp[cmp.status == "differs"].reason.value_counts().items()}
    out["tables"] = {t: counts(cmp[cmp.table == t]) for t in dict.fromkeys(cmp.table)}
    out["in_tables"] = counts(cmp[cmp.table != "text"])
    return out
