"""Validation of the discrimination planner by simulation (tests and ``benchmarks/discrimination.py``): the rival
models of :mod:`stiffcal.measured.discrimination` simulated with the truth simulator (:mod:`stiffcal.testing.truth`)
and analysed, to compare the separation rate with the power the planner predicts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..measured import discrepancy as D
from ..measured import discrimination as X
from ..measured.discrimination import RivalModels, Rival
from ..measured.measurements import Measurements
from ..model.robot import Robot
from .truth import Truth, physics

#: causes whose fitted parameters are a physical truth of :mod:`stiffcal.testing.truth` exactly (the others are
#: simulated from their regressors)
PHYSICAL = {"link_compliance": "link_bending", "joint_coupling": "coupling", "measurement_offset": "offset"}


def model_mean(robot: Robot, model: Rival, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """(N, d) [m]: the displacement ``model`` with its fitted parameters gives at q (N, n) [rad] under force
    (N, d) [N]. Joint compliances, link bending, joint coupling and a measurement offset are simulated by
    :func:`stiffcal.testing.truth.physics` (written from the physics, independent of the analysis's regressors);
    a nonlinear joint law or backlash, which the simulator models by other laws, by the model's regressors."""
    if not set(model.causes) <= set(PHYSICAL):
        return D.model_columns(robot, q, force, model.causes) @ model.beta
    d = robot.task_dim
    moment = force[:, d:] if force.shape[1] > d else None
    n = robot.n_joints
    k = np.zeros(n)
    k[robot.params] = model.beta[: robot.n_params]
    at, fields = robot.n_params, {}
    for c in model.causes:
        size = len(D.parameter_names(c, robot))
        b = model.beta[at: at + size]
        at += size
        if c == "joint_coupling":
            C = np.zeros((n, n))
            C[np.triu_indices(n, 1)] = b
            b = C + C.T
        fields[PHYSICAL[c]] = b
    return physics(robot, Truth(k, **fields), q, force[:, :d], moment=moment)


@dataclass(frozen=True)
class SeparationRate:
    """Simulated separation of ``rival`` when ``truth`` holds: the share of ``repetitions`` analyses of the
    old design plus the plan (both simulated) whose verdict tells them apart (``rate``): some listed
    combination (``causes`` or an equivalent one) holds the truth's causes (perhaps beside a false alarm) and
    the rival's combination is no longer listed, i.e. no longer explains the data on its own (the event whose
    probability the separating F-test's power predicts); the share whose ``causes`` are exactly the truth's
    (``named``); and the predicted power."""
    truth: tuple[str, ...]
    rival: tuple[str, ...]
    repetitions: int
    rate: float
    named: float
    predicted: float


def _widen(load: np.ndarray, width: int) -> np.ndarray:
    """Loads (N, w) padded with zero moments to (N, width)."""
    return np.hstack([load, np.zeros((len(load), width - load.shape[1]))])


def simulate_separation(rm: RivalModels, q: np.ndarray, force: np.ndarray, repeats: int = 1, truth: int = 0,
                        repetitions: int = 100, seed: int = 0) -> list[SeparationRate]:
    """Measure the plan q (M, n) [rad], force (M, d) [N] on simulated truth: ``rm.models[truth]`` with its
    fitted parameters (:func:`model_mean`) gives the old design's rows and the plan's (each point ``repeats``
    times) with Gaussian noise of the verdict's sigma (divided by the analysis's row weights on the old rows),
    and :func:`stiffcal.measured.discrepancy.analyse` runs on old and new data together at the verdict's alpha. Returns
    one :class:`SeparationRate` per other model, beside the power :func:`plan_power` predicts."""
    robot, old = rm.robot, rm.old
    T = rm.models[truth]
    qn, fn = np.repeat(q, repeats, axis=0), np.repeat(force, repeats, axis=0)
    width = max(D.load_of(old).shape[1], fn.shape[1])
    q_all, f_all = np.vstack([old.q, qn]), np.vstack([_widen(D.load_of(old), width), _widen(fn, width)])
    mean = model_mean(robot, T, q_all, f_all)
    sig = np.concatenate([rm.sigma / rm.weights, np.full(len(qn), rm.sigma)])
    rng = np.random.default_rng(seed)
    others = [j for j in range(len(rm.models)) if j != truth]
    separated = np.zeros(len(others))
    named = 0
    for _ in range(repetitions):
        dp = mean + rng.normal(size=mean.shape) * sig[:, None]
        d = robot.task_dim
        meas = Measurements.from_arrays(q_all, f_all[:, :d], dp, angle_resolution_deg=old.resolutions[0],
                                        force_resolution_N=old.resolutions[1],
                                        moment=f_all[:, d:] if width > d else None,
                                        moment_resolution_Nm=old.resolutions[2])
        v = D.analyse(robot, meas, rm.alpha, gain=False)
        listed = [set(c) for c in [v["causes"], *v["equivalent_combinations"]]]
        told = any(set(T.causes) <= c for c in listed)  # the truth named, perhaps beside a false alarm
        separated += [told and set(rm.models[j].causes) not in listed for j in others]
        named += X._combination(v["causes"]) == T.causes
    pred = {p.rival: p.power for p in X.plan_power(rm, q, force, repeats, truth)}
    return [SeparationRate(T.causes, rm.models[j].causes, repetitions, float(s / repetitions), named / repetitions,
                           pred[rm.models[j].causes]) for j, s in zip(others, separated)]
