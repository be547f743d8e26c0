"""Measured deflections in the CSV contract of DESIGN.md, read and validated.

One row per measurement: ``pose_id`` (optional), ``q1_deg`` ... ``qn_deg``, ``fx_N``, ``fy_N``, ``dx_m``,
``dy_m``: the end-effector displacement between the unloaded and the loaded state. Every problem is one
:class:`InputError` naming the file, the row (1-based line of the file) and the column; nothing is fitted
on bad data.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError
from .robot import Robot

_UNITS = {"q": "deg", "f": "N", "d": "m"}
_PATTERN = re.compile(r"^(q\d+|f[xyz]|d[xyz])(?:_(.*))?$")
_NAMES = {"q": "joint angles", "f": "force components", "d": "displacements"}


@dataclass(frozen=True)
class Measurements:
    """q (N, n) [rad]; force (N, d) [N]; dp (N, d) [m]; group (N,) int: rows with equal group are
    replicates (same pose and force); source: the file."""

    q: np.ndarray
    force: np.ndarray
    dp: np.ndarray
    group: np.ndarray
    source: str

    @property
    def n_rows(self) -> int:
        return len(self.q)

    def subset(self, rows: np.ndarray) -> "Measurements":
        return Measurements(self.q[rows], self.force[rows], self.dp[rows], self.group[rows], self.source)


def expected_columns(robot: Robot) -> list[str]:
    axes = "xyz"[: robot.task_dim]
    return ([f"q{i + 1}_deg" for i in range(robot.n_joints)] + [f"f{a}_N" for a in axes]
            + [f"d{a}_m" for a in axes])


def _check_units(columns, source: str) -> None:
    for col in columns:
        m = _PATTERN.match(col)
        if not m:
            continue
        kind, unit = m.group(1)[0], m.group(2)
        want = _UNITS[kind]
        if unit != want:
            got = f"unit '{unit}'" if unit else "no unit"
            raise InputError(f"expected {_NAMES[kind]} in {want} with the unit in the name ('{m.group(1)}_{want}'), "
                             f"got {got}", source=source, field=f"column {col}")


def read_measurements(path: str | Path, robot: Robot) -> Measurements:
    """Read and validate a measured-data CSV for ``robot``."""
    source = str(path)
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read a CSV table ({err})", source=source) from None
    df.columns = [c.strip() for c in df.columns]
    _check_units(df.columns, source)
    joints = sorted(int(c[1:-4]) for c in df.columns if re.fullmatch(r"q\d+_deg", c))
    if joints and max(joints) > robot.n_joints:
        raise InputError(f"expected {robot.n_joints} joint angles (q1_deg ... q{robot.n_joints}_deg) for robot "
                         f"{robot.source}, got a column q{max(joints)}_deg", source=source,
                         field=f"column q{max(joints)}_deg")
    cols = expected_columns(robot)
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; expected {', '.join(cols)} (and optionally pose_id)",
                         source=source)
    if len(df) == 0:
        raise InputError("no measurements (the file has a header only)", source=source)
    values = np.empty((len(df), len(cols)))
    for j, c in enumerate(cols):
        num = pd.to_numeric(df[c].str.strip(), errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(num))
        if bad.size:
            r = bad[0]
            raise InputError(f"expected a finite number, got {df[c].iloc[r]!r}", source=source,
                             field=f"row {r + 2} (data row {r}), column {c}")
        values[:, j] = num
    n, d = robot.n_joints, robot.task_dim
    q = np.radians(values[:, :n])
    force = values[:, n:n + d]
    dp = values[:, n + d:]
    if "pose_id" in df.columns:
        _, group = np.unique(df["pose_id"].str.strip().to_numpy(), return_inverse=True)
    else:
        key = np.round(np.hstack([values[:, :n], force]), 9)
        _, group = np.unique(key, axis=0, return_inverse=True)
    return Measurements(q, force, dp, group.ravel(), source)
