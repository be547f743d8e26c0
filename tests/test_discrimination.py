"""The next experiment (stiffcal.measured.discrimination): a plan that tells rival causes apart, its predicted power
against the rate at which the analysis separates them on simulated truth (stiffcal.testing.truth, written from the
physics), the T-criterion and its equivalence-theorem bound against independent least squares and a brute
force, the compound plan, rivals that no plan of positions separates, a measurement model with more rows,
the command line."""

import json
from pathlib import Path

import numpy as np
import pytest

from stiffcal.measured import discrepancy as D
from stiffcal.measured import discrimination as X
from stiffcal.testing import separation as S
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.measured.measurements import Measurements, read_measurements
from stiffcal.model.robot import as_xyz, load_robot, planar_robot

ROOT = Path(__file__).resolve().parents[1]
#: a quick search for the tests (the command's defaults search finer)
FAST = X.Effort(pool_step_deg=20.0, search_step_deg=12.0, n_starts=1, rounds=1)
HANG = T.Protocol("one hanging mass, twice", magnitudes_N=(400.0,), repeats=2)


def _lab(robot, protocol, effect, seed, n_configs, size, k):
    """Old data: the lab protocol with one hidden effect (stiffcal.testing.truth) whose displacement, less what the
    nominal model absorbs, is ``size`` times the noise (RMS)."""
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, protocol, rng, n_configs)
    base = T.Truth(k)
    unit = R._unit_truth(effect, robot, k, rng, log)
    truth = R._scaled_truth(effect, unit, base, robot, log, size * protocol.sigma_m)
    dp = T.measure(robot, truth, log, rng)
    return log, dp, Measurements.from_arrays(log.q, log.force, dp, config=log.config)


def _binomial_ok(rate, p, n, extra=0.02):
    """The simulated rate within three binomial standard errors (and ``extra``) of the predicted power."""
    se = np.sqrt(max(p * (1 - p), 0.01) / n)
    return abs(rate - p) <= 3 * se + extra


@pytest.fixture(scope="module")
def three_link():
    """A 3-link arm measured under one hanging mass at 16 configurations: a hidden backlash (the simulator's
    smooth gap law) that the analysis cannot tell from a nonlinear joint stiffness on these data."""
    robot = planar_robot([0.5, 0.4, 0.3], "3-link")
    _, _, meas = _lab(robot, HANG, "backlash", 1, 16, 1.0, R.compliances(robot))
    return robot, meas, D.analyse(robot, meas, 0.01, gain=False)


@pytest.fixture(scope="module")
def three_link_plan(three_link):
    robot, meas, v = three_link
    return X.discriminate(robot, meas, 6, X.load_set("hanging:400,800", 2), verdict=v, m_curve=[1, 6], effort=FAST)


# --- the check ------------------------------------------------------------------------------------

def test_six_poses_separate_causes_the_data_cannot_tell_apart(three_link, three_link_plan):
    robot, meas, v = three_link
    combos = {tuple(c) for c in [v["causes"], *v["equivalent_combinations"]]}
    assert combos == {("backlash",), ("nonlinear_joint_stiffness",)}
    res = three_link_plan
    rm = res.rivals
    # the design of the given data, measured again, would separate them with a power well below 0.9
    before = X.plan_power(rm, np.zeros((0, 3)), np.zeros((0, 2)), 1, 0)[0]
    assert before.power < 0.8
    assert res.separable and res.plan is not None and len(res.plan.poses_deg) == 6
    q, F = np.radians(res.plan.poses_deg), res.plan.forces_N
    assert not robot.outside_limits(q).any()
    assert all(any(np.allclose(f, g) for g in res.loads.forces) for f in F)  # loads from the stated set
    assert res.power > 0.9
    (sim,) = S.simulate_separation(rm, q, F, 1, truth=0, repetitions=60, seed=11)
    assert sim.predicted == pytest.approx(res.power)
    assert sim.rate > 0.9 and _binomial_ok(sim.rate, sim.predicted, 60)


def test_simulated_rate_matches_the_predicted_power_of_any_plan(three_link):
    """The noncentral-F prediction against the analysis run on simulated old and new data, for the first two
    random plans of two points whose predicted power lies between 0.3 and 0.8 (either rival as the truth)."""
    robot, meas, v = three_link
    rm = X.rivals_from_verdict(robot, meas, v)
    rng = np.random.default_rng(5)
    F = np.array([[0.0, -400.0]] * 2)
    chosen = []
    while len(chosen) < 2:
        q = rng.uniform(-np.pi, np.pi, (2, 3))
        chosen += [(q, t) for t in (0, 1) if 0.3 < X.plan_power(rm, q, F, 1, t)[0].power < 0.8][:2 - len(chosen)]
    for i, (q, truth) in enumerate(chosen):
        (sim,) = S.simulate_separation(rm, q, F, 1, truth, repetitions=100, seed=i)
        assert _binomial_ok(sim.rate, sim.predicted, 100), sim


# --- the criterion against independent least squares -----------------------------------------------------------

def _stacked(rm, causes, q, F):
    X0 = rm.old_rows(causes)
    return np.vstack([X0, D._stack(D.model_columns(rm.robot, q, F, causes))])


def test_t_criterion_is_the_rivals_lack_of_fit_and_the_updates_match_a_brute_force(three_link):
    robot, meas, v = three_link
    rm = X.rivals_from_verdict(robot, meas, v)
    loads = X.load_set("hanging:400,800", 2)
    pool = X.make_pool(robot, X.pose_pool(robot, 30.0), loads.forces, {"backlash"})
    crit = X.build_criterion(rm, pool, [(0, 1)], kappa=1.0)
    rng = np.random.default_rng(1)
    rest = rng.choice(len(pool), 3)
    truth, rival = rm.models
    # Delta: least squares of the truth's mean (old rows and plan) on the rival's columns, by lstsq
    mu = np.concatenate([rm.old_mean(truth), (D.model_columns(robot, pool.q[rest], pool.force[rest], truth.causes)
                                              @ truth.beta).ravel()])
    Xr = _stacked(rm, rival.causes, pool.q[rest], pool.force[rest])
    resid = mu - Xr @ np.linalg.lstsq(Xr, mu, rcond=None)[0]
    assert crit.deltas(rest)[0] == pytest.approx(resid @ resid, rel=1e-7)
    scores = crit.scores(rest)
    for c in rng.choice(len(pool), 12):
        assert scores[c] == pytest.approx(crit.value(np.append(rest, c)), rel=1e-6, abs=1e-6)


def test_compound_scores_and_o_t_against_direct_computation(three_link):
    robot, meas, v = three_link
    rm = X.rivals_from_verdict(robot, meas, v)
    pool = X.make_pool(robot, X.pose_pool(robot, 30.0), X.load_set("hanging:400,800", 2).forces, {"backlash"})
    qt, ft = np.radians([60.0, 30.0, -40.0]), np.array([0.0, -400.0])
    rng = np.random.default_rng(2)
    rest = rng.choice(len(pool), 4)
    Xt = D.model_columns(robot, qt[None], ft[None], rm.extended, predict=True)[0]
    Xe = _stacked(rm, rm.extended, pool.q[rest], pool.force[rest])
    direct = rm.sigma**2 * np.trace(Xt @ np.linalg.pinv(Xe.T @ Xe) @ Xt.T)
    for kappa in (0.0, 0.5):
        crit = X.build_criterion(rm, pool, [(0, 1)], 1, kappa, qt, ft)
        assert crit.o_t(rest) == pytest.approx(direct, rel=1e-7)
        scores = crit.scores(rest)
        for c in rng.choice(len(pool), 8):
            assert scores[c] == pytest.approx(crit.value(np.append(rest, c)), rel=1e-6, abs=1e-6)


def test_repeating_a_point_is_measuring_it_twice(three_link):
    """repeats = 2 gives the same T-criterion, degrees of freedom and power as listing every point twice."""
    robot, meas, v = three_link
    rm = X.rivals_from_verdict(robot, meas, v)
    q = np.radians([[10.0, 20.0, 30.0], [-100.0, 5.0, -60.0]])
    F = np.array([[0.0, -400.0], [0.0, -800.0]])
    for truth in (0, 1):
        (a,) = X.plan_power(rm, q, F, 2, truth)
        (b,) = X.plan_power(rm, np.repeat(q, 2, axis=0), np.repeat(F, 2, axis=0), 1, truth)
        assert a.delta == pytest.approx(b.delta, rel=1e-9) and a.df_den == b.df_den == rm.noise_df + 2 * 2
        assert a.power == pytest.approx(b.power, rel=1e-9)


def test_each_model_in_turn_as_the_truth(two_link_csv):
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    meas = read_measurements(two_link_csv, robot)
    res = X.discriminate(robot, meas, 3, X.load_set("hanging:100,300,600", 2), truth="each", m_curve=[3], effort=FAST)
    assert sorted(res.pairs) == [(0, 1), (1, 0)]
    assert res.power == pytest.approx(min(p.power for p in res.plan.powers))
    assert res.certificate.bound >= res.certificate.delta == pytest.approx(res.plan.deltas.min())


# --- the certificate -----------------------------------------------------------------------------------------

def test_bound_holds_for_every_plan_of_a_brute_force_and_the_exchange_finds_its_best(three_link):
    robot, meas, v = three_link
    rm = X.rivals_from_verdict(robot, meas, v)
    loads = X.load_set("hanging:400,800", 2)
    poses = np.random.default_rng(6).permutation(X.pose_pool(robot, 30.0))[:24]
    pool = X.make_pool(robot, poses, loads.forces, {"backlash"})
    crit = X.build_criterion(rm, pool, [(0, 1)])
    K = len(pool)
    # every plan of 2 points from the pool, each Delta by its own least squares
    best = 0.0
    truth, rival = rm.models
    mu_pool = D.model_columns(robot, pool.q, pool.force, truth.causes) @ truth.beta
    Xr_pool = D.model_columns(robot, pool.q, pool.force, rival.causes)
    mu_old, X_old = rm.old_mean(truth), rm.old_rows(rival.causes)
    for i in range(K):
        for j in range(i, K):
            mu = np.concatenate([mu_old, mu_pool[[i, j]].ravel()])
            Xr = np.vstack([X_old, D._stack(Xr_pool[[i, j]])])
            r = mu - Xr @ np.linalg.lstsq(Xr, mu, rcond=None)[0]
            best = max(best, float(r @ r))
    ex = X.exchange(crit, 2, n_starts=4)
    assert crit.deltas(ex.indices)[0] >= best * (1 - 1e-9)
    cert = X.t_certificate(crit, rm, pool, pool.q[ex.indices], pool.force[ex.indices], effort=FAST)
    assert cert.bound >= best and cert.bound >= cert.delta
    assert 0 < cert.efficiency <= 1


def test_certificate_of_the_plan(three_link_plan):
    res = three_link_plan
    c = res.certificate
    assert c.bound >= c.delta > 0 and c.efficiency == pytest.approx(c.delta / c.bound)
    assert c.power_bound >= res.power - 1e-12
    assert res.power_against_m[-1] == (6, pytest.approx(res.power))


# --- the compound plan ---------------------------------------------------------------------------------------

def test_compound_plan_weighs_o_t_and_discrimination(three_link):
    robot, meas, v = three_link
    qt, ft = np.radians([60.0, 30.0, -40.0]), np.array([0.0, -400.0])
    res = X.discriminate(robot, meas, 4, X.load_set("hanging:400,800", 2), verdict=v, test_pose=qt, test_force=ft,
                         m_curve=[4], effort=FAST)
    t, c, o = res.plan, res.compound, res.ot_plan
    assert c is not None and o is not None and res.weight == X.COMPOUND_WEIGHT
    # each plan is the best of the three for its own criterion
    assert t.deltas.min() >= c.deltas.min() * (1 - 1e-9)
    assert o.o_t <= c.o_t * (1 + 1e-9)
    rm = res.rivals
    pool = X.make_pool(robot, X.pose_pool(robot, 20.0), res.loads.forces, {"backlash"})
    crit = X.build_criterion(rm, pool, list(res.pairs), 1, res.weight, qt, ft)
    value = {k: crit.on(np.radians(s.poses_deg), s.forces_N).value(np.arange(4)) for k, s in
             (("t", t), ("c", c), ("o", o))}
    assert value["c"] >= max(value["t"], value["o"]) - 1e-9
    # the O_t bound lies below the O_t of every plan (the three and random ones)
    rng = np.random.default_rng(4)
    crit0 = X.build_criterion(rm, pool, list(res.pairs), 1, 0.0, qt, ft)
    others = [crit0.o_t(rng.choice(len(pool), 4)) for _ in range(30)]
    assert res.ot_bound <= min([t.o_t, c.o_t, o.o_t, *others])
    assert res.ot_bound > 0


# --- rivals no plan of positions separates ---------------------------------------------------------------

@pytest.fixture(scope="module")
def two_link_bending():
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    pr = T.Protocol("4 pushes, twice", loads="directions", n_directions=4, magnitudes_N=(300.0,), repeats=2)
    _, _, meas = _lab(robot, pr, "link_compliance", 0, 12, 4.0, np.array([1.5e-6, 3e-6]))
    return robot, meas, D.analyse(robot, meas, 0.01, gain=False)


def test_coinciding_spans_are_named_with_the_measurement_that_would_separate_them(two_link_bending):
    robot, meas, v = two_link_bending
    combinations = {tuple(c) for c in [v["causes"], *v["equivalent_combinations"]]}
    assert combinations == {("link_compliance",), ("joint_coupling",)}
    res = X.discriminate(robot, meas, 4, X.load_set("directions:4:300", 2), verdict=v, effort=FAST)
    assert not res.separable and res.plan is None and res.power_against_m == ()
    assert len(res.separability) == 2 and not any(s.separable for s in res.separability)
    assert all("the end-effector orientation" in s.needs for s in res.separability)
    out = X.to_json(res)
    assert out["separable"] is False and out["plan"] is None
    assert any("no plan of these measurements can separate" in n for n in out["notes"])
    # no plan can: the lack of fit of the rival stays at round-off for random plans
    pool = X.make_pool(robot, X.pose_pool(robot, 20.0), res.loads.forces)
    crit = X.build_criterion(res.rivals, pool, [(0, 1)])
    scale = np.sum(res.rivals.old_mean() ** 2)
    for idx in np.random.default_rng(0).choice(len(pool), (5, 6)):
        assert crit.deltas(idx)[0] <= 1e-9 * scale


class PlanarAngle:
    """A measurement model with one more row per pose: the end-effector angle of a planar arm, dphi = sum dq_i
    plus the bending rotation of every link, here integrated from the curvature c M(s) by quadrature (the
    kind of model issue 15 adds for robot files with orientation measurements)."""

    name = "position and angle of the end effector"
    _x, _w = np.polynomial.legendre.leggauss(6)

    def rows(self, robot):
        return robot.task_dim + 1

    def columns(self, robot, q, force, causes=()):
        pos = D.model_columns(robot, q, force, causes)
        tau = np.einsum("ndj,nd->nj", robot.jacobian(q), force)
        n = robot.n_joints
        cols = [tau]
        for c in sorted(causes, key=D.CAUSES.index):
            if c == "joint_coupling":
                cols.append(np.stack([tau[:, j] + tau[:, i] for i in range(n) for j in range(i + 1, n)], -1))
            elif c == "link_compliance":
                pts, F = as_xyz(robot.link_points(q)), as_xyz(force)
                turn = []
                for i in range(n):
                    a, b = pts[:, i], pts[:, i + 1]
                    L = np.linalg.norm(b - a, axis=-1)
                    turn.append(sum(0.5 * w * L * np.cross(pts[:, -1] - (a + 0.5 * (x + 1) * (b - a)), F)[:, 2]
                                    for x, w in zip(self._x, self._w)))
                cols.append(np.stack(turn, -1))
            else:
                raise NotImplementedError(c)
        return np.concatenate([pos, np.concatenate(cols, -1)[:, None, :]], axis=1)


def test_a_measurement_model_with_more_rows_plugs_in(two_link_bending):
    robot, meas, v = two_link_bending
    rm = X.rivals_from_verdict(robot, meas, v)
    loads = X.load_set("directions:4:300", 2)
    pool = X.make_pool(robot, X.pose_pool(robot, 20.0), loads.forces)
    angle = PlanarAngle()
    assert np.allclose(angle.columns(robot, pool.q[:5], pool.force[:5], rm.truth.causes)[:, :2],
                       X.PositionModel().columns(robot, pool.q[:5], pool.force[:5], rm.truth.causes))
    seps = {(rm.models[s.truth].causes, rm.models[s.rival].causes): s.separable
            for s in X.separability(rm, pool, angle)}
    # with the angle, a bending link can be told from coupled joints (not the other way: coupling's one
    # extra direction lies in the span of the link compliances)
    assert seps[(("link_compliance",), ("joint_coupling",))] is True
    assert seps[(("joint_coupling",), ("link_compliance",))] is False
    t = [i for i, m in enumerate(rm.models) if m.causes == ("link_compliance",)][0]
    crit = X.build_criterion(rm, pool, [(t, 1 - t)], measurement=angle)
    ex = X.exchange(crit, 3, n_starts=1)
    q, F = pool.q[ex.indices], pool.force[ex.indices]
    (p,) = X.plan_power(rm, q, F, 1, t, angle)
    assert p.delta == pytest.approx(crit.deltas(ex.indices)[0], rel=1e-7) and p.delta > 0 and p.df_num >= 1


# --- a 6-axis arm --------------------------------------------------------------------------------------------

def test_six_axis_plan_within_limits_and_its_power_on_simulated_physics():
    robot = load_robot(ROOT / "config/robots/kuka_kr210_r2700.yaml")
    pr = T.Protocol("2 pushes, twice", loads="pushes3d", n_directions=2, magnitudes_N=(600.0,), repeats=2)
    _, _, meas = _lab(robot, pr, "link_compliance", 1, 8, 1.0, R.compliances(robot))
    v = D.analyse(robot, meas, 0.01, gain=False)
    combinations = {tuple(c) for c in [v["causes"], *v["equivalent_combinations"]]}
    assert combinations == {("link_compliance",), ("joint_coupling",)}
    res = X.discriminate(robot, meas, 6, X.load_set("directions:6:600", 3), verdict=v, m_curve=[6],
                         effort=X.Effort(pool_log2=10, search_log2=11, n_starts=1, rounds=1))
    q, F = np.radians(res.plan.poses_deg), res.plan.forces_N
    assert not robot.outside_limits(q).any()
    assert res.certificate.bound >= res.certificate.delta
    # both rivals are physical truths of the simulator (link bending, coupled joints): each in turn
    for truth in (0, 1):
        (sim,) = S.simulate_separation(res.rivals, q, F, 1, truth, repetitions=40, seed=truth)
        assert _binomial_ok(sim.rate, sim.predicted, 40, extra=0.03), sim


def test_fitted_link_coupling_and_offset_models_are_the_simulators_physics():
    """:func:`model_mean` simulates link bending, coupled joints and an offset with stiffcal.testing.truth; the
    analysis's regressors must give the same displacement (an independent check of both)."""
    rng = np.random.default_rng(3)
    for robot in (planar_robot([0.5, 0.4, 0.3]), load_robot(ROOT / "config/robots/kuka_kr210_r2700.yaml")):
        q = rng.uniform(*robot.joint_limits_rad.T, (20, robot.n_joints))
        F = rng.normal(size=(20, robot.task_dim)) * 300
        causes = ("link_compliance", "joint_coupling", "measurement_offset")
        p = D.model_columns(robot, q, F, causes).shape[-1]
        beta = rng.uniform(0.5, 2.0, p) * 1e-7
        model = X.Rival(causes, beta, 0.0, 1)
        assert np.allclose(S.model_mean(robot, model, q, F), D.model_columns(robot, q, F, causes) @ beta,
                           rtol=1e-9, atol=1e-9 * np.abs(D.model_columns(robot, q, F, causes) @ beta).max())


def test_angles_a_round_off_below_zero_group_with_zero():
    """A simulated plan's angle of -1e-17 rad wraps (mod 360 deg) to the edge of the periodic box of the grouping;
    it must be one configuration with the angle 0 (stiffcal.measured.measurements.cluster)."""
    q = np.array([[-1e-17, 0.5], [0.0, 0.5], [1.0, 0.5]])
    F = np.array([[0.0, -300.0]] * 3)
    m = Measurements.from_arrays(q, F, np.zeros((3, 2)))
    assert m.group[0] == m.group[1] != m.group[2]


# --- loads and bad input -----------------------------------------------------------------------------------------

def test_load_sets():
    h = X.load_set("hanging:100,250", 3)
    assert np.allclose(h.forces, [[0, 0, -100], [0, 0, -250]])
    d = X.load_set("directions:4:100,200", 2)
    assert len(d.forces) == 8 and np.allclose(np.linalg.norm(d.forces, axis=1), [100, 200] * 4)
    s = X.load_set("directions:6:50", 3)
    assert np.allclose(np.linalg.norm(s.forces, axis=1), 50) and abs(s.forces.sum(axis=0)).max() < 50
    f = X.load_set("forces:1,2;3,-4", 2)
    assert np.allclose(f.forces, [[1, 2], [3, -4]])
    data = X.load_set(None, 2, np.array([[0, -300.0], [0, -300.2], [300.0, 0]]), 0.5)
    assert len(data.forces) == 2 and data.kind == "data"
    # a weight given as a mass (a fresh user gave 5, 10, 20 kg as newtons): its weight at standard gravity
    kg = X.load_set("hanging:5kg, 10 kg,98.0665N", 3)
    assert np.allclose(kg.forces[:, 2], [-5 * 9.80665, -10 * 9.80665, -98.0665], rtol=1e-12)
    assert np.allclose(X.load_set("bar:0.3,0,0:2kg", 3).forces[0, 2], -2 * 9.80665)
    for bad in ("hanging:", "hanging:-5", "directions:0:10", "directions:x:10", "forces:1,2,3", "forces:0,0",
                "pushes:1", "hanging:1,nan", "hanging:5kgs", "directions:4:5kg"):
        with pytest.raises(InputError, match="--loads"):
            X.load_set(bad, 2)


@pytest.fixture(scope="module")
def two_link_csv(tmp_path_factory):
    """A CSV of the paper's arm under one hanging mass: backlash that cannot be told from a nonlinear stiffness."""
    robot = load_robot(ROOT / "config/robots/paper_2r.yaml")
    log, dp, _ = _lab(robot, T.Protocol("300 N hanging, twice", magnitudes_N=(300.0,)), "backlash", 0, 10, 1.0,
                      np.array([1.5e-6, 3e-6]))
    path = tmp_path_factory.mktemp("csv") / "hanging.csv"
    path.write_text(T.lab_csv(robot, log, dp), encoding="utf-8")
    return path


def test_command_writes_the_plan_and_a_figure_and_reruns_identically(two_link_csv, tmp_path, capsys):
    robot = str(ROOT / "config/robots/paper_2r.yaml")
    args = ["discriminate", "--robot", robot, "--data", str(two_link_csv), "--experiments", "4", "--loads",
            "hanging:100,300,600", "--test-pose-deg", "60,30", "--force-N", "0,-300"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["separable"] and sorted(map(tuple, [out["truth"], *out["rivals"]])) == [("backlash",),
                                                                                     ("nonlinear_joint_stiffness",)]
    assert len(out["poses_deg"]) == 4 and 0 < out["power"] <= 1 and 0 < out["efficiency"] <= 1
    assert out["compound"]["weight"] == 0.5 and len(out["compound"]["poses_deg"]) == 4
    plan = json.loads((tmp_path / "a/plan.json").read_text())
    for key in ("models", "separability", "plan", "compound", "ot_plan", "power_against_m", "loads", "notes"):
        assert key in plan
    assert (tmp_path / "a/plan.png").stat().st_size > 0 and (tmp_path / "a/plan.svg").stat().st_size > 0
    # the Python API gives the same plan, byte for byte
    X.run(load_robot(robot), str(two_link_csv), str(tmp_path / "b"), 4, "hanging:100,300,600",
          test_pose=np.radians([60, 30]), test_force=np.array([0, -300.0]))
    assert (tmp_path / "a/plan.json").read_bytes().replace(b'"data": "', b"") == \
        (tmp_path / "b/plan.json").read_bytes().replace(b'"data": "', b"")


@pytest.mark.parametrize("extra, field", [
    (["--experiments", "0"], "--experiments"),
    (["--experiments", "3", "--loads", "hanging:0"], "--loads"),
    (["--experiments", "3", "--loads", "forces:1,2,3"], "--loads"),
    (["--experiments", "3", "--weight", "1.5"], "--weight"),
    (["--experiments", "3", "--repeats", "0"], "--repeats"),
    (["--experiments", "3", "--test-pose-deg", "60,30"], "--test-pose-deg"),
])
def test_bad_input_is_one_line_and_exit_2_with_nothing_written(two_link_csv, tmp_path, capsys, extra, field):
    out = tmp_path / "out"
    code = main(["discriminate", "--robot", str(ROOT / "config/robots/paper_2r.yaml"), "--data", str(two_link_csv),
                 "--out", str(out), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and field in err and "Traceback" not in err
    assert not out.exists()


# --- a new user's lab logs (tests/data/lab) -------------------------------------------------------------------

LAB = ROOT / "tests" / "data" / "lab"


@pytest.fixture(scope="module")
def lab3():
    """The planar 3-link arm under a loading bar (every load a force and a moment 0.15 m x |F|), joint coupling
    hidden: the verdict, and the plan of 4 points (quick search)."""
    robot = load_robot(LAB / "lab_3r.yaml")
    meas = read_measurements(LAB / "lab_3r_coupling.csv", robot)
    verdict = D.analyse(robot, meas, 0.01, gain=False)
    res = X.discriminate(robot, meas, 4, X.load_set(None, robot.task_dim, meas.force), verdict=verdict,
                         effort=FAST, m_curve=[1])
    return robot, meas, verdict, res, X.to_json(res)


def test_plan_keeps_the_moments_of_the_data(lab3):
    """The data's loads are wrenches (a loading bar): the plan's loads, its points and the rivals' fits keep the
    moment. The loads equal the CSV's distinct (force, moment) rows (read here with pandas); the rival that is
    the verdict's combination fits the data with the residual sum of squares of the verdict's extended model (the
    analysis fits with the wrench; a fit without the moments leaves a residual about 400 times larger)."""
    import pandas as pd

    robot, meas, verdict, res, out = lab3
    df = pd.read_csv(LAB / "lab_3r_coupling.csv")
    loaded = df[(df.fx_N.abs() > 0.5) | (df.fy_N.abs() > 0.5)]
    want = {(r.fx_N, r.fy_N, r.mz_Nm) for r in loaded.itertuples()}
    got = {(f[0], f[1], m[0]) for f, m in zip(out["loads"]["forces_N"], out["loads"]["moments_Nm"])}
    assert got == want and len(want) == 8
    assert "moment" in out["loads"]["description"]
    plan = out["plan"]
    assert len(plan["moments_Nm"]) == len(plan["forces_N"]) == 4
    assert all((f[0], f[1], m[0]) in want for f, m in zip(plan["forces_N"], plan["moments_Nm"]))
    assert all(p["moment_Nm"] is not None for p in plan["points"])
    assert plan["certificate"]["psi_max_moment_Nm"] is not None
    same = [m for m in out["models"] if m["causes"] == verdict["causes"]][0]
    assert same["rss_m2"] == pytest.approx(verdict["extended"]["rss"], rel=1e-9)
    ext = verdict["extended"]  # its parameters are the verdict's, name by name (null where the verdict's are)
    assert same["parameter_names"] == verdict["nominal"]["k_names"] + ext["parameter_names"]
    for got, want in zip(same["parameters"], ext["k"] + ext["parameters"]):
        assert (got is None) == (want is None) and (got is None or got == pytest.approx(want, rel=1e-6, abs=1e-15))
    # the verdict's advice names a load the lab applies: force and moment
    assert all("moment" in text for text in verdict["separation"].values())


def test_truth_is_the_verdicts_combination_not_the_one_with_most_parameters():
    """Clean UR10 data under a loading bar (joint compliances only, tests/data/lab/make_ur10.py): the global
    test raises a 1 % false alarm (p just below alpha) and the verdict names one cause beside equivalent ones,
    joint_coupling (15 parameters) among them, none significant on its own. The plan takes the verdict's
    combination as the truth, not the one of the smallest residual (joint_coupling, fitting the noise)."""
    robot = load_robot(LAB / "ur10.yaml")
    meas = read_measurements(LAB / "ur10_bar.csv", robot)
    verdict = D.analyse(robot, meas, 0.01, gain=False)
    assert len(verdict["causes"]) == 1 and not any(t["significant"] for t in verdict["tests"].values())
    combos = [verdict["causes"], *verdict["equivalent_combinations"]]
    assert ["joint_coupling"] in combos
    # the tie-break among them is the verdict's (the smallest p against the nominal model: joint_coupling here); the
    # planner follows the verdict whichever it is: given an equivalent with fewer parameters, it takes that one
    alt = next(c for c in combos if c != ["joint_coupling"])
    verdict = {**verdict.to_dict(), "causes": alt, "equivalent_combinations": [c for c in combos if c != alt]}
    res = X.discriminate(robot, meas, 2, X.load_set(None, robot.task_dim, meas.force), verdict=verdict,
                         effort=X.Effort(pool_log2=7, search_log2=8, n_starts=0, rounds=0), m_curve=[1])
    out = X.to_json(res)
    rss = {tuple(m["causes"]): m["rss_m2"] for m in out["models"]}
    chosen = tuple(verdict["causes"])
    assert res.rivals.truth.causes == chosen
    assert out["models"][0]["role"] == "truth" and out["models"][0]["causes"] == list(chosen)
    assert len(res.rivals.truth.beta) < len(next(m.beta for m in res.rivals.models if m.causes == ("joint_coupling",)))
    assert rss[("joint_coupling",)] < rss[chosen]  # the rival the smallest RSS would have chosen
    assert out["verdict"]["significant_on_its_own"] == []
    # the moments' offset test explains the rows as well as joint_coupling and neither adds to the other: the verdict
    # keeps the cause (it was `unexplained` by the offset), with a note that the two cannot be told apart
    assert verdict["cause"] != "unexplained" and any("cannot be told apart; the verdict keeps joint_coupling" in n
                                                     for n in D.analyse(robot, meas, 0.01, gain=False)["notes"])
    # an unexplained verdict's plan says what it separates
    res = X.discriminate(robot, meas, 2, X.load_set(None, robot.task_dim, meas.force),
                         verdict={**verdict, "cause": "unexplained"},
                         effort=X.Effort(pool_log2=7, search_log2=8, n_starts=0, rounds=0), m_curve=[1])
    assert any(n.startswith("the verdict is 'unexplained'") for n in X.to_json(res)["notes"])


def test_power_bound_holds_for_the_plan_itself(lab3):
    """The certified power bound is at least the plan's own predicted power. The 3-link case printed power
    0.43801 beside a bound of 0.43790: the lack of fit was within 1e-11 of its bound (efficiency 1), but the bound
    used the unmerged plan's denominator degrees of freedom while merging repeated points adds pure error (384
    -> 386). The bound now uses the most denominator and fewest numerator degrees of freedom of any M-point plan;
    checked here against scipy's noncentral F at the plan's own degrees of freedom."""
    from scipy import stats

    robot, meas, verdict, res, out = lab3
    plan, cert = out["plan"], out["plan"]["certificate"]
    pair = [t for t in plan["tests"] if t["truth"] == cert["pair"]["truth"] and t["rival"] == cert["pair"]["rival"]][0]
    assert pair["t_criterion_m2"] <= cert["bound_m2"] * (1 + 1e-9)
    at_bound = stats.ncf.sf(stats.f.isf(pair["level"], pair["df_num"], pair["df_den"]), pair["df_num"],
                            pair["df_den"], cert["bound_m2"] / out["sigma_m"] ** 2)
    assert pair["power"] <= at_bound + 1e-12 and at_bound <= cert["power_bound"] + 1e-12
    assert plan["power"] <= cert["power_bound"]


def test_no_rival_note_says_why_the_verdict_s_other_causes_are_not_rivals():
    """A fresh user's UR10: the verdict listed indistinguishable_from [backlash] while discriminate said 'the data
    single out nonlinear_joint_stiffness; nothing to discriminate', which read as a contradiction. The note now says
    that those causes are needed with the named one, not equally good combinations, and how to plan against them;
    without such causes it stays as it was."""
    from types import SimpleNamespace

    from stiffcal.measured.discrimination import _rival_notes

    truth = SimpleNamespace(label="nonlinear_joint_stiffness", causes=("nonlinear_joint_stiffness",))
    rm = SimpleNamespace(models=(truth,), truth=truth)
    tests = {c: {"significant": c == "nonlinear_joint_stiffness"} for c in ("nonlinear_joint_stiffness", "backlash")}
    verdict = {"cause": "nonlinear_joint_stiffness", "causes": ["nonlinear_joint_stiffness"], "tests": tests,
               "indistinguishable_from": ["backlash"], "equivalent_combinations": [], "p_value": 1e-4,
               "nominal": {"noise_varies": None}}
    notes = _rival_notes(verdict, rm, [], [])
    assert any("the data single out nonlinear_joint_stiffness" in n and "indistinguishable_from, {backlash}" in n
               and "combinations=" in n for n in notes), notes
    verdict["indistinguishable_from"] = []
    assert _rival_notes(verdict, rm, [], []) == ["no rival combination: the data single out nonlinear_joint_stiffness; "
                                                 "nothing to discriminate"]
