"""The catalogue of causes the measured-data analysis tests (docs/measured-data.md), by name: what a
calibrated robot file (:mod:`stiffcal.calibration`) needs without the analysis itself."""

from __future__ import annotations

#: the catalogue's causes, in the order of every model's parameters after the compliances
CAUSES = ("link_compliance", "joint_coupling", "nonlinear_joint_stiffness", "backlash", "measurement_offset")
#: causes that belong to the measuring system, not to the robot: they do not enter test-pose predictions
MEASUREMENT_CAUSES = ("measurement_offset",)


def parameter_names(cause: str, robot, orientation: bool = False) -> list[str]:
    """The names, with units, of a cause's parameters for ``robot`` (``orientation``: the rows measure the tool's
    rotation too, so a measurement offset has rotation components): ``c1_1/(N m^2)`` .. (link bending, one per
    segment), ``k12_rad/(N m)`` .. (coupling, one per pair of joints), ``g1_rad/(N m)^3`` .. (cubic stiffness),
    ``b1_rad`` .. (backlash), ``ox_m`` .. and ``orz_rad`` .. (the tracker's offset)."""
    n = robot.n_joints
    rot = ([] if not orientation else ["orz_rad"] if robot.kind == "planar" else ["orx_rad", "ory_rad", "orz_rad"])
    if cause == "link_compliance":
        return [f"c{i + 1}_1/(N m^2)" for i in range(robot.n_segments)]
    if cause == "joint_coupling":
        cols = robot.joint_columns("")
        return [f"k{a}{b}_rad/(N m)" for i, a in enumerate(cols) for b in cols[i + 1:]]
    if cause == "nonlinear_joint_stiffness":
        return [f"g{i + 1}_rad/(N m)^3" for i in range(n)]
    if cause == "backlash":
        return [f"b{i + 1}_rad" for i in range(n)]
    if cause == "measurement_offset":
        return [f"o{a}_m" for a in "xyz"[: robot.task_dim]] + rot
    raise ValueError(f"unknown cause {cause!r}")
