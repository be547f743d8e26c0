"""The ``calibration`` section of a calibrated robot file (docs/contracts.md, "The calibrated model"): the model a
verdict chose, as :class:`Calibration`, and its reading and checking against the robot (:func:`from_dict`). Kept
apart from :mod:`stiffcal.measured.calibrated` (prediction, compensation, the next round) so that reading a robot file
does not depend on the analysis."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .catalogue import CAUSES, extension_size, parameter_names
from ..errors import InputError
from ..jsonsafe import json_safe

if TYPE_CHECKING:
    from ..model.robot import Robot


@dataclass(frozen=True)
class Calibration:
    """The model a verdict chose, ready for prediction (module docstring).

    causes: the extension's catalogue causes (empty: the nominal model); k_joints (p_k,) the joints (0-based)
    of the compliance parameters (a joint the data could not identify is not among them); names (p,): the
    parameters' names, the compliances' (``k1`` .., ``k_<name>``) then the extension's with their units
    (``b1_rad`` ..); theta (p,) their values [SI]; cov (p, p) their covariance [SI^2]; estimable (p,) bool: the
    data determine the parameter (a parameter they do not keeps its minimum-norm value); n_offsets: the
    parameters of ``measurement_offset`` (left out of predictions); sigma_m [m] and rotation_weight_m_per_rad:
    the noise of the analysis; error_model: its summary (the verdict's ``error_model``); source: the data file,
    its SHA-256, the robot file, the verdict's cause and p-value, alpha, the stiffcal version; model_error_m [m]:
    where the data reject this model, its error per position coordinate at a configuration it was not fitted to
    beyond the noise (0: none known), which predictions add to their variance; untested_backlash: the joints
    (0-based) the loads turned but whose total torque no load of the data reversed (the arm's weight preloads them),
    so that a backlash there could not show (the verdict's note), which predictions name where their load reverses
    it; free_directions (k, p): unit vectors along which the data leave the parameters free (the null space of their
    design; None where they determine every parameter): a prediction is determined where it does not move along
    them."""
    causes: tuple[str, ...]
    k_joints: tuple[int, ...]
    names: tuple[str, ...]
    theta: np.ndarray
    cov: np.ndarray
    estimable: tuple[bool, ...]
    n_offsets: int
    sigma_m: float
    rotation_weight_m_per_rad: float | None = None
    error_model: dict = field(default_factory=dict)
    source: dict = field(default_factory=dict)
    model_error_m: float = 0.0
    untested_backlash: tuple[int, ...] = ()
    free_directions: np.ndarray | None = None

    def compliances(self, n_joints: int) -> np.ndarray:
        """(n,) [rad/(N m)]: the identified compliance of every joint, NaN for one the data did not identify."""
        k = np.full(n_joints, np.nan)
        k[list(self.k_joints)] = self.theta[: len(self.k_joints)]
        return k

    def to_dict(self) -> dict:
        """The ``calibration`` section of a calibrated robot file (plain YAML types)."""
        return json_safe({"causes": list(self.causes), "k_joints": [int(j) + 1 for j in self.k_joints],
                          "parameter_names": list(self.names), "parameters": [float(v) for v in self.theta],
                          "covariance": [[float(v) for v in row] for row in self.cov],
                          "estimable": [bool(e) for e in self.estimable], "n_offsets": int(self.n_offsets),
                          "sigma_m": float(self.sigma_m),
                          "rotation_weight_m_per_rad": self.rotation_weight_m_per_rad,
                          "error_model": self.error_model, "source": self.source,
                          **({"model_error_m": float(self.model_error_m)} if self.model_error_m > 0 else {}),
                          **({"untested_backlash_joints": [int(j) + 1 for j in self.untested_backlash]}
                             if self.untested_backlash else {}),
                          **({"free_directions": [[float(v) for v in row] for row in self.free_directions]}
                             if self.free_directions is not None and len(self.free_directions) else {})})


#: the largest standard deviation of a calibration's parameter accepted (SI units: rad/(N m), rad, m, 1/(N m^2))
MAX_PARAMETER_SD = 1e3


def from_dict(doc: dict, robot: Robot, source: str) -> Calibration:
    """The :class:`Calibration` of a robot file's ``calibration`` section (validated by the robot schema),
    checked against the robot: one joint number per compliance within the robot's joints, a parameter vector
    as long as the names, a square symmetric covariance of that size. Raises :class:`InputError` naming the
    field."""
    def bad(msg, key):
        return InputError(msg, source=source, field=f"calibration.{key}")

    causes = tuple(doc["causes"])
    for c in causes:
        if c not in CAUSES:
            raise bad(f"expected causes of the catalogue ({', '.join(CAUSES)}), got {c!r}", "causes")
    joints = [int(j) - 1 for j in doc["k_joints"]]
    if any(not 0 <= j < robot.n_joints for j in joints) or len(set(joints)) != len(joints):
        raise bad(f"expected distinct joint numbers 1..{robot.n_joints}, got {doc['k_joints']}", "k_joints")
    theta = np.asarray(doc["parameters"], float)
    names = tuple(doc["parameter_names"])
    if len(names) != theta.size or theta.size < len(joints):
        raise bad(f"expected one value per parameter name ({len(names)}), got {theta.size}", "parameters")
    cov = np.asarray(doc["covariance"], float)
    if cov.shape != (theta.size, theta.size):
        raise bad(f"expected a {theta.size} x {theta.size} matrix (one row and column per parameter), got shape "
                  f"{cov.shape}", "covariance")
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
        i, j = np.unravel_index(np.argmax(np.abs(cov - cov.T)), cov.shape)
        raise bad(f"expected a symmetric matrix, got entry [{i}][{j}] = {cov[i, j]:.6g} against [{j}][{i}] = "
                  f"{cov[j, i]:.6g}", "covariance")
    lam = np.linalg.eigvalsh(0.5 * (cov + cov.T))
    if lam[0] < -1e-9 * max(lam[-1], 0.0) or lam[-1] < 0:
        raise bad(f"expected a positive semi-definite matrix (a covariance), got an eigenvalue {lam[0]:.3g} (the "
                  f"largest {lam[-1]:.3g})", "covariance")
    variance = np.diag(cov)
    est = np.array([bool(e) for e in doc.get("estimable", [True] * theta.size)])
    if est.size == theta.size and np.any(est & ~(variance > 0)):
        i = int(np.flatnonzero(est & ~(variance > 0))[0])
        raise bad(f"expected a positive variance for every estimable parameter (a variance of 0 claims it known "
                  f"exactly, which no data can give), got {variance[i]:.3g} for {names[i]}", "covariance")
    if np.any(variance > MAX_PARAMETER_SD**2):
        i = int(np.argmax(variance))
        raise bad(f"expected standard deviations of at most {MAX_PARAMETER_SD:g} in the parameters' SI units (no "
                  f"compliance, angle, offset or bending compliance is that uncertain), got {np.sqrt(variance[i]):.3g} "
                  f"for {names[i]}", "covariance")
    expected = len(joints) + _extension_size(robot, causes, int(doc["n_offsets"]))
    if theta.size != expected:
        raise bad(f"expected {expected} parameters (the compliances of joints {doc['k_joints']} and those of "
                  f"{', '.join(causes) or 'no extension'} for this robot), got {theta.size}", "parameters")
    est = tuple(bool(e) for e in doc.get("estimable", [True] * theta.size))
    if len(est) != theta.size:
        raise bad(f"expected one flag per parameter ({theta.size}), got {len(est)}", "estimable")
    want = [robot.joint_columns("k")[j] for j in joints] + [
        name for c in sorted(causes, key=CAUSES.index) for name in _names_of(c, robot, int(doc["n_offsets"]))]
    if list(names) != want:
        wrong = next(i for i, (a, b) in enumerate(zip(names, want)) if a != b)
        raise bad(f"expected the names {', '.join(want)} (the compliances of joints {doc['k_joints']}, then "
                  f"{', '.join(causes) or 'no extension'}), got {names[wrong]!r} at position {wrong + 1}",
                  "parameter_names")
    return Calibration(causes, tuple(joints), names, theta, cov, est, int(doc["n_offsets"]), float(doc["sigma_m"]),
                       doc.get("rotation_weight_m_per_rad"), dict(doc.get("error_model") or {}),
                       dict(doc.get("source") or {}), float(doc.get("model_error_m", 0.0)),
                       _untested(doc, robot, bad), _free(doc, theta.size, bad))


def _free(doc: dict, p: int, bad) -> np.ndarray | None:
    """The section's ``free_directions`` (k, p): unit vectors of the parameters along which the data leave them free
    (None where the file has none: written before they were, or every parameter determined)."""
    rows = doc.get("free_directions")
    if not rows:
        return None
    V = np.asarray(rows, float)
    if V.ndim != 2 or V.shape[1] != p or not np.all(np.isfinite(V)):
        raise bad(f"expected rows of {p} numbers (one per parameter), got shape {V.shape}", "free_directions")
    return V


def _names_of(cause: str, robot: Robot, n_offsets: int) -> list[str]:
    """The parameter names of a cause in a calibration (a measurement offset of n_offsets components: the
    position's, then the rotation's)."""
    return parameter_names(cause, robot, cause == "measurement_offset" and n_offsets > robot.task_dim)


def _extension_size(robot: Robot, causes, n_offsets: int) -> int:
    return sum(extension_size(c, robot, n_offsets) for c in causes)


def _untested(doc: dict, robot: Robot, bad) -> tuple[int, ...]:
    """The section's ``untested_backlash_joints`` (1-based) as 0-based joints, each within the robot's."""
    joints = [int(j) for j in doc.get("untested_backlash_joints") or []]
    if any(not 1 <= j <= robot.n_joints for j in joints):
        raise bad(f"expected joint numbers 1..{robot.n_joints}, got {joints}", "untested_backlash_joints")
    return tuple(j - 1 for j in joints)

