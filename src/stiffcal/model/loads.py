"""The loads a lab can apply (``--loads``): the load-set text that ``stiffcal discriminate`` and ``stiffcal design``
read (:func:`load_set`), kept apart from :mod:`stiffcal.measured.discrimination` (which re-exports it) so that reading a
load set does not need the measured-data analysis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..limits import MAX_FORCE_N, MAX_LOADS, MIN_LOAD


def _gravity(d: int) -> np.ndarray:
    """The default direction of gravity: -y for a planar arm in its vertical plane, -z for a spatial one (as
    :class:`stiffcal.model.robot.Robot` and :mod:`stiffcal.testing.truth` have it)."""
    return np.array([0.0, -1.0]) if d == 2 else np.array([0.0, 0.0, -1.0])

#: most distinct loads of the data a plan is made over by default (beyond, the loads must be given)
MAX_DATA_LOADS = 16


@dataclass(frozen=True)
class LoadSet:
    """The loads a lab can apply: forces (L, d) [N], or wrenches (L, d + d_m) [N, N m] (force, then the moment
    about the tool point: the data's loads when they have moments, a loading bar); kind: 'hanging',
    'directions', 'forces' or 'data'; spec: the text it was read from; d: the force components."""

    forces: np.ndarray
    kind: str
    spec: str
    d: int | None = None
    arm: np.ndarray | None = None

    @property
    def force_part(self) -> np.ndarray:
        """(L, d) [N]: the forces."""
        return self.forces[:, : self.d or self.forces.shape[1]]

    @property
    def moments(self) -> np.ndarray | None:
        """(L, d_m) [N m]: the moments about the tool point, or None for pure forces."""
        d = self.d or self.forces.shape[1]
        return self.forces[:, d:] if self.forces.shape[1] > d else None

    def describe(self) -> str:
        mags = sorted({round(float(np.linalg.norm(f)), 2) for f in self.force_part})
        text = {"hanging": f"hanging weights of {', '.join(f'{m:g}' for m in mags)} N",
                "bar": f"weights of {', '.join(f'{m:g}' for m in mags)} N hung from a loading bar"
                       + ("" if self.arm is None else " whose end is at "
                          f"({', '.join(f'{round(float(x), 4) + 0.0:g}' for x in self.arm)}) m from the tool point in "
                          "the tip frame (its moment turns with the tool)"),
                "wrenches": f"{len(self.forces)} given wrenches",
                "directions": f"{len(self.forces)} pushes ({', '.join(f'{m:g}' for m in mags)} N in several "
                              "directions)",
                "forces": f"{len(self.forces)} given forces",
                "data": f"the {len(self.forces)} loads of the data"}[self.kind]
        if self.moments is not None and np.any(self.moments):
            text += " (each a force and a moment about the tool point, as the data's loading bar applies them)"
        return text


def sphere_directions(count: int) -> np.ndarray:
    """``count`` quasi-uniform unit vectors on the sphere (Fibonacci lattice), (count, 3)."""
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z**2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def _numbers(text: str, what: str, field_name: str) -> np.ndarray:
    try:
        v = np.array([float(t) for t in text.split(",") if t.strip()], float)
    except ValueError:
        raise InputError(f"expected comma-separated numbers for {what}, got {text!r}", field=field_name) from None
    if v.size == 0 or not np.all(np.isfinite(v)):
        raise InputError(f"expected finite numbers for {what}, got {text!r}", field=field_name)
    return v


def load_set(spec: str | None, d: int, data_forces: np.ndarray | None = None, resolution_N: float | None = 0.5,
             field_name: str = "--loads", moment_resolution_Nm: float = 0.05, gravity=None, cluster=None) -> LoadSet:
    """Parse a load set (d = 2 or 3 force components):

    - ``hanging:M1,M2,...``: hanging weights, forces of M_k newtons along gravity (``gravity``, the robot file's
      direction; default -y for a planar arm in its vertical plane, -z for a spatial one, as
      :class:`stiffcal.testing.truth.Protocol` has them); a weight given as a mass, ``5kg``, is its weight in
      newtons at standard gravity (here and in ``bar:``);
    - ``bar:AX,AY[,AZ]:M1,M2,...``: weights of M_k newtons hung from the end of a loading bar clamped to the
      tool, at (AX, AY, AZ) [m] from the tool point in the tip frame: at the tool point a force along gravity
      and its moment, which turns with the tool (``arm``; :class:`stiffcal.model.observation.Loads`, for ``design``);
    - ``wrenches:FX,FY,FZ,MX,MY,MZ;...`` (planar ``FX,FY,MZ``): the given forces and moments about the tool point
      [N, N m];
    - ``directions:K:M1,M2,...``: K directions (equally spaced in the plane for a planar arm, quasi-uniform on
      the sphere for a spatial one), each at every magnitude [N];
    - ``forces:FX,FY[,FZ];...``: the given forces [N];
    - None or ``data``: the distinct loads of the data (``data_forces`` (N, d), or the wrenches (N, d + d_m)
      when the data have moments, merged within ``resolution_N`` and ``moment_resolution_Nm``): a loading bar's
      moments stay with their forces.

    ``cluster``: the function that groups the data's loads (:func:`stiffcal.measured.measurements.cluster`, which
    :func:`stiffcal.measured.discrimination.load_set` passes). Raises :class:`InputError` naming ``field_name`` for
    anything else, a magnitude that is not > 0, a zero force, more than :data:`~stiffcal.limits.MAX_LOADS` loads, or
    a load outside the physical range: below ``resolution_N`` (the load-cell resolution: such a load cannot be told from
    no load; None for a design's loads, which have no load cell: :data:`~stiffcal.limits.MIN_LOAD`) or above
    :data:`~stiffcal.limits.MAX_FORCE_N` (:func:`check_lab_loads`)."""
    text = "data" if spec is None else spec.strip()
    kind, _, rest = text.partition(":")
    mixed = [k for k in ("hanging", "directions", "forces", "wrenches", "bar") if f"{k}:" in rest]
    if mixed:
        raise InputError(f"expected one kind of load per set, got {kind!r} and {mixed[0]!r} in {text!r}: to combine "
                         "hanging masses with pushes, give every load as 'forces:FX,FY,FZ;...' (a mass M [N] as "
                         "the force M along gravity; the hanging cable's path is then not checked)", field=field_name)
    g = None if gravity is None else np.asarray(gravity, float)
    if kind == "data":
        return LoadSet(_data_loads(data_forces, d, resolution_N, moment_resolution_Nm, cluster, field_name), kind,
                       text, d)
    if kind == "bar":
        arm, forces = _bar_loads(rest, text, d, resolution_N, field_name, g)
        return LoadSet(forces, kind, text, d, arm)
    parse = _LOAD_KINDS.get(kind)
    if parse is None:
        raise InputError(f"expected 'hanging:M1,M2', 'directions:K:M1,M2', 'forces:FX,FY;...', "
                         f"'wrenches:FX,..,MZ;...', 'bar:AX,AY,AZ:M1,M2' or 'data', got {text!r}", field=field_name)
    return LoadSet(np.asarray(parse(rest, text, d, resolution_N, field_name, g), float), kind, text, d)


def _data_loads(data_forces, d, resolution_N, moment_resolution_Nm, cluster, field_name) -> np.ndarray:
    """The distinct loads of the data (``data_forces`` (N, d) or (N, d + d_m)), merged by ``cluster``."""
    if data_forces is None or len(data_forces) == 0 or cluster is None:
        raise InputError("expected loads (the data have none)", field=field_name)
    width = data_forces.shape[1]
    labels = cluster(data_forces, np.r_[np.full(d, resolution_N), np.full(width - d, moment_resolution_Nm)])
    if labels.max() + 1 > MAX_DATA_LOADS:
        raise InputError(f"expected the loads the lab can apply: the data have {labels.max() + 1} distinct loads "
                         f"(more than {MAX_DATA_LOADS} to plan over); give them as 'hanging:M1,M2', "
                         "'directions:K:M1,M2', 'forces:FX,FY;...' or 'wrenches:FX,..,MZ;...'", field=field_name)
    return np.array([data_forces[labels == g].mean(axis=0) for g in range(labels.max() + 1)])


def _masses_in_newtons(text: str) -> str:
    """``text`` with every comma-separated weight given as a mass in kilograms (``5kg``) written in newtons (standard
    gravity, 9.80665 m/s^2), and a trailing ``N`` dropped: ``hanging:5kg,10kg`` is ``hanging:49.03325,98.0665``."""
    from .robot import STANDARD_GRAVITY_M_S2

    out = []
    for t in text.split(","):
        t = t.strip()
        low = t.lower()
        if low.endswith("kg") and t[:-2].strip():
            try:
                t = repr(float(t[:-2]) * STANDARD_GRAVITY_M_S2)
            except ValueError:
                pass  # left as it is: _numbers names it
        elif t.endswith("N") and t[:-1].strip():
            t = t[:-1]
        out.append(t)
    return ",".join(out)


def _weights(mtext, what, count, resolution_N, field_name, noun="weight") -> np.ndarray:
    """The magnitudes [N] of ``mtext`` (a weight may be given as a mass, ``5kg``: :func:`_masses_in_newtons`), each
    > 0 and within the lab's range (:func:`check_lab_loads`)."""
    mags = _numbers(_masses_in_newtons(mtext) if noun == "weight" else mtext, what, field_name)
    if np.any(mags <= 0):
        raise InputError(f"expected {noun}s > 0 N, got {mtext!r}", field=field_name)
    check_lab_loads(mags, count(len(mags)), resolution_N, field_name, noun)
    return mags


def _hanging_loads(rest, text, d, resolution_N, field_name, gravity) -> np.ndarray:
    """``hanging:M1,M2,...``: forces of M_k newtons along gravity."""
    mags = _weights(rest, "the hanging weights [N]", lambda n: n, resolution_N, field_name)
    return mags[:, None] * (_gravity(d) if gravity is None else gravity)


def _bar_loads(rest, text, d, resolution_N, field_name, gravity) -> tuple[np.ndarray, np.ndarray]:
    """``bar:AX,AY[,AZ]:M1,M2,...``: (the bar's end (3,) [m] in the tip frame, the forces along gravity)."""
    arm_text, _, mtext = rest.partition(":")
    arm = _numbers(arm_text, "the bar's end [m] from the tool point in the tip frame", field_name)
    if arm.size != d:
        raise InputError(f"expected 'bar:AX,AY{',AZ' if d == 3 else ''}:M1,M2' with {d} coordinates of the bar's "
                         f"end [m] in the tip frame, got {text!r}", field=field_name)
    if not np.any(arm):
        raise InputError(f"a loading bar of length 0 (its end at the tool point), got {text!r}: masses hung at the "
                         "tool point are 'hanging:M1,M2'", field=field_name)
    mags = _weights(mtext, "the weights [N]", lambda n: n, resolution_N, field_name)
    g = _gravity(d) if gravity is None else gravity
    return (np.r_[arm, 0.0] if d == 2 else arm), mags[:, None] * g


def _wrench_loads(rest, text, d, resolution_N, field_name, gravity) -> np.ndarray:
    """``wrenches:FX,FY,FZ,MX,MY,MZ;...`` (planar ``FX,FY,MZ``): forces and moments about the tool point."""
    w = d + (1 if d == 2 else 3)
    rows = [_numbers(r, "a wrench [N, N m]", field_name) for r in rest.split(";") if r.strip()]
    if not rows or any(len(r) != w for r in rows):
        names = "FX,FY,MZ" if d == 2 else "FX,FY,FZ,MX,MY,MZ"
        raise InputError(f"expected wrenches of {w} components ({names}) separated by ';', got {rest!r}",
                         field=field_name)
    if len(rows) > MAX_LOADS:
        check_lab_loads(np.ones(1), len(rows), resolution_N, field_name, "wrench")
    forces = np.array(rows)
    if np.any(np.linalg.norm(forces, axis=1) == 0):
        raise InputError(f"expected nonzero wrenches, got {rest!r}", field=field_name)
    floor = MIN_LOAD if resolution_N is None else resolution_N  # a wrench may be a moment with no force
    check_lab_loads(np.linalg.norm(forces[:, :d], axis=1).clip(min=floor), len(rows), resolution_N, field_name,
                    "wrench's force")
    return forces


def _direction_loads(rest, text, d, resolution_N, field_name, gravity) -> np.ndarray:
    """``directions:K:M1,M2,...``: K directions (equally spaced in the plane, quasi-uniform on the sphere), each at
    every magnitude."""
    count, _, mtext = rest.partition(":")
    try:
        k = int(count)
    except ValueError:
        k = 0
    if k < 1:
        raise InputError(f"expected 'directions:K:M1,M2' with K >= 1 directions, got {text!r}", field=field_name)
    mags = _weights(mtext, "the push magnitudes [N]", lambda n: k * n, resolution_N, field_name, "magnitude")
    if d == 2:
        ang = 2 * np.pi * np.arange(k) / k
        u = np.stack([np.cos(ang), np.sin(ang)], -1)
    else:
        u = sphere_directions(k)
    return (u[:, None, :] * mags[None, :, None]).reshape(-1, d)


def _force_loads(rest, text, d, resolution_N, field_name, gravity) -> np.ndarray:
    """``forces:FX,FY[,FZ];...``: the given forces."""
    rows = [_numbers(r, "a force [N]", field_name) for r in rest.split(";") if r.strip()]
    if not rows or any(len(r) != d for r in rows):
        raise InputError(f"expected forces of {d} components separated by ';', got {rest!r}", field=field_name)
    if len(rows) > MAX_LOADS:
        check_lab_loads(np.ones(1), len(rows), resolution_N, field_name, "force")
    forces = np.array(rows)
    if np.any(np.linalg.norm(forces, axis=1) == 0):
        raise InputError(f"expected nonzero forces, got {rest!r}", field=field_name)
    big = np.abs(forces).max(axis=1)
    check_lab_loads(np.where(big > MAX_FORCE_N, big, np.hypot.reduce(forces, axis=1)), len(rows), resolution_N,
                    field_name, "force")
    return forces


#: the parsers of the load kinds whose loads are forces (or wrenches) alone, by the kind's word in a SPEC
_LOAD_KINDS = {"hanging": _hanging_loads, "wrenches": _wrench_loads, "directions": _direction_loads,
               "forces": _force_loads}


def check_lab_loads(magnitudes: np.ndarray, count: int, resolution_N: float | None, field_name: str,
                    what: str) -> None:
    """The loads of a load set within the bounds of :mod:`stiffcal.limits`: at most
    :data:`~stiffcal.limits.MAX_LOADS` of them (``count``: directions times magnitudes), each magnitude [N] at
    least the load-cell resolution ``resolution_N`` (None: a design's loads, at least
    :data:`~stiffcal.limits.MIN_LOAD`) and at most :data:`~stiffcal.limits.MAX_FORCE_N`."""
    if count > MAX_LOADS:
        raise InputError(f"{count} loads: expected at most {MAX_LOADS} (each load is a candidate at every pose of the "
                         "pool; docs/contracts.md, 'Limits')", field=field_name)
    low, high = float(np.min(magnitudes)), float(np.max(magnitudes))
    if high > MAX_FORCE_N:
        raise InputError(f"expected each {what} at most {MAX_FORCE_N:g} N (the physical range of loads), got {high:g}",
                         field=field_name)
    if low < (MIN_LOAD if resolution_N is None else resolution_N):
        floor = (f"the smallest load of a design, {MIN_LOAD:g} (MIN_LOAD; docs/contracts.md, 'Limits')"
                 if resolution_N is None else f"the load-cell resolution {resolution_N:g} N "
                 "(force_resolution_N, --force-resolution-N): a smaller load cannot be told from no load")
        raise InputError(f"expected each {what} at least {floor}, got {low:g}", field=field_name)
