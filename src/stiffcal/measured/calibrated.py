"""The calibrated model in use: written as a robot file, read back, used to predict deflections and to
compensate a path, and handed to the next round.

``stiffcal discrepancy`` writes ``DIR/calibrated.yaml``: the robot file it analysed, every key kept (a URDF arm
keeps its URDF, referred to from the new file's folder; a cell and joint limits given apart are added), with
``compliances_rad_per_Nm`` replaced by the
identified joint compliances and a ``calibration`` section holding the model the verdict chose
(:class:`Calibration`: the extension's causes and parameters with their units, the covariance of every
parameter, the noise, the rows' error model and where it all came from: the data file and its SHA-256, the
robot file, the verdict). :func:`stiffcal.model.robot.load_robot` reads it back like any robot file (the section is
:attr:`stiffcal.model.robot.Robot.calibration`), so ``design``, ``discriminate`` and the analysis take it as the
nominal model of the next round.

Predictions (:func:`predict`) use every part of the calibrated model that belongs to the robot: the joint
compliances and every catalogue extension (link bending, coupling, the nonlinear stiffness and backlash on the
total torque with the arm's own weight, :func:`stiffcal.measured.discrepancy.model_columns` with ``predict=True``); a
measurement offset belongs to the tracker and is left out. Their standard deviation comes from the parameters'
covariance, ``sd = sqrt(diag(X Cov X^T))`` (the model's own error, not the noise of a new reading).

Compensation (:func:`compensate`) of a path (poses and the wrench at each): the predicted deflection of the
tool point at each pose; the corrected tool target (first order: aim at the nominal point less the deflection);
and the corrected joint angles q_c with fk(q_c) + dp(q_c) = fk(q), solved by Gauss-Newton iterations on the
tool point's Jacobian (the minimum-norm step for a redundant arm) to a residual below ``tol_m``, beside the
first-order step q - J^+ dp(q); the predicted residual error at each pose.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..model.calibration import Calibration, from_dict  # noqa: F401  (re-exported: part of this module's API)
from ..errors import InputError
from ..model.robot import Robot

#: the file ``stiffcal discrepancy`` writes beside ``verdict.json``
CALIBRATED_FILE = "calibrated.yaml"
#: Gauss-Newton iterations and residual [m] of the joint-angle compensation
COMPENSATE_ITERATIONS = 30
COMPENSATE_TOL_M = 1e-10


def sha256(path) -> str:
    """The SHA-256 of a file (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def from_analysis(robot: Robot, pre, verdict: dict, data_path=None) -> Calibration:
    """The :class:`Calibration` of an analysis (:func:`stiffcal.measured.discrepancy.prepare` and the verdict of it):
    the verdict's extended model (its causes; the nominal model for ``none`` or ``unexplained``), refitted by the
    analysis's generalised least squares (the same numbers as the verdict's), its covariance sigma^2 (X^T X)^+
    in the whitened rows, where the rows share estimated errors grown by Kenward-Roger's 2 Lambda for the estimated
    variance ratios (Kenward & Roger 1997, eq. 3; :class:`stiffcal.measured.discrepancy.Intervals`)."""
    from .. import __version__
    from . import discrepancy as D

    causes = tuple(verdict["extended"]["causes"]) if verdict.get("extended") else ()
    X = pre.des.model(frozenset(causes))
    f = D.fit(X, pre.des.y)
    ok, _ = D.estimability(X)
    free = D.free_directions(X)
    params = pre.ob.model_params(robot)
    names = [robot.joint_columns("k")[int(j)] for j in params]
    names += [name for c in sorted(causes, key=D.CAUSES.index) for name in D.parameter_names(c, robot, pre.ob)]
    src = {"data": None if data_path is None else str(data_path),
           "data_sha256": None if data_path is None else sha256(data_path), "robot": robot.source,
           "robot_sha256": sha256(robot.source) if Path(robot.source).is_file() else None,
           "verdict_cause": verdict["cause"], "verdict_causes": list(verdict["causes"]),
           "p_value": verdict["p_value"], "alpha": verdict["alpha"], "stiffcal": __version__}
    if any(n.startswith(D.GEOMETRY_NOTE) for n in pre.meas.notes):  # the rows were corrected for the exact statics:
        src["second_order"] = True                                   # predictions add it back (predict)
    kr = D.intervals(pre, causes).kr
    cov = f.cov_unscaled if kr is None else f.cov_unscaled + kr.extra_covariance
    return Calibration(causes, tuple(int(j) for j in params), tuple(names), np.asarray(f.beta, float),
                       pre.noise.s2 * cov, tuple(bool(e) for e in ok), pre.ob.rows_per(robot),
                       float(np.sqrt(pre.noise.s2)), verdict["nominal"]["rotation_weight_m_per_rad"],
                       verdict.get("error_model") or {}, src,
                       untested_backlash=tuple(D.unseen_backlash_joints(robot, pre)),
                       free_directions=free if len(free) else None)


def calibrated_document(robot: Robot, cal: Calibration, out_dir) -> dict:
    """The calibrated robot file (module docstring) as a YAML document for ``out_dir``: the robot file's own
    keys (a URDF given directly: a robot file of kind ``urdf`` naming it and its frames; a cell and joint limits
    given apart added; relative paths of a URDF and of a cell's SRDF made relative to ``out_dir``, absolute ones
    kept),
    ``compliances_rad_per_Nm`` replaced when every joint's is identified and positive (else the file's own, or
    none), and the ``calibration`` section."""
    import json
    import os

    from ..validation import read_yaml

    if not Path(robot.source).is_file():
        raise InputError("the calibrated model is written beside the robot file it came from: give the robot as a "
                         "file", field="robot")
    if robot.source.lower().endswith(".urdf") and robot.urdf_info:  # a URDF read directly (load_robot)
        doc = {"name": Path(robot.source).stem, "kind": "urdf", "urdf": Path(robot.source).name,
               "base_frame": robot.urdf_info["base_frame"], "tip_frame": robot.urdf_info["tip_frame"]}
    else:
        doc = dict(read_yaml(robot.source))

    def moved(path):  # a file the robot file names by a relative path, from the new file's folder (absolute: kept)
        if Path(path).is_absolute():
            return str(path)
        return os.path.relpath((Path(robot.source).parent / path).resolve(), Path(out_dir).resolve())

    if doc.get("kind") == "urdf":
        doc["urdf"] = moved(doc["urdf"])
    if robot.cell is not None and "cell" not in doc:  # a cell given apart (--cell): the next round plans in it too
        doc["cell"] = json.loads(robot.cell.spec)
    limits = _limits_given_apart(robot)
    if limits is not None:  # limits given apart (--joint-limits-deg): the next round plans within them too
        doc["joint_limits_deg"] = limits
    if isinstance(doc.get("cell"), dict) and doc["cell"].get("srdf"):
        doc["cell"] = {**doc["cell"], "srdf": moved(doc["cell"]["srdf"])}
    doc.pop("calibration", None)
    k, _ = _written_compliances(cal, robot.n_joints, doc.get("compliances_rad_per_Nm"))
    if k is not None:
        doc["compliances_rad_per_Nm"] = k
    doc["name"] = f"{doc['name']} (calibrated)" if not str(doc["name"]).endswith("(calibrated)") else doc["name"]
    doc["calibration"] = cal.to_dict()
    return doc


def _written_compliances(cal: Calibration, n: int, own) -> tuple[list | None, list[int]]:
    """(the calibrated file's ``compliances_rad_per_Nm`` (n,) [rad/(N m)] or None: the robot file's own kept as they
    are; the joints (0-based) that keep the robot file's value): each joint's identified compliance where the data
    identified (determined: its estimable flag) and it is positive, the robot file's own value for the others (a
    vertical axis under hanging masses; a planar arm's last joint confounded with its link's bending); None when a
    joint has neither."""
    k = cal.compliances(n)
    determined = np.zeros(n, bool)  # a compliance the data did not determine (its minimum-norm value) is no estimate
    determined[list(cal.k_joints)] = np.asarray(cal.estimable, bool)[: len(cal.k_joints)]
    ok = np.isfinite(k) & (k > 0) & determined
    kept = [j for j in range(n) if not ok[j]]
    if kept and not (isinstance(own, list) and len(own) == n):
        return None, kept
    return [float(k[j]) if ok[j] else float(own[j]) for j in range(n)], kept


def _compliances_comment(robot: Robot, kept: list[int], written: bool) -> str:
    """The calibrated file's comment on its ``compliances_rad_per_Nm`` (:func:`_written_compliances`: the joints
    ``kept`` at the robot file's value, and whether the key was ``written``): which joints keep the robot file's
    value, or that the file's own are kept; empty when every joint's is identified."""
    if not kept:
        return ""
    if not written:
        return ("# compliances_rad_per_Nm: as in the robot file (these data did not identify every joint's, and the "
                "robot\n# file gives none for those); calibration.k_joints lists the joints identified\n")
    names = ", ".join(robot.joint_names[j] for j in kept)
    which = f"joint {names} keeps" if len(kept) == 1 else f"joints {names} keep"
    return (f"# compliances_rad_per_Nm: {which} the robot file's value (these data did not determine\n# it, or "
            "determined a value that is not positive); calibration.k_joints and .estimable say which\n")


def _limits_given_apart(robot: Robot) -> list | None:
    """The joint limits [deg] (n [lower, upper] pairs, rounded to 1e-9) of ``robot`` where they differ from its
    file's (narrowed by an argument), else None."""
    from ..model.robot import load_robot

    own = load_robot(robot.source)
    same = own.has_joint_limits and np.allclose(own.joint_limits_rad, robot.joint_limits_rad, rtol=0, atol=1e-12)
    if robot.has_joint_limits and not same:
        return np.round(robot.limits_deg, 9).tolist()
    return None


def write_calibrated(robot: Robot, cal: Calibration, out_dir, doc: dict | None = None) -> Path:
    """Write ``out_dir/calibrated.yaml`` (``doc``: :func:`calibrated_document`, computed here when not given);
    returns its path."""
    import yaml

    doc = calibrated_document(robot, cal, out_dir) if doc is None else doc
    _, kept = _written_compliances(cal, robot.n_joints, None)
    path = Path(out_dir) / CALIBRATED_FILE
    text = ("# written by stiffcal discrepancy: the robot file with its identified compliances and the calibrated\n"
            "# model (calibration); read it with stiffcal.load_robot, predict and compensate with it (docs)\n")
    text += _compliances_comment(robot, kept, "compliances_rad_per_Nm" in doc)
    text += yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)
    path.write_text(text, encoding="utf-8")
    return path


# --- predictions ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Prediction:
    """Predicted deflections: q (N, n) [rad]; load (N, d (+ d_m)) [N (, N m)]; displacement (N, d) [m] of each
    row's target and its standard deviation sd (N, d) [m] from the parameters' covariance; rotation (N, d_r)
    [rad] and rotation_sd with the orientation (else None); cov (N, r, r): the covariance of each row's prediction
    (positions, then rotations) [m^2, m rad, rad^2]; targets (N,) names; causes: the extension applied; notes;
    determined (N,) bool: the row's prediction rests only on what the calibration's data determined
    (:func:`determined_rows`; where not, its error can be far above sd)."""
    q: np.ndarray
    load: np.ndarray
    displacement: np.ndarray
    sd: np.ndarray
    rotation: np.ndarray | None
    rotation_sd: np.ndarray | None
    cov: np.ndarray
    targets: tuple
    causes: tuple
    notes: tuple = ()
    determined: np.ndarray | None = None


def _calibration(robot: Robot) -> Calibration:
    """The robot's calibration, or one of its file's compliances (no extension, no covariance)."""
    cal = getattr(robot, "calibration", None)
    if cal is not None:
        return cal
    if robot.compliances is None:
        raise InputError("the robot file has neither a calibration nor compliances_rad_per_Nm: nothing to predict "
                         "with; give the calibrated.yaml that stiffcal discrepancy writes", source=robot.source,
                         field="compliances_rad_per_Nm")
    n = robot.n_joints
    return Calibration((), tuple(range(n)), tuple(robot.joint_columns("k")), np.asarray(robot.compliances, float),
                       np.zeros((n, n)), (True,) * n, robot.task_dim, 0.0)


def columns(robot: Robot, q: np.ndarray, load: np.ndarray, target=None, orientation: bool = False) -> np.ndarray:
    """(N, r, p): the calibrated model's regressors of a prediction (the measuring system's causes zero) at poses
    q (N, n) [rad] under loads (N, d (+ d_m)), for the rows' targets (``target`` (N,) indices into the robot's
    target names; None: the tool point) and, with ``orientation``, the tool's rotation (rows after the
    positions, unweighted)."""
    from . import discrepancy as D

    cal = _calibration(robot)
    ob = D.Observed(robot.target_names, None if target is None else np.asarray(target, int), orientation, 1.0,
                    np.asarray(cal.k_joints, int), cal.n_offsets)
    return D.model_columns(robot, np.asarray(q, float), np.asarray(load, float), cal.causes, predict=True,
                           observed=ob)


def predict(robot: Robot, q: np.ndarray, load: np.ndarray, target=None, orientation: bool = False) -> Prediction:
    """The calibrated model's deflection of each row's target (and the tool's rotation) at poses q (N, n) [rad]
    under loads (N, d) [N] or wrenches (N, d + d_m) [N, N m] at the tool point, with its standard deviation from
    the parameters' covariance (module docstring). ``robot``: a robot with a calibration (its calibrated.yaml),
    or with compliances only (then no extension and no covariance). Raises :class:`InputError` without either."""
    cal = _calibration(robot)
    q = np.atleast_2d(np.asarray(q, float))
    load = np.atleast_2d(np.asarray(load, float))
    X, mean, unidentified = _motion(robot, cal, q, load, target, orientation)
    cov = np.einsum("nrp,pq,nsq->nrs", X, cal.cov, X)
    d = robot.task_dim
    cov[:, np.arange(d), np.arange(d)] += cal.model_error_m**2  # a model the data reject: its error beyond the noise
    sd = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
    notes = _model_error_note(cal)
    if getattr(robot, "calibration", None) is None:
        notes.append("the robot file has no calibration section: the predictions use its compliances_rad_per_Nm "
                     "alone, with no extension and no uncertainty (sd 0); give the calibrated.yaml that stiffcal "
                     "discrepancy writes")
    notes += [unidentified] if unidentified else []
    notes += _negative_compliance_notes(robot, cal)
    notes += _negative_backlash_notes(robot, cal)
    notes += _unset_backlash_notes(robot, cal, q, load) + _untested_backlash_notes(robot, cal, q, load)
    notes += _uncertain_rows_note(cal, X, mean[:, :d], sd[:, :d])
    names = robot.target_names
    tnames = tuple(names[t] for t in (np.zeros(len(q), int) if target is None else np.asarray(target, int)))
    ok = determined_rows(robot, cal, q, load, X, target, orientation)
    if not ok.all():
        notes.append(f"{int((~ok).sum())} of {len(ok)} row(s) (determined False) rest on what the calibration's data "
                     "did not determine (a joint they did not identify that the row's load turns and that moves what "
                     "the row measures, a joint whose backlash they could not test that the row's load reverses, or a "
                     "parameter they did not determine that the row moves): their error can be far above sd")
    return Prediction(q, load, mean[:, :d], sd[:, :d], mean[:, d:] if orientation else None,
                      sd[:, d:] if orientation else None, cov, tnames, cal.causes, tuple(notes), ok)


def _model_error_note(cal) -> list[str]:
    """A note where the calibration carries a model error (:attr:`Calibration.model_error_m`)."""
    if not cal.model_error_m > 0:
        return []
    return [f"the data reject this model (verdict {cal.source.get('verdict_cause')}): sd includes its error at "
            f"configurations it was not fitted to, {_model_error_um(cal)} (its held-out RMS beyond what a right model "
            "leaves, calibration.model_error_m), an estimate from the measured configurations: farther from them the "
            "error can be larger"]


def _model_error_um(cal) -> str:
    """'12.3 um per coordinate': the calibration's model error (:attr:`Calibration.model_error_m`) as the notes give
    it."""
    return f"{cal.model_error_m * 1e6:.3g} um per coordinate"


def _negative_compliance_notes(robot: Robot, cal) -> list[str]:
    """Notes on the calibrated compliances below zero: beyond their 95 % interval (z = 1.96; the data were likely
    logged with a sign reversed or in the wrong frame; in an extended model, the extension trading it against its own
    parameters: a fresh user's nonlinear stiffness fitted k4 = -7.1e-6 +- 5.2e-6 on clean signs and was told they
    were reversed), or within it (the data barely determine the compliance: a fresh user's Z1 had k5 = -2.1e-4 +-
    1.1e-3 and was told its signs were reversed)."""
    k = cal.compliances(robot.n_joints)
    sd = np.full(robot.n_joints, np.inf)
    sd[list(cal.k_joints)] = np.sqrt(np.clip(np.diag(cal.cov)[: len(cal.k_joints)], 0.0, None))
    far, near = _below_zero(k, sd)
    beyond = [robot.joint_names[j] for j in far]
    within = [f"{robot.joint_names[j]} ({k[j]:.3g} +- {1.96 * sd[j]:.2g} rad/(N m), 95 %)" for j in near]
    notes = []
    if beyond and cal.causes:  # the nominal model's compliances passed the analysis's sign and frame checks
        notes.append(f"the calibrated model's compliance of joint(s) {', '.join(beyond)} is negative beyond its 95 % "
                     f"interval in its extended model ({'+'.join(cal.causes)}): the extension trades it against its "
                     "own parameters and is not physical there (its verdict's notes say so), so predictions where "
                     "that joint turns are doubtful; the nominal model (the verdict's nominal section) is the safer "
                     "one there")
    elif beyond:
        notes.append(f"the calibrated model's compliance of joint(s) {', '.join(beyond)} is negative beyond its 95 % "
                     "interval: its deflections push against the load, which no joint does; the data it came from were "
                     "likely logged with the force's or the displacement's sign reversed, or in the wrong frame (its "
                     "verdict's notes say which): fix them and analyse again before using these predictions")
    if within:
        notes.append(f"the calibrated model's compliance of joint(s) {', '.join(within)} is negative but within "
                     "its interval of zero: its data barely determine it, so a row whose load turns that joint has a "
                     "large sd; measure with loads that turn it to identify it")
    return notes


def _below_zero(value: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(beyond, within): the indices of the values (n,) below zero beyond their 95 % interval (z = 1.96 with their
    sd (n,)), and of those below zero within it."""
    negative, far = value < 0, value + 1.96 * sd < 0
    return np.flatnonzero(negative & far), np.flatnonzero(negative & ~far)


def _backlash_gaps(robot: Robot, cal) -> dict:
    """{joint index: (b_j [rad], sd [rad])} of the calibration's backlash parameters the data determined (the
    catalogue's ``b<j>_rad``, :mod:`stiffcal.model.catalogue`; an undetermined one's round-off value is no jump)."""
    out = {}
    for j in range(robot.n_joints):
        name = f"b{j + 1}_rad"
        if name in cal.names and cal.estimable[cal.names.index(name)]:
            i = cal.names.index(name)
            out[j] = (float(cal.theta[i]), float(np.sqrt(max(cal.cov[i, i], 0.0))))
    return out


def _negative_backlash_notes(robot: Robot, cal) -> list[str]:
    """Notes on the calibrated backlash gaps below zero, which no gear has (its predictions put the jump against the
    load): beyond the 95 % interval, or within it (barely determined; a fresh user's iiwa had b5 = -1.6e-4 rad
    against a true +1e-4, and its predictions used it without a word)."""
    gaps = _backlash_gaps(robot, cal)
    joints = list(gaps)
    b, sd = (np.array([gaps[j][i] for j in joints], float).reshape(-1) for i in (0, 1))
    text = [f"{robot.joint_names[j]} ({gaps[j][0]:.3g} +- {1.96 * gaps[j][1]:.2g} rad, 95 %)" for j in joints]
    far, near = _below_zero(b, sd)
    beyond, within = [text[i] for i in far], [text[i] for i in near]
    notes = []
    if beyond:
        notes.append(f"the calibrated model's backlash of joint(s) {', '.join(beyond)} is negative beyond its 95 % "
                     "interval: a jump against the load, which no gear makes; it stands for something else the data "
                     "show at that joint (a misfit that changes sign with the load, a frame or sign error; the "
                     "verdict's notes), so the predictions' jump there is not a gear's: do not compensate with it")
    if within:
        notes.append(f"the calibrated model's backlash of joint(s) {', '.join(within)} is negative but within its "
                     "interval of zero: the data barely determine the gap, and the predictions' jump there (against "
                     "the load) is within their sd; measure with loads that reverse that joint's torque to identify it")
    return notes


def _uncertain_rows_note(cal, X: np.ndarray, mean: np.ndarray, sd: np.ndarray) -> list[str]:
    """A note when rows' predicted deflection (N, d) [m] is smaller than its own standard deviation (N, d) (in norm):
    the calibrated model does not determine the deflection there, and a compensation may add error (a fresh user's
    Z1: a cubic stiffness of joint 5 at 0.24 of its sd made a compensated path 3.5 times worse than none), naming
    the parameter that contributes most to those rows' variance (X (N, r, p): the rows' regressors)."""
    bad = np.linalg.norm(sd, axis=1) > np.linalg.norm(mean, axis=1)
    if not bad.any():
        return []
    share = np.einsum("nrp,p->p", X[bad] ** 2, np.clip(np.diag(cal.cov), 0.0, None))  # each parameter's variance
    top = int(np.argmax(share))
    value, half = cal.theta[top], 1.96 * float(np.sqrt(max(cal.cov[top, top], 0.0)))
    return [f"{int(bad.sum())} of {len(bad)} row(s) have a predicted deflection smaller than its own sd: the "
            f"calibrated model does not determine the deflection there (mostly through {cal.names[top]} = "
            f"{value:.3g} +- {half:.2g}, 95 %), so a compensation there may add error rather than remove it; "
            "measure such poses and loads in the next round (stiffcal design --prior)"]


#: a joint's motion of the measured point at most this fraction of the row's largest identified joint's is round-off
ROUND_OFF = 1e-9


def determined_rows(robot: Robot, cal, q: np.ndarray, load: np.ndarray, X: np.ndarray, target=None,
                    orientation: bool = False) -> np.ndarray:
    """(N,) bool: the rows whose prediction rests only on what the calibration's data determined: no joint the
    calibration did not identify (:attr:`Calibration.k_joints`) moves what the row measures (``target``,
    ``orientation`` as :func:`predict`) under the row's load (its deflection per unit compliance above round-off:
    1e-9 of the row's largest identified joint's; a joint whose axis passes through the measured point, a Panda's
    flange joint turned by a loading bar's moment, moves nothing there), the row's load reverses the total torque of
    no joint whose backlash the data could not test (:func:`untested_backlash_reversed`), and no parameter it did not
    determine moves the row's prediction: no parameter it did not determine (its estimable flag) has a column of X
    (N, r, p) above 1e-9 of the row's largest (scaled by the parameter's standard deviation, so that units do not
    decide), or X times no free direction of the data (:attr:`Calibration.free_directions`, where the file has them)
    is above :data:`stiffcal.measured.discrepancy.ESTIMABLE_TOL` of the sum of its terms' sizes (two link segments the
    data determine only in a sum leave a row that sees only their sum determined: a fresh user's UR10 had 20 of 20
    held-out rows flagged, though they did not move along it)."""
    n = robot.n_joints
    missing = np.array([j for j in range(n) if j not in cal.k_joints], int)
    ok = np.ones(len(q), bool)
    if missing.size:  # moved: above round-off, row by row
        moves = np.abs(_joint_columns(robot, q, load, target, orientation, missing)).max(axis=1)
        scale = np.abs(X[..., : len(cal.k_joints)]).max(axis=(1, 2)) if len(cal.k_joints) else moves.max(axis=1)
        ok &= ~np.any(moves > ROUND_OFF * scale[:, None], axis=1)
    ok &= ~untested_backlash_reversed(robot, cal, q, load).any(axis=1)
    from .discrepancy import ESTIMABLE_TOL

    p = X.shape[-1]
    undetermined = ~np.asarray(cal.estimable, bool)[:p]
    if undetermined.any():  # the rows a parameter the data did not determine moves above round-off
        sd = np.sqrt(np.clip(np.diag(cal.cov), 0.0, None))[:p]
        size = np.abs(X).max(axis=1) * np.where(sd > 0, sd, 1.0)  # (N, p)
        loose = np.any(size[:, undetermined] > 1e-9 * size.max(axis=1, keepdims=True), axis=1)
        free = cal.free_directions
        if free is not None and len(free) and free.shape[1] >= p:  # ... and along a free direction of the data, not
            v = free[:, :p]  # only along sums they determine (each term x_j v_j a displacement: unit-free)
            moved = np.abs(np.einsum("nrp,kp->nrk", X, v))
            terms = np.einsum("nrp,kp->nrk", np.abs(X), np.abs(v))
            loose &= np.any(moved > ESTIMABLE_TOL * np.maximum(terms, 1e-300), axis=(1, 2))
        ok &= ~loose
    return ok


@dataclass(frozen=True)
class Compensation:
    """A path compensated (module docstring): q (N, n) [rad] the nominal poses; load; deflection (N, d) [m] the
    predicted deflection of the tool point there and sd (N, d); band95_m (N,): the radius [m] of a sphere about
    the nominal tool point that holds the compensated tool point with probability >= 95 % (the bounding sphere of
    the prediction error's 95 % ellipsoid, sqrt(chi2_0.95(d) lambda_max(Cov)): the calibrated model's own
    error, which compensation leaves; the noise of a reading is not in it); target_m (N, d): the nominal tool points;
    corrected_target_m (N, d): the points to command (nominal less the deflection, first order); q_first
    (N, n) [rad]: q - J^+ dp(q); q_corrected (N, n) [rad]: the joint angles whose deflected tool point is the
    nominal one (iterated; a row that does not converge keeps the better of q_first and q when the iteration ended
    further away); residual_m (N,): the predicted error left at q_corrected;
    first_order_residual_m (N,): that of q_first; iterations (N,) int; converged (N,) bool; determined (N,) bool:
    as :class:`Prediction`'s (where False, the band does not hold the model's error)."""
    q: np.ndarray
    load: np.ndarray
    deflection: np.ndarray
    sd: np.ndarray
    band95_m: np.ndarray
    target_m: np.ndarray
    corrected_target_m: np.ndarray
    q_first: np.ndarray
    q_corrected: np.ndarray
    residual_m: np.ndarray
    first_order_residual_m: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    notes: tuple = ()
    determined: np.ndarray | None = None


def _no_worse(q, q1, qc, e0, e1, residual, done) -> tuple[np.ndarray, np.ndarray, int]:
    """(q_corrected, residual_m, how many rows changed): each row that did not converge takes the best of the
    nominal pose (predicted error e0: the deflection itself), the first-order step (e1) and the iteration's pose
    (residual), so that compensating never commands a pose the model predicts to be worse than either."""
    errors = np.column_stack([residual, e1, e0])
    best = np.where(done, 0, np.argmin(errors, axis=1))
    poses = np.stack([qc, q1, q], axis=0)[best, np.arange(len(q))]
    return poses, errors[np.arange(len(q)), best], int(np.count_nonzero(best))


def _pinv_step(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """(N, n): the minimum-norm solutions of J dq = e, J (N, d, n), e (N, d)."""
    return np.einsum("nid,nd->ni", np.linalg.pinv(J), e)


def compensate(robot: Robot, q: np.ndarray, load: np.ndarray, iterations: int = COMPENSATE_ITERATIONS,
               tol_m: float = COMPENSATE_TOL_M) -> Compensation:
    """Compensate a path of poses q (N, n) [rad] under loads (N, d (+ d_m)) with the robot's calibrated model
    (module docstring): the deflection of the tool point, the corrected targets and joint angles, the residual."""
    q = np.atleast_2d(np.asarray(q, float))
    load = np.atleast_2d(np.asarray(load, float))
    pred = predict(robot, q, load)
    x = np.asarray(robot.fk(q), float)
    J = robot.jacobian(q)
    q1 = q - _pinv_step(J, pred.displacement)
    cal = _calibration(robot)

    def error(qc):  # the predicted position error at qc (the prediction's mean alone: no covariance, no notes)
        return np.asarray(robot.fk(qc), float) + _motion(robot, cal, qc, load)[1][:, : robot.task_dim] - x

    e1 = np.linalg.norm(error(q1), axis=1)
    qc = q1.copy()
    its = np.zeros(len(q), int)
    done = np.zeros(len(q), bool)
    for it in range(iterations):
        e = error(qc)
        size = np.linalg.norm(e, axis=1)
        done = size <= tol_m
        if done.all():
            break
        step = _pinv_step(robot.jacobian(qc), e)  # the deflection's own change with the pose is second order
        qc = np.where(done[:, None], qc, qc - step)
        its += ~done
    residual = np.linalg.norm(error(qc), axis=1)
    done = residual <= tol_m
    notes = list(pred.notes)
    if not done.all():
        notes.append(f"{int((~done).sum())} pose(s) did not converge to {tol_m:g} m in {iterations} iterations (a "
                     "pose near a singularity, or a backlash the load does not set: a joint's torque near zero flips "
                     "its jump as the pose is corrected): their residual_m says how far they are")
    qc, residual, kept = _no_worse(q, q1, qc, np.linalg.norm(pred.displacement, axis=1), e1, residual, done)
    if kept:
        notes.append(f"{kept} pose(s) that did not converge are left at the better of the first-order step and no "
                     "correction (q1_cmd_deg; the iteration ended further from the nominal point than either)")
    return Compensation(q, load, pred.displacement, pred.sd, band95(pred.cov), x, x - pred.displacement, q1, qc,
                        residual, e1, its, done, tuple(notes), pred.determined)


def _motion(robot: Robot, cal, q: np.ndarray, load: np.ndarray, target=None, orientation: bool = False):
    """(the calibration's regressors X (N, r, p), the predicted motion (N, r) of what each row measures, the note on
    joints the calibration did not identify or None): :func:`predict`'s mean, without its covariance and notes."""
    X = columns(robot, q, load, target, orientation)
    mean, note = _with_unidentified_joints(robot, cal, q, load, target, orientation,
                                           np.einsum("nrp,p->nr", X, cal.theta))
    if (cal.source or {}).get("second_order"):  # the exact statics' part, as the analysis corrected its rows
        mean = mean.copy()
        mean[:, : robot.task_dim] += _second_order(robot, cal, q, load, target)
    return X, mean, note


def _second_order(robot: Robot, cal, q: np.ndarray, load: np.ndarray, target) -> np.ndarray:
    """(N, d) [m]: :func:`stiffcal.measured.discrepancy.second_order_part` of poses q (N, n) [rad] under ``load``
    at the calibration's compliances, each row's target."""
    from . import discrepancy as D
    from .measurements import Measurements

    d = robot.task_dim
    target = None if target is None else np.asarray(target, int)
    meas = Measurements.from_arrays(q, load[:, :d], np.zeros((len(q), d)), moment=load[:, d:] if load.shape[1] > d
                                    else None, target=target, target_names=robot.target_names)
    ob = D.Observed(robot.target_names, target, False, 1.0, np.asarray(cal.k_joints, int), 0)
    return D.second_order_part(robot, meas, ob, np.asarray(cal.theta[: len(cal.k_joints)], float))


def _joint_columns(robot: Robot, q: np.ndarray, load: np.ndarray, target, orientation: bool, joints) -> np.ndarray:
    """(N, r, m): the motion of what each row measures (``target``, ``orientation`` as :func:`predict`) per unit
    compliance of each of the m ``joints`` (0-based) under the row's load (eq. 4's columns)."""
    from . import discrepancy as D

    ob = D.Observed(robot.target_names, None if target is None else np.asarray(target, int), orientation, 1.0,
                    np.asarray(joints, int), 0)
    return D.model_columns(robot, q, load, (), predict=True, observed=ob)[..., : len(joints)]


def _with_unidentified_joints(robot: Robot, cal, q, load, target, orientation, mean):
    """(mean, note): the predicted motion ``mean`` (N, r) plus that of the joints the calibration did not identify
    (their compliance deflected no measured point of its data), each with the robot file's compliance where it has
    one (the calibrated file keeps the original's); their error is not in the sd, which the note says for those that
    move a row by more than :data:`UNIDENTIFIED_SHARE` of the largest deflection. None: every joint identified, or
    none of them moves a row."""

    missing = [j for j in range(robot.n_joints) if j not in cal.k_joints]
    if not missing:
        return mean, None
    k = robot.compliances
    if k is None or not all(np.isfinite(k[j]) and k[j] > 0 for j in missing):
        names = ", ".join(robot.joint_names[j] for j in missing)
        return mean, (f"joint(s) {names} were not identified by the calibration and the robot file gives no "
                      "compliance for them: their deflection is left out of the prediction")
    X = _joint_columns(robot, q, load, target, orientation, missing)
    each = X * np.asarray(k, float)[missing]  # (N, r, m): each joint's deflection
    added = each.sum(axis=-1)
    size = np.abs(each).max(axis=(0, 1))
    moved = [j for j, c in zip(missing, size) if c > UNIDENTIFIED_SHARE * float(np.abs(mean + added).max())]
    if not moved:  # the rows' loads do not turn them (a vertical axis under hanging masses): nothing to say
        return mean + added, None
    names = ", ".join(robot.joint_names[j] for j in moved)
    values = ", ".join(f"{k[j]:.3g}" for j in moved)
    return mean + added, (f"joint(s) {names} were not identified by the calibration (their compliance deflected no "
                          "measured point of its data: no load turned them, or their axis passes through the "
                          f"measured point): their deflection uses the robot file's compliance ({values} rad/(N m)), "
                          "whose error the sd does not include; measure loads that turn them at points they move")


#: a joint the calibration did not identify whose deflection in every row is at most this fraction of the largest
#: predicted one is not named (the rows' loads do not turn it)
UNIDENTIFIED_SHARE = 1e-3


#: a backlash joint whose (total) torque is within this fraction of the row's largest torque of zero: its state is
#: not set by the load
UNSET_TORQUE_FRACTION = 1e-6


def untested_backlash_reversed(robot: Robot, cal, q: np.ndarray, load: np.ndarray) -> np.ndarray:
    """(N, n) bool: where the row's load (N, d (+ d_m)) at q (N, n) [rad] reverses the total torque (the arm's weight's
    and the load's) of a joint of :attr:`Calibration.untested_backlash`, against the weight's alone."""
    out = np.zeros(q.shape, bool)
    joints = [j for j in cal.untested_backlash if j < robot.n_joints]
    if not joints or robot.masses is None:
        return out
    from .discrepancy import torques

    from ..model.catalogue import preloaded_signs

    total, weight = preloaded_signs(torques(robot, q, load), robot.gravity_torques(q))
    out[:, joints] = (total * weight < 0)[:, joints]
    return out


def _untested_at_test_pose(robot: Robot, cal, test_pose: np.ndarray, test_load: np.ndarray) -> list[str]:
    """A note where the test load reverses the total torque of a joint whose backlash the calibration's data could
    not test (:func:`untested_backlash_reversed`): the next round's O_t values leave that backlash out (a fresh
    user's Jaco2: rms_prior_m 6.3 um against an error of 138 um there), and the plan does not aim at it."""
    q, load = np.atleast_2d(np.asarray(test_pose, float)), np.atleast_2d(np.asarray(test_load, float))
    joints = [robot.joint_names[j] for j in np.flatnonzero(untested_backlash_reversed(robot, cal, q, load)[0])]
    if not joints:
        return []
    return [f"the test load reverses the total torque of joint(s) {', '.join(joints)}, whose backlash the "
            "calibration's data could not test (no load of theirs reversed it): the O_t values leave that backlash "
            "out and the plan does not aim at it; measure loads that reverse it (the test load at poses near the test "
            "pose) to test it"]


def _untested_backlash_notes(robot: Robot, cal, q: np.ndarray, load: np.ndarray) -> list[str]:
    """A note on the rows whose load reverses the total torque (the weight's and the load's) of a joint whose backlash
    the calibration's data could not test (:attr:`Calibration.untested_backlash`: no load of theirs reversed it): a
    gap there would add its jump, which neither the prediction nor its sd holds (a fresh user's Jaco2: 138 um off at
    its test pose, sd 6 um, where the verdict had said joint 3's backlash could not be tested)."""
    reversed_ = untested_backlash_reversed(robot, cal, q, load)
    hit = {j: np.flatnonzero(reversed_[:, j]) for j in cal.untested_backlash if reversed_[:, j].any()}
    if not hit:
        return []
    where = "; ".join(f"joint {robot.joint_names[j]} at row(s) (0-based) {', '.join(str(int(r)) for r in rows[:5])}"
                      f"{' ...' if rows.size > 5 else ''}" for j, rows in hit.items())
    return [f"the load reverses the total torque of a joint whose backlash the calibration's data could not test (no "
            f"load of theirs reversed it; calibration.untested_backlash_joints): {where}; a gap there would add its "
            "jump, which neither the prediction nor sd holds: measure such loads (stiffcal design --prior) to test it"]


def _unset_backlash_notes(robot: Robot, cal, q: np.ndarray, load: np.ndarray) -> list[str]:
    """A note on the rows where a joint of the calibration's backlash carries no torque (its total torque, with the
    arm's own weight where the backlash is preloaded, zero to :data:`UNSET_TORQUE_FRACTION` of the row's largest),
    or a torque that the joints' own deflection reverses (the weight's torque at the sagged pose q + k t0, or the
    total torque at the loaded pose q + k (t0 + tau), of the other sign than at the commanded pose: a fresh user's
    Jaco2 at +0.005 N m commanded, -0.002 N m sagged, left 135 um against a band of 30 um): the load does not say on
    which side of its gap the joint rests, so the prediction may be off by the jump b_j either way, which its sd does
    not include."""
    if "backlash" not in cal.causes:
        return []
    from functools import partial

    from ..model.catalogue import torque_signs
    from .discrepancy import _preload, torques

    tau = torques(robot, q, load)
    t0 = _preload("backlash", robot, q)
    total = tau if t0 is None else tau + t0
    scale = np.abs(tau).max(axis=1, keepdims=True) + (0.0 if t0 is None else np.abs(t0).max(axis=1, keepdims=True))
    gaps = {j: b for j, (b, _) in _backlash_gaps(robot, cal).items()}
    loose = np.abs(total) <= UNSET_TORQUE_FRACTION * scale
    if t0 is not None:  # near balance: the deflection itself reverses the weight's torque, or the total torque
        k = np.nan_to_num(np.asarray(cal.compliances(robot.n_joints), float))
        if robot.compliances is not None:
            k = np.where(k > 0, k, np.asarray(robot.compliances, float))
        sagged, loaded = q + k * t0, q + k * total
        # a torque within round-off of zero has no sign (a UR10's wrist 2: its weight's torque +-4e-17 N m was read as
        # flipping, "near balance")
        sign = partial(torque_signs, scale=scale)
        flipped = ((sign(robot.gravity_torques(sagged)) != sign(t0))
                   | (sign(robot.gravity_torques(loaded) + torques(robot, loaded, load)) != sign(total)))
        loose |= flipped
    unset = {j: np.flatnonzero(loose[:, j]) for j in gaps}
    unset = {j: rows for j, rows in unset.items() if rows.size and abs(gaps[j]) > 0}
    if not unset:
        return []
    where = "; ".join(f"joint {robot.joint_names[j]} (b = {gaps[j]:.3g} rad) at row(s) (0-based) "
                      f"{', '.join(str(int(r)) for r in rows[:5])}{' ...' if rows.size > 5 else ''}"
                      for j, rows in unset.items())
    return [f"a joint with backlash carries no torque under the load, or one its own deflection reverses (near "
            f"balance): {where}; the load does not set on which side of its gap the joint rests, so the prediction "
            "there may be off by the joint's jump b either way, which sd does not include: load the joint, or measure "
            "that pose"]


def band95(cov: np.ndarray) -> np.ndarray:
    """(N,) [m]: the radius of the sphere bounding the 95 % ellipsoid of a position error of covariance cov
    (N, d, d): sqrt(chi2_0.95(d) lambda_max); the error is within it with probability >= 95 %."""
    from .distributions import chi2_ppf

    lam = np.linalg.eigvalsh(cov)[:, -1]
    return np.sqrt(chi2_ppf(0.95, cov.shape[-1]) * np.clip(lam, 0.0, None))


# --- files of poses and loads ------------------------------------------------------------------------------

@dataclass(frozen=True)
class PoseFile:
    """Poses and loads read from a CSV (:func:`read_poses`): q (N, n) [rad]; load (N, d (+ d_m)); target (N,)
    int or None; columns: the file's header; text (N, k): its cells, kept for the output; source: the file;
    notes: load columns the robot does not use."""
    q: np.ndarray
    load: np.ndarray
    target: np.ndarray | None
    columns: list
    text: list
    source: str | None = None
    notes: tuple = ()


def read_poses(path, robot: Robot) -> PoseFile:
    """A CSV of poses and loads for :func:`predict` or :func:`compensate`: the joint angles (``q<i>_deg`` or
    ``q_<name>_deg``), the force at the tool point (``fx_N`` .., in the base frame), optionally the moment
    (``mx_Nm`` .., planar ``mz_Nm``) and ``target`` (docs/contracts.md, "The calibrated model"). Other columns are
    kept as they are. Raises :class:`InputError` naming the file, row and column, as the measured-data reader."""
    import pandas as pd

    from . import measurements as M
    from ..limits import MAX_MEASURED_ROWS
    from ..model.observation import force_dim, moment_dim
    from ..safeio import regular_file

    source = str(path)
    regular_file(path, source=source)
    try:
        M._header(path, source, MAX_MEASURED_ROWS, "(the most poses read, as of measured data; docs/contracts.md, "
                  "'Limits'): split the path")
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read a CSV table ({err})", source=source) from None
    df.columns = [c.strip() for c in df.columns]
    M._check_units(df.columns, source)
    d, dm = force_dim(robot), moment_dim(robot)
    qcols = M.angle_columns(list(df.columns), robot, source)
    fcols = M._axes("f", "N", d)
    for col, name in M._misspelled(df.columns, qcols + fcols + M._axes("m", "Nm", dm, True) + ["target"]).items():
        raise InputError(f"the column {col!r} looks like {name} (a misspelling?); it is read only under that name: "
                         f"rename the column {name}", source=source, field=f"column {col}")
    missing = [c for c in qcols + fcols if c not in df.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; expected {', '.join(qcols + fcols)} (and "
                         "optionally the moment and target)", source=source)
    mcols = M._axes("m", "Nm", dm, True)
    have = [c for c in mcols if c in df.columns]
    if have and len(have) < len(mcols):
        raise InputError(f"missing column(s) {', '.join(c for c in mcols if c not in have)}: give the whole moment or "
                         "none", source=source, field=f"column {have[0]}")
    if len(df) == 0:
        raise InputError("no poses (the file has a header only)", source=source)
    values = M._numbers(df, qcols + fcols + (mcols if have else []), source)
    n = robot.n_joints
    M.check_angles(values[:, :n], qcols, robot, source)  # radians in degree columns are refused, as in measured data
    q = np.radians(values[:, :n])
    outside = np.argwhere(robot.outside_limits(q))
    if outside.size:
        r, j = (int(v) for v in outside[0])
        lo, hi = np.degrees(robot.joint_limits_rad[j])
        raise InputError(f"expected an angle within the joint's limits [{lo:g}, {hi:g}] deg (the robot file's), got "
                         f"{values[r, j]:g}: the arm cannot reach this pose, and a compensated command there would "
                         f"be outside them too ({len(np.unique(outside[:, 0]))} row(s) in all)", source=source,
                         field=f"row {r + 2} (data row {r}), column {qcols[j]}")
    load = values[:, n:] if have else values[:, n:n + d]
    target = M._targets(df, robot, source)[0] if "target" in df.columns else None
    used = set(qcols + fcols + (mcols if have else []) + ["target"])
    surplus = [c for c in df.columns if c.startswith(("f", "m")) and M._PATTERN.match(c) and c not in used]
    notes = (f"column(s) {', '.join(surplus)} do not belong to a {robot.kind} robot's load and are not used (copied "
             "to the output as they are)",) if surplus else ()
    return PoseFile(q, load, target, list(df.columns), df.to_numpy().tolist(), source, notes)


def _check_new_columns(poses: PoseFile, head: list, source: str | None = None) -> None:
    """Refuse an input column that the output would write again (a measured file's ``dx_m``)."""
    clash = [c for c in head[len(poses.columns):] if c in poses.columns]
    if clash:
        raise InputError(f"the column(s) {', '.join(clash)} are written by the output: rename or remove them in the "
                         "input", source=source, field=f"column {clash[0]}")


def _cells(values: np.ndarray, fmt: str) -> list:
    return [[format(float(v), fmt) for v in row] for row in np.atleast_2d(values)]


def prediction_csv(robot: Robot, poses: PoseFile, pred: Prediction) -> str:
    """The pose file with the prediction's columns appended: ``dx_m`` .. and ``sd_dx_m`` .. (and ``rx_rad`` ..,
    ``sd_rx_rad`` .. with the orientation), and ``determined`` (True/False: :func:`determined_rows`)."""
    d = robot.task_dim
    axes = "xyz"[:d]
    head = list(poses.columns) + [f"d{a}_m" for a in axes] + [f"sd_d{a}_m" for a in axes]
    parts = [_cells(pred.displacement, ".9e"), _cells(pred.sd, ".3e")]
    if pred.rotation is not None:
        rot = "z" if d == 2 else "xyz"
        head += [f"r{a}_rad" for a in rot] + [f"sd_r{a}_rad" for a in rot]
        parts += [_cells(pred.rotation, ".12e"), _cells(pred.rotation_sd, ".3e")]
    head.append("determined")
    _check_new_columns(poses, head, poses.source)
    rows = [list(t) + sum((p[i] for p in parts), []) + [str(bool(pred.determined[i]))]
            for i, t in enumerate(poses.text)]
    return _csv(head, rows)


def compensation_csv(robot: Robot, poses: PoseFile, comp: Compensation) -> str:
    """The path with the compensation's columns appended: the predicted deflection ``dx_m`` .. and ``sd_dx_m``
    .. and the 95 % error radius ``band95_m`` (:class:`Compensation`); the nominal tool point ``x_m`` ..; the
    corrected target ``x_cmd_m`` ..; the corrected joint angles (``q1_cmd_deg`` .., iterated) and the first-order
    ones (``q1_first_deg`` ..); ``residual_m``, ``first_order_residual_m``, ``iterations``, ``converged``."""
    d = robot.task_dim
    axes = "xyz"[:d]
    qc = [c[:-4] + "_cmd_deg" for c in robot.joint_columns("q", "_deg")]
    q1 = [c[:-4] + "_first_deg" for c in robot.joint_columns("q", "_deg")]
    head = list(poses.columns) + [f"d{a}_m" for a in axes] + [f"sd_d{a}_m" for a in axes] + ["band95_m"] + \
        [f"{a}_m" for a in axes] + [f"{a}_cmd_m" for a in axes] + qc + q1 + \
        ["residual_m", "first_order_residual_m", "iterations", "converged", "determined"]
    parts = [_cells(comp.deflection, ".9e"), _cells(comp.sd, ".3e"), _cells(comp.band95_m[:, None], ".3e"),
             _cells(comp.target_m, ".9f"),
             _cells(comp.corrected_target_m, ".9f"), _cells(np.degrees(comp.q_corrected), ".6f"),
             _cells(np.degrees(comp.q_first), ".6f"), _cells(comp.residual_m[:, None], ".3e"),
             _cells(comp.first_order_residual_m[:, None], ".3e")]
    _check_new_columns(poses, head, poses.source)
    rows = [list(t) + sum((p[i] for p in parts), []) + [str(int(comp.iterations[i])), str(bool(comp.converged[i])),
                                                        str(bool(comp.determined[i]))]
            for i, t in enumerate(poses.text)]
    return _csv(head, rows)


def _csv(head: list, rows: list) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    w.writerows(rows)
    return buf.getvalue()


# --- the next round ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class NextRound:
    """The next round's plan given the information already collected (:func:`next_round`). poses (m, n) [rad];
    O_t [m^2] of the plan with the old information added; O_t_prior [m^2]: the old data's alone (no new
    measurement), ``tr(X_t Cov X_t^T)``; O_t_fresh [m^2]: the best m-pose plan of the same pool without the old
    data; lower_bound [m^2]: certified lower bound of O_t over every m-pose plan of the candidate pool with the
    old information added (:func:`prior_design_bound`); design: the approximate design behind it (support
    (k, n) [rad], weights (k,)); names (p,): the parameters; cov_diag (p,) [SI^2]: their variances after the
    next round; pool_size; causes; sigma_m [m]; notes."""
    poses: np.ndarray
    O_t: float
    O_t_prior: float
    O_t_fresh: float
    lower_bound: float
    support: np.ndarray
    weights: np.ndarray
    equivalence_gap: float
    names: tuple
    cov_diag: np.ndarray
    pool_size: int
    causes: tuple
    sigma_m: float
    notes: tuple = ()


def prior_information(cal: Calibration, sigma_m: float) -> tuple[np.ndarray, int, tuple]:
    """The information the calibration's data hold on the robot's parameters, in units of the new rows' noise:
    ``sigma_m^2 Cov_rr^+`` (p_r, p_r) with Cov_rr the covariance of the compliances and the robot's extensions
    (a measurement offset belongs to the old tracker set-up: marginalised out, which is the Schur complement of
    the information matrix). A parameter the data did not determine (its estimable flag) holds no information,
    whatever round-off its covariance row carries (a fresh user's Panda: b2 with a variance of 8e-40 and
    covariances of 1e-27 became an information of 1e31, an indefinite prior, and every next round 'inf').
    Returns (information, p_r, the robot's causes)."""
    causes = tuple(c for c in cal.causes if c != "measurement_offset")
    p_r = len(cal.theta) - (cal.n_offsets if "measurement_offset" in cal.causes else 0)
    determined = np.asarray(cal.estimable, bool)[:p_r]
    cov = cal.cov[:p_r, :p_r] * np.outer(determined, determined)
    return sigma_m**2 * _psd_inverse(cov), p_r, causes


#: relative eigenvalue (of a matrix scaled to a unit diagonal) below which a direction counts as not determined
PSD_RTOL = 1e-12


def _scaled_eigh(A: np.ndarray):
    """(d, ev, U, keep) of a symmetric positive semi-definite A (p, p) in its correlation form D^-1/2 A D^-1/2 (unit
    diagonal: the parameters' units do not decide the rank): d (p,) the square roots of A's diagonal (1 where it is
    zero), the eigenvalues ev and vectors U of the scaled matrix (parameters with a zero diagonal at zero), and keep
    (p,) bool the eigenvalues above :data:`PSD_RTOL` of the largest (round-off's negative ones are not)."""
    A = 0.5 * (A + A.T)
    d = np.sqrt(np.clip(np.diag(A), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    ev, U = np.linalg.eigh(A / np.outer(d, d))
    return d, ev, U, ev > PSD_RTOL * max(float(ev.max(initial=0.0)), 1e-300)


def _psd_inverse(A: np.ndarray) -> np.ndarray:
    """The pseudo-inverse of a symmetric positive semi-definite A (p, p) (a covariance or an information matrix),
    taken in its correlation form (:func:`_scaled_eigh`): eigenvalues below :data:`PSD_RTOL` of the largest,
    round-off's negative ones included, are not inverted; a parameter with a zero diagonal gets zero. A covariance
    read back from calibrated.yaml whose correlations are near 1 had an eigenvalue of -1e-18 that numpy's pinv
    inverted to a negative information of -1e15, and every next-round plan came out 'inf' (a fresh user's UR3)."""
    d, ev, U, keep = _scaled_eigh(A)
    return ((U[:, keep] / ev[keep]) @ U[:, keep].T) / np.outer(d, d)


def prior_design_bound(P: np.ndarray, prior: np.ndarray, W: np.ndarray, m: int, iters: int = 3000,
                       tol: float = 1e-6) -> tuple[float, np.ndarray, float]:
    """A certified lower bound of ``f(xi) = tr(W (prior + m M(xi))^-1)`` over every design xi on a pool of
    information matrices P (K, p, p) (W = X_t^T X_t; every exact m-point plan of the pool is such a design,
    weights k/m). f is convex in the weights, so for any weights w, with ``B = M^-1 W M^-1`` and ``phi_c = tr(B
    P_c)``, ``f* >= f(w) - m (max_c phi_c - sum_c w_c phi_c)`` (the equivalence theorem's gap; Pukelsheim,
    *Optimal Design of Experiments*, 1993, ch. 7; Fedorov 1972, sec. 4.2 for the prior). The weights come from the
    multiplicative algorithm ``w_c <- w_c phi_c / sum w phi`` until the relative gap is below ``tol``. Returns
    (bound, w (K,), relative gap (f(w) - bound) / f(w))."""
    K = len(P)
    w = np.full(K, 1.0 / K)
    best = (-np.inf, w, np.inf)
    for _ in range(iters):
        M = prior + m * np.einsum("k,kij->ij", w, P)
        try:
            Minv = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            raise InputError("the prior's information with every candidate pose cannot identify every parameter of "
                             "the calibrated model (the calibration's covariance is singular in a direction no pose "
                             "measures)", field="prior") from None
        f = float(np.trace(W @ Minv))
        B = Minv @ W @ Minv
        phi = np.einsum("ij,kji->k", B, P)
        bound = f - m * (phi.max() - w @ phi)
        if bound > best[0]:
            best = (bound, w, (f - bound) / f)
        if best[2] <= tol:
            break
        w = w * phi / (w @ phi)
    return best


def next_round(robot: Robot, test_pose: np.ndarray, test_load: np.ndarray, m: int, sigma_m: float | None = None,
               step_deg: float = 10.0, seed: int = 0, loads=None) -> NextRound:
    """The O_t-optimal plan of m more poses given the information already collected: the robot's calibrated model
    (its calibration's causes, less a measurement offset) with the old data's information
    (:func:`prior_information`) added to the plan's, the test load in every new measurement of the tool point, or
    every pose measured under each of ``loads`` (:class:`stiffcal.model.observation.Loads`: the lab's hanging
    masses, with their cable free in the cell; None: the test load)
    (as :func:`stiffcal.measured.discrepancy.optimal_plan`, over its candidate poses, by the same exchange), with the
    certified bound of :func:`prior_design_bound` and the plans with no new data and with no old data beside it.
    test_pose (n,) [rad]; test_load (d,) [N] or (d + d_m,) [N, N m]; sigma_m [m]: the new readings' noise
    (default the calibration's). Raises :class:`InputError` for a robot without a calibration."""
    from . import discrepancy as D
    from ..model.workcell import cell_notes
    from ..planning.plans import fedorov_exchange

    cal = getattr(robot, "calibration", None)
    if cal is None:
        raise InputError("the prior is a calibrated robot file (DIR/calibrated.yaml of stiffcal discrepancy); this one "
                         "has no calibration section", source=robot.source, field="prior")
    sigma = float(cal.sigma_m if sigma_m is None else sigma_m)
    prior, p_r, causes = prior_information(cal, sigma)
    ob = D.Observed(robot.target_names, None, False, 1.0, np.asarray(cal.k_joints, int), cal.n_offsets)
    pool, Xp, Xt, scale = D.plan_regressors(robot, causes, test_pose, test_load, ob, step_deg, loads)
    live = (np.abs(Xp).max(axis=(0, 1)) > 0) | (np.abs(Xt).max(axis=0) > 0)  # round-off columns are zero
    prior_s = _marginal(prior / np.outer(scale, scale), live)
    Xp, Xt, scale = Xp[..., live], Xt[:, live], scale[live]
    P = np.einsum("kdi,kdj->kij", Xp, Xp)
    ridged = prior_s + _nuisance_ridge(cal, P, Xt, live)
    ridged = ridged + _unmeasured_ridge(ridged, P, Xt)
    with_old = fedorov_exchange(Xp, Xt, m, greedy=True, n_starts=4, seed=seed, prior=ridged)
    notes = _unidentified_at_test_pose(robot, cal, test_pose, test_load)
    fresh = fedorov_exchange(Xp, Xt, m, greedy=True, n_starts=4, seed=seed)
    if not np.isfinite(fresh.value):
        notes.append(f"{m} new poses alone cannot identify the {Xp.shape[-1]} parameters of the model that the "
                     f"candidate poses or the test pose move (of {len(live)}): O_t_fresh is infinite")
    notes += (_shared_error_note(cal, sigma_m) + _model_error_plan_note(cal)
              + cell_notes(robot, pool[with_old.indices]) + _untested_at_test_pose(robot, cal, test_pose, test_load))
    W = Xt.T @ Xt
    bound, w, gap = prior_design_bound(P, ridged, W, m)
    cov_rr = cal.cov[:p_r, :p_r]
    post = np.where(np.array(cal.estimable, bool)[:p_r], np.diag(cov_rr), np.inf)  # a parameter that no pose and
    #                           not the test pose moves keeps its variance (inf where its data did not determine it)
    post[live] = sigma**2 * _posterior_variances(prior_s + P[with_old.indices].sum(axis=0)) / scale**2
    keep = w > 1e-4 * w.max()
    names = cal.names[:p_r]
    notes += _left_undetermined_note(names, post, np.isfinite(with_old.value))
    Xt_raw = Xt * scale
    prior_ot = float(np.trace(Xt_raw @ cov_rr[np.ix_(live, live)] @ Xt_raw.T))
    undetermined = [names[j] for j in np.flatnonzero(live)[_moves_undetermined(cal, Xt, live)]]
    if undetermined:
        prior_ot = np.inf
        notes.append(f"the test pose's deflection depends on {', '.join(undetermined)}, which the calibration's data "
                     "did not determine (its estimable flags): O_t_prior is infinite (rms_prior_m null), the old data "
                     "alone do not predict it")
    return NextRound(pool[with_old.indices], sigma**2 * with_old.value, prior_ot, sigma**2 * fresh.value,
                     sigma**2 * bound, pool[keep], w[keep] / w[keep].sum(), float(gap), tuple(names), post, len(pool),
                     causes, sigma, tuple(notes))


def _model_error_plan_note(cal: Calibration) -> list[str]:
    """A note where the calibration carries a model error (:attr:`Calibration.model_error_m`): the plan's O_t and RMS
    figures are its parameters' uncertainty alone (a fresh user's soft Panda: 2.9 um promised, 1060 um left, with a
    model error of 7.2 mm in the file)."""
    if not cal.model_error_m > 0:
        return []
    return [f"the data reject the calibrated model (verdict {cal.source.get('verdict_cause')}; its error beyond the "
            f"noise at configurations it was not fitted to, {_model_error_um(cal)}, calibration.model_error_m): O_t "
            "and every RMS figure here are its parameters' uncertainty alone, and the model's error adds to them"]


def _left_undetermined_note(names, post: np.ndarray, finite: bool) -> list[str]:
    """A note naming the parameters whose variance after the next round is infinite (``post`` (p,)); ``finite``: the
    test pose's O_t is finite all the same (its deflection does not depend on them)."""
    left = [names[j] for j in np.flatnonzero(~np.isfinite(post))]
    if not left:
        return []
    return [f"{', '.join(left)} stay undetermined with the old data and the plan's poses (their variances are "
            "infinite)" + ("; the test pose's deflection does not depend on them, so its O_t is finite without them"
                           if finite else "")]


def _shared_error_note(cal: Calibration, sigma_m: float | None) -> list[str]:
    """A note when the calibration's rows shared errors (its error model's components, by REML) and the next round's
    noise is the calibration's sigma_m: O_t takes the new readings as independent, so it promises more than rows
    that share a reference reading give (a fresh user's UR5: 3.41 um promised, 4.13 um reached)."""
    parts = {k: c.get("sd_m") for k, c in ((cal.error_model or {}).get("components") or {}).items()
             if c.get("estimable") and (c.get("sd_m") or 0.0) > 0.0}
    if sigma_m is not None or not parts:
        return []
    shared = ", ".join(f"{k} {v * 1e6:.3g} um" for k, v in parts.items())
    return [f"O_t takes the new readings as independent, with the calibration's noise sigma_m "
            f"{cal.sigma_m * 1e6:.3g} um; its rows also shared errors ({shared} RMS: error_model.components), which "
            "new readings from shared references will share too, so the next round's rms_m is optimistic; give "
            "--sigma sqrt(sigma_m^2 + the shared parts^2) for a conservative plan"]


def _moves_undetermined(cal: Calibration, Xt: np.ndarray, live: np.ndarray) -> np.ndarray:
    """(p_live,) bool: the parameters (of ``live``) that the calibration's data did not determine (its estimable
    flags) and whose column of the test pose's scaled regressor Xt (d, p_live) is not round-off. A parameter
    undetermined alone but determined in a sum with another (a group of the verdict's ``not_estimable``) counts
    too: the prior then errs on the safe side."""
    from .discrepancy import moved_columns

    return ~np.array(cal.estimable, bool)[: len(live)][live] & moved_columns(Xt)


def _nuisance_ridge(cal: Calibration, P: np.ndarray, Xt: np.ndarray, live: np.ndarray) -> np.ndarray:
    """(p_live, p_live): :func:`stiffcal.planning.plans.nuisance_ridge` on the next round's nuisance parameters:
    those the calibration's data did not determine (its estimable flags) and the test pose does not move (their
    column of Xt (d, p_live) round-off; a backlash of a joint whose total torque the old loads never reversed and the
    test load does not turn). Without it, a plan that left them undetermined had an infinite O_t, and the posterior
    variances raised. P (K, p_live, p_live): the candidates' information."""
    from ..planning.plans import nuisance_ridge
    from .discrepancy import moved_columns

    return nuisance_ridge(P, ~np.array(cal.estimable, bool)[: len(live)][live] & ~moved_columns(Xt))


def _unmeasured_ridge(prior: np.ndarray, P: np.ndarray, Xt: np.ndarray) -> np.ndarray:
    """(p, p): the ridge of :func:`stiffcal.planning.plans.nuisance_ridge` on the directions that neither the prior
    (p, p) nor any candidate (P (K, p, p)) measures and the test pose (Xt (d, p)) does not see: a combination of
    parameters the calibration confounded (a planar arm's last joint and its link's bending) whose sum the test pose
    needs but not their difference. Zero where there is none; where the test pose sees such a direction, zero as
    well (its O_t is then infinite, and the bound says so)."""
    from ..planning.plans import NUISANCE_RIDGE

    d, _, U, keep = _scaled_eigh(prior + P.mean(axis=0))
    null = U[:, ~keep] / d[:, None]
    if not null.size:
        return np.zeros_like(prior)
    seen = np.abs(Xt @ null).max(axis=0) > 1e-9 * np.abs(Xt).max() * np.abs(null).max(axis=0)
    null = null[:, ~seen]
    mean = float(np.trace(P.mean(axis=0))) / max(P.shape[-1], 1)
    return NUISANCE_RIDGE * max(mean, 1e-300) * (null @ null.T) / max(float(np.abs(null).max(initial=0.0)) ** 2,
                                                                       1e-300)


def _posterior_variances(M: np.ndarray) -> np.ndarray:
    """(p,): the diagonal of M^+ for the parameters M (p, p) (an information matrix, symmetric positive
    semi-definite) determines, inf for those it does not (e_j outside M's range: in M's correlation form, as
    :func:`_psd_inverse` decides the rank, so that well-determined old parameters beside new ones do not count
    as round-off)."""
    d, ev, U, keep = _scaled_eigh(M)
    var = ((U[:, keep] ** 2) @ (1.0 / ev[keep])) / d**2
    determined = (U[:, ~keep] ** 2).sum(axis=1) <= 1e-10
    return np.where(determined & (np.diag(M) > 0), var, np.inf)


def _marginal(information: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The information on the parameters ``keep`` (p,) bool with the others marginalised out: the Schur complement
    I_kk - I_kd I_dd^+ I_dk (the others are then unknown; here they are the parameters that no candidate pose and
    not the test pose moves: a backlash of a joint whose axis passes through the measured point)."""
    if keep.all():
        return information
    kk, kd, dd = information[np.ix_(keep, keep)], information[np.ix_(keep, ~keep)], information[np.ix_(~keep, ~keep)]
    return kk - kd @ _psd_inverse(dd) @ kd.T


def _unidentified_at_test_pose(robot: Robot, cal, test_pose: np.ndarray, test_load: np.ndarray) -> list[str]:
    """A note when the test load turns a joint the calibration did not identify: the next round's O_t (of the
    calibrated model's parameters) leaves that joint's compliance error out, and its measurements do not identify
    it either (they are taken under the test load's kind of loading only where it turns the joint)."""
    from .discrepancy import torques

    tau = torques(robot, np.atleast_2d(test_pose), np.atleast_2d(test_load))[0]
    turned = [robot.joint_names[j] for j in range(robot.n_joints)
              if j not in cal.k_joints and abs(tau[j]) > 1e-9 * max(np.abs(tau).max(), 1e-300)]
    if not turned:
        return []
    return [f"the test load turns joint(s) {', '.join(turned)}, which the calibration did not identify: O_t, "
            "O_t_prior and O_t_fresh leave out the error of their compliance (the deflection there rests on the robot "
            "file's value); a plan that identifies them needs loads that turn them (stiffcal design without --prior)"]


def rms(ot: float) -> float | None:
    """sqrt(O_t) [m] of an O_t [m^2]; None (null) where the plan does not identify the model (O_t infinite, or
    below zero by round-off)."""
    return float(np.sqrt(ot)) if np.isfinite(ot) and ot >= 0 else None


def next_round_summary(robot: Robot, test_pose: np.ndarray, test_load: np.ndarray,
                       m: int | None = None, loads=None) -> tuple[dict, list[str]]:
    """The verdict's ``next_round``: :func:`next_round` of m poses (default: the fewest that identify the model's
    parameters alone, plus one, as :func:`stiffcal.measured.discrepancy.optimal_plan`) as RMS errors [m] at the test
    pose: ``rms_prior_m`` (the data's alone), ``rms_next_m`` (with the plan's m poses added), ``rms_fresh_m`` (the best
    m poses without the data), each null when its O_t is not finite (m poses alone cannot identify the model), and
    ``lower_bound_rms_m``;
    ``experiments``, ``poses_deg``, ``loads`` (what every new pose is measured under: ``loads``, the lab's, e.g.
    :func:`stiffcal.measured.discrepancy.lab_loads`, or the test load); and the notes of :func:`next_round` (a test
    load that turns a joint the calibration did not identify, a test pose that moves a parameter it did not
    determine), for the verdict's."""
    cal = robot.calibration
    _, p_r, _ = prior_information(cal, cal.sigma_m)
    m = m or int(np.ceil(p_r / robot.task_dim)) + 1
    nr = next_round(robot, test_pose, test_load, m, loads=loads)
    from ..model.robot import round_within

    return ({"experiments": m, "poses_deg": round_within(np.degrees(nr.poses), robot.limits_deg, 3).tolist(),
             "loads": "the test load" if loads is None else loads.spec,
             "rms_prior_m": rms(nr.O_t_prior), "rms_next_m": rms(nr.O_t), "rms_fresh_m": rms(nr.O_t_fresh),
             "lower_bound_rms_m": float(np.sqrt(max(nr.lower_bound, 0.0)))},
            [f"next_round: {n}" for n in nr.notes])


def machining_path(robot: Robot, test_pose: np.ndarray, count: int = 41, span_deg: float = 20.0) -> np.ndarray:
    """(count, n) [rad]: a simulated machining path through the test pose: every joint swept linearly from
    ``-span_deg`` to ``+span_deg`` about it (clipped to the joint limits)."""
    t = np.linspace(-1.0, 1.0, count)[:, None]
    q = np.asarray(test_pose, float)[None] + np.radians(span_deg) * t
    lim = robot.joint_limits_rad
    return q if lim is None else np.clip(q, lim[:, 0], lim[:, 1])


def path_check(calibrated_robot: Robot, nominal_robot: Robot, q: np.ndarray, load: np.ndarray) -> dict:
    """A path compensated with the nominal and with the calibrated model, the calibrated one taken as the truth
    (the best model of the data): per pose [m] ``before`` |dp| (no compensation), ``after_nominal`` (the error
    left when the nominal model's corrected angles are commanded), ``after_calibrated`` (the iteration's residual)
    and ``band95`` (the calibrated model's own 95 % error radius, :class:`Compensation`). Returns lists and their
    maxima (``max_before_m`` ..)."""
    load = np.broadcast_to(np.asarray(load, float), (len(q), np.shape(load)[-1]))
    cal = compensate(calibrated_robot, q, load)
    nom = compensate(nominal_robot, q, load)
    left = np.asarray(calibrated_robot.fk(nom.q_corrected)) + predict(calibrated_robot, nom.q_corrected,
                                                                       load).displacement - cal.target_m
    out = {"before": np.linalg.norm(cal.deflection, axis=1), "after_nominal": np.linalg.norm(left, axis=1),
           "after_calibrated": cal.residual_m, "band95": cal.band95_m}
    return {**{k: [float(x) for x in v] for k, v in out.items()}, **{f"max_{k}_m": float(np.max(v))
                                                                     for k, v in out.items()}}
