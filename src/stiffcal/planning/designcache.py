"""A disk cache of optimal approximate designs and candidate pools, shared by every M and every call.

The optimal approximate design for O_t and its certificate (:func:`stiffcal.planning.certificate.approximate_design`),
and the candidate pool of the exchange (:func:`stiffcal.planning.certificate.candidate_pool`: in a cell, the poses that
pass the collision checks), depend on the robot, the test pose and load, the measurement loads, what is sensed,
the joint limits, the cell and the candidate poses, never on M, the criterion of the plan or the seed.
``stiffcal design`` computes them once for these inputs and reads them back on every later call with the same
inputs (a study of M = 2..8 from a script, a lab asking for M = 6 and then M = 10): the plan and every number
of the output are the same as without the cache, bit for bit (the design is stored as JSON, whose floats read
back exactly, the pool as .npy).

Key: SHA-256 of the problem's every field (:func:`fingerprint`, :func:`stiffcal.memo.feed`: the robot's
kinematics, limits, masses, cell and targets as their exact bytes; for a URDF arm in a cell the URDF file, its
collision meshes and the cell's SRDF too), the source of the ``stiffcal`` package and the versions of numpy,
scipy and Pinocchio: an edit to any of them makes a new entry (old entries stay, 5 kB and 0.4 MB for a 6-axis
arm, until the folder is cleared). Every entry starts with a line that holds the SHA-256 of its key and
content: an entry that does not match it (truncated, edited, renamed, from another layout) or does not hold a
design or pool this code could have written is recomputed and rewritten. Entries are written whole (a
temporary file renamed, readable as the umask allows), so concurrent calls never read half an entry.

Where: ``--cache-dir`` (API ``cache_dir``), else the environment variable ``STIFFCAL_CACHE_DIR``, else
``$XDG_CACHE_HOME/stiffcal`` (``~/.cache/stiffcal``); ``--no-cache`` (API ``cache_dir=None``) computes it afresh.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import stat
from pathlib import Path

import numpy as np

from .certificate import ApproximateDesign
from ..memo import NotFingerprintable, feed, feed_file, package_fingerprint, write_whole

#: the environment variable naming the cache folder
CACHE_ENV = "STIFFCAL_CACHE_DIR"
#: the layout of an entry (a new layout ignores the old entries)
FORMAT = 2
#: the largest entry read back [bytes] (a pool of 10^7 poses of 7 joints is 0.56 GB)
MAX_ENTRY_BYTES = 2**30


def default_cache_dir() -> Path:
    """``$STIFFCAL_CACHE_DIR``, else ``$XDG_CACHE_HOME/stiffcal``, else ``~/.cache/stiffcal``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "stiffcal"


def fingerprint(problem) -> str:
    """The cache key (hex SHA-256) of the approximate design and pool of ``problem``; raises
    :class:`stiffcal.memo.NotFingerprintable` for an input it cannot read exactly."""
    h = hashlib.sha256()
    feed(h, [FORMAT, package_fingerprint()])
    feed(h, problem)
    robot = problem.robot
    if robot.cell is not None and robot.cell.srdf:  # the pairs the cell leaves unchecked are read from a file
        feed_file(h, robot.cell.srdf)
    if robot.cell is not None and robot.urdf_info:  # the cell's collision meshes are read from files
        from ..model.workcell import _urdf_geometry

        feed_file(h, robot.urdf_info["path"])
        for g in _urdf_geometry(robot)[2].geometryObjects:
            if getattr(g, "meshPath", ""):
                feed_file(h, g.meshPath)
    return h.hexdigest()


def _to_json(design: ApproximateDesign) -> bytes:
    return json.dumps({f.name: (v.tolist() if isinstance(v, np.ndarray) else v)
                       for f in dataclasses.fields(design) for v in [getattr(design, f.name)]}, sort_keys=True,
                      allow_nan=False, default=lambda v: v.item()).encode()  # a non-finite value is not stored


def _from_json(data: bytes, n_joints: int) -> ApproximateDesign | None:
    """The design of an entry's payload, or None when it is not a design of n_joints this code could have
    written (then it is recomputed)."""
    try:
        doc = json.loads(data.decode("utf-8"))
        if not isinstance(doc, dict) or set(doc) != {f.name for f in dataclasses.fields(ApproximateDesign)}:
            return None
        support = np.array(doc["support_deg"], float).reshape(-1, n_joints)
        weights = np.array(doc["weights"], float)
        scalars = np.array([doc[k] for k in ("phi", "max_phi", "phi_lower")], float)
        counts = [doc["iterations"], doc["n_candidates"]]
        if not (len(support) and weights.shape == (len(support),) and np.isfinite(support).all()
                and np.isfinite(weights).all() and weights.min() >= 0.0 and abs(weights.sum() - 1.0) <= 1e-9
                and np.isfinite(scalars).all() and scalars.min() > 0.0 and isinstance(doc["region"], str)
                and all(type(c) is int and 0 <= c < 2**53 for c in counts) and type(doc["near_singular"]) is bool):
            return None
        return ApproximateDesign(support, weights, *map(float, scalars), *counts[:1], doc["region"], counts[1],
                                 doc["near_singular"])
    except (ValueError, TypeError, KeyError, AttributeError, UnicodeDecodeError, OverflowError, RecursionError):
        return None


def _pool_bytes(pool: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, pool, allow_pickle=False)
    return buf.getvalue()


def _pool_from(data: bytes, n_joints: int) -> np.ndarray | None:
    """The pool (N >= 1, n_joints) float64 of an entry's payload, or None; the .npy header is checked against
    the payload's length before anything is allocated."""
    try:
        buf = io.BytesIO(data)
        version = np.lib.format.read_magic(buf)
        if version not in ((1, 0), (2, 0)):
            return None
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = read(buf)
        if (dtype != np.float64 or fortran or len(shape) != 2 or shape[1] != n_joints or shape[0] < 1
                or len(data) - buf.tell() != shape[0] * n_joints * 8):
            return None
        pool = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError, TypeError, SyntaxError):
        return None
    return pool if np.isfinite(pool).all() else None


#: the first line of an entry: its layout, what it holds and the SHA-256 of its key and payload
_HEADER = "stiffcal-cache {format} {kind} {digest}\n"


def _entry(key: str, kind: str, payload: bytes) -> bytes:
    digest = hashlib.sha256(key.encode() + b"\0" + payload).hexdigest()
    return _HEADER.format(format=FORMAT, kind=kind, digest=digest).encode() + payload


def _payload(key: str, kind: str, data: bytes) -> bytes | None:
    """The payload of an entry written by :func:`_entry` for this key and kind, or None (another layout, a
    truncated, edited or renamed entry: its checksum fails)."""
    head, sep, payload = data.partition(b"\n")
    if not sep or len(head) > 200:
        return None
    expected = _entry(key, kind, payload)
    return payload if data == expected else None


def _cached(problem, cache_dir, kind: str, compute, encode, decode):
    """compute() read from / stored in ``cache_dir/kind/<fingerprint>``; computed and not stored with cache_dir
    None or inputs that cannot be fingerprinted; an entry that does not check and decode is recomputed."""
    if cache_dir is None:
        return compute()
    try:
        key = fingerprint(problem)
    except NotFingerprintable:
        return compute()
    path = Path(cache_dir) / kind / key
    try:  # a FIFO, a device or an oversized file in its place is never read (a FIFO would block)
        info = path.stat()
        payload = (_payload(key, kind, path.read_bytes())
                   if stat.S_ISREG(info.st_mode) and info.st_size <= MAX_ENTRY_BYTES else None)
    except OSError:
        payload = None
    found = None if payload is None else decode(payload)
    if found is None:
        found = compute()
        try:
            write_whole(path, _entry(key, kind, encode(found)))
        except ValueError:  # a non-finite number: never read back as a valid entry, so not written
            pass
    return found


def cached_design(problem, cache_dir) -> ApproximateDesign:
    """:func:`stiffcal.planning.certificate.approximate_design` of ``problem`` (its O_t problem, any M), read from
    ``cache_dir`` when an entry for the same inputs is there, else computed and stored there (None: computed,
    nothing stored)."""
    from .certificate import approximate_design

    n = problem.robot.n_joints
    return _cached(problem, cache_dir, "approximate-design", lambda: approximate_design(problem), _to_json,
                   lambda b: _from_json(b, n))


def cached_pool(problem, cache_dir) -> np.ndarray:
    """The candidate pool (N, n) [rad] of the plans of ``problem`` (:func:`stiffcal.planning.certificate.candidate_pool`
    at the default step, as the workflow's design job saves it), cached as :func:`cached_design` is (.npy)."""
    from .certificate import candidate_pool, default_pool_step

    n = problem.robot.n_joints
    return _cached(problem, cache_dir, "candidate-pool", lambda: candidate_pool(problem.robot, default_pool_step(n),
                                                                                problem),
                   _pool_bytes, lambda b: _pool_from(b, n))
