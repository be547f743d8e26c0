"""Robot files of ``kind: urdf``: the serial chain of a URDF between two of its frames, read with Pinocchio.

A URDF (ROS's Unified Robot Description Format, http://wiki.ros.org/urdf/XML) describes a tree of links
joined by joints, each joint placed in its parent link's frame (``<origin xyz rpy>``) and turning about its
``<axis>``. Pinocchio (Carpentier et al., "The Pinocchio C++ library", SII 2019; its URDF parser is ROS's
urdfdom) reads the file into a model of joints and frames; :func:`read_chain` takes from that model the
joints on the path from ``base_frame`` to ``tip_frame`` and folds everything between two moving joints (fixed
joints, and chain joints held at a stated angle) into one fixed transform: a
:class:`stiffcal.model.robot.Chain` of placements and axes. The library then evaluates the kinematics with numpy,
batched over arrays of poses of any shape like the planar and DH kinds, which also gives every joint's axis
in the base frame (:meth:`stiffcal.model.robot.Robot.joint_frames`: the Jacobian of any point of the tip frame)
and keeps the :class:`~stiffcal.model.robot.Robot` a plain array-holding value. It costs about what Pinocchio costs
called once per pose (``benchmarks/bench_urdf.py``: the Jacobian at 32768 poses in 0.057 s of CPU, Pinocchio
0.060 s for position and Jacobian; the DH table 0.044 s); the tests check it against Pinocchio's own forward
kinematics and frame Jacobian, pose by pose.

Joints: ``revolute`` joints keep the URDF's ``<limit lower upper>`` as their joint limits; ``continuous``
joints have none (their angle is reported in [-180, 180) deg). Prismatic, floating, planar and mimic joints
cannot be in the chain (stiffcal's model is one compliance per revolute joint).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..limits import MAX_JOINTS, MAX_URDF_BYTES
from .robot import GRAVITY_M_S2, MAX_JOINT_ANGLE_DEG, Chain, MassModel, rotation_about

#: Pinocchio joint types (``JointModel.shortname()``) of revolute joints with limits, and of continuous ones
REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
CONTINUOUS = ("JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned")
#: names listed in a message at most (the message itself is capped at errors.MAX_MESSAGE characters)
_MAX_LISTED = 40


@dataclass(frozen=True)
class UrdfArm:
    """What :func:`read_chain` returns: names (n,) of the moving joints, base to tip; chain
    (:class:`stiffcal.model.robot.Chain`, base frame to tip frame); limits_rad (n, 2) [rad] (continuous joints:
    [-pi, pi], a full turn); has_limits: some joint is revolute (limited); unlimited: indices of the continuous
    joints, which have no limits; masses: the URDF's inertias as point masses on the moving joints' frames
    (:func:`chain_masses`), None when it has none; held: {name: angle [rad]} of the chain joints that do not
    move."""

    names: tuple[str, ...]
    chain: Chain
    limits_rad: np.ndarray
    has_limits: bool
    unlimited: tuple[int, ...] = ()
    masses: MassModel | None = None
    held: dict = field(default_factory=dict)


def _listing(names, near: str | None = None) -> str:
    """``names`` for a message, the ones closest to ``near`` (the name given) first: the same name but for case,
    then names that begin with it, then by :mod:`difflib`'s similarity (at least 0.5), ties in the file's order (a
    fresh user's 'link0' listed link06 .. link00, the one meant last)."""
    import difflib

    names = list(dict.fromkeys(names))
    if near is not None:
        low = near.lower()

        def rank(i_name):
            i, n = i_name
            return (n.lower() != low, not n.lower().startswith(low),
                    -round(difflib.SequenceMatcher(None, near, n).ratio(), 12), i)
        close = [n for _, n in sorted(enumerate(names), key=rank)
                 if n.lower().startswith(low) or difflib.SequenceMatcher(None, near, n).ratio() >= 0.5]
        names = close + [n for n in names if n not in close]
    more = f", ... ({len(names) - _MAX_LISTED} more)" if len(names) > _MAX_LISTED else ""
    return ", ".join(names[:_MAX_LISTED]) + more


#: XML namespaces of xacro (ROS's XML macro language), whose files must be expanded into a URDF first
XACRO_NAMESPACES = ("http://www.ros.org/wiki/xacro", "http://ros.org/wiki/xacro", "http://wiki.ros.org/xacro")


def collision_meshes(urdf_path: str | Path) -> list[str]:
    """The mesh files of the URDF's ``<collision>`` geometry that exist, as the cell's geometry reads them
    (``package://name/...`` looked for in every directory above the URDF, :func:`stiffcal.model.workcell._package_dirs`;
    ``file://`` and relative names against the URDF's folder), sorted, as absolute paths. Nothing for a URDF that
    cannot be read (loading it reports why). The workflow lists them as inputs of a robot in a cell."""
    from .workcell import _package_dirs

    path = Path(urdf_path)
    try:
        root = _check_text(path, str(path))
    except InputError:
        return []
    found = set()
    for collision in root.iter("collision"):
        for mesh in collision.iter("mesh"):
            name = mesh.get("filename", "")
            if name.startswith("package://"):
                rest = name[len("package://"):]
                candidates = [Path(parent) / rest for parent in _package_dirs(path)]
            else:
                name = name[len("file://"):] if name.startswith("file://") else name
                candidates = [path.resolve().parent / name] if name else []
            hit = next((c for c in candidates if c.is_file()), None)
            if hit is not None:
                found.add(str(hit))
    return sorted(found)


def _check_text(path: Path, source: str):
    """The URDF's parsed XML (its root element), refused (naming the robot file's field ``urdf``) when missing,
    not a regular file (a directory, a FIFO, a device), too large, not UTF-8, a xacro file, not well-formed XML,
    with a DOCTYPE or entity declarations (parsed with ``defusedxml``, so a comment that mentions them is fine),
    not a ``<robot>``, or when its links and joints (:func:`_check_elements`) are out of range."""
    import defusedxml.ElementTree as DET
    from defusedxml import DefusedXmlException

    from ..safeio import file_kind

    def bad(msg):
        return InputError(f"{msg} (the URDF {path})", source=source, field="urdf")

    try:
        st = path.stat()
    except OSError:
        raise bad("no such file") from None
    kind = file_kind(st.st_mode)
    if kind:
        raise bad(f"expected a URDF file, but it is {kind}: refused without reading it")
    if st.st_size > MAX_URDF_BYTES:
        raise bad(f"larger than {MAX_URDF_BYTES // 1_000_000} MB (the largest URDF read; docs/contracts.md, 'Limits')")
    from ..safeio import read_bounded

    raw = read_bounded(path, MAX_URDF_BYTES, source=source, field="urdf", what="URDF")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise bad(f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    xacro = bad("a xacro file (ROS's XML macros and ${...} expressions), not a URDF: expand it first, e.g. 'xacro "
                "FILE.urdf.xacro > FILE.urdf' (ROS's xacro package), and name the .urdf")
    if "xacro" in path.name.lower().split(".")[1:]:
        raise xacro
    try:
        root = DET.fromstring(text, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException:
        raise bad("XML entity or DOCTYPE declarations are not allowed") from None
    except DET.ParseError as err:
        if "<xacro:" in text:  # macros without their namespace declared
            raise xacro from None
        raise bad(f"not well-formed XML: {err}") from None
    if any(str(e.tag).startswith(tuple("{" + ns + "}" for ns in XACRO_NAMESPACES)) for e in root.iter()) or any(
            "${" in v or "$(" in v for e in root.iter() for v in e.attrib.values()):
        raise xacro  # an expanded file keeps the namespace declaration (harmless), never its elements
    if root.tag != "robot":
        raise bad(f"expected the root element <robot>, got <{str(root.tag)[:80]}>")
    _check_elements(root, bad)
    return root


def _numbers(element, attribute: str, default: str, what: str, bad) -> np.ndarray:
    """The 3 finite numbers of ``element``'s ``attribute`` (``default`` when the element or attribute is
    absent), or InputError from ``bad``."""
    text = default if element is None else element.get(attribute, default)
    try:
        vals = np.array([float(v) for v in text.split()], float)
    except ValueError:
        vals = np.zeros(0)
    if vals.size != 3 or not np.all(np.isfinite(vals)):
        raise bad(f"{what}: expected 3 finite numbers, got {text[:80]!r}")
    return vals


def _check_tree(links, joints, bad) -> None:
    """The joints join declared links into a tree: every joint's parent and child are ``<link>`` s, no link is
    the child of two joints, and following parents never comes back to a link (no loop). Linear in the size."""
    names = {e.get("name") for e in links}
    parent_of = {}
    for j in joints:
        name = j.get("name")[:80]
        ends = {}
        for end in ("parent", "child"):
            e = j.find(end)
            ends[end] = None if e is None else e.get("link")
            if ends[end] not in names:
                given = "none" if ends[end] is None else repr(str(ends[end])[:80])
                raise bad(f"joint {name!r}: <{end} link> {given}: expected one of the URDF's links")
        child = ends["child"]
        if child in parent_of:
            raise bad(f"link {child[:80]!r} is the child of two joints, {parent_of[child][0]!r} and {name!r}: expected "
                      "a tree (each link hangs from one joint)")
        parent_of[child] = (name, ends["parent"])
    reaches_root = set()
    for start in parent_of:
        path, link = set(), start
        while link in parent_of and link not in reaches_root:
            if link in path:
                raise bad(f"the joints form a loop through link {link[:80]!r} (joint {parent_of[link][0]!r}): "
                          "expected a tree from one root link")
            path.add(link)
            link = parent_of[link][1]
        reaches_root |= path


def _check_elements(root, bad) -> None:
    """The URDF's links and joints before Pinocchio reads them (:mod:`stiffcal.limits`): at most
    :data:`~stiffcal.limits.MAX_URDF_ELEMENTS` of them, names present and unique, every joint's origin within
    +-:data:`~stiffcal.limits.MAX_LENGTH_M` m and +-:data:`~stiffcal.limits.MAX_RPY_RAD` rad, every axis of a
    joint that moves a direction (not the zero vector), every limit a finite number."""
    from ..limits import MAX_AXIS_NORM, MAX_LENGTH_M, MAX_RPY_RAD, MAX_URDF_ELEMENTS, MIN_AXIS_NORM

    links, joints = root.findall("link"), root.findall("joint")
    if len(links) + len(joints) > MAX_URDF_ELEMENTS:
        raise bad(f"{len(links)} links and {len(joints)} joints: expected at most {MAX_URDF_ELEMENTS} in all (the "
                  "largest URDF read; docs/contracts.md, 'Limits')")
    for tag, elements in (("link", links), ("joint", joints)):
        seen = set()
        for e in elements:
            name = e.get("name")
            if not name or not name.strip():
                raise bad(f"a <{tag}> without a name")
            if name in seen:
                raise bad(f"two {tag}s named {name[:80]!r}: expected unique {tag} names")
            seen.add(name)
    _check_tree(links, joints, bad)
    for j in joints:
        name = j.get("name")[:80]
        origin = j.find("origin")
        xyz = _numbers(origin, "xyz", "0 0 0", f"joint {name!r}: <origin xyz>", bad)
        if np.abs(xyz).max() > MAX_LENGTH_M:
            raise bad(f"joint {name!r}: <origin xyz> {np.abs(xyz).max():g} m: expected coordinates of at most "
                      f"{MAX_LENGTH_M:g} m (the physical range of lengths)")
        rpy = _numbers(origin, "rpy", "0 0 0", f"joint {name!r}: <origin rpy>", bad)
        if np.abs(rpy).max() > MAX_RPY_RAD:
            raise bad(f"joint {name!r}: <origin rpy> {np.abs(rpy).max():g} rad: expected angles of at most "
                      f"{MAX_RPY_RAD:g} rad")
        if j.get("type") in ("revolute", "continuous", "prismatic"):
            axis = _numbers(j.find("axis"), "xyz", "1 0 0", f"joint {name!r}: <axis xyz>", bad)
            norm = math.hypot(*axis)  # no overflow for large components
            if not MIN_AXIS_NORM <= norm <= MAX_AXIS_NORM:
                raise bad(f"joint {name!r}: <axis xyz> {' '.join(f'{v:g}' for v in axis)}: expected a direction "
                          f"(a vector of length between {MIN_AXIS_NORM:g} and {MAX_AXIS_NORM:g}, such as '0 0 1')"
                          + (", not the zero vector" if norm == 0 else ""))
        limit = j.find("limit")
        if limit is not None:
            for key in ("lower", "upper"):
                try:
                    ok = key not in limit.attrib or np.isfinite(float(limit.get(key)))
                except ValueError:
                    ok = False
                if not ok:
                    raise bad(f"joint {name!r}: <limit {key}> {limit.get(key)[:40]!r}: expected a finite number [rad]")


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


def _joint_axis(model, j: int, neutral: np.ndarray) -> np.ndarray:
    """The unit axis (3,) of the revolute or continuous joint ``j`` of a Pinocchio model in its own frame: the
    angular part of its motion subspace at its neutral angle, from the joint's own data (no Data of the whole
    model is made: its matrices grow with the square of the URDF's joints)."""
    joint = model.joints[j]
    data = joint.createData()
    joint.calc(data, neutral[model.idx_qs[j]:model.idx_qs[j] + joint.nq])
    axis = np.asarray(data.S.matrix() if hasattr(data.S, "matrix") else data.S, float).reshape(6, -1)[3:, 0]
    return axis / np.linalg.norm(axis)


def frame_index(model, name: str, source: str = "", field: str = "") -> int:
    """Index of the frame called ``name`` (a link's body frame first, else a joint's or another frame: a URDF may
    name a link and a fixed joint alike, where pinocchio's ``getFrameId`` without a type raises). InputError
    naming ``field`` when there is none."""
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


def _mimic_joints(root) -> set[str]:
    return {j.get("name") for j in root.iter("joint") if j.find("mimic") is not None}


def chain_frames(urdf_path: str | Path, base_frame: str | None = None, tip_frame: str | None = None,
                 source: str = "<memory>") -> tuple[str, str]:
    """(base_frame, tip_frame) of the arm of a URDF: the given ones, else guessed from its tree of links. The base:
    the root link (the one no joint has as its child). The tip: of the leaf links, those reached through the most
    revolute (or continuous) joints; a single one is the tip; several that hang by fixed joints from the same
    last moving link (a flange's tool frames, a gripper's fingers) give that link, the flange. Raises
    :class:`InputError` naming ``tip_frame`` (or ``base_frame``) when the URDF has no single root or its longest
    chains end in different links, listing them."""
    root = _check_text(Path(urdf_path), source)
    joints = [(j.get("type"), j.find("parent"), j.find("child")) for j in root.findall("joint")]
    edges = [(t, pa.get("link"), ch.get("link")) for t, pa, ch in joints if pa is not None and ch is not None]
    parent_of = {child: (t, parent) for t, parent, child in edges}
    links = [link.get("name") for link in root.findall("link")]
    if base_frame is None:
        roots = [name for name in links if name not in parent_of]
        if len(roots) != 1:
            raise InputError(f"expected one root link (the arm's base), got {len(roots)}: {_listing(roots)}; name "
                             "the base frame", source=source, field="base_frame")
        base_frame = roots[0]
    if tip_frame is not None:
        return base_frame, tip_frame
    moving = ("revolute", "continuous")

    def last_moving(link):  # (revolute joints from the base to link, the link after the last of them)
        count, flange = 0, None
        while link in parent_of and link != base_frame:
            kind, parent = parent_of[link]
            if kind in moving:
                count += 1
                flange = flange or link
            link = parent
        return count, flange

    leaves = [name for name in links if name not in {parent for _, parent, _ in edges}]
    counted = {leaf: last_moving(leaf) for leaf in leaves}
    most = max((c for c, _ in counted.values()), default=0)
    tips = [leaf for leaf, (c, _) in counted.items() if c == most and c > 0]
    flanges = {counted[leaf][1] for leaf in tips}
    if len(tips) == 1:
        return base_frame, tips[0]
    if len(flanges) == 1 and tips:
        return base_frame, flanges.pop()
    raise InputError(f"the URDF's longest chains ({most} revolute joints) end in {_listing(tips)}: name the tip frame "
                     "(load_robot(path, tip_frame=...), or a robot file's tip_frame)", source=source,
                     field="tip_frame")


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
    :data:`~stiffcal.model.robot.MAX_JOINT_ANGLE_DEG`, more than :data:`~stiffcal.limits.MAX_JOINTS` moving joints.
    """
    path = Path(urdf_path)
    mimic = _mimic_joints(_check_text(path, source))
    model = _build_model(path, source)
    b, t = frame_index(model, base_frame, source, "base_frame"), frame_index(model, tip_frame, source, "tip_frame")
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

    axes, limits = _chain_joints(model, path_joints, names, mimic, base_frame, tip_frame, source)
    moving = _moving(names, joints, source)
    if len(moving) > MAX_JOINTS:
        raise InputError(f"{len(moving)} joints move between {base_frame!r} and {tip_frame!r}: expected at most "
                         f"{MAX_JOINTS} (the design's searches grow exponentially with the joints; docs/contracts.md, "
                         "'Limits'); name the joints that move in 'joints' and hold the others with "
                         "'fixed_joints_deg'", source=source, field="joints" if joints is not None else "tip_frame")
    held = _held(names, moving, limits, fixed_joints_deg, source)
    chain = _moving_chain(model, b, t, path_joints, names, moving, axes, held)
    lim = np.array([limits.get(name, (-np.pi, np.pi)) for name in moving], float)
    moving_ids = [j for j, name in zip(path_joints, names) if name in moving]
    return UrdfArm(tuple(moving), chain, lim, any(name in limits for name in moving),
                   tuple(i for i, name in enumerate(moving) if name not in limits),
                   chain_masses(model, moving_ids, {j: (held[name], axes[name]) for j, name in zip(path_joints, names)
                                                    if name in held}), held)


def _chain_joints(model, path_joints: list[int], names: list[str], mimic, base_frame: str, tip_frame: str,
                  source: str) -> tuple[dict, dict]:
    """({name: unit axis (3,)}, {name: (lower, upper) [rad]} of the limited ones) of the chain's joints; InputError
    for a mimic joint, a joint that is not revolute or continuous, or limits that are inverted or too wide."""
    import pinocchio as pin

    axes, limits, neutral = {}, {}, pin.neutral(model)
    for j, name in zip(path_joints, names):
        kind = model.joints[j].shortname()
        if name in mimic:
            raise InputError(f"joint {name!r} of the chain mimics another joint; stiffcal needs independent revolute "
                             "joints", source=source, field="urdf")
        if kind not in REVOLUTE + CONTINUOUS:
            raise InputError(f"joint {name!r} of the chain from {base_frame!r} to {tip_frame!r} is not revolute or "
                             f"continuous (Pinocchio: {kind}); stiffcal models one compliance per revolute joint",
                             source=source, field="urdf")
        axes[name] = _joint_axis(model, j, neutral)
        if kind in REVOLUTE:
            lo, hi = model.lowerPositionLimit[model.idx_qs[j]], model.upperPositionLimit[model.idx_qs[j]]
            if not lo < hi:
                raise InputError(f"joint {name!r} has limits lower {lo:g} >= upper {hi:g} rad in the URDF; expected "
                                 "lower < upper", source=source, field="urdf")
            if max(abs(lo), abs(hi)) > np.radians(MAX_JOINT_ANGLE_DEG) + 1e-9:
                raise InputError(f"joint {name!r} has limits [{np.degrees(lo):g}, {np.degrees(hi):g}] deg in the URDF; "
                                 f"expected within +-{MAX_JOINT_ANGLE_DEG:g} deg", source=source, field="urdf")
            limits[name] = (lo, hi)
    return axes, limits


def _moving_chain(model, b: int, t: int, path_joints: list[int], names: list[str], moving, axes: dict,
                  held: dict) -> Chain:
    """The chain of the moving joints from frame ``b`` to frame ``t``: the held joints folded into the placements
    at their held angles."""
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
    return Chain(np.array(placements), np.array(chain_axes), C @ model.frames[t].placement.homogeneous)


def chain_masses(model, moving: list[int], held: dict[int, tuple]) -> MassModel | None:
    """The URDF's inertias as point masses on the frames of the moving joints (:class:`MassModel`; gravity the
    default, -z of the base frame, until the robot file says otherwise): every body of the model (Pinocchio
    merges the links of fixed joints into their parent's body) whose nearest moving ancestor joint is in
    ``moving`` (Pinocchio joint ids, base to tip), its mass and centre in that joint's frame, with the chain's
    held joints at their angles ``held`` {joint id: (rad, unit axis (3,) in the joint's frame)} and other joints
    (off the chain: a gripper's fingers) at Pinocchio's neutral configuration. Bodies before the first moving
    joint never move and are left out.
    None when no such body has mass."""
    import pinocchio as pin

    index = {j: i for i, j in enumerate(moving)}
    kg, link, com = [], [], []
    placed: dict[int, object] = {0: pin.SE3.Identity()}

    def motion(j):  # joint j's own motion: a held chain joint turned by its angle about its axis; every other
        if j in held:  # joint at Pinocchio's neutral configuration, whose motion is the identity for every type
            angle, axis = held[j]
            return pin.SE3(rotation_about(np.asarray(axis, float), angle), np.zeros(3))
        return pin.SE3.Identity()

    def placement(j):  # joint j's frame in the model's root frame, joint by joint (no Data of the whole model:
        if j not in placed:  # its matrices grow with the square of the URDF's joints; and no JointData, whose
            # calc on the variant binding acts on a copy and leaves M unset)
            placed[j] = placement(model.parents[j]) * model.jointPlacements[j] * motion(j)
        return placed[j]

    for b in range(1, model.njoints):
        mass = float(model.inertias[b].mass)
        if not mass > 0:
            continue
        a = b
        while a != 0 and a not in index:
            a = model.parents[a]
        if a == 0:
            continue
        centre = placement(b).act(model.inertias[b].lever)
        kg.append(mass)
        link.append(index[a])
        com.append(placement(a).actInv(centre))
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
