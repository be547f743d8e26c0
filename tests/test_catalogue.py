"""Conformance of every registered catalogue cause (stiffcal.model.catalogue.CATALOGUE), parametrised over the
registry: a cause added there is checked here without a new test (docs/extending.md)."""

import numpy as np
import pytest

from stiffcal.model import catalogue as C
from stiffcal.measured import discrepancy as D
from stiffcal.model.calibration import _extension_size
from stiffcal.model.robot import load_robot
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T

from conftest import ROOT

ARMS = {"2R": "config/robots/paper_2r.yaml", "6-axis": "config/robots/kuka_kr210_r2700.yaml",
        "UR5 URDF, own weight": "tests/data/urdf/ur5_cont.urdf"}  # the URDF alone: its inertias preload the joints


def _poses(robot, rng, n=12):
    q = rng.uniform(*robot.joint_limits_rad.T, (n, robot.n_joints))
    F = rng.normal(size=(n, robot.task_dim)) * 300.0
    return q, F


@pytest.mark.parametrize("arm", ARMS)
@pytest.mark.parametrize("cause", C.CAUSES)
def test_every_cause_has_as_many_named_parameters_as_regressors(cause, arm):
    robot = load_robot(ROOT / ARMS[arm])
    q, F = _poses(robot, np.random.default_rng(1))
    X = D.cause_columns(cause, robot, q, F)
    names = C.parameter_names(cause, robot)
    assert X.shape == (len(q), robot.task_dim, len(names))
    assert len(set(names)) == len(names)
    assert _extension_size(robot, [cause], robot.task_dim) == len(names)
    pred = D.model_columns(robot, q, F, [cause], predict=True)[..., robot.n_params:]
    assert np.all(pred == 0) == (C.CATALOGUE[cause].kind == "measurement")  # the tracker's, not the robot's


def _law(cause, tau, t0, beta, n):
    """The joints' deflection dq (N, n) of a joint cause with parameters beta, written from its law in
    docs/measured-data.md (not from the registry's regressors)."""
    if cause == "joint_coupling":
        K = np.zeros((n, n))
        K[np.triu_indices(n, 1)] = beta
        return tau @ (K + K.T).T
    if cause == "nonlinear_joint_stiffness":
        return beta * ((t0 + tau) ** 3 - t0**3)
    if cause == "backlash":
        return beta * (np.sign(t0 + tau) - np.sign(t0))
    raise AssertionError(f"no law written for {cause}: add it here")


@pytest.mark.parametrize("arm", ARMS)
@pytest.mark.parametrize("cause", [c for c, e in C.CATALOGUE.items() if e.kind == "joint"])
def test_joint_cause_regressors_move_the_tool_as_the_forward_kinematics_does(cause, arm):
    """Regressors times parameters = the tool point's motion when the joints turn by the cause's law, by central
    finite differences of the forward kinematics (no Jacobian); with the arm's own weight when it has masses."""
    robot = load_robot(ROOT / ARMS[arm])
    rng = np.random.default_rng(2)
    q, F = _poses(robot, rng)
    tau = D.torques(robot, q, F)
    t0 = robot.gravity_torques(q) if C.CATALOGUE[cause].preloaded and robot.masses is not None else np.zeros_like(tau)
    assert (arm == "UR5 URDF, own weight") == (robot.masses is not None)
    p = len(C.parameter_names(cause, robot))
    beta = rng.uniform(0.5, 1.5, p)
    law = _law(cause, tau, t0, beta, robot.n_joints)
    s = 1e-6 / np.abs(law).max()  # a small turn (at most 1 urad): the central difference is linear to ~1e-12
    dq = s * law
    fd = (robot.fk(q + dq) - robot.fk(q - dq))[:, : robot.task_dim] / 2.0
    model = D.cause_columns(cause, robot, q, F) @ (beta * s)
    assert np.allclose(model, fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max())


def test_every_registered_cause_is_simulated_and_listed_in_the_docs():
    """The simulator can hide every catalogue cause (its registry stiffcal.testing.truth.EFFECTS, in the catalogue's
    order, so that the rate matrix measures how often each is named), and the list of docs/measured-data.md names
    exactly the registry's causes in its order."""
    import re

    assert [e for e in T.EFFECTS if e in C.CATALOGUE] == list(C.CAUSES)
    text = (ROOT / "docs/measured-data.md").read_text(encoding="utf-8")
    listed = text.split("<!-- registry:causes -->", 1)[1].split("<!-- /registry:causes -->", 1)[0]
    assert re.findall(r"^  - `([a-z_]+)` \(", listed, flags=re.M) == list(C.CAUSES)


@pytest.mark.parametrize("effect", list(T.EFFECTS))
def test_every_simulated_effect_reaches_the_rows_of_a_case(effect):
    """Every effect of the simulator's registry (stiffcal.testing.truth.EFFECTS) moves a case's rows, and moves
    them as much once merged with the other effects of a case (stiffcal.testing.rates._merge) as alone: a new
    effect's Truth field is not dropped on the way (a fresh user's new cause was: the oracle's power 1, the verdict
    `none`). 3-link arm, hanging masses with a reference per visit and return readings, effect 2 noise RMS."""
    robot = R.robots(ROOT)["3-link"]
    rng = np.random.default_rng(3)
    log = T.lab_log(robot, R.PROTOCOLS["hanging x3, reference per visit, 2 passes"], rng, 8)
    k = R.compliances(robot)
    base = T.Truth(k)
    unit = T.EFFECTS[effect].unit(robot, k, rng, log)
    alone = R._scaled_truth(effect, unit, base, robot, log, 2.0 * float(np.median(log.sigma)))
    moved = R._effect_displacement(robot, alone, base, log)
    assert np.sqrt(np.mean(moved**2)) > 0.5 * np.median(log.sigma)
    assert np.array_equal(R._effect_displacement(robot, R._merge(base, alone), base, log), moved)
