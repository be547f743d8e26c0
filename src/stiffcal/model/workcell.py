"""The cell a robot stands in, and which poses it can take there: one feasibility engine for every plan.

A :class:`WorkCell` (robot-file key ``cell:``, docs/contracts.md) describes where the robot stands, in its base
frame: half-spaces (``floor_m``, the mounting plane under the base, and ``half_spaces``: a table, a wall),
``boxes`` and ``cylinders``, a minimum ``clearance_m`` between bodies, and self-collision. A pose is feasible
when every check below holds; :func:`feasible` answers for arrays of poses (vectorised over poses, cached),
:func:`clearance` gives the smallest distance for reporting.

The robot's bodies
------------------
* URDF arms with collision geometry (``<collision>`` meshes and shapes): Pinocchio's geometry model of the URDF
  (``pinocchio.buildGeomFromUrdf``), checked by coal (Pan et al., FCL; coal is its successor) through
  ``pinocchio.computeCollisionsInParallel`` on one thread, each pair with a security margin (the clearance):
  a pair is in collision when its distance is below its margin. Self-collision pairs: every pair of bodies
  that are not on the same joint, not on joints next to each other (a joint and its parent: adjacent links),
  not moved by the same joints of the chain (both fixed to the base, or both held on one link: a gripper's fingers
  whose own joints are not in the chain never move relative to each other), and not disabled by the SRDF
  (``cell.srdf``, ``pinocchio.removeCollisionPairs``).
  Against a half-space a body's convex hull is used: its signed distance to a plane is the same as the mesh's
  (the extreme point in a direction is a vertex of the hull), at a hundredth of the cost.
* Planar and DH arms, and URDF arms without collision geometry or with ``link_radius_m`` given: capsules of
  radius ``link_radius_m`` around the segments of :meth:`stiffcal.model.robot.Robot.link_points` (segment k from
  point k to point k + 1), checked here in numpy: segment-segment distances (Ericson, *Real-Time Collision
  Detection*, sec. 5.1.9) for self-collision (segments that are not consecutive), and for an obstacle the
  minimum of its signed distance function along the segment, which is convex along it (the signed distance to
  a convex set is convex), found by golden-section search to 1e-10 of the segment's length (after cheaper
  bounds: the sdf is 1-Lipschitz). The segment that starts at the base origin stands on the mounting plane:
  against a half-space only its far end (a sphere of its radius) is checked; against boxes and cylinders all of
  it (a pedestal under the base is the floor: ``floor_m`` at its top).

Besides the bodies, every joint origin, the tip frame's origin, the tool point and the targets must lie on the
free side of every half-space and outside every box and cylinder (distance >= 0): the heights of the joints
above the mounting plane.

Pairs are probed once on random poses within the joint limits (:data:`PROBE_LOG2`): a self-collision pair
in collision at every probe pose (a pair the SRDF should disable) is not checked, and one within its margin
at every probe pose but not in collision is checked without the margin, each with a note; a pair of a body
and an obstacle in collision at every probe pose is refused (the cell leaves no pose), naming both.

Hanging masses
--------------
With hanging masses (loads ``hanging:``) the cable must be free too: the segment from the tool point along
gravity (the robot file's ``gravity``) of ``cable_length_m`` (from the tool point to the lowest point of the
hanging mass) must end on the free side of every half-space (a mass that would rest on the table or the floor
loads nothing), and must not pass through any body nor through a box or cylinder (distance >
``cable_clearance_m``, default 0: the cable is a line; give the cable's radius and sway, and the mass's radius, to
keep it off the arm's meshes). The body it hangs from (the link carrying the tool point) is checked from
:data:`CABLE_START_M` below the tool point (beyond a capsule's radius): a cable from a flange that faces sideways or
up runs through the flange itself (a fresh user's UR10: 22-49 mm of cable inside wrist_3_link in 18 of 34 planned
poses); a tool point inside that body's hull (a gripper's), at least :data:`CABLE_START_M` from its surface,
leaves that body unchecked (one on a fingertip's face does not: a fresh user's Panda hung its cable through the
fingertip boxes, 8.5 mm deep, in every planned pose). Without ``cable_length_m``
the segment runs down to the first half-space it meets (the floor: the mass's height is then not checked), else
:data:`CABLE_DEFAULT_M`.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .urdf import frame_index

#: 2**PROBE_LOG2 random poses within the joint limits decide which pairs are always in collision
PROBE_LOG2 = 8
#: golden-section iterations of the distance of a segment to a box or a cylinder (0.618**50 = 3.5e-11)
GOLDEN_ITERS = 50
#: a distance this far below its margin [m] still counts as meeting it (round-off)
TOL_M = 1e-9
#: a self pair in collision at this fraction of the probe poses or more (not all) is named when no pose is free
#: (:func:`no_pose_hint`): most likely a pair the SRDF should disable
FREQUENT_PAIR = 0.5
#: poses checked per batch (memory of the numpy engine, one call of the coal engine)
CHUNK = 4096
#: default cable length [m] when no half-space is below the tool point
CABLE_DEFAULT_M = 1.0
#: a body no joint moves (the base) may reach this far into an obstacle [m] (a base resting on its mounting plane,
#: its mesh a little below it) before the cell is refused
FIXED_OVERLAP_M = 5e-3
#: the body the cable hangs from is checked against the cable from this far below its start [m] (beyond the
#: cable's clearance and, for a capsule, its radius): the attachment itself touches it
CABLE_START_M = 1e-3
#: points sampled along a segment near a box or a cylinder before its exact distance is sought
SAMPLES = 33
#: batches of at least this many poses are cached (pools and search points are checked again and again)
CACHE_MIN = 256


# ---------------------------------------------------------------------------------------------------
# geometry in numpy

def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def segment_distance(p1, q1, p2, q2):
    """Distance between segments [p1, q1] and [p2, q2] (..., 3) [m] -> (...,), Ericson's closest points of two
    segments (degenerate segments, points, included)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    eps = 1e-24
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = a * e - b * b
        s = np.where(denom > eps * np.maximum(a * e, eps), np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
        t = np.where(e > eps, (b * s + f) / e, 0.0)
        s = np.where(t < 0, np.where(a > eps, np.clip(-c / a, 0.0, 1.0), 0.0), s)
        s = np.where(t > 1, np.where(a > eps, np.clip((b - c) / a, 0.0, 1.0), 0.0), s)
        t = np.clip(t, 0.0, 1.0)
        # a degenerate first segment: the point p1 against the second
        s = np.where(a <= eps, 0.0, s)
        t = np.where(a <= eps, np.where(e > eps, np.clip(f / e, 0.0, 1.0), 0.0), t)
        # a degenerate second segment: the point p2 against the first
        s = np.where((e <= eps) & (a > eps), np.clip(-c / a, 0.0, 1.0), s)
        t = np.where(e <= eps, 0.0, t)
    return np.linalg.norm(p1 + s[..., None] * d1 - p2 - t[..., None] * d2, axis=-1)


@dataclass(frozen=True)
class Obstacle:
    """One solid of the cell in the robot's base frame: ``kind`` 'half_space' (the solid is ``normal . x <
    offset``; the free side ``normal . x >= offset``, normal a unit vector), 'box' (centre, rotation (3, 3) whose
    columns are the box's axes, half sizes (3,)) or 'cylinder' (centre of its axis, unit axis, radius,
    half_length). Lengths in metres. Planar arms use them in their plane (z = 0): a box or a cylinder then
    reaches far along z (a rectangle, a disc)."""

    name: str
    kind: str
    normal: np.ndarray | None = None
    offset: float = 0.0
    center: np.ndarray | None = None
    rotation: np.ndarray | None = None
    half: np.ndarray | None = None
    axis: np.ndarray | None = None
    radius: float = 0.0
    half_length: float = 0.0
    flat: bool = False

    @property
    def bounding_radius(self) -> float:
        """The radius [m] of a sphere about the centre that holds a box or a cylinder (``flat``: a planar cell's
        rectangle or disc, of a circle in the plane z = 0 that holds it there)."""
        if self.kind == "box":
            return float(np.linalg.norm(self.half[:2] if self.flat else self.half))
        return float(self.radius if self.flat else np.hypot(self.radius, self.half_length))

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """Signed distance [m] of points p (..., 3) to the solid: > 0 outside, < 0 inside."""
        if self.kind == "half_space":
            return _dot(p, self.normal) - self.offset
        if self.kind == "box":
            local = (p - self.center) @ self.rotation
            d = np.abs(local) - self.half
            return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(d.max(axis=-1), 0.0)
        v = p - self.center
        along = _dot(v, self.axis)
        radial = np.linalg.norm(v - along[..., None] * self.axis, axis=-1)
        dr, da = radial - self.radius, np.abs(along) - self.half_length
        return np.hypot(np.maximum(dr, 0.0), np.maximum(da, 0.0)) + np.minimum(np.maximum(dr, da), 0.0)

    def box_segment_sdf(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The smallest signed distance of the segments [a, b] (..., 3) to a box, exactly: in the box's frame the
        squared distance outside is, between the breakpoints where a coordinate crosses a face, a sum of squares
        of linear functions of the segment's parameter t, minimised at a point that depends only on which
        coordinates are outside and on which side (26 candidates), and inside the signed distance is the largest
        of six linear functions, minimised where two of them cross (15); the minimum over [0, 1] is at one of
        these candidates, the 6 breakpoints or an end, all evaluated at once."""
        A = (a - self.center) @ self.rotation
        D = (b - a) @ self.rotation
        h = self.half
        with np.errstate(divide="ignore", invalid="ignore"):
            t = [np.zeros(A.shape[:-1]), np.ones(A.shape[:-1])]
            t += [(sh * h[i] - A[..., i]) / D[..., i] for i in range(3) for sh in (1.0, -1.0)]
            for S in _BOX_SUBSETS:
                for signs in S[1]:
                    num = sum(D[..., i] * (sg * h[i] - A[..., i]) for i, sg in zip(S[0], signs))
                    den = sum(D[..., i] ** 2 for i in S[0])
                    t.append(num / den)
            lin = [(i, sg) for i in range(3) for sg in (1.0, -1.0)]
            for x in range(6):
                for y in range(x + 1, 6):
                    (i, si), (j, sj) = lin[x], lin[y]
                    t.append((h[i] - h[j] - si * A[..., i] + sj * A[..., j]) / (si * D[..., i] - sj * D[..., j]))
        T = np.clip(np.nan_to_num(np.stack(t, axis=-1), nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        return self.sdf(a[..., None, :] + T[..., None] * (b - a)[..., None, :]).min(axis=-1)

    def segment_sdf(self, a: np.ndarray, b: np.ndarray, enough: float | None = None) -> np.ndarray:
        """The smallest signed distance of the segments [a, b] (..., 3) to the solid (...,): exact for a
        half-space (linear along the segment), golden-section search on the convex sdf otherwise. With
        ``enough`` [m], a segment whose lower bound ``sdf(middle) - length / 2`` (the sdf is 1-Lipschitz) is at
        least that gets the bound instead (all a feasibility check needs), the others the exact value."""
        if self.kind == "half_space":
            return np.minimum(self.sdf(a), self.sdf(b))
        exact = self.box_segment_sdf if self.kind == "box" else (lambda x, y: golden_min(self.sdf, x, y))
        if enough is None:
            return exact(a, b)
        length = np.linalg.norm(b - a, axis=-1)
        lower = np.maximum(self.sdf(0.5 * (a + b)) - 0.5 * length,
                           segment_distance(a, b, self.center, self.center) - self.bounding_radius)
        near = np.flatnonzero(lower < enough)
        if near.size and self.kind == "box":
            lower = np.array(lower, float)
            lower[near] = exact(a[near], b[near])
        elif near.size:  # samples along the segment: their minimum less half the spacing bounds it from below
            lower = np.array(lower, float)
            t = np.linspace(0.0, 1.0, SAMPLES)
            pts = a[near, None, :] + t[:, None] * (b - a)[near, None, :]
            sampled = self.sdf(pts).min(axis=-1)
            lower[near] = np.where(sampled < enough, sampled, sampled - 0.5 * length[near] / (SAMPLES - 1))
            close = near[(lower[near] < enough) & (sampled >= enough)]  # neither certain: the exact minimum
            if close.size:
                lower[close] = exact(a[close], b[close])
        return lower


#: the subsets of the box's coordinates that can be outside together, with every choice of sides
_BOX_SUBSETS = [(S, list(__import__("itertools").product((1.0, -1.0), repeat=len(S))))
                for k in (1, 2, 3) for S in __import__("itertools").combinations(range(3), k)]


def golden_min(fun, a: np.ndarray, b: np.ndarray, iters: int = GOLDEN_ITERS) -> np.ndarray:
    """min over t in [0, 1] of ``fun(a + t (b - a))`` for a function convex along each segment, vectorised over
    segments (..., 3): golden-section search, ends included."""
    g = (np.sqrt(5.0) - 1.0) / 2.0
    d = b - a
    lo, hi = np.zeros(a.shape[:-1]), np.ones(a.shape[:-1])
    x1, x2 = hi - g, lo + g
    f1, f2 = fun(a + x1[..., None] * d), fun(a + x2[..., None] * d)
    for _ in range(iters):
        left = f1 < f2  # the minimum lies in [lo, x2]
        hi, lo = np.where(left, x2, hi), np.where(left, lo, x1)
        x_new = np.where(left, hi - g * (hi - lo), lo + g * (hi - lo))
        f_new = fun(a + x_new[..., None] * d)
        x1, f1, x2, f2 = (np.where(left, x_new, x2), np.where(left, f_new, f2),
                          np.where(left, x1, x_new), np.where(left, f1, f_new))
        x1, x2, f1, f2 = np.minimum(x1, x2), np.maximum(x1, x2), np.where(x1 <= x2, f1, f2), np.where(x1 <= x2, f2, f1)
    return np.minimum(np.minimum(f1, f2), np.minimum(fun(a), fun(b)))


# ---------------------------------------------------------------------------------------------------
# the cell

#: the default ``self_clearance_m`` [m]: two bodies of the robot 1 um apart were "feasible" and touched at the
#: plan's printed digits by coal (a fresh user's Bravo 7: 13 of 35 poses within 5 um of self-contact, 3 in contact)
SELF_CLEARANCE_M = 1e-3


@dataclass(frozen=True)
class WorkCell:
    """Where the robot stands (module docstring; robot-file key ``cell:``, docs/contracts.md).

    obstacles: the half-spaces, boxes and cylinders (:class:`Obstacle`), in the base frame; clearance_m: the
    smallest distance [m] a body of the robot may have to an obstacle; self_clearance_m: between two bodies of
    the robot (default :data:`SELF_CLEARANCE_M`, 1 mm: links a micrometre apart touch at a plan's printed digits, its
    pose repeatability and its deflection under load, and no operator sends a robot there; more would cost compact
    arms, whose links pass within centimetres of each other by design); self_collision: check the robot against itself;
    link_radius_m: capsule radii [m] per segment of :meth:`stiffcal.model.robot.Robot.link_points` (capsules instead
    of a URDF's meshes; needed for planar and DH arms); srdf: the SRDF whose disabled pairs are not checked
    (URDF arms); ignore_pairs: pairs of bodies (link names, segment names ``link1``.., ``tool``, obstacle names)
    not checked;
    cable_length_m: from the tool point to the lowest point of the longest hanging mass, cable and mass [m]; the
    mass must hang clear of every half-space (default: down to the first half-space, unchecked, else
    :data:`CABLE_DEFAULT_M`); cable_clearance_m: the smallest distance [m] the cable keeps from the robot's other
    bodies and from boxes and cylinders (default 0: no contact); source: the file it came from (for messages);
    spec: the cell as given (the document, for the outputs and for caching).
    """

    obstacles: tuple[Obstacle, ...] = ()
    clearance_m: float = 0.0
    self_clearance_m: float | None = None
    self_collision: bool = True
    link_radius_m: tuple[float, ...] | None = None
    srdf: str | None = None
    ignore_pairs: tuple[tuple[str, str], ...] = ()
    cable_length_m: float | None = None
    source: str = "<memory>"
    spec: str = ""
    cable_clearance_m: float = 0.0
    prefix: str = field(default="cell", compare=False)  # the fields' prefix in ``source`` ('': a cell file's own)
    srdf_disabled: int = field(default=0, compare=False)  # the SRDF's disable_collisions entries (read once)
    _engines: dict = field(default_factory=dict, compare=False, repr=False, hash=False)

    @property
    def srdf_field(self) -> str:
        """The name of the ``srdf`` field in :attr:`source` (for messages)."""
        return _at(self.prefix, "srdf")

    @property
    def self_margin(self) -> float:
        """The smallest distance [m] two bodies of the robot keep: ``self_clearance_m``, default
        :data:`SELF_CLEARANCE_M`."""
        return SELF_CLEARANCE_M if self.self_clearance_m is None else self.self_clearance_m

    def ignored(self, a: str, b: str) -> bool:
        return (a, b) in self.ignore_pairs or (b, a) in self.ignore_pairs

    def describe(self) -> str:
        """One line for notes and the report."""
        parts = [f"{o.kind.replace('_', '-')} {o.name}" for o in self.obstacles]
        parts.append(f"clearance {self.clearance_m:g} m")
        if self.self_collision:
            parts.append(f"self-collision (clearance {self.self_margin:g} m)")
        return ", ".join(parts)


def _unit(v, source, fld) -> np.ndarray:
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if not n > 0:
        raise InputError(f"expected a nonzero direction, got {v.tolist()}", source=source, field=fld)
    return v / n


def rpy_matrix(rpy_rad) -> np.ndarray:
    """Rotation of roll, pitch, yaw (about fixed x, y, z, as URDF's ``rpy``): Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy_rad
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


#: the extent along z [m] of a planar cell's boxes and cylinders (rectangles and discs in the plane z = 0)
PLANAR_DEPTH_M = 1e3


def with_cell(robot, value, source: str | None, field: str = "cell", root: Path | str = "."):
    """``robot`` in the cell ``value``: a :class:`WorkCell`, a mapping of the cell's keys (paths in it relative to
    ``root``) or the path of a YAML file holding one (relative to ``root``; paths in it relative to the file);
    None keeps the robot file's cell. Raises :class:`InputError` naming ``source`` and ``field``."""
    from dataclasses import replace

    from ..validation import read_yaml

    if value is None:
        return robot
    if isinstance(value, WorkCell):
        return replace(robot, cell=value)
    if isinstance(value, dict):
        return replace(robot, cell=parse_cell(value, robot, source or "<cell>", root, field))
    if isinstance(value, (str, Path)):
        path = Path(root) / value
        doc = read_yaml(path)
        if not isinstance(doc, dict):
            raise InputError("expected a mapping of the cell's keys (clearance_m, floor_m, boxes, ...)",
                             source=str(path))
        return replace(robot, cell=parse_cell(doc, robot, str(path), path.parent, ""))
    raise InputError(f"expected a cell (a mapping of its keys, or the path of a YAML file), got "
                     f"{type(value).__name__}", source=source, field=field)


def cell_inputs(value, root: Path | str = ".") -> list[str]:
    """The files a study's ``cell`` value reads: the cell file (a path) and the SRDF it or the mapping names,
    relative to ``root`` as the workflow lists inputs; nothing for a file that cannot be read (loading it says
    why)."""
    from ..validation import read_yaml

    out, doc, base = [], value, Path(".")
    if isinstance(value, str):
        out.append(str(Path(value)))
        base = Path(value).parent
        try:
            doc = read_yaml(Path(root) / value)
        except InputError:
            return out
    if isinstance(doc, dict) and isinstance(doc.get("srdf"), str):
        out.append(str(base / doc["srdf"]))
    return out


def parse_cell(doc: dict, robot, source: str, base_dir: Path | str = ".", prefix: str = "cell") -> WorkCell:
    """A validated cell mapping (schema ``cell.schema.yaml``) -> :class:`WorkCell` for ``robot`` (its kind
    decides 2- or 3-component vectors; its ``gravity`` the floor's normal). Paths (``srdf``) are relative to
    ``base_dir``. Raises :class:`InputError` naming ``source`` and ``prefix.<field>``."""
    import json

    from ..validation import validate

    validate(doc, "cell", source, prefix)
    _check_clearances(doc, robot, source, prefix)
    obstacles = _obstacles(doc, robot, source, prefix)
    names = {o.name for o in obstacles}
    radius = _link_radii(doc.get("link_radius_m"), robot, source, prefix)
    srdf, disabled = _srdf_path(doc.get("srdf"), robot, base_dir, source, prefix)
    self_collision = bool(doc.get("self_collision", True))
    if (self_collision or obstacles) and radius is None and not _has_meshes(robot):
        what = "a URDF without collision geometry" if robot.kind == "urdf" else f"a {robot.kind} robot"
        raise InputError(f"{what} needs capsules around its links to be checked: give link_radius_m (one radius or "
                         f"one per segment: {', '.join(segment_names(robot))}), or self_collision: false without "
                         "obstacles", source=source, field=_at(prefix, "link_radius_m"))
    pairs = tuple((str(a), str(b)) for a, b in doc.get("ignore_pairs", []))
    known = set(body_names(robot, radius)) | names
    for i, pair in enumerate(pairs):
        for nm in pair:
            if nm not in known:
                raise InputError(f"unknown body {nm!r}; the bodies: {', '.join(sorted(known))}", source=source,
                                 field=_at(prefix, f"ignore_pairs[{i}]"))
    spec = json.dumps({**doc, **({"srdf": srdf} if srdf else {})}, sort_keys=True, allow_nan=False)
    return WorkCell(tuple(obstacles), float(doc.get("clearance_m", 0.0)), doc.get("self_clearance_m"), self_collision,
                    radius, srdf, pairs, doc.get("cable_length_m"), source, spec,
                    float(doc.get("cable_clearance_m", 0.0)), prefix, disabled)


def _check_clearances(doc: dict, robot, source: str, prefix: str) -> None:
    """Refuse a clearance (``clearance_m``, ``self_clearance_m``, ``cable_clearance_m``) longer than the arm itself
    (:func:`stiffcal.model.robot.own_length`): no pose keeps a mounted arm that far from its surroundings (a fresh
    user's ``clearance_m: 5``, meant as 5 mm, planned in silence, every link checked for contact only)."""
    from .robot import own_length

    arm = own_length(robot)
    for key in ("clearance_m", "self_clearance_m", "cable_clearance_m"):
        value = doc.get(key)
        if value is not None and arm > 0 and float(value) > arm:
            raise InputError(f"{float(value):.4g} m, longer than the arm itself ({arm:.3g} m, its links without the "
                             "tool): no pose keeps that far "
                             "from everything; clearances are in metres (millimetres given?)", source=source,
                             field=_at(prefix, key))


def _obstacles(doc: dict, robot, source: str, prefix: str) -> list[Obstacle]:
    """The cell's obstacles (the floor, half-spaces, boxes, cylinders), in that order; InputError for a vector of
    the wrong size, a key that belongs to the other robot kind, or a name used twice."""
    planar = robot.planar
    d = 2 if planar else 3

    def vec(v, fld, size=d):
        v = np.asarray(v, float)
        if v.shape != (size,):
            raise InputError(f"expected {size} components for a {robot.kind} robot, got {len(v)}", source=source,
                             field=_at(prefix, fld))
        return np.r_[v, 0.0] if size == 2 else v

    found = []
    up = -np.asarray(robot.gravity, float)
    up = np.r_[up, 0.0] if up.size == 2 else up
    if "floor_m" in doc:
        found.append((Obstacle("floor", "half_space", normal=up, offset=float(doc["floor_m"])), "floor_m"))
    for i, h in enumerate(doc.get("half_spaces", [])):
        fld = f"half_spaces[{i}]"
        found.append((Obstacle(h.get("name", f"half_space{i + 1}"), "half_space",
                               normal=_unit(vec(h["normal"], f"{fld}.normal"), source, _at(prefix, f"{fld}.normal")),
                               offset=float(h.get("offset_m", 0.0))), fld))
    found += [(_box(b, i, planar, vec, source, prefix), f"boxes[{i}]") for i, b in enumerate(doc.get("boxes", []))]
    found += [(_cylinder(c, i, planar, vec, source, prefix), f"cylinders[{i}]")
              for i, c in enumerate(doc.get("cylinders", []))]
    names = set()
    reach = robot.reach_m
    for o, fld in found:
        if o.name in names:
            raise InputError(f"expected unique obstacle names, got {o.name!r} twice", source=source,
                             field=_at(prefix, fld))
        names.add(o.name)
        size = 2.0 * o.bounding_radius if o.kind != "half_space" else 0.0
        if size > HUGE_OBSTACLE_REACHES * reach:
            raise InputError(f"obstacle {o.name!r} is {size:.4g} m across, more than {HUGE_OBSTACLE_REACHES:g} times "
                             f"the arm's reach ({reach:.3g} m, with the tool): lengths in the cell are in metres "
                             "(millimetres given?); a floor or a wall is a half-space", source=source,
                             field=_at(prefix, fld))
        far = float(o.sdf(np.zeros(3)))
        if far > FAR_OBSTACLE_REACHES * reach:
            raise InputError(f"obstacle {o.name!r} is {far:.4g} m from the base, more than {FAR_OBSTACLE_REACHES:g} "
                             f"times the arm's reach ({reach:.3g} m, with the tool): it can never touch the arm; "
                             "lengths in the cell are in metres (millimetres given?)", source=source,
                             field=_at(prefix, fld))
    return [o for o, _ in found]


#: an obstacle farther from the base than this many reaches of the arm is refused (a length in mm given as m)
FAR_OBSTACLE_REACHES = 20.0
#: a box or cylinder larger than this many reaches of the arm is refused (a fresh user's table of 800 x 1000 x 750
#: "m" was accepted and then said to cut 374628 mm into the base)
HUGE_OBSTACLE_REACHES = 100.0


def _box(b: dict, i: int, planar: bool, vec, source: str, prefix: str) -> Obstacle:
    """The i-th box of the cell (a planar robot's: a rectangle in its plane, turned by ``angle_deg``)."""
    fld = f"boxes[{i}]"
    size = vec(b["size_m"], f"{fld}.size_m")
    if planar:
        rot = rpy_matrix([0.0, 0.0, np.radians(b.get("angle_deg", 0.0))])
        size[2] = 2 * PLANAR_DEPTH_M
    else:
        rot = rpy_matrix(np.radians(b.get("rpy_deg", [0.0, 0.0, 0.0])))
    if "angle_deg" in b and not planar or "rpy_deg" in b and planar:
        bad = "angle_deg" if not planar else "rpy_deg"
        raise InputError(f"'{bad}' belongs to a {'planar' if bad == 'angle_deg' else 'spatial'} robot's box "
                         f"({'angle_deg' if planar else 'rpy_deg'} here)", source=source,
                         field=_at(prefix, f"{fld}.{bad}"))
    return Obstacle(b.get("name", f"box{i + 1}"), "box", center=vec(b["center_m"], f"{fld}.center_m"), rotation=rot,
                    half=size / 2, flat=planar)


def _cylinder(c: dict, i: int, planar: bool, vec, source: str, prefix: str) -> Obstacle:
    """The i-th cylinder of the cell (a planar robot's: a disc in its plane)."""
    fld = f"cylinders[{i}]"
    if planar:
        for bad in ("axis", "length_m"):
            if bad in c:
                raise InputError(f"a planar robot's cylinder is a disc in its plane: '{bad}' does not apply",
                                 source=source, field=_at(prefix, f"{fld}.{bad}"))
        axis, half = np.array([0.0, 0.0, 1.0]), PLANAR_DEPTH_M
    else:
        if "length_m" not in c:
            raise InputError("missing required field 'length_m' (a spatial robot's cylinder)", source=source,
                             field=_at(prefix, fld))
        axis = _unit(vec(c.get("axis", [0.0, 0.0, 1.0]), f"{fld}.axis"), source, _at(prefix, f"{fld}.axis"))
        half = float(c["length_m"]) / 2
    return Obstacle(c.get("name", f"cylinder{i + 1}"), "cylinder", center=vec(c["center_m"], f"{fld}.center_m"),
                    axis=axis, radius=float(c["radius_m"]), half_length=half, flat=planar)


def _link_radii(radius, robot, source: str, prefix: str) -> tuple[float, ...] | None:
    """``link_radius_m``: one radius for every segment of the drawn arm, or one per segment; None if not given."""
    if radius is None:
        return None
    radius = [radius] * robot.n_segments if isinstance(radius, (int, float)) else list(radius)
    if len(radius) != robot.n_segments:
        raise InputError(f"expected one radius or {robot.n_segments} (one per segment of the drawn arm: "
                         f"{', '.join(segment_names(robot))}), got {len(radius)}", source=source,
                         field=_at(prefix, "link_radius_m"))
    return tuple(float(r) for r in radius)


def _srdf_path(srdf, robot, base_dir, source: str, prefix: str) -> tuple[str | None, int]:
    """(the absolute path of ``srdf`` (relative to ``base_dir``), a file, this robot's (:func:`_check_srdf`); the
    number of pairs it disables); only for a URDF robot."""
    if srdf is None:
        return None, 0
    if robot.kind != "urdf":
        raise InputError("'srdf' belongs to a URDF robot (kind: urdf)", source=source, field=_at(prefix, "srdf"))
    srdf = os.path.abspath(Path(base_dir) / srdf)  # as the user gave it (a symlink not resolved away in messages)
    if not Path(srdf).is_file():
        raise InputError(f"no such file: {srdf}", source=source, field=_at(prefix, "srdf"))
    return srdf, _check_srdf(srdf, robot, source, _at(prefix, "srdf"))


def _at(prefix: str, fld: str) -> str:
    """A field's name under ``prefix`` (``cell.floor_m``; a cell file's own fields have no prefix)."""
    return f"{prefix}.{fld}" if prefix else fld


def segment_names(robot) -> list[str]:
    """Names of the segments of :meth:`stiffcal.model.robot.Robot.link_points` (capsules): ``link1`` .. ``link<n>`` and,
    for a spatial arm, ``tool`` (to the tool point)."""
    return [f"link{k + 1}" for k in range(robot.n_joints)] + (["tool"] if robot.kind_spec.tool_segment else [])


def body_names(robot, radius=None) -> list[str]:
    """The bodies a cell checks: the capsule segments, or the links of a URDF's collision geometry."""
    if radius is not None or not _has_meshes(robot):
        return segment_names(robot)
    return sorted({g.link for g in _urdf_geometry(robot)[0]})


def _has_meshes(robot) -> bool:
    return robot.kind == "urdf" and bool(robot.urdf_info) and bool(_urdf_geometry(robot)[0])


# ---------------------------------------------------------------------------------------------------
# engines

def probe_poses(robot) -> np.ndarray:
    """2**PROBE_LOG2 random poses (seeded) within the joint limits (one turn for a joint with a wider range): the
    poses at which every pair is probed once."""
    lo, hi = robot.joint_limits_rad.T
    span = np.minimum(hi - lo, 2 * np.pi)
    return lo + np.random.default_rng(3).uniform(size=(2**PROBE_LOG2, robot.n_joints)) * span


@dataclass(frozen=True)
class Check:
    """A group of distance checks of an engine: name (for notes), margin [m] (the distance that must be met)."""
    name: str
    margin: float


class _Base:
    """What both engines share: points against the cell, the cable, pair probing."""

    def __init__(self, robot, cell: WorkCell):
        self.robot, self.cell = robot, cell
        self.notes: list[str] = []
        #: the self pairs in collision at most of the probe poses: (link, link, fraction), most often first
        self.frequent: list[tuple[str, str, float]] = []
        self._cache: dict = {}

    def _points(self, q):
        """(..., k, 3) points that must lie outside every solid: joint origins, tip origin, tool point, targets."""
        robot = self.robot
        origins, _ = robot.joint_frames(q)
        R, p = robot.tool_frame(q)
        pts = [origins, p[..., None, :]]
        for name in robot.target_names:
            pts.append((p + R @ robot.target_point(name))[..., None, :])
        from .robot import as_xyz
        return as_xyz(np.concatenate(pts, axis=-2))

    def points_margin(self, q) -> np.ndarray:
        """(N,) the smallest signed distance of the points to the solids (>= 0 feasible)."""
        out = np.full(q.shape[0], np.inf)
        if self.cell.obstacles:
            P = self._points(q)
            for o in self.cell.obstacles:
                out = np.minimum(out, o.sdf(P).min(axis=-1))
        return out

    def cable(self, q, offset=None):
        """(top (N, 3), bottom (N, 3)) of the hanging cable (module docstring): from the tool point, or ``offset``
        (3,) [m] from it in the tip frame (a loading bar's end), down along gravity."""
        robot = self.robot
        from .robot import as_xyz
        R, p = robot.tool_frame(q)
        start = robot.target_point("tool") + (0.0 if offset is None else np.asarray(offset, float)[:3])
        top = as_xyz(p + R @ start)
        g = np.asarray(robot.gravity, float)
        g = np.r_[g, 0.0] if g.size == 2 else g
        if self.cell.cable_length_m is not None:  # the mass hangs this far below: it must clear every half-space
            return top, top + float(self.cell.cable_length_m) * g
        length = np.full(len(q), np.inf)
        for o in self.cell.obstacles:
            if o.kind == "half_space" and _dot(o.normal, g) < 0:
                hit = (_dot(top, o.normal) - o.offset) / -_dot(o.normal, g)
                length = np.minimum(length, np.where(hit > 0, hit, np.inf))
        length = np.where(np.isfinite(length), length, CABLE_DEFAULT_M)
        return top, top + length[:, None] * g

    def cable_bodies_ok(self, q, top, bottom) -> np.ndarray:
        """(N,) bool: the poses q (N, n) whose hanging cable (``top``, ``bottom`` (N, 3)) meets no body of the arm (each
        engine's ``cable_hits``)."""
        return np.array([not h for h in self.cable_hits(q, top, bottom)], bool)

    def cable_obstacles_margin(self, top, bottom) -> np.ndarray:
        out = np.full(len(top), np.inf)
        for o in self.cell.obstacles:
            if o.kind == "half_space":  # its ends stay on the free side (the floor is where it ends)
                out = np.minimum(out, np.minimum(o.sdf(top), o.sdf(bottom) + 1e-9))
            else:  # a box or a cylinder: kept at the cable's clearance
                out = np.minimum(out, o.segment_sdf(top, bottom) - self.cell.cable_clearance_m)
        return out

    def feasible(self, q: np.ndarray, hanging=None) -> np.ndarray:
        """(N,) bool for poses q (N, n) [rad], cached by the poses' bytes; ``hanging``: where the cable of hanging
        masses starts, from the tool point in the tip frame (3,) [m] (None: no cable)."""
        q = np.ascontiguousarray(q, float)
        hanging = _offset(hanging)
        if len(q) < CACHE_MIN:  # a few poses (a polish step): checked, not cached
            return self._feasible(q, hanging)
        key = (hashlib.blake2b(q.tobytes(), digest_size=16).hexdigest(), q.shape,
               None if hanging is None else tuple(hanging))
        hit = self._cache.get(key)
        if hit is None:
            hit = np.concatenate([self._feasible(q[i:i + CHUNK], hanging) for i in range(0, len(q), CHUNK)]) \
                if len(q) else np.zeros(0, bool)
            hit.flags.writeable = False
            if len(self._cache) > 64:
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = hit
        return hit

    def _feasible(self, q, hanging):
        ok = self.points_margin(q) >= -TOL_M
        ok &= self.bodies_ok(q)
        if hanging is not None:
            top, bottom = self.cable(q, hanging)
            ok &= self.cable_obstacles_margin(top, bottom) > 0
            ok &= self.cable_bodies_ok(q, top, bottom)
        return ok


class CapsuleEngine(_Base):
    """Capsules around the segments of the drawn arm (module docstring), in numpy."""

    def __init__(self, robot, cell: WorkCell):
        super().__init__(robot, cell)
        names = segment_names(robot)
        self.radius = np.asarray(cell.link_radius_m, float)
        S = len(names)
        self.names = names
        pairs = [(i, j) for i in range(S) for j in range(i + 2, S) if not cell.ignored(names[i], names[j])] \
            if cell.self_collision else []
        self.obst = [(k, o) for k in range(S) for o in cell.obstacles if not cell.ignored(names[k], o.name)]
        self.pairs = np.array(pairs, int).reshape(-1, 2)
        self.pair_margin = np.full(len(self.pairs), cell.self_margin)
        self.obst_margin = np.full(len(self.obst), cell.clearance_m)
        self._probe()

    def _segments(self, q):
        from .robot import as_xyz
        P = as_xyz(self.robot.link_points(q))
        return P[:, :-1], P[:, 1:]

    def pair_distances(self, q):
        a, b = self._segments(q)
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        d = segment_distance(a[:, i], b[:, i], a[:, j], b[:, j])
        return d - self.radius[i] - self.radius[j]

    def obstacle_distances(self, q, enough: bool = False):
        """(N, obstacle pairs) signed distances [m]; ``enough``: lower bounds where they already meet the margin
        (:meth:`Obstacle.segment_sdf`), for the feasibility check."""
        a, b = self._segments(q)
        out = np.empty((len(q), len(self.obst)))
        for c, (k, o) in enumerate(self.obst):
            # the segment from the base stands on the mounting plane: against a half-space its far end only
            start = b[:, k] if k == 0 and o.kind == "half_space" else a[:, k]
            need = self.obst_margin[c] + self.radius[k] if enough else None
            out[:, c] = o.segment_sdf(start, b[:, k], need) - self.radius[k]
        return out

    def _probe(self):
        q = probe_poses(self.robot)
        d = self.pair_distances(q) if len(self.pairs) else np.zeros((len(q), 0))
        always = np.all(d < 0, axis=0)
        within = np.all(d < self.pair_margin, axis=0) & ~always
        for c in np.flatnonzero(always):
            i, j = self.pairs[c]
            self.notes.append(f"{self.names[i]} and {self.names[j]} collide at every one of {len(q)} probe poses "
                              "(capsules too thick, or links that overlap by design): that pair is not checked")
        for c in np.flatnonzero(within):
            i, j = self.pairs[c]
            self.notes.append(f"{self.names[i]} and {self.names[j]} are within the clearance at every probe pose: "
                              "that pair is checked for contact only")
        self.pair_margin[within] = 0.0
        self.pairs, self.pair_margin = self.pairs[~always], self.pair_margin[~always]
        if self.obst:
            e = self.obstacle_distances(q)
            bad = np.flatnonzero(np.all(e < 0, axis=0))
            if bad.size:
                k, o = self.obst[bad[0]]
                raise InputError(f"{self.names[k]} is inside obstacle {o.name!r} at every one of {len(q)} probe "
                                 "poses within the joint limits: the cell leaves no pose; move the obstacle, or list "
                                 "the pair under ignore_pairs", source=self.cell.source, field="cell")
            within = np.all(e < self.obst_margin, axis=0)
            for c in np.flatnonzero(within):
                k, o = self.obst[c]
                self.notes.append(f"{self.names[k]} is within the clearance of {o.name} at every probe pose: that "
                                  "pair is checked for contact only")
            self.obst_margin[within] = 0.0

    def bodies_ok(self, q):
        ok = np.ones(len(q), bool)
        if len(self.pairs):
            ok &= np.all(self.pair_distances(q) >= self.pair_margin - TOL_M, axis=1)
        if self.obst:
            ok &= np.all(self.obstacle_distances(q, enough=True) >= self.obst_margin - TOL_M, axis=1)
        return ok

    def cable_hits(self, q, top, bottom) -> list[str]:
        """Per pose the body the hanging cable meets nearest ('' where it hangs free of the arm)."""
        a, b = self._segments(q)
        tool = b[:, -1]
        # the body the cable hangs from (the segments ending at the tool point) against the cable below its start
        hang = np.all(np.abs(b - tool[:, None]) <= 1e-12, axis=-1) | np.all(np.abs(a - tool[:, None]) <= 1e-12, axis=-1)
        clear = self.cell.cable_clearance_m
        d = segment_distance(a, b, top[:, None], bottom[:, None]) - self.radius
        span = bottom - top
        u = (span / np.maximum(np.linalg.norm(span, axis=-1, keepdims=True), 1e-300))[:, None]
        start = top[:, None] + (self.radius + clear + CABLE_START_M)[None, :, None] * u
        below = segment_distance(a, b, start, bottom[:, None]) - self.radius
        d = np.where(hang, below, d)
        k = np.argmin(d, axis=1)
        return [self.names[k[i]] if d[i, k[i]] <= clear else "" for i in range(len(q))]

    def distances(self, q):
        """(N, checks) signed distances [m] and the names of the checks (pairs, then obstacles)."""
        names = [f"{self.names[i]}-{self.names[j]}" for i, j in self.pairs]
        names += [f"{self.names[k]}-{o.name}" for k, o in self.obst]
        parts = [self.pair_distances(q) if len(self.pairs) else np.zeros((len(q), 0)),
                 self.obstacle_distances(q) if self.obst else np.zeros((len(q), 0))]
        return np.hstack(parts), names


@dataclass(frozen=True)
class _Geom:
    """A collision body of a URDF: its geometry-object index, link name, parent joint, whether it moves with
    the chain, whether it is the body the tool hangs from, and the chain's joints that move it (two bodies moved by
    the same ones never move relative to each other: a gripper's fingers held on the last link)."""
    index: int
    link: str
    joint: int
    moving: bool
    tip: bool
    movers: frozenset = frozenset()


def _loader_message(err: Exception) -> str:
    """The mesh loader's error without the C++ source location coal puts first ("From file: ... message: ")."""
    text = str(err)
    return re.sub(r"^.*?\bmessage:\s*", "", text, count=1, flags=re.S) if "From file:" in text else text


def _package_dirs(urdf: Path) -> list[str]:
    """Where ``package://name/...`` URIs are looked for: every directory above the URDF (Pinocchio looks for
    ``<dir>/name``), nearest first."""
    return [str(p) for p in Path(urdf).resolve().parents]


_GEOMETRY: dict = {}


def _urdf_geometry(robot):
    """(bodies, model, geometry model) of a URDF robot's collision geometry, read once per URDF file."""
    info = robot.urdf_info
    key = (info["path"], info["base_frame"], info["tip_frame"], tuple(info["joints"]))
    if key not in _GEOMETRY:
        import tempfile

        import pinocchio as pin

        path = info["path"]
        model = pin.buildModelFromUrdf(path)
        sys_err = os.dup(2)
        with tempfile.TemporaryFile() as log:  # urdfdom and assimp write to the C stderr
            os.dup2(log.fileno(), 2)
            try:
                geom = pin.buildGeomFromUrdf(model, path, pin.GeometryType.COLLISION, package_dirs=_package_dirs(path))
            except (ValueError, RuntimeError, OSError) as err:
                where = ("; package:// paths are looked for as DIR/<package>/... for every folder DIR above the URDF"
                         if "package://" in str(err) else "")
                raise InputError(f"cannot read the collision geometry of the URDF {path}: {_loader_message(err)}"
                                 + where, source=robot.source, field="urdf") from None
            finally:
                os.dup2(sys_err, 2)
                os.close(sys_err)
        moving = {model.getJointId(n) for n in info["joints"]}
        tip_joint = model.frames[frame_index(model, info["tip_frame"])].parentJoint
        bodies = []
        for i, g in enumerate(geom.geometryObjects):
            support = set(model.supports[g.parentJoint])
            bodies.append(_Geom(i, model.frames[g.parentFrame].name, int(g.parentJoint), bool(support & moving),
                                tip_joint in support, frozenset(support & moving)))
        _GEOMETRY[key] = (bodies, model, geom)
    return _GEOMETRY[key]


def full_configuration(robot, model, q: np.ndarray) -> np.ndarray:
    """Pinocchio configurations (N, nq) of the URDF model for chain poses q (N, n) [rad]: the moving joints at
    q, the held ones at their angle, every other joint at its neutral value (continuous joints as cos, sin)."""
    import pinocchio as pin

    info = robot.urdf_info
    Q = np.tile(pin.neutral(model), (len(q), 1))
    angles = {**{n: np.full(len(q), a) for n, a in info["held"].items()},
              **{n: q[:, i] for i, n in enumerate(info["joints"])}}
    for name, a in angles.items():
        j = model.getJointId(name)
        i = model.idx_qs[j]
        if model.nqs[j] == 2:
            Q[:, i], Q[:, i + 1] = np.cos(a), np.sin(a)
        else:
            Q[:, i] = a
    return Q


class MeshEngine(_Base):
    """A URDF's collision geometry, checked by coal through Pinocchio (module docstring)."""

    def __init__(self, robot, cell: WorkCell):
        super().__init__(robot, cell)
        import coal
        import pinocchio as pin

        bodies, model, geom0 = _urdf_geometry(robot)
        self.model = model
        geom = geom0.copy()
        data = model.createData()
        pin.framesForwardKinematics(model, data, full_configuration(robot, model, np.zeros((1, robot.n_joints)))[0])
        T_wb = data.oMf[frame_index(model, robot.urdf_info["base_frame"])]
        self.bodies = bodies
        pairs, margins, labels = [], [], []
        if cell.self_collision:
            for x in range(len(bodies)):
                for y in range(x + 1, len(bodies)):
                    a, b = bodies[x], bodies[y]
                    if a.movers == b.movers or a.joint == b.joint or model.parents[a.joint] == b.joint \
                            or model.parents[b.joint] == a.joint or cell.ignored(a.link, b.link):
                        continue
                    pairs.append((a.index, b.index))
                    margins.append(cell.self_margin)
                    labels.append((a.link, b.link, "self"))
        hulls = {}
        for o in cell.obstacles:
            if o.kind == "half_space":  # solid n . x <= offset in the base frame, placed in the world
                shape, M = coal.Halfspace(o.normal, o.offset), pin.SE3.Identity()
            elif o.kind == "box":
                shape, M = coal.Box(*(2 * o.half)), pin.SE3(o.rotation, o.center)
            else:
                z = np.array([0.0, 0.0, 1.0])
                shape, M = coal.Cylinder(o.radius, 2 * o.half_length), pin.SE3(_rotation_to(z, o.axis), o.center)
            idx = geom.addGeometryObject(pin.GeometryObject(f"cell:{o.name}", 0, 0, T_wb * M, shape))
            self._check_fixed_bodies(geom0, data, o, shape, T_wb * M)
            for b in bodies:
                if not b.moving or cell.ignored(b.link, o.name):
                    continue
                body = b.index
                if o.kind == "half_space":
                    body = hulls.get(b.index)
                    if body is None:
                        body = hulls[b.index] = self._hull(geom, b.index)
                pairs.append((body, idx))
                margins.append(cell.clearance_m)
                labels.append((b.link, o.name, "obstacle"))
        keep = list(range(len(pairs)))
        for cp in [pin.CollisionPair(a, b) for a, b in pairs]:
            geom.addCollisionPair(cp)
        if cell.srdf:
            self._remove_srdf(geom)
            present = {(geom.collisionPairs[k].first, geom.collisionPairs[k].second) for k in
                       range(len(geom.collisionPairs))}
            keep = [k for k, (a, b) in enumerate(pairs) if (a, b) in present or (b, a) in present]
        self.geom = geom
        self.pairs = [pairs[k] for k in keep]
        self.margins = np.array([margins[k] for k in keep])
        self.labels = [labels[k] for k in keep]
        self._probe()

    def _hull_shape(self, index: int):
        """The convex hull of body ``index`` (a BVH mesh's; a shape is its own)."""
        return _convex(self.geom.geometryObjects[index].geometry)

    def _hull(self, geom, index: int) -> int:
        """A convex hull copy of body ``index`` (a half-space sees the same distance as the mesh's), added to
        ``geom``."""
        import pinocchio as pin

        self.geom = geom
        g = geom.geometryObjects[index]
        return geom.addGeometryObject(pin.GeometryObject(f"{g.name}#hull", g.parentJoint, g.parentFrame, g.placement,
                                                         self._hull_shape(index)))

    def _remove_srdf(self, geom) -> None:
        import pinocchio as pin

        if not self.cell.srdf_disabled and self.cell.self_collision:  # counted when the cell was parsed
            self.notes.append(f"the SRDF {self.cell.srdf} disables no pair of links: the self-collision check is as "
                              "without an SRDF (every pair of bodies that are not adjacent, a pair that overlaps by "
                              "design left out only where it collides at every probe pose); is it this robot's, and "
                              "complete?")
        try:
            pin.removeCollisionPairs(self.model, geom, self.cell.srdf)
        except (ValueError, RuntimeError) as err:
            raise InputError(f"cannot read the SRDF {self.cell.srdf}: {err}", source=self.cell.source,
                             field=self.cell.srdf_field) from None

    def _rebuild(self, pairs, margins, labels):
        import pinocchio as pin

        self.geom.removeAllCollisionPairs()
        for a, b in pairs:
            self.geom.addCollisionPair(pin.CollisionPair(a, b))
        self.pairs, self.margins, self.labels = pairs, np.asarray(margins, float), labels
        self.gdata = pin.GeometryData(self.geom)
        for k, m in enumerate(self.margins):
            self.gdata.collisionRequests[k].security_margin = float(m)
        self.pool = pin.GeometryPool(self.model, self.geom, 1)
        for k, m in enumerate(self.margins):
            self.pool.getGeometryDatas()[0].collisionRequests[k].security_margin = float(m)
        self.data = self.model.createData()

    def _pair_hits(self, q, margins=True) -> np.ndarray:
        """(N, pairs) bool: which pairs collide (within their margins, or without them) at poses q (N, n)."""
        import pinocchio as pin

        Q = full_configuration(self.robot, self.model, q)
        out = np.zeros((len(q), len(self.pairs)), bool)
        for k, m in enumerate(self.margins):
            self.gdata.collisionRequests[k].security_margin = float(m) if margins else 0.0
        for i, x in enumerate(Q):
            pin.computeCollisions(self.model, self.data, self.geom, self.gdata, x, False)
            out[i] = [r.isCollision() for r in self.gdata.collisionResults]
        for k, m in enumerate(self.margins):
            self.gdata.collisionRequests[k].security_margin = float(m)
        return out

    def _probe(self):
        self._rebuild(self.pairs, self.margins, self.labels)
        if not self.pairs:
            return
        q = probe_poses(self.robot)
        hit0, hitm = self._pair_hits(q, margins=False), self._pair_hits(q)
        always, within = hit0.all(axis=0), hitm.all(axis=0) & ~hit0.all(axis=0)
        share = hit0.mean(axis=0)
        self.frequent = [(self.labels[k][0], self.labels[k][1], float(share[k]))
                         for k in np.argsort(-share, kind="stable")
                         if self.labels[k][2] == "self" and FREQUENT_PAIR <= share[k] < 1.0]
        for k in np.flatnonzero(always):
            a, b, kind = self.labels[k]
            if kind == "obstacle":
                raise InputError(f"link {a} is inside obstacle {b!r} at every one of {len(q)} probe poses within the "
                                 "joint limits: the cell leaves no pose; move the obstacle, or list the pair under "
                                 "ignore_pairs", source=self.cell.source, field="cell")
            self.notes.append(f"links {a} and {b} collide at every one of {len(q)} probe poses (a pair the SRDF "
                              "should disable): that pair is not checked")
        margins = self.margins.copy()
        for k in np.flatnonzero(within):
            a, b, _ = self.labels[k]
            self.notes.append(f"{a} and {b} are within the clearance at every probe pose: that pair is checked for "
                              "contact only")
            margins[k] = 0.0
        keep = np.flatnonzero(~always)
        self._rebuild([self.pairs[k] for k in keep], margins[keep], [self.labels[k] for k in keep])

    def _check_fixed_bodies(self, geom, data, o: Obstacle, shape, M) -> None:
        """Refuse a cell whose obstacle ``o`` (its coal ``shape`` placed at ``M`` in the world) cuts more than
        :data:`FIXED_OVERLAP_M` into a body no joint of the chain moves (the base: no pose frees it; a fresh
        user's wall 74 mm into the Panda's link0 was accepted in silence), naming both; ``data``: the model's
        frames at any pose (those bodies do not move)."""
        import coal
        import pinocchio as pin

        gd = pin.GeometryData(geom)
        pin.updateGeometryPlacements(self.model, data, geom, gd)
        req = coal.DistanceRequest()
        req.enable_signed_distance = True
        for b in self.bodies:
            if b.moving or self.cell.ignored(b.link, o.name):
                continue
            d = coal.distance(_convex(geom.geometryObjects[b.index].geometry), _transform(gd.oMg[b.index]), shape,
                              _transform(M), req, coal.DistanceResult())
            if d < -FIXED_OVERLAP_M:
                raise InputError(f"{o.name} cuts {-d * 1e3:.0f} mm into {b.link}, which no joint moves (the robot's "
                                 "base): no pose can free it; move it, or list the pair "
                                 f"[{b.link}, {o.name}] under ignore_pairs", source=self.cell.source, field="cell")

    def bodies_ok(self, q):
        import pinocchio as pin

        if not self.pairs:
            return np.ones(len(q), bool)
        Q = np.asfortranarray(full_configuration(self.robot, self.model, q).T)
        return ~np.asarray(pin.computeCollisionsInParallel(1, self.pool, Q, True), bool)

    def cable_hits(self, q, top, bottom) -> list[str]:
        """Per pose the link of the first body the hanging cable meets ('' where it hangs free of the arm)."""
        import coal
        import pinocchio as pin

        model, data, gd, T_wb = self._placing()
        Q = full_configuration(self.robot, model, q)
        req = coal.CollisionRequest()
        bodies = [(b.index, self._hull_shape(b.index), b.tip, b.link) for b in self.bodies]
        clear = max(1e-6, self.cell.cable_clearance_m)
        hits = [""] * len(q)
        for i, x in enumerate(Q):
            pin.updateGeometryPlacements(model, data, self.geom, gd, x)
            a, b = T_wb.act(top[i]), T_wb.act(bottom[i])
            length = float(np.linalg.norm(b - a))
            if length <= 0:
                continue
            u = (b - a) / length
            R = _rotation_to(np.array([0.0, 0.0, 1.0]), u)
            cap = coal.Capsule(clear, length)  # the cable with its clearance
            M = coal.Transform3s(R, (a + b) / 2)
            # the bodies the cable hangs from: the cable from just below its start, unless it starts inside one
            s0 = min(clear + CABLE_START_M, length / 2)
            below = (coal.Capsule(clear, length - s0), coal.Transform3s(R, (a + s0 * u + b) / 2))
            for index, shape, tip, link in bodies:
                T = _transform(gd.oMg[index])
                if tip and _deep_inside(shape, T, a, CABLE_START_M):
                    continue  # the tool point inside the body it hangs from (a gripper's hull): not checkable
                if coal.collide(shape, T, *(below if tip else (cap, M)), req, coal.CollisionResult()):
                    hits[i] = link
                    break
        return hits

    def cable_exempt(self, hanging) -> list[str]:
        """The links of the bodies the cable hangs from whose hull holds its start (``hanging``: :meth:`feasible`'s)
        at least :data:`CABLE_START_M` deep: :meth:`cable_hits` does not check the cable against them. They are fixed
        to the tool's link, so what holds at the zero pose holds at every pose."""
        import pinocchio as pin

        model, data, gd, T_wb = self._placing()
        q0 = np.zeros((1, self.robot.n_joints))
        pin.updateGeometryPlacements(model, data, self.geom, gd, full_configuration(self.robot, model, q0)[0])
        start = T_wb.act(self.cable(q0, _offset(hanging))[0][0])
        return list(dict.fromkeys(b.link for b in self.bodies if b.tip and _deep_inside(
            self._hull_shape(b.index), _transform(gd.oMg[b.index]), start, CABLE_START_M)))

    def _placing(self):
        """(model, data, geometry data, T_wb): what places the bodies at a pose (pinocchio's
        ``updateGeometryPlacements``) and the base frame's placement in the world, for the cable's checks."""
        import pinocchio as pin

        _, model, _ = _urdf_geometry(self.robot)
        data = model.createData()
        return model, data, pin.GeometryData(self.geom), self._T_wb(data)

    def _T_wb(self, data):
        import pinocchio as pin

        model = self.model
        pin.framesForwardKinematics(model, data, full_configuration(self.robot, model,
                                                                    np.zeros((1, self.robot.n_joints)))[0])
        return data.oMf[frame_index(model, self.robot.urdf_info["base_frame"])]

    def distances(self, q):
        """(N, checks) signed distances [m] of every checked pair and their names (mesh distances: slow,
        for the few poses of a plan). Each pose from a fresh geometry data: coal's distance starts its search where
        the last one ended (a cached guess), and its result within its tolerance depends on that start, so the same
        pose gave 0.015061 and 0.015062 m after different poses (a fresh user's CLI and workflow printed them)."""
        import pinocchio as pin

        Q = full_configuration(self.robot, self.model, q)
        out = np.empty((len(q), len(self.pairs)))
        for i, x in enumerate(Q):
            gdata = pin.GeometryData(self.geom)
            pin.computeDistances(self.model, self.data, self.geom, gdata, x)
            out[i] = [r.min_distance for r in gdata.distanceResults]
        return out, [f"{a}-{b}" for a, b, _ in self.labels]


def _deep_inside(shape, T, point: np.ndarray, depth: float) -> bool:
    """Whether ``point`` (3,) [m, world] lies inside the convex ``shape`` placed at ``T`` at least ``depth`` from its
    surface along every axis (the six points ``depth`` away along +-x, +-y, +-z inside too): a tool point between a
    gripper's jaws, in its hull, is; one on a fingertip's face is not, and the cable from it is checked."""
    import coal

    req = coal.CollisionRequest()
    eye = np.eye(3)
    probes = [point] + [point + sign * depth * e for e in eye for sign in (1.0, -1.0)]
    return all(coal.collide(shape, T, coal.Sphere(1e-9), coal.Transform3s(eye, x), req, coal.CollisionResult())
               for x in probes)


def _convex(shape):
    """The convex hull of a coal BVH mesh (built once, kept on the mesh); any other shape is its own."""
    import coal

    if isinstance(shape, coal.BVHModelBase):
        if shape.convex is None:
            shape.buildConvexHull(True, "Qt")
        shape = shape.convex
    return shape


def _transform(M):
    import coal
    return coal.Transform3s(np.asarray(M.rotation), np.asarray(M.translation))


def _rotation_to(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation taking the unit vector a to the unit vector b."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1 + 1e-12:
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2 * np.outer(axis, axis) - np.eye(3)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


#: fields of a Robot that do not change where its bodies are (left out of :func:`_geometry_key`)
_NOT_GEOMETRY = ("name", "compliances", "reference", "masses", "calibration", "cell")


def _hashable(v):
    """``v`` (arrays, dataclasses such as a Chain, dicts, sequences, scalars) as a hashable value."""
    import dataclasses

    if isinstance(v, np.ndarray):
        return (v.shape, v.dtype.str, v.tobytes())
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return tuple(_hashable(getattr(v, f.name)) for f in dataclasses.fields(v))
    if isinstance(v, dict):
        return tuple(sorted((str(k), _hashable(x)) for k, x in v.items()))
    if isinstance(v, (list, tuple)):
        return tuple(_hashable(x) for x in v)
    return v


def _geometry_key(robot) -> tuple:
    """What decides ``robot``'s bodies in its cell: every field of the robot but :data:`_NOT_GEOMETRY`, whatever its
    kind (the kind's own geometry, its limits, targets, gravity and URDF), as a hashable key."""
    import dataclasses

    return tuple((f.name, _hashable(getattr(robot, f.name))) for f in dataclasses.fields(robot)
                 if f.name not in _NOT_GEOMETRY)


def engine(robot):
    """The feasibility engine of ``robot``'s cell (None without a cell), built once per robot geometry and joint
    limits and kept with the cell."""
    cell = robot.cell
    if cell is None:
        return None
    seen = cell._engines.get(id(robot))  # this very robot object asked before: no key to build
    if seen is not None and seen[0] is robot:
        return seen[1]
    key = _geometry_key(robot)
    eng = cell._engines.get(key)
    if eng is None:
        use_caps = cell.link_radius_m is not None or not _has_meshes(robot)
        eng = CapsuleEngine(robot, cell) if use_caps else MeshEngine(robot, cell)
        cell._engines[key] = eng
    if len(cell._engines) > 512:  # many robot objects asked once each (copies in a loop): forget them, not the engines
        for k in [k for k in cell._engines if isinstance(k, int)]:
            del cell._engines[k]
    cell._engines[id(robot)] = (robot, eng)
    return eng


def _offset(hanging):
    """The cable's start from the tool point (3,) [m] of a ``hanging`` argument: None or False (no cable), True
    (the tool point), or an offset in the tip frame."""
    if hanging is None or hanging is False:
        return None
    if hanging is True:
        return np.zeros(3)
    h = np.asarray(hanging, float).ravel()
    return np.r_[h, np.zeros(3 - h.size)] if h.size < 3 else h[:3]


def feasible(robot, q: np.ndarray, hanging=None) -> np.ndarray:
    """(...,) bool: the poses q (..., n) [rad] the robot can take in its cell (all True without a cell), with the
    cable of hanging masses free when ``hanging`` is given (True: hung from the tool point; an offset (3,) [m] in
    the tip frame: from there, a loading bar's end)."""
    eng = engine(robot)
    q = np.asarray(q, float)
    if eng is None:
        return np.ones(q.shape[:-1], bool)
    flat = q.reshape(-1, q.shape[-1])
    return eng.feasible(flat, hanging).reshape(q.shape[:-1])


def _srdf_root(srdf: str, source: str, field_: str):
    """The SRDF's parsed XML (its root element; ``defusedxml``), refused (naming ``field_`` of ``source``) with a
    DOCTYPE or entity declarations or when not well-formed."""
    import defusedxml.ElementTree as DET
    from defusedxml import DefusedXmlException

    text = Path(srdf).read_text(encoding="utf-8", errors="replace")
    try:
        return DET.fromstring(text, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException:
        raise InputError("XML entity or DOCTYPE declarations are not allowed", source=source, field=field_) from None
    except DET.ParseError as err:
        raise InputError(f"cannot read the SRDF {srdf}: {err}", source=source, field=field_) from None


def _check_srdf(srdf: str, robot, source: str, field_: str) -> int:
    """The number of the SRDF's ``disable_collisions`` entries; refuse another robot's SRDF (naming ``field_`` of
    ``source``): one whose disabled pairs name no link of the
    robot's URDF (a Panda's given for a Baxter disabled nothing, and the cell then left no pose, with a message about
    clearances), or that disables nothing and whose groups, chains and states name none of its links and joints (a
    Kinova's given for a Z1 ran with a note only). Read when the cell is parsed, so that the workflow's config check
    refuses it before any job runs."""
    root = _srdf_root(srdf, source, field_)
    entries = sum(1 for _ in root.iter("disable_collisions"))
    info = getattr(robot, "urdf_info", None)
    if not info:
        return entries
    from .urdf import _check_text  # the URDF's own reader (bounded, defused, checked), as the robot was loaded

    urdf = _check_text(Path(info["path"]), source)
    known = {e.get("name") for tag in ("link", "joint") for e in urdf.iter(tag)} - {None}
    named = {e.get(k) for e in root.iter("disable_collisions") for k in ("link1", "link2")} - {None}
    if named and not named & known:
        raise InputError(f"the SRDF {srdf} disables pairs of links none of which is in the URDF (e.g. "
                         f"{sorted(named)[0]!r}): expected this robot's SRDF", source=source, field=field_)
    mentioned = _srdf_names(root)
    if not named and mentioned and not mentioned & known:
        raise InputError(f"the SRDF {srdf} (robot {root.get('name')!r}) names links and joints none of which is in "
                         f"the URDF (e.g. {sorted(mentioned)[0]!r}): expected this robot's SRDF", source=source,
                         field=field_)
    return entries


#: the attributes of an SRDF's elements that name a link or a joint of the robot (groups, chains, states, end
#: effectors, virtual and passive joints)
SRDF_NAME_ATTRIBUTES = {"link": ("name",), "joint": ("name",), "chain": ("base_link", "tip_link"),
                        "end_effector": ("parent_link",), "virtual_joint": ("child_link",),
                        "passive_joint": ("name",), "link_sphere_approximation": ("link",)}


def _srdf_names(root) -> set:
    """Every link and joint name an SRDF's elements give (:data:`SRDF_NAME_ATTRIBUTES`)."""
    return {e.get(a) for tag, attrs in SRDF_NAME_ATTRIBUTES.items() for e in root.iter(tag) for a in attrs} - {None}


def cell_notes(robot, q: np.ndarray | None = None, hanging=None) -> list[str]:
    """What the cell's engine decided about pairs (pairs not checked, checked for contact only) and, with hanging
    masses (``hanging``: :func:`feasible`'s), about the cable (:func:`cable_exempt_note`); for a spatial robot without
    a cell, that its poses are checked against the joint limits only, and which of the planned poses ``q`` (M, n)
    [rad] (None: not known) reach below the base's mounting plane (:func:`below_base_note`)."""
    if robot.cell is None:
        return [] if robot.planar else [
            "the robot has no cell: the poses are checked against the joint limits only, not against the table, the "
            "arm itself or obstacles (a cell in the robot file, or --cell, keeps them out)",
            *([] if q is None else below_base_note(robot, q))]
    eng = engine(robot)
    bare = (["the cell checks the arm's self-collision without an SRDF: every pair of bodies that are not adjacent is "
             "checked, and a pair that overlaps by design is left out only where it collides at every probe pose; "
             "give the robot's SRDF (cell.srdf) for the pairs its makers disabled"]
            if robot.cell.self_collision and getattr(robot, "urdf_info", None) and not robot.cell.srdf
            and isinstance(eng, MeshEngine) else [])
    cable = cable_exempt_note(eng, hanging) if hanging is not None and isinstance(eng, MeshEngine) else []
    return [] if eng is None else bare + list(dict.fromkeys(eng.notes)) + cable  # a link of several shapes: once


def cable_exempt_note(eng: MeshEngine, hanging) -> list[str]:
    """A note naming the bodies whose hull holds the hanging masses' cable start (:meth:`MeshEngine.cable_exempt`),
    which the cable is not checked against: right for a hook between a gripper's jaws, wrong for a tool point at a
    flange that carries a hand (a fresh user's Panda, the tool point at panda_link8: the cable ran 35-104 mm inside
    panda_hand at every planned pose, and nothing said it)."""
    links = eng.cable_exempt(hanging)
    if not links:
        return []
    return [f"the hanging masses' cable starts inside the hull of {', '.join(links)} (the tool point, or the bar's "
            "end, lies in it): the cable is not checked against that body, as for a hook between a gripper's jaws; if "
            "the mass hangs from a hook outside it (a hand on the flange), give tool_m that hook and the cable is "
            "checked against the hand too"]


#: a point this far [m] below the base's mounting plane is named by :func:`below_base_note`
BELOW_BASE_M = 1e-3


def below_base_note(robot, q: np.ndarray) -> list[str]:
    """A note naming the poses q (M, n) [rad] of a spatial robot whose tool point lies more than
    :data:`BELOW_BASE_M` below the plane through the base normal to ``gravity``: with no cell nothing keeps the arm
    off the table it stands on (a fresh user's next round under hanging masses put the tool 13 mm below it)."""
    q = np.atleast_2d(np.asarray(q, float))
    if robot.planar or not len(q):
        return []
    up = -np.asarray(robot.gravity, float)
    depth = -(np.asarray(robot.link_points(q), float)[:, -1, :] @ up)  # (M,) [m] the tool point below the plane
    low = np.flatnonzero(depth > BELOW_BASE_M)
    if not low.size:
        return []
    return [f"pose(s) {', '.join(str(i + 1) for i in low)} put the tool point up to {1e3 * depth[low].max():.3g} mm "
            "below the plane of the base (normal to gravity): on a table or a floor it goes through it; give the "
            "robot a cell (floor_m, docs/contracts.md \"The cell\") to keep them above it"]


def no_pose_hint(robot) -> str:
    """What to look at first when the cell leaves no pose: the self pairs in collision at half the probe poses or
    more (a pair that only overlaps by design, which the SRDF should disable: a missing SRDF, or another robot's),
    else the clearance, the obstacles and the joint limits."""
    eng = engine(robot)
    frequent = [] if eng is None else eng.frequent[:3]
    if frequent:
        pairs = ", ".join(f"{a} and {b} ({100 * f:.0f} %)" for a, b, f in frequent)
        return (f"at {2**PROBE_LOG2} random poses within the joint limits these links collide most often: {pairs}; "
                "links that overlap by design are pairs the SRDF should disable (cell.srdf: is it this robot's?), or "
                "list them under ignore_pairs")
    return "lower the clearance, move the obstacles or widen the joint limits"


def no_pose_reason(robot, q: np.ndarray, hanging=None) -> str:
    """Why none of the poses q (N, n) [rad] can be taken in the cell: where the arm itself can take some of them but
    the hanging masses' cable (``hanging``: where it starts, :func:`feasible`'s) hangs free at none,
    :func:`cable_hint`; else :func:`no_pose_hint`."""
    if hanging is not None:
        arm = feasible(robot, q)
        if arm.any():
            return cable_hint(robot, q[arm], hanging) or no_pose_hint(robot)
    return no_pose_hint(robot)


def cable_hint(robot, q: np.ndarray, hanging, at_most: int = 512) -> str:
    """Why the hanging masses' cable hangs free at none of the poses q (N, n) [rad] the arm itself can take (at most
    ``at_most`` of them looked at): how many put the mass or the cable into an obstacle (the mass resting on the table
    loads nothing) and how many run the cable through the arm, naming the links it meets most often."""
    from collections import Counter

    eng = engine(robot)
    q = np.asarray(q, float)[:at_most]
    top, bottom = eng.cable(q, _offset(hanging))
    blocked = eng.cable_obstacles_margin(top, bottom) <= 0
    hits = eng.cable_hits(q, top, bottom)
    links = Counter(h for h in hits if h).most_common(3)
    parts = []
    if blocked.any():
        length = robot.cell.cable_length_m
        parts.append(f"at {int(blocked.sum())} the mass or cable meets an obstacle"
                     + (f" (cable_length_m {length:g} m more than the tool point's height?)"
                        if length is not None else ""))
    if links:
        where = ", ".join(f"{name} {n}" for name, n in links)
        lower = ", or lower cable_clearance_m" if robot.cell.cable_clearance_m > 0 else ""
        parts.append(f"at {sum(1 for h in hits if h)} the cable runs through the arm ({where}; from a tool point on "
                     "a fingertip it runs along it once the tool tilts: set tool_m to a hook past the fingertips; from "
                     "the end of a capsule, give that segment a smaller link_radius_m (a list, one per segment)"
                     f"{lower})")
    return (f"the masses' cable hangs free at none of the {len(q)} the arm can take: " + "; ".join(parts)
            if parts else "")


#: a plan's pose closer than this [m] to contact (over the cell's checked pairs) is noted
CONTACT_NOTE_M = 1e-3



def contact_note(clear: np.ndarray, names: list[str], what: str = "the plan") -> list[str]:
    """A note naming ``what``'s poses (the design's plan, a discriminating or compound plan) whose smallest distance
    over the cell's pairs (:func:`clearance`: ``clear`` (M,) [m], ``names`` the closest pair of each) is below
    :data:`CONTACT_NOTE_M`: feasible (the clearances the cell asks for hold) but touching, which no operator sends a
    robot to; the cure is a clearance in the cell file (a fresh user's discriminating plan put two Panda links
    0.12 mm apart without a word)."""
    close = [i for i, v in enumerate(clear) if v < CONTACT_NOTE_M]
    if not close:
        return []
    where = "; ".join(f"pose {i + 1}: {1e3 * clear[i]:.3g} mm ({names[i]})" for i in close[:5])
    return [f"{len(close)} pose(s) of {what} lie within {1e3 * CONTACT_NOTE_M:g} mm of contact ({where}): within "
            "the cell's clearances, but touching; give the cell file a larger self_clearance_m or clearance_m (e.g. "
            "0.005) to keep the bodies apart"]


def test_pose_note(robot, problem, q_t: np.ndarray) -> list[str]:
    """A note when the test pose q_t (n,) [rad] cannot be taken in ``robot``'s cell (``problem``: the design's
    :class:`stiffcal.planning.problem.Problem`, whose ``feasible`` holds the hanging masses' cable too), saying why:
    the pairs that touch or overlap there (a mesh pair in contact has no depth, coal gives 0: a fresh user's Bravo 7
    was told of a sensor 19.5 mm into a cylinder where two links' hulls overlapped by 70 mm), else the closest pair
    within the clearance, or (with hanging masses) only the cable, which meets a body or an obstacle (a fresh user's
    Z1 on a table: told 'a body within the clearance' where the cable lay on the table); [] without a cell."""
    if robot.cell is None or problem.feasible(q_t[None])[0]:
        return []
    if problem.hang_offset is not None and feasible(robot, q_t[None])[0]:
        why = ("the cable of the hanging masses meets a body or an obstacle there (the arm itself is clear: the "
               "masses cannot hang at the test pose, though a push there can be measured)")
    else:
        eng = engine(robot)
        d, names = eng.distances(q_t[None]) if eng is not None else (np.zeros((1, 0)), [])
        touch = [(names[k], d[0, k]) for k in np.argsort(d[0], kind="stable") if d[0, k] <= 0.0]
        if touch:
            why = (f"{len(touch)} pair(s) touch or overlap: "
                   + ", ".join(n + (f" ({-1e3 * v:.3g} mm deep)" if v < 0 else "") for n, v in touch[:4])
                   + (", ..." if len(touch) > 4 else ""))
        else:
            c, closest = clearance(robot, q_t[None])
            why = "a body within the clearance of an obstacle or of another body" + (
                f"; closest: {closest[0]} at {c[0] * 1e3:.3g} mm" if closest[0] and np.isfinite(c[0]) else "")
    return [f"the test pose itself cannot be taken in the cell ({why}): the plan predicts its compensation error all "
            "the same"]


def clearance(robot, q: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The smallest distance [m] of every pose q (N, n) [rad] over the pairs its cell checks (bodies against the
    obstacles and against each other) and the pair it belongs to; (inf, '') without a cell or without pairs."""
    eng = engine(robot)
    q = np.atleast_2d(np.asarray(q, float))
    if eng is None:
        return np.full(len(q), np.inf), [""] * len(q)
    d, names = eng.distances(q)
    if not names:
        pts = eng.points_margin(q)
        return pts, ["joint points" if np.isfinite(v) else "" for v in pts]
    k = np.argmin(d, axis=1)
    return d[np.arange(len(q)), k], [names[i] for i in k]


# ---------------------------------------------------------------------------------------------------
# candidate poses from a file

def _candidate_rows(path: Path, src: str) -> list[list[str]]:
    """The CSV rows of a candidate file (at most MAX_CANDIDATE_BYTES, MAX_CANDIDATES poses, UTF-8), the header
    first; InputError naming the file."""
    import csv

    from ..limits import MAX_CANDIDATE_BYTES, MAX_CANDIDATES
    from ..safeio import read_bounded

    raw = read_bounded(path, MAX_CANDIDATE_BYTES, source=src, what="candidate file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text (byte 0x{raw[err.start]:02x} at {err.start})", source=src) from None
    lines = text.splitlines()
    if sum(1 for line in lines if line.strip()) - 1 > MAX_CANDIDATES:
        raise InputError(f"more than {MAX_CANDIDATES:,} candidate poses (the most read; docs/contracts.md, 'Limits'):"
                         " thin the set", source=src)
    try:
        rows = list(csv.reader(lines))
    except csv.Error as err:
        raise InputError(f"not a CSV file a reader can split ({err})", source=src) from None
    if not rows:
        raise InputError("empty file: expected a header row and one pose per row", source=src)
    return rows


def _candidate_angles(rows: list[list[str]], idx: list[int], cols: list[str], scale: float, src: str) -> list:
    """The joint angles [rad] of each non-blank row after the header (columns ``idx``, times ``scale``);
    InputError naming the row and column of a value that is not a finite angle within +-MAX_JOINT_ANGLE_DEG."""
    from .robot import MAX_JOINT_ANGLE_DEG

    out = []
    for r, row in enumerate(rows[1:], start=2):
        if not any(v.strip() for v in row):
            continue
        vals = []
        for c, i in zip(cols, idx):
            try:
                v = float(row[i])
            except (ValueError, IndexError):
                raise InputError(f"expected a number, got {row[i] if i < len(row) else 'nothing'!r}", source=src,
                                 field=f"row {r}, column {c}") from None
            if not np.isfinite(v) or abs(v * scale) > np.radians(MAX_JOINT_ANGLE_DEG) * (1 + 1e-12):
                unit = ("" if scale != 1.0 else f" (a column named by the joint is in radians: {row[i]} rad is "
                        f"{np.degrees(v):.6g} deg; degrees go in the pose columns, q_<name>_deg or q1_deg ..)")
                raise InputError(f"expected a finite angle within +-{MAX_JOINT_ANGLE_DEG:g} deg, got {row[i]}{unit}",
                                 source=src, field=f"row {r}, column {c}")
            vals.append(v * scale)
        out.append(vals)
    return out


def read_candidates(path, robot) -> np.ndarray:
    """Candidate poses (N, n) [rad] from a CSV file (FIGAROH-style: one configuration per row): columns
    ``q1_deg`` .. (``q_<name>_deg``, the project's pose columns, in degrees) or the joint names themselves (in
    radians, as ROS joint states and FIGAROH write them); other columns are ignored. Rows outside the joint
    limits or beyond +-MAX_JOINT_ANGLE_DEG are refused, and so is a file that is not a regular file (a FIFO), larger
    than :data:`~stiffcal.limits.MAX_CANDIDATE_BYTES` or with more than :data:`~stiffcal.limits.MAX_CANDIDATES`
    poses (before it is parsed). Raises :class:`InputError` naming the file, row and column."""
    src = str(path)
    rows = _candidate_rows(Path(path), src)
    header = [h.strip() for h in rows[0]]
    deg_cols, rad_cols = robot.joint_columns("q", "_deg"), list(robot.joint_names)
    if all(c in header for c in deg_cols):
        cols, scale = deg_cols, np.pi / 180
    elif all(c in header for c in rad_cols):
        cols, scale = rad_cols, 1.0
    else:
        raise InputError(f"expected the columns {', '.join(deg_cols)} [deg] or {', '.join(rad_cols)} [rad], got "
                         f"{', '.join(header)}", source=src)
    out = _candidate_angles(rows, [header.index(c) for c in cols], cols, scale, src)
    if not out:
        raise InputError("no poses: expected one pose per row after the header", source=src)
    q = np.array(out, float)
    bad = np.argwhere(robot.outside_limits(q))
    if len(bad):
        r, j = bad[0]
        lo, hi = np.degrees(robot.joint_limits_rad[j])
        raise InputError(f"outside the joint limits [{lo:g}, {hi:g}] deg", source=src,
                         field=f"row {int(r) + 2}, column {cols[j]}")
    return q
