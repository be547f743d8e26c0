"""What one measurement sees: the load as a wrench, the measured quantities (positions of named targets,
the orientation of the tool) with their noise, and the observation matrix of eqs. 2-4 on the 6-D geometric
Jacobian.

The paper's eqs. 2-4 with a wrench and any measured quantities
---------------------------------------------------------------
The load is a wrench ``W = (F, M)`` applied at the tool point (``tool_m``; the end of the last link of a
planar arm), the moment M taken about that point, both in the base frame. With ``J_W`` the 6-D geometric
Jacobian of the tool point (linear rows ``a_j x (p_tool - o_j)``, angular rows ``a_j`` for joint j's axis
a_j through o_j; Siciliano et al., *Robotics*, 2009, eq. 3.30), the joint torques are ``tau = J_W^T W`` and
the joint deflections ``dq = diag(k) tau`` (eq. 2 is ``dp = J diag(k) J^T F``). The tool moves as a rigid
body by the twist ``J_W dq`` at the tool point: a target t moves by ``dp_t = v + w x (x_t - p_tool)`` and
the tool turns by the small-angle rotation vector ``dr = w``. Stacking the measured quantities y (the
positions of the measured targets, the orientation when it is measured) as ``y = J_y dq``,

    y = J_y diag(J_W^T W) k = A k,        column j of A:  J_y[:, j] tau_j                (eqs. 3-4)

For a force at the tool point and its position measured, ``J_y = J_W = J`` and A is eq. 4. A planar arm
has the coordinates (x, y) for positions and forces and (z) for rotations and moments: wrench
``(fx, fy, mz)``, twist ``(vx, vy, wz)``; a spatial arm (x, y, z) for both.

Noise and weighting (eqs. 10-11)
--------------------------------
Positions are measured with the standard deviation ``sigma_m`` [m] per coordinate, orientation with
``sigma_rad`` [rad]. The rows of A are those of weighted least squares: orientation rows are multiplied by
``sigma_m / sigma_rad``, so every row has the noise sigma_m, and eqs. 10-11 (``cov = sigma_m^2 M^-1``) and
16 hold with sigma = sigma_m. Position rows are not rescaled, so a plan that measures one position only
has exactly the paper's matrices.

The test pose's error (eq. 16)
------------------------------
O_t is the mean squared error of the compensated position of one named target (``test_target``, the tool
point by default) at the test pose. With a length scale ``L = orientation_length_m`` > 0 it also counts the
tool's rotation: the error is ``|dp|^2 + L^2 |dr|^2``, which is the mean squared error over the points at
distance ``L * sqrt(3/2)`` from the target in every direction of space (for a rotation w and a point at r,
``E|w x r|^2 = (2/3) |r|^2 |w|^2`` over directions; planar arms: over the circle of radius L in the plane).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .robot import TOOL_TARGET, Robot

#: rows of a 6-D twist or wrench (x, y, z, rx, ry, rz) that a planar arm uses: (x, y) and (rz)
PLANAR_ROWS = (0, 1, 5)


def force_dim(robot: Robot) -> int:
    """Force components (and position coordinates) of the arm: 2 planar, 3 spatial."""
    return 2 if robot.planar else 3


def moment_dim(robot: Robot) -> int:
    """Moment components (and rotation coordinates) of the arm: 1 planar (about z), 3 spatial."""
    return 1 if robot.planar else 3


def wrench_dim(robot: Robot) -> int:
    return force_dim(robot) + moment_dim(robot)


def as_wrench(robot: Robot, load: np.ndarray) -> np.ndarray:
    """A force (..., d) or a wrench (..., d + d_m) [N, N m] as a wrench (..., d + d_m) (zero moment for a force).
    Raises ValueError for any other length."""
    load = np.asarray(load, float)
    d, w = force_dim(robot), wrench_dim(robot)
    if load.shape[-1] == w:
        return load
    if load.shape[-1] == d:
        return np.concatenate([load, np.zeros(load.shape[:-1] + (w - d,))], axis=-1)
    raise ValueError(f"expected {d} force or {w} wrench components, got {load.shape[-1]}")


def reduce_rows(robot: Robot, v6: np.ndarray, axis: int = -2) -> np.ndarray:
    """The rows a planar arm uses ((x, y, rz) of a 6-D twist or wrench along ``axis``); spatial: all six."""
    return np.take(v6, PLANAR_ROWS, axis=axis) if robot.planar else v6


def _lift6(robot: Robot, v: np.ndarray) -> np.ndarray:
    """(..., w) wrench or twist of the arm -> (..., 6) in 3-D (planar: z, rx, ry = 0)."""
    if not robot.planar:
        return v
    out = np.zeros(v.shape[:-1] + (6,))
    out[..., list(PLANAR_ROWS)] = v
    return out


def tool_twists(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 6-D geometric Jacobian of the tool point and the frame it lives in.

    q: (..., n) [rad]. Returns ``(J6 (..., 6, n), R (..., 3, 3), p_tool (..., 3))``: column j of J6 is the twist
    ``(a_j x (p_tool - o_j), a_j)`` of a unit rotation of joint j (linear part [m/rad] at the tool point,
    angular part [rad/rad]); R the tip frame's rotation; p_tool the tool point [m]."""
    origins, axes = robot.joint_frames(q)
    R, p = robot.tool_frame(q)
    p_tool = p + R @ robot.target_point(TOOL_TARGET)
    lin = np.cross(axes, p_tool[..., None, :] - origins)
    return np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(axes, -1, -2)], axis=-2), R, p_tool


def torques(robot: Robot, q: np.ndarray, load: np.ndarray) -> np.ndarray:
    """tau = J_W^T W (..., n) [N m] for a force or a wrench at the tool point (:func:`as_wrench`)."""
    J6 = tool_twists(robot, q)[0]
    return np.einsum("...wn,...w->...n", J6, _lift6(robot, as_wrench(robot, load)))


@dataclass(frozen=True)
class Sensing:
    """What is measured at every pose and how precisely (module docstring).

    targets: names of the targets whose positions are measured (:attr:`Robot.target_names`; ``"tool"`` is the
    tool point); orientation: the tool's orientation (small-angle rotation vector) is measured too;
    sigma_m: position noise [m] per coordinate; sigma_rad: orientation noise [rad] per coordinate (needed when
    ``orientation``). Only the ratio sigma_m / sigma_rad enters the rows (weighted least squares).
    """

    targets: tuple[str, ...] = (TOOL_TARGET,)
    orientation: bool = False
    sigma_m: float = 1.0
    sigma_rad: float | None = None

    @property
    def is_default(self) -> bool:
        """Only the tool point's position: the paper's measurement."""
        return self.targets == (TOOL_TARGET,) and not self.orientation

    @property
    def rad_weight(self) -> float:
        """sigma_m / sigma_rad [m/rad]: the factor of orientation rows (weighted least squares)."""
        return 1.0 if not self.orientation or self.sigma_rad is None else self.sigma_m / self.sigma_rad

    def rows_per_pose(self, robot: Robot) -> int:
        return len(self.targets) * force_dim(robot) + (moment_dim(robot) if self.orientation else 0)

    def row_names(self, robot: Robot) -> list[str]:
        """Names of the measured rows of one pose: ``dx@A``, ``dy@A``, ..., ``rz``."""
        axes = "xyz"[: force_dim(robot)]
        rot = ["rz"] if robot.planar else ["rx", "ry", "rz"]
        return [f"d{a}@{t}" for t in self.targets for a in axes] + (rot if self.orientation else [])

    def check(self, robot: Robot, prefix: str = "", source: str | None = None) -> "Sensing":
        """Raise :class:`InputError` (field ``<prefix>targets`` or ``<prefix>sigma_rad``) for an unknown or
        repeated target, no measured quantity, or the orientation without its noise level."""
        known = robot.target_names
        for t in self.targets:
            if t not in known:
                raise InputError(f"expected a target of robot {robot.source} ({', '.join(known)}), got {t!r}",
                                 source=source, field=f"{prefix}targets")
        if len(set(self.targets)) != len(self.targets):
            raise InputError(f"expected each target once, got {list(self.targets)}", source=source,
                             field=f"{prefix}targets")
        if not self.targets and not self.orientation:
            raise InputError("expected at least one measured quantity (a target's position or the orientation)",
                             source=source, field=f"{prefix}targets")
        if self.orientation and not (self.sigma_rad is not None and self.sigma_rad > 0):
            raise InputError("expected the orientation noise sigma_rad > 0 [rad] when the orientation is measured",
                             source=source, field=f"{prefix}sigma_rad")
        return self


def target_offsets(robot: Robot, names) -> np.ndarray:
    """(k, 3) [m]: the targets ``names`` minus the tool point, in the tip frame."""
    tool = robot.target_point(TOOL_TARGET)
    return np.array([robot.target_point(t) - tool for t in names], float).reshape(-1, 3)


def observe(robot: Robot, twist: np.ndarray, R: np.ndarray, offsets: np.ndarray, orientation: bool,
            rad_weight: float = 1.0) -> np.ndarray:
    """The measured rows of rigid motions of the tool given as twists at the tool point.

    twist: (..., 6, p) columns ``(v, w)`` [m, rad per unit parameter]; R: (..., 3, 3) the tip frame's rotation;
    offsets: (k, 3) or (..., k, 3) [m] targets minus the tool point in the tip frame; orientation: append the
    rotation rows, multiplied by ``rad_weight``. Returns (..., k d + d_r, p): for each target its position
    rows ``v + w x (R offset)`` (d coordinates), then the orientation rows ``w`` (d_r coordinates)."""
    v, w = twist[..., :3, :], twist[..., 3:, :]
    arm = np.einsum("...ij,...kj->...ki", R, np.broadcast_to(offsets, R.shape[:-2] + np.shape(offsets)[-2:]))
    moved = v[..., None, :, :] + np.cross(w[..., None, :, :], arm[..., :, :, None], axisa=-2, axisb=-2, axisc=-2)
    d = force_dim(robot)
    pos = moved[..., :d, :].reshape(moved.shape[:-3] + (-1, moved.shape[-1]))
    if not orientation:
        return pos
    rot = w[..., 2:, :] if robot.planar else w
    return np.concatenate([pos, rad_weight * rot], axis=-2)


def sensed_jacobian(robot: Robot, q: np.ndarray, sensing: Sensing) -> tuple[np.ndarray, np.ndarray]:
    """``(J_y (..., r, n), J6 (..., 6, n))``: the Jacobian of the measured quantities (orientation rows
    weighted, :attr:`Sensing.rad_weight`) and the 6-D Jacobian of the tool point (:func:`tool_twists`)."""
    J6, R, _ = tool_twists(robot, q)
    return observe(robot, J6, R, target_offsets(robot, sensing.targets), sensing.orientation,
                   sensing.rad_weight), J6


def observation_rows(robot: Robot, q: np.ndarray, load: np.ndarray, sensing: Sensing,
                     params: np.ndarray | None = None) -> np.ndarray:
    """The observation matrix A (eqs. 3-4 with a wrench, module docstring) of every pose.

    q: (..., n) [rad]; load: (w,) or (..., w) wrench, or (d,) force [N, N m] at the tool point; sensing: what is
    measured; params: the joints whose compliances are the model's parameters (default all).
    Returns (..., r, p) [m^2 N/rad per row weight]."""
    Jy, J6 = sensed_jacobian(robot, q, sensing)
    tau = np.einsum("...wn,...w->...n", J6, _lift6(robot, as_wrench(robot, load)))
    A = Jy * tau[..., None, :]
    return A if params is None else A[..., params]


@dataclass(frozen=True)
class Loads:
    """The loads every measurement pose is measured under, apart from the test pose's wrench (``--loads``): a
    lab's load sequence at each configuration (hanging masses, pushes in a few directions, given wrenches, a
    loading bar), as the measured-data CSV logs it.

    wrenches: (L, w) [N, N m] at the tool point in the base frame (the moment about the tool point), or for a
    loading bar the forces (L, d) of its masses, hung at ``arm`` (3,) [m] from the tool point in the tip frame,
    so that their moment about the tool point turns with the tool; hanging: the loads hang from a cable (masses),
    whose path below the tool point (or the bar's end) must be free (:mod:`stiffcal.model.workcell`); spec: the text
    they were read from."""

    wrenches: np.ndarray
    arm: np.ndarray | None = None
    hanging: bool = False
    spec: str = ""

    def at(self, robot: Robot, q: np.ndarray) -> np.ndarray:
        """The wrenches (..., L, w) [N, N m] at poses q (..., n) [rad] (the same at every pose but a bar's)."""
        q = np.asarray(q, float)
        if self.arm is None:
            W = as_wrench(robot, self.wrenches)
            return np.broadcast_to(W, q.shape[:-1] + W.shape)
        R, _ = robot.tool_frame(q)
        r = R @ self.arm  # (..., 3): the bar's end from the tool point, base frame
        d = force_dim(robot)
        F = np.asarray(self.wrenches, float)[:, :d]
        F3 = F if d == 3 else np.concatenate([F, np.zeros((len(F), 1))], axis=1)
        M = np.cross(r[..., None, :], F3)  # (..., L, 3)
        M = M if d == 3 else M[..., 2:]
        return np.concatenate([np.broadcast_to(F, M.shape[:-1] + (d,)), M], axis=-1)

    @property
    def hang_offset(self) -> np.ndarray | None:
        """Where the cable of hanging masses starts, from the tool point in the tip frame [m] (None: no cable)."""
        if not self.hanging:
            return None
        return np.zeros(3) if self.arm is None else np.asarray(self.arm, float)


def measurement_loads(robot: Robot, spec: str, field: str = "loads", source: str | None = None) -> Loads:
    """The :class:`Loads` of a load-set text (:func:`stiffcal.model.loads.load_set`, the SPEC of ``discriminate``:
    ``hanging:M1,M2``, ``directions:K:M1,M2``, ``forces:FX,FY[,FZ];...``, ``wrenches:...;...``,
    ``bar:AX,AY[,AZ]:M1,M2``), hanging masses along the robot's gravity. Raises :class:`InputError` naming
    ``source`` and ``field``."""
    from .loads import load_set

    if not isinstance(spec, str):
        raise InputError(f"expected a load set such as 'hanging:49,98', got {spec!r}", source=source, field=field)
    if spec.strip().partition(":")[0] == "data":
        raise InputError("expected the loads the lab applies ('hanging:M1,M2', 'directions:K:M1,M2', 'forces:...', "
                         "'wrenches:...', 'bar:...'): a design has no data to take them from", source=source,
                         field=field)
    try:
        ls = load_set(spec, force_dim(robot), resolution_N=None, field_name=field, gravity=robot.gravity)
        check_bar(robot, ls.arm, field)
    except InputError as err:
        raise err.renamed(field=field, source=source) if source else err from None
    return Loads(np.asarray(ls.forces, float), ls.arm, ls.kind in ("hanging", "bar"), ls.spec)


def check_bar(robot: Robot, arm, field: str) -> None:
    """Refuse a loading bar whose end ``arm`` (3,) [m] (None: no bar) is more than
    :data:`~stiffcal.limits.TOOL_LENGTHS` times the arm's own length from the tool point (a fresh user's
    'bar:400,0,0:...' meant in millimetres planned 46 kN m moments in silence)."""
    if arm is None:
        return
    from .robot import check_tool_length, own_length

    check_tool_length(float(np.linalg.norm(arm)), own_length(robot), None, field, "the loading bar's end is ",
                      "the tool point")


def loaded_rows(robot: Robot, q: np.ndarray, loads: Loads, sensing: Sensing,
                params: np.ndarray | None = None) -> np.ndarray:
    """The observation rows of poses q (..., n) [rad] measured under every load of ``loads``, stacked load by load
    (:func:`observation_rows` for each): (..., L r, p)."""
    Jy, J6 = sensed_jacobian(robot, q, sensing)
    W = _lift6(robot, loads.at(robot, q))  # (..., L, 6)
    tau = np.einsum("...wn,...lw->...ln", J6, W)
    A = Jy[..., None, :, :] * tau[..., :, None, :]  # (..., L, r, n)
    A = A.reshape(A.shape[:-3] + (-1, A.shape[-1]))
    return A if params is None else A[..., params]


def sensed_params(robot: Robot, sensing: Sensing, samples: int = 512, seed: int = 0) -> np.ndarray:
    """Indices of the joints whose rotation changes some measured quantity at some pose (the model's
    parameters): a joint whose axis passes through every measured target at every pose, with the orientation
    not measured, never shows in the measurements (:func:`stiffcal.model.robot.inert_joints` for the tool point)."""
    if sensing.is_default:
        return robot.params
    lo, hi = robot.joint_limits_rad.T
    q = np.random.default_rng(seed).uniform(lo, hi, (samples, robot.n_joints))
    col = np.abs(sensed_jacobian(robot, q, Sensing(sensing.targets, sensing.orientation))[0]).max(axis=(0, 1))
    return np.flatnonzero(col > 1e-12 * max(robot.reach_m, 1e-300))


def test_rows(robot: Robot, q: np.ndarray, load: np.ndarray, target: str = TOOL_TARGET, length_m: float = 0.0,
              params: np.ndarray | None = None) -> np.ndarray:
    """A_t of eq. 16 with a wrench: the rows of the compensated error at the test pose q (n,) [rad] under
    ``load`` (module docstring): the position of ``target``, and the rotation times ``length_m`` [m] when it
    is > 0. Returns (d (+ d_r), p)."""
    return observation_rows(robot, q, load, Sensing((target,), length_m > 0, 1.0, 1.0 / length_m if length_m > 0
                                                     else None), params)
