"""The catalogue of causes the measured-data analysis tests (docs/measured-data.md, "What the analysis does"): a
registry, :data:`CATALOGUE`, of :class:`Cause` entries, each with its parameters' names and, for a cause acting
at the joints, its regressors. The analysis (:mod:`stiffcal.measured.discrepancy`), the calibrated robot file
(:mod:`stiffcal.model.calibration`), the discrimination planner and the docs' list of causes all read it; a new joint
cause is one entry here, its physics in the simulator (:mod:`stiffcal.testing.truth`) and its row in the docs
(docs/extending.md)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Cause:
    """One catalogue cause.

    name: its key (the verdict's, the calibrated file's); meaning: its law in one line (the docs' list of causes
    is written from it: ``make docs``); kind: ``"joint"`` (its regressors are the joints' Jacobian columns weighted
    by a function of the joint torques, :attr:`joint_effect`), ``"link"`` (link bending,
    :func:`stiffcal.measured.discrepancy._link_twists`) or ``"measurement"`` (the measuring system's, one bias per
    measured axis: not in predictions of the robot's deflection); names: ``names(robot, rotation)`` the parameters'
    names with units (``rotation``: the names of the measured rotation axes' extra parameters, for a measurement
    cause); joint_effect: ``(J (N, k, n), tau (N, n) [N m], t0 (N, n) [N m]) -> (N, k, p)``, the rows' regressors
    from the joints' Jacobian columns J, the load's joint torques tau and the arm's own weight's t0 (zero without
    masses); preloaded: it acts on the total torque t0 + tau (a row then sees the loaded state less the unloaded
    one)."""
    name: str
    meaning: str
    kind: str
    names: Callable
    joint_effect: Callable | None = None
    preloaded: bool = False


def torque_signs(tau: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """sign(tau) with a torque within round-off of zero (relative to ``scale``, (N, 1)) taken as zero."""
    return np.sign(tau) * (np.abs(tau) > 1e-12 * scale)


def preloaded_signs(tau: np.ndarray, t0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sign(t0 + tau), sign(t0)) (N, n) of the total torque and the arm's own weight's (``tau`` the load's,
    ``t0`` the weight's [N m]), each within round-off of the row's largest torque taken as zero
    (:func:`torque_signs`): the backlash's law, and where a load reverses a joint's total torque."""
    scale = np.maximum(np.abs(tau), np.abs(t0)).max(axis=-1, keepdims=True)
    return torque_signs(t0 + tau, scale), torque_signs(t0, scale)


def _coupling(J: np.ndarray, tau: np.ndarray, t0: np.ndarray) -> np.ndarray:
    """dq_i = sum_j k_ij tau_j (k_ij = k_ji): per pair (i < j) J_i tau_j + J_j tau_i."""
    n = J.shape[-1]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    return np.stack([J[:, :, i] * tau[:, j, None] + J[:, :, j] * tau[:, i, None] for i, j in pairs], axis=-1)


def _cubic(J: np.ndarray, tau: np.ndarray, t0: np.ndarray) -> np.ndarray:
    """dq_i = g_i ((t0 + tau)^3 - t0^3): a compliance that grows with the total torque."""
    return J * ((t0 + tau) ** 3 - t0**3)[:, None, :]


def _backlash(J: np.ndarray, tau: np.ndarray, t0: np.ndarray) -> np.ndarray:
    """dq_i = b_i (sign(t0 + tau) - sign(t0)): a gap preloaded by the weight jumps only where the load reverses
    the total torque; a torque within round-off of zero (the arm along the force) has no sign."""
    total, weight = preloaded_signs(tau, t0)
    return J * (total - weight)[:, None, :]


def _offset_names(robot, rotation: list[str]) -> list[str]:
    return [f"o{a}_m" for a in "xyz"[: robot.task_dim]] + rotation


#: the catalogue, in the order of every model's parameters after the compliances
CATALOGUE: dict[str, Cause] = {c.name: c for c in (
    Cause("link_compliance", "the links bend: a cantilever per link segment, c = 1/(E I) per segment", "link",
          lambda robot, rotation: [f"c{i + 1}_1/(N m^2)" for i in range(robot.n_segments)]),
    Cause("joint_coupling", "the joints' compliances are coupled: dq_i = sum_j k_ij tau_j", "joint",
          lambda robot, rotation: [f"k{a}{b}_rad/(N m)" for i, a in enumerate(robot.joint_columns(""))
                                   for b in robot.joint_columns("")[i + 1:]], _coupling),
    Cause("nonlinear_joint_stiffness",
          ("a compliance that changes with the torque: dq_i = k_i tau_i + g_i ((t0_i + tau_i)^3 - t0_i^3), "
           "t0 the arm's own weight's torque (zero without masses)"), "joint",
          lambda robot, rotation: [f"g{i + 1}_rad/(N m)^3" for i in range(robot.n_joints)], _cubic,
          preloaded=True),
    Cause("backlash", ("a gear's gap: dq_i = b_i (sign(t0_i + tau_i) - sign(t0_i)), a jump of b_i (half the gap) "
                       "either way where the load reverses the total torque"), "joint",
          lambda robot, rotation: [f"b{i + 1}_rad" for i in range(robot.n_joints)], _backlash, preloaded=True),
    Cause("measurement_offset", ("a constant shift of every loaded reading from its reference, one per measured "
                                 "position axis (and rotation axis): a tracker's bias cancels in a difference, so "
                                 "this is a target that settles in its nest or a fixture that moves when loaded, or "
                                 "a reference read in another state"),
          "measurement", _offset_names),
)}
#: the catalogue's causes, in the order of every model's parameters after the compliances
CAUSES = tuple(CATALOGUE)
#: causes that belong to the measuring system, not to the robot: they do not enter test-pose predictions
MEASUREMENT_CAUSES = tuple(c for c, cause in CATALOGUE.items() if cause.kind == "measurement")


def parameter_names(cause: str, robot, orientation: bool = False) -> list[str]:
    """The names, with units, of a cause's parameters for ``robot`` (``orientation``: the rows measure the tool's
    rotation too, so a measurement offset has rotation components): ``c1_1/(N m^2)`` .. (link bending, one per
    segment), ``k12_rad/(N m)`` .. (coupling, one per pair of joints), ``g1_rad/(N m)^3`` .. (cubic stiffness),
    ``b1_rad`` .. (backlash), ``ox_m`` .. and ``orz_rad`` .. (the tracker's offset)."""
    if cause not in CATALOGUE:
        raise ValueError(f"unknown cause {cause!r}")
    rot = ([] if not orientation else ["orz_rad"] if robot.planar else ["orx_rad", "ory_rad", "orz_rad"])
    return CATALOGUE[cause].names(robot, rot)


def joint_columns(cause: str, J: np.ndarray, tau: np.ndarray, preload: np.ndarray | None = None) -> np.ndarray:
    """(N, k, p): the regressors of a joint cause (:attr:`Cause.joint_effect`; ``"nominal"``: the compliances,
    J tau) from the joints' Jacobian columns J (N, k, n) (positions of the tool point, or 6-D twists), the load's
    torques tau (N, n) [N m] and the arm's own weight's torques ``preload`` (N, n) [N m] (None: no masses).
    Raises ValueError for a cause that is not a joint cause."""
    if cause == "nominal":
        return J * tau[:, None, :]
    entry = CATALOGUE.get(cause)
    if entry is None or entry.joint_effect is None:
        raise ValueError(f"unknown cause {cause!r}")
    return entry.joint_effect(J, unturned_to_zero(tau), np.zeros_like(tau) if preload is None else preload)


#: a joint whose load torque is at most this fraction of the largest joint's over every row is not turned by the
#: loads (a vertical axis under hanging weights: what is left is round-off, ~1e-13 of the others; a push through the
#: flange joint's axis logged to 0.001 N and 0.0001 N m: the printed digits, ~1e-7, whose compliance a fresh user's
#: KR 210 logs fitted to 0.09 +- 0.44 rad/(N m), then refused as a unit error in 7 of 12 clean logs)
TORQUE_RTOL = 1e-6


def unturned_to_zero(tau: np.ndarray) -> np.ndarray:
    """The load torques tau (N, n) [N m] with the joints the loads never turn (:func:`unturned`) set to exactly zero:
    a cause's parameter of such a joint (a
    nonlinear stiffness on tau^3: 1e-35 of the others) would otherwise be estimated from round-off (a fresh
    user's Jaco2 under hanging masses: g1 = 1.5e28 +- 3e28 rad/(N m)^3, written into calibrated.yaml)."""
    still = unturned(tau)
    return np.where(still, 0.0, tau) if still.any() else tau


def unturned(tau: np.ndarray) -> np.ndarray:
    """(n,) bool: the joints the load torques tau (N, n) [N m] never turn: their torque over every row at most
    :data:`TORQUE_RTOL` of the largest joint's."""
    norm = np.sqrt(np.einsum("nj,nj->j", tau, tau))
    return norm <= TORQUE_RTOL * norm.max() if norm.max() > 0 else np.ones(tau.shape[-1], bool)


def extension_size(cause: str, robot, n_offsets: int) -> int:
    """The number of parameters of ``cause`` for ``robot`` (a measurement cause: ``n_offsets``, the measured
    axes)."""
    return n_offsets if CATALOGUE[cause].kind == "measurement" else len(parameter_names(cause, robot))
