"""Our numbers beside the paper's printed ones, with a status per number.

A printed number is *reproduced* when ours, rounded to the printed number of decimals, equals it
(``inf`` matches ``inf``). Otherwise it *differs*, and the comparison gives the first reason that holds;
each is a computed fact, shown beside the number in the report:

* ``flat-optimum`` (pose columns) -- the criterion at the paper's printed pose is within ``FLAT_RTOL`` of
  our optimum: the criterion does not fix the pose to the printed digits;
* ``printed-pose`` -- our value at the paper's own rounded pose rounds to the printed number;
* ``rounding-box`` -- the printed number lies in the range this quantity spans over the poses that round
  to the printed pose (a +-half-unit box): the paper's optimiser stopped at another point of that box;
* a named note from ``printed_values.yaml`` (``notes:``), attached by ``explain:`` there, whose claim
  is checked numerically by ``tests/test_paper.py``;
* ``unexplained`` -- anything else (the tests require there be none).

For the plans of Tables 4-5, a printed pose is *reproduced* when it rounds to one of our poses or to one
of its symmetric copies (``symmetric-copy``: same information, see :mod:`stiffcal.plans`).
"""

from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd

from . import criteria
from .design import plan_loss
from .study import Study
from .tables import plan_summary
from .validation import read_yaml


def load_printed(path: str | Path) -> dict:
    """Read the paper's printed values (strings as printed)."""
    return read_yaml(path)


def printed_decimals(text: str) -> int:
    """Number of decimals printed: '13.7315' -> 4, '0' -> 0, 'inf' -> 0."""
    exp = Decimal(text).as_tuple().exponent if text != "inf" else 0
    return max(0, -int(exp))


def matches(ours: float, printed: str) -> bool:
    """True when ``ours`` rounds to ``printed`` at the printed precision (half-unit tolerance)."""
    if printed == "inf":
        return bool(np.isinf(ours))
    if not np.isfinite(ours):
        return False
    unit = 10.0 ** -printed_decimals(printed)
    return abs(ours - float(printed)) <= 0.5 * unit * (1 + 1e-9) + 1e-12


FLAT_RTOL = 1e-6
BOX_POINTS = 21


def rounding_box(pose_deg: np.ndarray, decimals: int = 2, points: int = BOX_POINTS) -> np.ndarray:
    """Poses that round to ``pose_deg`` at ``decimals``: a (points^n, n) grid over the +-half-unit box."""
    half = 0.5 * 10.0 ** -decimals
    axes = [np.linspace(q - half, q + half, points) for q in pose_deg]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(pose_deg))


def _pose(entry: dict, n: int) -> np.ndarray:
    return np.array([float(entry[f"q{i + 1}_deg"]) for i in range(n)])


def _criterion_excess(study: Study, key: str, pose_deg: np.ndarray, best_loss: float) -> float:
    """Relative excess of the criterion (as minimised) at ``pose_deg`` over the optimum."""
    at = float(plan_loss(study.problem(key), np.radians(pose_deg)[None, None, :])[0])
    return (at - best_loss) / max(abs(best_loss), 1e-300)


def compare_tables(study: Study, t2: pd.DataFrame, t3: pd.DataFrame, printed: dict) -> pd.DataFrame:
    """Long table of every printed number of Tables 2-3 beside ours.

    Columns: table, row, quantity, printed, ours, ours_at_printed_pose, box_low, box_high (range over
    the rounding box of the printed pose), criterion_excess_at_printed_pose, status, reason.
    """
    n = study.robot.n_joints
    explain = printed.get("explain", {})
    out = []
    t2i = t2.set_index("criterion")
    t3i = t3.set_index("row")

    def row_pose(table, key):
        if table == "table3" and key == "ot_star":
            return None
        return _pose(printed["ot_pose_deg"] if key == "ot" else printed["table2"][key], n)

    for table, entries, ours_df in (("table2", printed["table2"], t2i), ("table3", printed["table3"], t3i)):
        for key, entry in entries.items():
            if key not in ours_df.index:
                continue
            pose = row_pose(table, key)
            at = box = None
            excess = np.nan
            if pose is not None:
                at = plan_summary(study, pose[None, :])
                box = plan_summary(study, rounding_box(pose)[:, None, :])
                crit = key if table == "table2" else None
                if crit:
                    excess = _criterion_excess(study, crit, pose, float(ours_df.loc[key, "value"])
                                               * (1 if criteria.sense(crit) == "min" else -1))
            for qty, pr in entry.items():
                ours = float(ours_df.loc[key, qty])
                is_pose = qty.endswith("_deg")
                at_v = float(pr) if is_pose else (None if at is None else float(at[qty]))
                lo = hi = np.nan
                if box is not None and not is_pose:
                    lo, hi = float(np.min(box[qty])), float(np.max(box[qty]))
                if matches(ours, pr):
                    status, reason = "reproduced", ""
                elif is_pose and excess <= FLAT_RTOL:
                    status, reason = "differs", "flat-optimum"
                elif not is_pose and at_v is not None and matches(at_v, pr):
                    status, reason = "differs", "printed-pose"
                elif not is_pose and np.isfinite(lo) and lo - 1e-12 <= float(pr) <= hi + 1e-12:
                    status, reason = "differs", "rounding-box"
                else:
                    status, reason = "differs", explain.get(f"{table}/{key}/{qty}", "unexplained")
                out.append({"table": table, "row": key, "quantity": qty, "printed": pr, "ours": ours,
                            "ours_at_printed_pose": np.nan if at_v is None or is_pose else at_v,
                            "box_low": lo, "box_high": hi,
                            "criterion_excess_at_printed_pose": excess, "status": status, "reason": reason})
    return pd.DataFrame(out)


def _matching_copy(study: Study, printed_pose: np.ndarray, plan_deg: np.ndarray, decimals: int):
    """Our pose (or symmetric copy of one) that rounds to the printed pose, else None."""
    from .plans import symmetric_copies

    half = 0.5 * 10.0 ** -decimals + 1e-9
    for pose in plan_deg:
        for copy in symmetric_copies(study.robot, pose, study.force):
            if np.all(np.abs(((copy - printed_pose) + 180.0) % 360.0 - 180.0) <= half):
                return copy
    return None


def compare_plans(study: Study, table: pd.DataFrame, printed_rows: dict, name: str, explain: dict,
                  seed: int = 0, samples: int = 4000) -> pd.DataFrame:
    """Every printed number of Table 4 or 5 beside ours (same columns as :func:`compare_tables`).

    Printed poses are matched to our plan up to the symmetric copies of each pose (half-turn, mirror);
    numbers that differ are tested against the range over plans whose poses round to ours
    (``rounding-box``, ``samples`` random plans within +-half a unit of the printed digits).
    """
    from .tables import parse_plan

    rng = np.random.default_rng(seed)
    ours_df = table.set_index("plan")
    out = []
    for key, entry in printed_rows.items():
        plan = parse_plan(ours_df.loc[key, "poses_deg"])
        box = plan_summary(study, plan + rng.uniform(-0.005, 0.005, (samples,) + plan.shape))
        for qty, pr in entry.items():
            if qty == "poses_deg":
                for k, p in enumerate(pr):
                    pose = np.array([float(v) for v in p])
                    dec = max(printed_decimals(v) for v in p)
                    copy = _matching_copy(study, pose, plan, dec)
                    if copy is None:
                        status, reason = "differs", explain.get(f"{name}/{key}/pose{k + 1}", "unexplained")
                    else:
                        as_is = any(_matching_copy(study, pose, q[None], dec) is not None
                                    and np.allclose(_matching_copy(study, pose, q[None], dec), q) for q in plan)
                        status, reason = "reproduced", "" if as_is else "symmetric-copy"
                    out.append({"table": name, "row": key, "quantity": f"pose{k + 1}", "printed": " ".join(p),
                                "ours": " ".join(f"{a:.2f}" for a in (copy if copy is not None else plan[k])),
                                "ours_at_printed_pose": np.nan, "box_low": np.nan, "box_high": np.nan,
                                "criterion_excess_at_printed_pose": np.nan, "status": status, "reason": reason})
                continue
            ours = float(ours_df.loc[key, qty])
            lo, hi = float(np.min(box[qty])), float(np.max(box[qty]))
            if matches(ours, pr):
                status, reason = "reproduced", ""
            elif lo - 1e-12 <= float(pr) <= hi + 1e-12:
                status, reason = "differs", "rounding-box"
            else:
                status, reason = "differs", explain.get(f"{name}/{key}/{qty}", "unexplained")
            out.append({"table": name, "row": key, "quantity": qty, "printed": pr, "ours": ours,
                        "ours_at_printed_pose": np.nan, "box_low": lo, "box_high": hi,
                        "criterion_excess_at_printed_pose": np.nan, "status": status, "reason": reason})
    return pd.DataFrame(out)


def summary(cmp: pd.DataFrame) -> dict:
    """Counts for the report's headline: reproduced / differs, and the reasons."""
    return {"total": int(len(cmp)), "reproduced": int((cmp.status == "reproduced").sum()),
            "differs": int((cmp.status == "differs").sum()),
            "reasons": {k: int(v) for k, v in cmp[cmp.status == "differs"].reason.value_counts().items()}}
