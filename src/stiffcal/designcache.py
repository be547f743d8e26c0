"""A disk cache of optimal approximate designs and candidate pools, shared by every M and every call.

The optimal approximate design for O_t and its certificate (:func:`stiffcal.certificate.approximate_design`),
and the candidate pool of the exchange (:func:`stiffcal.certificate.candidate_pool`: in a cell, the poses that
pass the collision checks), depend on the robot, the test pose and load, the measurement loads, what is sensed,
the joint limits, the cell and the candidate poses, never on M, the criterion of the plan or the seed.
``stiffcal design`` computes them once for these inputs and reads them back on every later call with the same
inputs (a study of M = 2..8 from a script, a lab asking for M = 6 and then M = 10): the plan and every number
of the output are the same as without the cache, bit for bit (the design is stored as JSON, whose floats read
back exactly, the pool as .npy).

Key: SHA-256 of the problem's every field (:func:`fingerprint`, :func:`stiffcal.memo.feed`: the robot's
kinematics, limits, masses, cell and targets as their exact bytes; for a URDF arm in a cell the URDF file and
its collision meshes too), the source of the ``stiffcal`` package and the versions of numpy, scipy and
Pinocchio: an edit to any of them makes a new entry (old entries stay, 5 kB and 0.4 MB for a 6-axis arm, until
the folder is cleared). An entry that cannot be read back (truncated, edited, from another layout) is
recomputed and rewritten. Entries are written whole (a temporary file renamed), so concurrent calls never read
half an entry.

Where: ``--cache-dir`` (API ``cache_dir``), else the environment variable ``STIFFCAL_CACHE_DIR``, else
``$XDG_CACHE_HOME/stiffcal`` (``~/.cache/stiffcal``); ``--no-cache`` (API ``cache_dir=None``) computes it afresh.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
from pathlib import Path

import numpy as np

from .certificate import ApproximateDesign
from .memo import NotFingerprintable, feed, feed_file, package_fingerprint, write_whole

#: the environment variable naming the cache folder
CACHE_ENV = "STIFFCAL_CACHE_DIR"
#: the layout of an entry (a new layout ignores the old entries)
FORMAT = 1


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
    if robot.cell is not None and robot.urdf_info:  # the cell's collision meshes are read from files
        from .workcell import _urdf_geometry

        feed_file(h, robot.urdf_info["path"])
        for g in _urdf_geometry(robot)[2].geometryObjects:
            if getattr(g, "meshPath", ""):
                feed_file(h, g.meshPath)
    return h.hexdigest()


def _to_json(design: ApproximateDesign) -> str:
    return json.dumps({"format": FORMAT, **{f.name: (v.tolist() if isinstance(v, np.ndarray) else v)
                                            for f in dataclasses.fields(design)
                                            for v in [getattr(design, f.name)]}}, sort_keys=True,
                      allow_nan=False, default=lambda v: v.item())  # numpy scalars; a non-finite value is not stored


def _from_json(data: bytes, n_joints: int) -> ApproximateDesign | None:
    """The design of an entry, or None when the entry is not one this code wrote (then it is recomputed)."""
    try:
        doc = json.loads(data.decode("utf-8"))
        if doc.pop("format") != FORMAT or set(doc) != {f.name for f in dataclasses.fields(ApproximateDesign)}:
            return None
        support = np.array(doc["support_deg"], float).reshape(-1, n_joints)
        weights = np.array(doc["weights"], float)
        scalars = [float(doc[k]) for k in ("phi", "max_phi", "phi_lower")]
        if weights.shape != (len(support),) or not (np.all(np.isfinite(support)) and np.all(np.isfinite(weights))
                                                    and np.all(np.isfinite(scalars))):
            return None
        return ApproximateDesign(support, weights, *scalars, int(doc["iterations"]), str(doc["region"]),
                                 int(doc["n_candidates"]))
    except (ValueError, TypeError, KeyError, AttributeError, UnicodeDecodeError):
        return None


def _read(path: Path, decode):
    try:
        return decode(path.read_bytes())
    except OSError:
        return None


def _cached(problem, cache_dir, folder: str, suffix: str, compute, encode, decode):
    """compute() read from / stored in ``cache_dir/folder/<fingerprint>suffix``; computed and not stored with
    cache_dir None or inputs that cannot be fingerprinted; an entry that does not decode is recomputed."""
    if cache_dir is None:
        return compute()
    try:
        path = Path(cache_dir) / folder / f"{fingerprint(problem)}{suffix}"
    except NotFingerprintable:
        return compute()
    found = _read(path, decode)
    if found is None:
        found = compute()
        try:
            write_whole(path, encode(found))
        except ValueError:  # a non-finite number: never read back as a valid entry, so not written
            pass
    return found


def cached_design(problem, cache_dir) -> ApproximateDesign:
    """:func:`stiffcal.certificate.approximate_design` of ``problem`` (its O_t problem, any M), read from
    ``cache_dir`` when an entry for the same inputs is there, else computed and stored there (None: computed,
    nothing stored)."""
    from .certificate import approximate_design

    n = problem.robot.n_joints
    return _cached(problem, cache_dir, "approximate-design", ".json", lambda: approximate_design(problem),
                   lambda d: _to_json(d).encode(), lambda b: _from_json(b, n))


def cached_pool(problem, cache_dir) -> np.ndarray:
    """The candidate pool (N, n) [rad] of the plans of ``problem`` (:func:`stiffcal.certificate.candidate_pool`
    at the default step, as the workflow's design job saves it), cached as :func:`cached_design` is (.npy)."""
    from .certificate import candidate_pool, default_pool_step

    n = problem.robot.n_joints

    def encode(pool):
        buf = io.BytesIO()
        np.save(buf, pool, allow_pickle=False)
        return buf.getvalue()

    def decode(data):
        try:
            pool = np.load(io.BytesIO(data), allow_pickle=False)
        except (ValueError, OSError, EOFError):
            return None
        ok = pool.ndim == 2 and pool.shape[1] == n and pool.dtype == np.float64 and np.isfinite(pool).all()
        return pool if ok else None

    return _cached(problem, cache_dir, "candidate-pool", ".npy",
                   lambda: candidate_pool(problem.robot, default_pool_step(n), problem), encode, decode)
