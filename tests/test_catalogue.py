"""Conformance of every registered catalogue cause (stiffcal.model.catalogue.CATALOGUE), parametrised over the
registry: a cause added there is checked here without a new test (docs/extending.md)."""

import numpy as np
import pytest

from stiffcal.model import catalogue as C
from stiffcal.measured import discrepancy as D
from stiffcal.model.calibration import _extension_size
from stiffcal.model.robot import load_robot

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


def test_the_docs_name_every_registered_cause():
    text = (ROOT / "docs/measured-data.md").read_text(encoding="utf-8")
    listed = text.split("- **The catalogue**:", 1)[1].split("each a physically derived", 1)[0]
    assert [c.strip(" `,\n") for c in listed.split(",") if c.strip(" `,\n")] == list(C.CAUSES)
