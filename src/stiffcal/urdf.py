"""Robot files of ``kind: urdf``: the serial chain of a URDF between two of its frames, read with Pinocchio.

A URDF (ROS's Unified Robot Description Format, http://wiki.ros.org/urdf/XML) describes a tree of links
joined by joints, each joint placed in its parent link's frame (``<origin xyz rpy>``) and turning about its
``<axis>``. Pinocchio (Carpentier et al., "The Pinocchio C++ library", SII 2019; its URDF parser is ROS's
urdfdom) reads the file into a model of joints and frames; :func:`read_chain` takes from that model the
joints on the path from ``base_frame`` to ``tip_frame`` and folds everything between two moving joints (fixed
joints, and chain joints held at a stated angle) into one fixed transform: a
:class:`stiffcal.robot.Chain` of placements and axes. The library then evaluates the kinematics with numpy,
batched over arrays of poses of any shape like the planar and DH kinds, which also gives every joint's axis
in the base frame (:meth:`stiffcal.robot.Robot.joint_frames`: the Jacobian of any point of the tip frame)
and keeps the :class:`~stiffcal.robot.Robot` a plain array-holding value. It costs about what Pinocchio costs
called once per pose (``benchmarks/bench_urdf.py``: the Jacobian at 32768 poses in 0.057 s of CPU, Pinocchio
0.060 s for position and Jacobian; the DH table 0.044 s); the tests check it against Pinocchio's own forward
kinematics and frame Jacobian, pose by pose.

Joints: ``revolute`` joints keep the URDF's ``<limit lower upper>`` as their joint limits; ``continuous``
joints have none (their angle is reported in [-180, 180) deg). Prismatic, floating, planar and mimic joints
cannot be in the chain (stiffcal's model is one compliance per revolute joint).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .robot import GRAVITY_M_S2, MAX_JOINT_ANGLE_DEG, Chain, MassModel, rotation_about

#: largest URDF file read [bytes] (meshes are referenced, not embedded: real URDFs are far smaller)
MAX_URDF_BYTES = 10_000_000
#: Pinocchio joint types (``JointModel.shortname()``) of revolute joints with limits, and of continuous ones
REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
CONTINUOUS = ("JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned")
#: names listed in a message at most (the message itself is capped at errors.MAX_MESSAGE characters)
_MAX_LISTED = 40


@dataclass(frozen=True)
class UrdfArm:
    """What :func:`read_chain` returns: names (n,) of the moving joints, base to tip; chain
    (:class:`stiffcal.robot.Chain`, base frame to tip frame); limits_rad (n, 2) [rad] (continuous joints:
    [-pi, pi], a full turn); has_limits: some joint is revolute (limited); unlimited: indices of the continuous
    joints, which have no limits; masses: the URDF's inertias as point masses on the moving joints' frames
    (:func:`chain_masses`), None when it has none."""

    names: tuple[str, ...]
    chain: Chain
    limits_rad: np.ndarray
    has_limits: bool
    unlimited: tuple[int, ...] = ()
    masses: MassModel | None = None


def _listing(names, near: str | None = None) -> str:
    """``names`` for a message, the ones closest to ``near`` (the name given, by :mod:`difflib`) first."""
    import difflib

    names = list(dict.fromkeys(names))
    if near is not None:
        close = difflib.get_close_matches(near, names, n=len(names), cutoff=0.5)
        names = close + [n for n in names if n not in close]
    more = f", ... ({len(names) - _MAX_LISTED} more)" if len(names) > _MAX_LISTED else ""
    return ", ".join(names[:_MAX_LISTED]) + more


def _check_text(path: Path, source: str) -> str:
    """The URDF's text, refused (naming the robot file's field ``urdf``) when missing, too large, not UTF-8,
    not well-formed XML, with entity declarations, or not a ``<robot>``."""
    import xml.etree.ElementTree as ET

    def bad(msg):
        return InputError(f"{msg} (the URDF {path})", source=source, field="urdf")

    if not path.is_file():
        raise bad("no such file")
    if path.stat().st_size > MAX_URDF_BYTES:
        raise bad(f"larger than {MAX_URDF_BYTES // 1_000_000} MB")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise bad(f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    if "<!ENTITY" in text or "<!DOCTYPE" in text:
        raise bad("XML entity or DOCTYPE declarations are not allowed")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise bad(f"not well-formed XML: {err}") from None
    if root.tag != "robot":
        raise bad(f"expected the root element <robot>, got <{root.tag}>")
    return text


def _build_model(path: Path, source: str):
    """Pinocchio's model of the URDF; urdfdom's own message (it writes to the C stderr) becomes the error."""
    import pinocchio as pin

    sys_err = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as log:
        os.dup2(log.fileno(), 2)
        try:
            model = pin.buildModelFromUrdf(str(path))
            error = None
        except (ValueError, RuntimeError) as err:
            model, error = None, err
        finally:
            os.dup2(sys_err, 2)
            os.close(sys_err)
        log.seek(0)
        said = [line.strip() for line in log.read().decode("utf-8", "replace").splitlines()
                if line.strip().startswith("Error:")]
    if model is None:
        why = said[0].removeprefix("Error:").strip() if said else str(error)
        raise InputError(f"the URDF {path} is not a valid URDF model: {why}", source=source, field="urdf")
    return model


def _frame(model, name: str, source: str, field: str) -> int:
    """Index of the frame called ``name`` (a link's body frame first, else a joint's or another frame)."""
    found = [i for i, f in enumerate(model.frames) if f.name == name]
    if not found:
        links = [f.name for f in model.frames if str(f.type).endswith("BODY")]
        raise InputError(f"the URDF has no link or frame {name!r}; its links, the closest names first: "
                         f"{_listing(links, name)}", source=source, field=field)
    body = [i for i in found if str(model.frames[i].type).endswith("BODY")]
    return (body or found)[0]


def _ancestors(model, joint: int) -> list[int]:
    """Joints from the root (excluded: the universe, 0) down to ``joint`` (included)."""
    out = []
    while joint != 0:
        out.append(joint)
        joint = model.parents[joint]
    return out[::-1]


def _mimic_joints(text: str) -> set[str]:
    import xml.etree.ElementTree as ET

    return {j.get("name") for j in ET.fromstring(text).iter("joint") if j.find("mimic") is not None}


def read_chain(urdf_path: str | Path, base_frame: str, tip_frame: str, joints=None, fixed_joints_deg=None,
               source: str = "<memory>") -> UrdfArm:
    """The serial chain of a URDF from ``base_frame`` to ``tip_frame`` (module docstring).

    urdf_path: the URDF file; base_frame, tip_frame: names of links (or other frames) of it, the base an
    ancestor of the tip; joints: the names of the joints that move, in order from base to tip (default every
    joint between the two frames); fixed_joints_deg: {name: angle [deg]} of chain joints that do not move
    (default 0 deg, which must then lie within the joint's limits). Raises :class:`InputError` naming
    ``source`` (the robot file) and its field: a URDF that cannot be read, an unknown frame, a base that is
    not on the tip's path, a prismatic, floating or mimic joint in the chain, a joint name that is not in the
    chain or out of order, a held angle outside its joint's limits, limits wider than
    :data:`~stiffcal.robot.MAX_JOINT_ANGLE_DEG`.
    """
    import pinocchio as pin

    path = Path(urdf_path)
    mimic = _mimic_joints(_check_text(path, source))
    model = _build_model(path, source)
    b, t = _frame(model, base_frame, source, "base_frame"), _frame(model, tip_frame, source, "tip_frame")
    jb, jt = model.frames[b].parentJoint, model.frames[t].parentJoint
    below_base, to_tip = _ancestors(model, jb), _ancestors(model, jt)
    if to_tip[:len(below_base)] != below_base:
        raise InputError(f"{base_frame!r} is not on the path from the URDF's root to {tip_frame!r}: expected a base "
                         "frame that the tip frame hangs from (a serial chain from base to tip)", source=source,
                         field="base_frame")
    path_joints = to_tip[len(below_base):]
    names = [model.names[j] for j in path_joints]
    if not path_joints:
        raise InputError(f"no joint moves {tip_frame!r} relative to {base_frame!r}", source=source, field="tip_frame")

    data = model.createData()
    pin.computeJointJacobians(model, data, pin.neutral(model))
    axes, limits = {}, {}
    for j, name in zip(path_joints, names):
        kind = model.joints[j].shortname()
        if name in mimic:
            raise InputError(f"joint {name!r} of the chain mimics another joint; stiffcal needs independent revolute "
                             "joints", source=source, field="urdf")
        if kind not in REVOLUTE + CONTINUOUS:
            raise InputError(f"joint {name!r} of the chain from {base_frame!r} to {tip_frame!r} is not revolute or "
                             f"continuous (Pinocchio: {kind}); stiffcal models one compliance per revolute joint",
                             source=source, field="urdf")
        axis = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.LOCAL)[3:, model.idx_vs[j]]
        axes[name] = axis / np.linalg.norm(axis)
        if kind in REVOLUTE:
            lo, hi = model.lowerPositionLimit[model.idx_qs[j]], model.upperPositionLimit[model.idx_qs[j]]
            if not lo < hi:
                raise InputError(f"joint {name!r} has limits lower {lo:g} >= upper {hi:g} rad in the URDF; expected "
                                 "lower < upper", source=source, field="urdf")
            if max(abs(lo), abs(hi)) > np.radians(MAX_JOINT_ANGLE_DEG) + 1e-9:
                raise InputError(f"joint {name!r} has limits [{np.degrees(lo):g}, {np.degrees(hi):g}] deg in the URDF; "
                                 f"expected within +-{MAX_JOINT_ANGLE_DEG:g} deg", source=source, field="urdf")
            limits[name] = (lo, hi)

    moving = _moving(names, joints, source)
    held = _held(names, moving, limits, fixed_joints_deg, source)
    C = model.frames[b].placement.inverse().homogeneous
    placements, chain_axes = [], []
    for j, name in zip(path_joints, names):
        C = C @ model.jointPlacements[j].homogeneous
        if name in moving:
            placements.append(C)
            chain_axes.append(axes[name])
            C = np.eye(4)
        else:
            rot = np.eye(4)
            rot[:3, :3] = rotation_about(axes[name], held[name])
            C = C @ rot
    chain = Chain(np.array(placements), np.array(chain_axes), C @ model.frames[t].placement.homogeneous)
    lim = np.array([limits.get(name, (-np.pi, np.pi)) for name in moving], float)
    moving_ids = [j for j, name in zip(path_joints, names) if name in moving]
    return UrdfArm(tuple(moving), chain, lim, any(name in limits for name in moving),
                   tuple(i for i, name in enumerate(moving) if name not in limits),
                   chain_masses(model, moving_ids, {j: held[name] for j, name in zip(path_joints, names)
                                                    if name in held}))


def chain_masses(model, moving: list[int], held: dict[int, float]) -> MassModel | None:
    """The URDF's inertias as point masses on the frames of the moving joints (:class:`MassModel`; gravity the
    default, -z of the base frame, until the robot file says otherwise): every body of the model (Pinocchio
    merges the links of fixed joints into their parent's body) whose nearest moving ancestor joint is in
    ``moving`` (Pinocchio joint ids, base to tip), its mass and centre in that joint's frame, with the chain's
    held joints at their angles ``held`` {joint id: rad} and other joints (off the chain: a gripper's fingers)
    at Pinocchio's neutral configuration. Bodies before the first moving joint never move and are left out.
    None when no such body has mass."""
    import pinocchio as pin

    q0 = pin.neutral(model)
    for j, angle in held.items():
        jm = model.joints[j]
        if jm.nq == 1:
            q0[jm.idx_q] = angle
        else:  # a continuous joint: (cos, sin)
            q0[jm.idx_q:jm.idx_q + 2] = [np.cos(angle), np.sin(angle)]
    data = model.createData()
    pin.forwardKinematics(model, data, q0)
    index = {j: i for i, j in enumerate(moving)}
    kg, link, com = [], [], []
    for b in range(1, model.njoints):
        mass = float(model.inertias[b].mass)
        if not mass > 0:
            continue
        a = b
        while a != 0 and a not in index:
            a = model.parents[a]
        if a == 0:
            continue
        centre = data.oMi[b].act(model.inertias[b].lever)
        kg.append(mass)
        link.append(index[a])
        com.append(data.oMi[a].actInv(centre))
    if not kg:
        return None
    return MassModel(np.array(kg), np.array(link, int), np.array(com, float), np.array(GRAVITY_M_S2[3]))


def _moving(names: list[str], joints, source: str) -> list[str]:
    """The joints that move: ``joints`` checked against the chain (every chain joint when None)."""
    if joints is None:
        return list(names)
    for i, name in enumerate(joints):
        if name not in names:
            raise InputError(f"joint {name!r} is not in the chain; its joints, base to tip: {', '.join(names)}",
                             source=source, field=f"joints[{i}]")
        if name in joints[:i]:
            raise InputError(f"joint {name!r} is listed twice", source=source, field=f"joints[{i}]")
    order = [n for n in names if n in joints]
    if list(joints) != order:
        raise InputError(f"expected the joints in their order from base to tip: {', '.join(order)}", source=source,
                         field="joints")
    return order


def _held(names: list[str], moving: list[str], limits: dict, fixed_joints_deg, source: str) -> dict[str, float]:
    """Angle [rad] of every chain joint that does not move: ``fixed_joints_deg`` or 0, within its limits."""
    given = dict(fixed_joints_deg or {})
    for name in given:
        if name not in names or name in moving:
            what = "moves (it is in 'joints')" if name in moving else "is not in the chain"
            raise InputError(f"joint {name!r} {what}; expected one of the chain's joints held fixed: "
                             f"{_listing([n for n in names if n not in moving]) or 'none'}", source=source,
                             field=f"fixed_joints_deg.{name}")
    held = {}
    for name in (n for n in names if n not in moving):
        q = np.radians(float(given.get(name, 0.0)))
        if name in limits and not limits[name][0] - 1e-12 <= q <= limits[name][1] + 1e-12:
            lo, hi = np.degrees(limits[name])
            stated = f"{given[name]:g} deg" if name in given else "0 deg (the default)"
            raise InputError(f"joint {name!r} is held at {stated}, outside its limits [{lo:g}, {hi:g}] deg; give an "
                             "angle within them", source=source, field=f"fixed_joints_deg.{name}")
        held[name] = q
    return held
