"""The discrepancy analysis: measured data as labs record them (several loads per configuration, replicates,
unloaded reference rows), hidden effects in simulated data (stiffcal.testing.truth, written from the physics and
independent of the analysis) found at the rates of an oracle, several effects at once, the handed-over
cases, bad and degenerate data, the CLI."""

import json
import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from stiffcal.measured import discrepancy as D
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.measured.measurements import Measurements, cluster, read_measurements
from stiffcal.model.robot import load_robot, planar_robot

SIGMA = 1e-5  # laser-tracker noise [m]
CASES = Path(__file__).parent / "data" / "discrepancy"


# --- the handed-over cases --------------------------------------------------------------------------------

@pytest.mark.parametrize("case, expected", [
    ("case1_2L_hanging_backlash", ["backlash"]),
    ("case2_3L_dirs_offset", ["measurement_offset"]),
    ("case3_2L_hanging_two_effects", ["backlash", "measurement_offset"]),
    ("case4_kuka_coupling", ["joint_coupling"]),
])
def test_handed_over_cases_name_their_causes_with_and_without_pose_id(case, expected):
    robot = load_robot(CASES / f"{case}.robot.yaml")
    verdicts = [D.analyse(robot, read_measurements(CASES / f"{case}.{v}.csv", robot), 0.01, gain=False) for v in "ab"]
    for v in verdicts:
        assert sorted(v["causes"]) == sorted(expected), v["causes"]
        assert v["cause"] in expected and v["cause"] != "unexplained"
    a, b = verdicts
    assert a["causes"] == b["causes"] and a["p_value"] == pytest.approx(b["p_value"])
    assert a["structure"]["n_configurations"] == b["structure"]["n_configurations"]


def test_unloaded_reference_rows_are_the_zero_point_not_replicates():
    robot = load_robot(CASES / "unloaded_rows.robot.yaml")
    meas = read_measurements(CASES / "unloaded_rows.csv", robot)
    assert len(meas.zero_rows) == 120 and meas.n_rows == 120
    v = D.analyse(robot, meas, 0.01, gain=False)
    assert v["cause"] == "none"
    assert 8e-6 < v["nominal"]["sigma_m"] < 12e-6  # the simulator's tracker noise is 10 um
    assert v["zero_point"]["n_rows"] == 120 and v["zero_point"]["rms_m"] == 0


# --- how rows are grouped ------------------------------------------------------------------------------

def _brute_force_components(values, res, period):
    """Connected components of 'agree within res on every column (modulo period)' by union-find over all pairs."""
    n = len(values)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            d = np.abs(values[i] - values[j])
            d = np.where(np.isfinite(period), np.minimum(d, period - d), d)
            if np.all(d <= res * (1 + 1e-9)):
                parent[find(i)] = find(j)
    roots = [find(i) for i in range(n)]
    return [sorted(i for i in range(n) if roots[i] == r) for r in dict.fromkeys(roots)]


def test_cluster_equals_a_brute_force_over_all_pairs(rng):
    for _ in range(20):
        base = rng.uniform(-180, 180, (12, 3))
        values = base[rng.integers(0, 12, 80)] + rng.uniform(-0.02, 0.02, (80, 3))
        values[:, 2] = np.round(values[:, 2] * 3) / 3 * 100  # a non-periodic column (a force) with ties
        res = np.array([0.01, 0.01, 0.5])
        period = np.array([360.0, 360.0, np.inf])
        labels = cluster(values, res, period)
        ours = [sorted(np.flatnonzero(labels == g).tolist()) for g in dict.fromkeys(labels.tolist())]
        assert sorted(ours) == sorted(_brute_force_components(values, res, period))


def test_angles_a_turn_apart_are_one_configuration():
    labels = cluster(np.array([[179.9995, 10.0], [-180.0, 10.0], [0.0, 10.0]]), np.array([0.01, 0.01]),
                     np.array([360.0, 360.0]))
    assert labels.tolist() == [0, 0, 1]


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


LAB = """pose_id,q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m
7,10,20,0,-100,1.0e-5,-2.0e-4
7,10,20,0,-200,2.1e-5,-4.0e-4
7,10,20,0,-100,1.1e-5,-2.1e-4
7,10,20,0,-200,2.0e-5,-3.9e-4
8,40,70,0,-100,3.0e-5,-1.0e-4
8,40,70,0,-200,6.0e-5,-2.1e-4
8,40.004,70,0,-100.3,3.1e-5,-1.1e-4
"""


def test_replicates_are_equal_angles_and_loads_whatever_the_pose_id(tmp_path, paper_robot):
    meas = read_measurements(_write(tmp_path, LAB), paper_robot)
    assert meas.n_configurations == 2 and meas.config_labels == ("7", "8")
    # (10,20) x {100, 200} twice; (40,70) x {100 (twice, within resolution), 200}
    assert meas.group.tolist() == [0, 1, 0, 1, 2, 3, 2]
    s = meas.structure()
    assert s["n_replicate_groups"] == 4 and s["loads_per_configuration"] == {"min": 2, "median": 2.0, "max": 2}
    same = read_measurements(_write(tmp_path, "\n".join(x.split(",", 1)[1] for x in LAB.splitlines()) + "\n", "b.csv"),
                             paper_robot)
    assert same.group.tolist() == meas.group.tolist() and same.config.tolist() == meas.config.tolist()
    with pytest.raises(InputError, match="pose_id '8'"):  # at a finer encoder resolution row 8 is another pose
        read_measurements(_write(tmp_path, LAB), paper_robot, angle_resolution_deg=0.001)


def test_a_pose_id_shared_by_different_joint_angles_is_refused_naming_the_rows(tmp_path, paper_robot):
    text = LAB.replace("8,40.004,70", "8,41,70")
    with pytest.raises(InputError) as err:
        read_measurements(_write(tmp_path, text), paper_robot)
    msg = str(err.value)
    assert "pose_id '8'" in msg and "rows 6, 8" in msg and "q1" in msg and "column pose_id" in msg


def test_blank_pose_id_cells_are_refused_and_an_empty_column_is_a_note(tmp_path, paper_robot):
    lines = LAB.splitlines()
    lines[3] = "," + lines[3].split(",", 1)[1]
    with pytest.raises(InputError, match=r"pose_id is blank in row 4 \(data row 2\)"):
        read_measurements(_write(tmp_path, "\n".join(lines) + "\n"), paper_robot)
    empty = "\n".join([lines[0]] + ["," + x.split(",", 1)[1] for x in LAB.splitlines()[1:]]) + "\n"
    meas = read_measurements(_write(tmp_path, empty, "e.csv"), paper_robot)
    assert meas.n_configurations == 2 and any("blank in every row" in n for n in meas.notes)


def test_unloaded_rows_are_set_apart_and_all_unloaded_is_refused(tmp_path, paper_robot):
    text = LAB + "8,40,70,0,0.2,0,0\n"
    meas = read_measurements(_write(tmp_path, text), paper_robot)
    assert meas.n_rows == 7 and meas.zero_rows.tolist() == [7] and meas.zero_config.tolist() == [1]
    assert any("unloaded" in n for n in meas.notes)
    with pytest.raises(InputError, match="every row is unloaded"):
        read_measurements(_write(tmp_path, "q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n1,2,0,0,0,0\n", "z.csv"), paper_robot)


def test_columns_the_analysis_does_not_use_are_named(tmp_path, paper_robot):
    head, *rows = LAB.splitlines()
    text = "\n".join([head + ",dz_m,temperature_C"] + [r + ",0,21" for r in rows]) + "\n"
    meas = read_measurements(_write(tmp_path, text), paper_robot)
    assert any("dz_m" in n and "ignored" in n for n in meas.notes)
    assert any("temperature_C" in n and "not used" in n for n in meas.notes)
    with pytest.raises(InputError, match="column mz_Nm"):
        read_measurements(_write(tmp_path, "\n".join([head + ",mz_Nm"] + [r + (",0" if i < 2 else ",")
                                                                             for i, r in enumerate(rows)]) + "\n"),
                          paper_robot)  # moment cells left blank


# --- the statistics against independent computations -------------------------------------------------------

def test_reduced_subset_fits_equal_direct_fits(rng):
    X = rng.normal(size=(300, 12)) * np.logspace(-6, 2, 12)
    X[:, 5] = X[:, 1] - 2 * X[:, 3]  # a dependent column: rank decisions must agree
    y = rng.normal(size=300)
    red = D.Reduced.of(X, y)
    for cols in ([0, 1, 2], [1, 3, 5], list(range(12)), [4]):
        a, b = red.fit(cols), D.fit(X[:, cols], y)
        assert a.rank == b.rank and a.rss == pytest.approx(b.rss, rel=1e-9)
        assert np.allclose(X[:, cols] @ a.beta, X[:, cols] @ b.beta, rtol=1e-8, atol=1e-10)


def test_rank_correlations_equal_scipy_spearman(rng, paper_robot):
    q = rng.uniform(-3, 3, (60, 2))
    f = rng.normal(0, 200, (60, 2))
    meas = Measurements.from_arrays(q, f, rng.normal(0, 1e-5, (60, 2)))
    resid = rng.normal(size=(60, 2))
    found = D.residual_structure(paper_robot, meas, resid, keep=None)
    feats = D._features(paper_robot, meas)
    for key, r in found.items():
        axis, name = "xyz".index(key[0]), key.split(" vs ", 1)[1]
        rho, p = stats.spearmanr(feats[name], resid[:, axis])
        assert r["spearman"] == pytest.approx(rho, abs=1e-12) and r["p_value"] == pytest.approx(p, rel=1e-9)


def test_configuration_model_removes_exactly_the_projection_on_its_dense_columns(rng):
    n_cfg, L, d = 5, 4, 2
    q = np.repeat(rng.uniform(-3, 3, (n_cfg, 2)), L, axis=0)
    f = rng.normal(0, 100, (n_cfg * L, d))
    f[:L] = f[0]  # a configuration with one load repeated: its G block has rank 2, not 3
    meas = Measurements.from_arrays(q, f, rng.normal(size=(n_cfg * L, d)))
    G = D.ConfigurationModel.of(meas)
    dense = np.zeros((n_cfg * L * d, n_cfg * d * (d + 1)))
    for r in range(n_cfg * L):
        c = meas.config[r]
        for a in range(d):
            base = c * d * (d + 1) + a * (d + 1)
            dense[r * d + a, base:base + d] = f[r]
            dense[r * d + a, base + d] = 1.0
    y = rng.normal(size=n_cfg * L * d)
    ref = y - dense @ np.linalg.lstsq(dense, y, rcond=None)[0]
    assert np.allclose(G.residualise(y), ref, atol=1e-12)
    assert G.rank == np.linalg.matrix_rank(dense)


def test_pure_error_is_the_spread_of_replicates():
    y = np.array([[1.0, 2.0], [3.0, 2.0], [5.0, 5.0]])
    ss, df = D.pure_error(y, np.array([0, 0, 1]))
    assert (ss, df) == (2.0 + 0.0, 2)


def test_link_regressors_equal_the_integrated_beam_of_the_truth(rng):
    """The closed-form link columns against the truth simulator's curvature integral."""
    robot = planar_robot([0.7, 0.5, 0.3])
    q = rng.uniform(-np.pi, np.pi, (20, 3))
    f = rng.normal(0, 300, (20, 2))
    c = np.array([1e-6, 2e-6, 3e-6])
    ours = np.einsum("ndp,p->nd", D.cause_columns("link_compliance", robot, q, f), c)
    assert np.allclose(ours, T.link_bending_displacement(robot, q, f, c), rtol=1e-10, atol=1e-18)


@pytest.mark.parametrize("block", [None, "backlash"])
def test_oracle_power_equals_a_monte_carlo_of_the_oracle_test(rng, block):
    """The noncentral-F power of the oracle (exact shape: 1 df; cause block: the backlash regressors) against
    the rejection rate of that F-test on the simulator's noise (every row a loaded reading less its own
    unloaded reference reading: independent rows of twice a reading's variance)."""
    robot = planar_robot([0.6, 0.4])
    log = T.lab_log(robot, R.PROTOCOLS["4 directions x 2, repeated"], rng, 10)
    rows = log.loaded
    X = D._stack(D.nominal_columns(robot, log.q[rows], log.force[rows]))
    B = D._stack(D.cause_columns("backlash", robot, log.q[rows], log.force[rows]))
    e = B @ np.array([1.0, -0.5]) * 6.5e-6
    df = 60
    power = R.oracle_power(robot, log, e.reshape(-1, 2), [], 0.01, df, block=block)
    Xe = np.hstack([X, e[:, None] if block is None else B])
    r = Xe.shape[1] - X.shape[1]
    crit = stats.f.isf(0.01, r, df)
    hits, n = 0, 2000
    still = T.Truth(np.zeros(2))
    for _ in range(n):
        y = e + T.measure(robot, still, log, rng)[rows].ravel()
        r0 = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
        r1 = y - Xe @ np.linalg.lstsq(Xe, y, rcond=None)[0]
        s2 = 2 * SIGMA**2 * rng.chisquare(df) / df  # an independent pure-error estimate on df degrees of freedom
        hits += (r0 @ r0 - r1 @ r1) / r / s2 > crit
    assert 0.2 < power < 0.95
    assert abs(hits / n - power) < 4 * np.sqrt(power * (1 - power) / n)


# --- hidden effects over seeds: the test matrix (a slice; benchmarks/rates_discrepancy.py prints it all) ---

SLICE = {  # robot -> protocols; every catalogue cause is hidden under each, with and without pose_id
    "2-link": ["hanging x4, repeated", "4 directions x 2, interleaved"],
    "3-link": ["hanging x4, once", "random load x3, unloaded rows, tracker"],
    "6-axis": ["3-D pushes x 2, repeated"],
}


@pytest.fixture(scope="module")
def arms(root):
    return R.robots(root)


def _binomial_consistent(k: int, n: int, p: float, level: float = 0.01, at_least: bool = False) -> bool:
    """The count k of n is consistent, by a one-sided exact binomial test at ``level``, with a rate of at most
    p (at_least=False) or at least p (at_least=True)."""
    return (stats.binom.cdf(k, n, p) if at_least else stats.binom.sf(k - 1, n, p)) > level


def test_each_cause_is_named_where_an_oracle_would_find_it(arms, tmp_path):
    """A slice of the test matrix: every catalogue cause under one or two protocols per arm, both CSV
    variants. The requirement is a rate of at least 95 % over the cases where the oracle's power is >= 0.9
    (benchmarks/rates_discrepancy.py measures it over the whole matrix); on this sample the count must be
    consistent with it (one-sided exact binomial test at 1 %), and no cause may be missed more than twice."""
    results = [R.run_case(arm, arms[arm], p, (c,), seed, size_range=(0.1, 1.0), workdir=str(tmp_path))
               for arm in SLICE for p in SLICE[arm] for c in D.CAUSES for seed in range(3)]
    table = R.rates(results)
    assert table["variants_agree"] == 1.0
    qualifying = sum(table[c]["qualifying"] for c in D.CAUSES)
    named = sum(table[c]["named"] for c in D.CAUSES)
    assert qualifying >= 0.5 * len(results)
    assert _binomial_consistent(named, qualifying, 0.95, at_least=True), table
    assert all(table[c]["named"] >= table[c]["qualifying"] - 2 for c in D.CAUSES), table


@pytest.mark.parametrize("arm, n_cases", [("2-link", 90), ("3-link", 45), ("6-axis", 18)])
def test_clean_data_raise_false_alarms_at_most_alpha(arm, n_cases, arms, tmp_path):
    protocols = R.protocols_for(arms[arm])
    results = [R.run_case(arm, arms[arm], protocols[s % len(protocols)], (), 50_000 + s, workdir=str(tmp_path))
               for s in range(n_cases)]
    alarms = sum(r.false_alarm for r in results)
    assert all(r.agree for r in results)
    assert _binomial_consistent(alarms, n_cases, 0.01), alarms


@pytest.mark.parametrize("arm, protocol, effects", [
    ("2-link", "hanging x4, repeated", ("backlash", "measurement_offset")),
    ("3-link", "4 directions x 2, repeated", ("joint_coupling", "nonlinear_joint_stiffness")),
    ("6-axis", "3-D pushes x 2, repeated", ("link_compliance", "backlash")),
])
def test_two_effects_at_once_are_both_named(arm, protocol, effects, arms, tmp_path):
    results = [R.run_case(arm, arms[arm], protocol, effects, seed, size_range=(0.3, 1.0), workdir=str(tmp_path))
               for seed in range(6)]
    both = [r for r in results if min(r.power.values()) >= 0.9]
    assert len(both) >= 4
    for r in both:
        v = r.verdict_with_pose_id
        assert set(effects) <= {*v["causes"], *v["indistinguishable_from"]}, (r.seed, v["causes"])
        # the principal cause is a hidden effect, or one the data cannot tell from a hidden effect (for a planar
        # arm measured at the tool point a bending link acts like a compliance block on its joints)
        assert v["cause"] in effects or set(v["indistinguishable_from"]) & set(effects), (r.seed, v["cause"])
        assert r.agree


def test_an_effect_outside_the_catalogue_is_unexplained(arms, tmp_path):
    """A compliance that varies over the joint's turn (a gear whose stiffness is not constant) is no catalogue
    cause: where the oracle that knows its shape finds it (power >= 0.9) the verdict says unexplained. (A drift
    and a tilted load, which the catalogue absorbs, are warned of: tests/test_errormodel.py.)"""
    results = [R.run_case("2-link", arms["2-link"], "hanging x4, repeated", ("modulation",), seed,
                          size_range=(0.5, 1.0), workdir=str(tmp_path)) for seed in range(5)]
    strong = [r for r in results if r.power["modulation"] >= 0.9]
    assert len(strong) >= 4
    assert sum(r.verdict_with_pose_id["cause"] == "unexplained" for r in strong) >= len(strong) - 1


def test_link_compliance_and_coupling_are_indistinguishable_for_a_2_link_arm(arms, tmp_path):
    """For a planar arm a bending link acts like a 2 x 2 compliance block on its end joints, so with position
    measurements its span lies inside nominal + joint_coupling; for two links the spans coincide."""
    r = R.run_case("2-link", arms["2-link"], "4 directions x 2, repeated", ("link_compliance",), 1,
                   size_range=(0.5, 1.0), workdir=str(tmp_path))
    v = r.verdict_with_pose_id
    assert {*v["causes"], *v["indistinguishable_from"]} >= {"joint_coupling", "link_compliance"}
    assert v["equivalent_combinations"]
    assert any("no choice of poses" in text for text in v["separation"].values())


# --- blunders, the extended model, physics checks, degenerate data --------------------------------------------

def _simulated(robot, truth, seed, n_configs=30, protocol="4 directions x 2, repeated", blunders=None):
    rng = np.random.default_rng(seed)
    log = T.lab_log(robot, R.PROTOCOLS[protocol], rng, n_configs)
    dp = T.measure(robot, truth, log, rng, blunders)
    return Measurements.from_arrays(log.q, log.force, dp, config=log.config)


def test_blunders_are_listed_and_do_not_drive_the_verdict(paper_robot):
    truth = T.Truth(np.array([1.5e-6, 3e-6]), gap=np.full(2, 5e-5))
    for seed in range(4):
        v = D.analyse(paper_robot, _simulated(paper_robot, truth, seed, blunders={5: np.array([1e-3, 0.0]),
                                                                               77: np.array([0.0, -6e-4])}), gain=False)
        assert v["outlier_rows"] == [5, 77]
        assert v["cause"] == "backlash"


def test_extended_fit_recovers_the_hidden_parameters_and_gains(paper_robot):
    k = np.array([1.5e-6, 3e-6])
    meas = _simulated(paper_robot, T.Truth(k, offset=np.array([2e-5, -1.5e-5])), 3)
    v = D.analyse(paper_robot, meas, test_pose=np.radians([60, 30]), test_force=np.array([0, -300.0]))
    ext = v["extended"]
    assert ext["causes"] == ["measurement_offset"]
    assert np.all(np.abs(np.array(ext["parameters"]) - [2e-5, -1.5e-5]) <= np.array(ext["parameters_ci95"]) * 1.5)
    assert np.all(np.abs(np.array(ext["k"]) - k) <= np.array(ext["k_ci95"]) * 1.5)
    assert v["gain"]["loco_ratio"] > 1
    # an offset of the tracker is no deflection of the robot: the test-pose prediction ignores it
    assert v["gain"]["test_pose_model_error_m"] < 2e-6


def test_a_verdict_without_a_cause_says_why_its_gain_is_null(paper_robot):
    """Clean data with a test pose: cause none, no extended model, gain null, and a note says why."""
    meas = _simulated(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), 3)
    v = D.analyse(paper_robot, meas, test_pose=np.radians([60, 30]), test_force=np.array([0, -300.0]))
    assert v["cause"] == "none" and v["extended"] is None and v["gain"] is None
    assert any(n.startswith("gain is null: no catalogue cause is named") for n in v["notes"])


@pytest.mark.parametrize("force_scale, dp_scale, words", [
    (1.0, -1.0, "no identified joint compliance is above zero.*every one below.*unloaded minus loaded"),
    (-1.0, 1.0, "no identified joint compliance is above zero.*forces of the opposite sign"),
    (1e-3, 1.0, "end-effector compliance is .* far above serial robots.*kN"),
    (1.0, 1e-4, "end-effector compliance is .* far below serial robots.*micrometres")])
def test_data_no_elastic_robot_gives_are_refused_with_their_likely_cause(paper_robot, force_scale, dp_scale, words):
    """A fresh user's bad inputs that were analysed with only a note (and a calibrated model written): the
    displacements' or the forces' signs flipped (the robot yields against every load), forces in kN labelled N,
    micrometres in columns of metres. The clean data give no such note."""
    meas = _simulated(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), 0)
    bad = Measurements.from_arrays(meas.q, meas.force * force_scale, meas.dp * dp_scale, config=meas.config)
    with pytest.raises(InputError, match=words):
        D.analyse(paper_robot, bad, gain=False)
    good = D.analyse(paper_robot, meas, gain=False)
    assert not any("compliance" in n or "reach" in n for n in good["notes"])


def test_masses_in_kg_logged_as_newtons_are_noted_against_the_robot_files_compliances(paper_robot):
    """Every identified compliance 9.81 times the robot file's (the forces divided by g: masses in kg written in
    fz_N): a note names it; the true forces give none."""
    k = np.array([1.5e-6, 3e-6])
    robot = replace(paper_robot, compliances=k)
    meas = _simulated(robot, T.Truth(k), 0)
    kg = Measurements.from_arrays(meas.q, meas.force / 9.80665, meas.dp, config=meas.config)
    assert any("masses in kg logged as newtons" in n for n in D.analyse(robot, kg, gain=False)["notes"])
    assert not any("times the robot file's" in n for n in D.analyse(robot, meas, gain=False)["notes"])
    # a fresh user's Z1: the file's compliances only guesses (here 1.2 and 0.85 times the truth), so the ratios
    # are 11.8 and 8.3, not all within 15 % of 9.81: still noted, and the true forces still give no note
    guessed = replace(paper_robot, compliances=k * np.array([1 / 1.2, 1 / 0.85]))
    assert any("masses in kg logged as newtons" in n for n in D.analyse(guessed, kg, gain=False)["notes"])
    assert not any("times the robot file's" in n for n in D.analyse(guessed, meas, gain=False)["notes"])


def test_a_compliance_far_from_the_robot_file_s_is_named():
    """A fresh user's clean log (its 6R arm, seed 8) took k6 = 8.4e-5 +- 6.1e-5 rad/(N m), 42 times its file's value
    and its simulator's truth, in silence (a joint the hanging loads barely turn). Named now, with its ratio (the
    nominal model's k6 over the file's, computed here); seed 1, whose intervals hold the truth, gets no such note."""
    robot = load_robot(NEWUSER / "arm6_dh_masses.yaml")
    v = D.analyse(robot, read_measurements(NEWUSER / "arm6_clean_s8.csv", robot), 0.01, gain=False)
    k6 = v["nominal"]["k"][v["nominal"]["k_names"].index("k6")]
    assert k6 / robot.compliances[5] > 10
    assert any(f"k6 = {k6:.3g} +- " in n and f"({k6 / robot.compliances[5]:.3g} times 2e-06)" in n
               and "far from the robot file's" in n for n in v["notes"]), v["notes"]
    clean = D.analyse(robot, read_measurements(NEWUSER / "arm6_clean_s1.csv", robot), 0.01, gain=False)
    assert not any("far from the robot file's" in n for n in clean["notes"])


def test_an_arm_softer_than_the_range_is_analysed_when_its_robot_file_says_so(paper_robot):
    """A fresh user's assistive arm (Jaco2 at 1e-3..5e-3 rad/(N m), 7.7e-4 m/N) was refused as "millimetres or
    kN", with no way to analyse it. The refusal (which now also names masses in kg logged as newtons) says how: the
    robot file's nominal compliances; with them (within a factor of 10 of the data's) the data are analysed and the
    compliances found within their intervals; a robot file whose values are 100 times off does not lift it."""
    k0 = np.array([1.5e-6, 3e-6])
    stiff = _simulated(paper_robot, T.Truth(k0), 0)
    k = 1000.0 * k0  # the same deflections under loads 1000 times smaller
    meas = Measurements.from_arrays(stiff.q, stiff.force / 1000.0, stiff.dp, config=stiff.config)
    with pytest.raises(InputError, match=r"far above serial robots.*masses in kg logged as newtons.*give its nominal "
                                         r"compliances_rad_per_Nm in the robot file"):
        D.analyse(paper_robot, meas, gain=False)
    v = D.analyse(replace(paper_robot, compliances=2.0 * k), meas, gain=False)
    assert np.all(np.abs(np.array(v["nominal"]["k"]) - k) <= np.array(v["nominal"]["k_ci95"]))
    with pytest.raises(InputError, match="far above serial robots"):
        D.analyse(replace(paper_robot, compliances=k / 100), meas, gain=False)


def test_absolute_positions_instead_of_displacements_are_refused(paper_robot):
    meas = _simulated(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), 0)
    absolute = Measurements.from_arrays(meas.q, meas.force, paper_robot.fk(meas.q) + meas.dp, config=meas.config)
    with pytest.raises(InputError, match="absolute positions"):
        D.analyse(paper_robot, absolute, gain=False)


@pytest.mark.parametrize("kind", ["one force direction", "one configuration", "every row a replicate",
                                  "no replicates", "constant column"])
def test_degenerate_protocols_give_a_verdict_without_nan_or_a_clear_refusal(paper_robot, kind, rng):
    n = 24
    q = np.tile([0.3, 1.1], (n, 1)) if kind in ("one configuration", "every row a replicate") else \
        np.repeat(rng.uniform(-3, 3, (n // 4, 2)), 4, axis=0)
    f = np.tile([0.0, -300.0], (n, 1))
    if kind == "one configuration":
        f[:, 1] = -np.repeat([100.0, 200.0, 300.0, 400.0], n // 4)
    if kind == "no replicates":
        f[:, 1] = -rng.uniform(100, 400, n)
    if kind == "constant column":
        q[:, 1] = 0.7
    k = np.array([1.5e-6, 3e-6])
    dp = T.simulate(paper_robot, T.Truth(k), q, f, SIGMA, rng)
    meas = Measurements.from_arrays(q, f, dp)
    try:
        v = D.analyse(paper_robot, meas, test_pose=np.radians([60, 30]), test_force=np.array([0, -300.0]))
    except InputError as err:
        assert "cannot" in str(err) or "expected" in str(err)
        return
    json.dumps(v.to_dict(), allow_nan=False)  # raises on NaN or inf


def test_too_few_equations_and_singular_plans_are_refused(tmp_path):
    robot = planar_robot([0.5, 0.4, 0.3])
    p = tmp_path / "m.csv"
    p.write_text("q1_deg,q2_deg,q3_deg,fx_N,fy_N,dx_m,dy_m\n0,10,20,100,0,1e-4,2e-4\n")
    with pytest.raises(InputError, match="at least 3 equations"):
        D.check_identifiable(robot, read_measurements(p, robot))
    two = planar_robot([0.6, 0.4])
    p.write_text("q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n0,0,100,0,1e-4,2e-4\n0,0,200,0,1e-4,2e-4\n")  # force along the arm
    with pytest.raises(InputError, match="rank 0.*no compliance is left"):
        D.check_identifiable(two, read_measurements(p, two))


def test_a_joint_the_loads_never_turn_is_left_out_with_a_note(root):
    """Hanging weights never turn the KR 210's vertical axis 1: the analysis leaves k1 out with a note (it used
    to refuse the data) and still names the hidden coupling of joints 2-3, fits the other compliances to their
    simulated values and computes the gain."""
    robot = load_robot(root / "config/robots/kuka_kr210_r2700.yaml")
    rng = np.random.default_rng(0)
    log = T.lab_log(robot, T.Protocol("hanging"), rng, 20)
    C = np.zeros((6, 6))
    C[1, 2] = C[2, 1] = 0.5 * robot.compliances[1]
    meas = Measurements.from_arrays(log.q, log.force, T.measure(robot, T.Truth(robot.compliances, C), log, rng))
    assert list(D.check_identifiable(robot, meas)) == [0]
    v = D.analyse(robot, meas, 0.01, test_pose=np.radians([10, -60, 80, 0, 30, 0]), test_force=np.array([0, 0, -300.0]))
    nom = v["nominal"]
    assert nom["not_identifiable_joints"] == [1] and nom["k_joints"] == [2, 3, 4, 5, 6]
    assert nom["k_names"] == [robot.joint_columns("k")[j - 1] for j in nom["k_joints"]]
    assert any(n.startswith("joint 1 never deflects") and "left out of the analysis" in n for n in v["notes"])
    assert v["causes"] == ["joint_coupling"]
    k_ext = np.array(v["extended"]["k"])
    assert np.all(np.abs(k_ext - robot.compliances[1:]) <= 2 * np.array(v["extended"]["k_ci95"]))
    assert v["gain"]["loco_ratio"] > 1 and v["gain"]["test_pose_rms_extended_m"] > 0
    json.dumps(v.to_dict(), allow_nan=False)


def _hanging_rows_of_ur10_bar(tmp_path) -> Path:
    """The UR10 loading-bar file without its pushes: hanging weights (and their bar's moment) only."""
    lines = (LAB_DIR / "ur10_bar.csv").read_text().splitlines()
    head = lines[0].split(",")
    fx, fy = head.index("fx_N"), head.index("fy_N")
    keep = [ln for ln in lines[1:] if float(ln.split(",")[fx]) == 0 and float(ln.split(",")[fy]) == 0]
    path = tmp_path / "ur10_hanging.csv"
    path.write_text("\n".join([lines[0], *keep]) + "\n")
    return path


def test_ur10_hanging_weights_analyse_and_plan_without_joint_1(tmp_path, capsys):
    """The user's UR10 file with hanging weights only: `stiffcal discrepancy` (which refused it: rank 4 of 5) gives a
    verdict without shoulder_pan_joint whose compliances match make_ur10.py's k_true, and `stiffcal discriminate`
    plans on the same data, k1 null in its models."""
    data = _hanging_rows_of_ur10_bar(tmp_path)
    robot = str(LAB_DIR / "ur10.yaml")
    assert main(["discrepancy", "--robot", robot, "--data", str(data), "--out", str(tmp_path / "v")]) == 0
    v = json.loads((tmp_path / "v/verdict.json").read_text())
    nom = v["nominal"]
    assert nom["not_identifiable_joints"] == [1, 6] and nom["k_joints"] == [2, 3, 4, 5]
    k_true = np.array([1.9e-6, 4.3e-6, 1.1e-5, 0.9e-5])  # tests/data/lab/make_ur10.py, joints 2-5
    assert np.all(np.abs(np.array(nom["k"]) - k_true) <= 2 * np.array(nom["k_ci95"]))
    assert any("shoulder_pan_joint (joint 1) never deflects" in n for n in v["notes"])
    assert main(["discriminate", "--robot", robot, "--data", str(data), "--experiments", "4",
                 "--out", str(tmp_path / "p")]) == 0
    plan = json.loads((tmp_path / "p/plan.json").read_text())
    assert all(m["parameters"][0] is None and None not in m["parameters"][1:] for m in plan["models"])
    assert any("shoulder_pan_joint" in n and "null" in n for n in plan["notes"])
    capsys.readouterr()


def test_joints_acting_in_a_fixed_combination_are_refused_naming_them(paper_robot):
    """A straight 2-link arm (q2 = 0 in every row) under forces across it: joints 1 and 2 deflect the tool point
    along the same direction with the fixed ratio ((l1 + l2) / l2)^2, so only that combination is identified; the
    loss of rank is not one joint's column, and the data are refused naming both joints."""
    rng = np.random.default_rng(3)
    q = np.column_stack([rng.uniform(-3, 3, 12), np.zeros(12)])
    u = np.column_stack([-np.sin(q[:, 0]), np.cos(q[:, 0])])  # across the straight arm
    f = 300.0 * u * rng.choice([-1.0, 1.0], (12, 1))
    dp = T.simulate(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), q, f, SIGMA, rng)
    X = D.nominal_columns(paper_robot, q, f).reshape(-1, 2)
    assert np.linalg.matrix_rank(X / np.linalg.norm(X, axis=0), 1e-9) == 1  # independent: numpy's rank
    with pytest.raises(InputError, match="joints 1, 2 act only in a fixed combination"):
        D.analyse(paper_robot, Measurements.from_arrays(q, f, dp))


def test_every_row_one_configuration_and_one_load_is_refused(paper_robot, rng):
    # q1 + q2 = 90 deg would put the vertical force through joint 2 (its torque round-off: not identifiable)
    q = np.tile(np.radians([10.0, 70.0]), (30, 1))
    f = np.tile([0.0, -300.0], (30, 1))
    dp = T.simulate(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), q, f, SIGMA, rng)
    with pytest.raises(InputError, match="cannot test any cause: their 30 loaded rows hold 1 distinct"):
        D.analyse(paper_robot, Measurements.from_arrays(q, f, dp))


def test_no_degree_of_freedom_for_the_noise_is_refused(paper_robot):
    q = np.radians([[10, 20], [50, 80]])
    f = np.array([[0, -100.0], [100.0, 0]])
    meas = Measurements.from_arrays(q, f, np.array([[1e-5, -2e-5], [3e-5, 1e-5]]))
    with pytest.raises(InputError, match="no degree of freedom"):
        D.analyse(paper_robot, meas)


# --- bad measured data ----------------------------------------------------------------------------------

GOOD = "pose_id,q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n0,10,20,100,0,1e-4,2e-4\n1,40,70,0,-200,3e-4,-1e-4\n"


@pytest.mark.parametrize("text, message", [
    (GOOD.replace("dx_m", "dx_mm"), "column dx_mm': expected displacements in m"),
    (GOOD.replace("dx_m", "dx"), "column dx': expected displacements in m"),
    (GOOD.replace("q1_deg", "q1_rad"), "column q1_rad': expected joint angles in deg"),
    (GOOD.replace(",dy_m", "").replace(",2e-4", "").replace(",-1e-4", ""), "missing column(s) dy_m"),
    (GOOD.replace("1e-4,2e-4", "1e-4,nan"), "row 2 (data row 0), column dy_m': expected a finite number"),
    (GOOD.replace("3e-4", "inf"), "row 3 (data row 1), column dx_m': expected a finite number"),
    (GOOD.replace("40,70", "forty,70"), "column q1_deg': expected a finite number, got 'forty'"),
    (GOOD.replace("3e-4", "3e295"), "row 3 (data row 1), column dx_m': expected displacements of at most 100 m"),
    (GOOD.replace("0,-200", "0,-2e12"), "column fy_N': expected force components of at most 1e+07 N"),
    ("q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n", "no measurements"),
    (GOOD.replace("q2_deg,", "q2_deg,q3_deg,").replace("10,20", "10,20,5").replace("40,70", "40,70,5"),
     "expected 2 joint angles"),
])
def test_bad_csv_gets_one_clear_error(tmp_path, paper_robot, text, message):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_measurements(p, paper_robot)
    assert str(err.value).startswith(str(p)) and message in str(err.value)


def test_no_figures_writes_the_same_verdict_and_model_without_figures(tmp_path, root, capsys):
    """`--no-figures` (batch runs): verdict.json and calibrated.yaml byte for byte those of the full run, and no
    figure file."""
    args = ["discrepancy", "--robot", str(root / "config/robots/paper_2r.yaml"), "--data",
            str(root / "data/synthetic_paper_2r.csv"), "--test-pose-deg", "60,30", "--force-N", "0,-300", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "full")]) == 0
    assert main([*args, "--out", str(tmp_path / "bare"), "--no-figures"]) == 0
    assert sorted(p.name for p in (tmp_path / "bare").iterdir()) == ["calibrated.yaml", "verdict.json"]
    for name in ("calibrated.yaml", "verdict.json"):
        assert (tmp_path / "bare" / name).read_bytes() == (tmp_path / "full" / name).read_bytes()
    assert {p.suffix for p in (tmp_path / "full").iterdir()} == {".yaml", ".json", ".png", ".svg"}
    capsys.readouterr()


def test_cli_writes_the_verdict_and_nothing_on_bad_data(tmp_path, root, capsys):
    out = tmp_path / "out"
    rc = main(["discrepancy", "--robot", str(root / "config/robots/paper_2r.yaml"), "--data",
               str(root / "data/synthetic_paper_2r.csv"), "--out", str(out), "--test-pose-deg", "60,30",
               "--force-N", "0,-300"])
    assert rc == 0
    v = json.loads((out / "verdict.json").read_text())
    assert v["cause"] == "backlash" and v["outlier_rows"] == [17]
    for key in ("causes", "indistinguishable_from", "p_value", "nominal", "extended", "gain", "structure", "notes"):
        assert key in v
    assert (out / "residuals.png").stat().st_size > 0
    bad = tmp_path / "bad.csv"
    bad.write_text(GOOD.replace("dx_m", "dx_mm"))
    rc = main(["discrepancy", "--robot", str(root / "config/robots/paper_2r.yaml"), "--data", str(bad),
               "--out", str(tmp_path / "none")])
    assert rc == 2 and not (tmp_path / "none").exists()
    assert "dx_mm" in capsys.readouterr().err


def test_resolutions_decide_the_replicate_groups_in_the_reader_and_the_cli(tmp_path, paper_robot, root):
    p = _write(tmp_path, LAB)
    for res, groups in ((0.5, 4), (0.01, 5)):  # 100 N and 100.3 N: one load at 0.5 N, two at 0.01 N
        assert read_measurements(p, paper_robot, force_resolution_N=res).structure()["n_replicate_groups"] == groups
    data = str(root / "data/synthetic_paper_2r.csv")
    robot = str(root / "config/robots/paper_2r.yaml")
    for res in ("0.5", "1e-9"):
        out = tmp_path / f"out{res}"
        args = ["discrepancy", "--robot", robot, "--data", data, "--out", str(out), "--force-resolution-N", res]
        assert main(args) == 0
        v = json.loads((out / "verdict.json").read_text())
        assert v["structure"]["force_resolution_N"] == float(res)
    assert main(["discrepancy", "--robot", robot, "--data", data, "--out", str(tmp_path / "x"),
                 "--angle-resolution-deg", "-1"]) == 2


# --- a new user's lab logs (tests/data/lab: made by make_3r.py and make_ur10.py beside them) -----------------

LAB_DIR = Path(__file__).parent / "data" / "lab"


@pytest.fixture(scope="module")
def lab3_verdict():
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    return D.analyse(robot, read_measurements(LAB_DIR / "lab_3r_coupling.csv", robot), 0.01, gain=False)


@pytest.fixture(scope="module")
def ur10_verdict():
    robot = load_robot(LAB_DIR / "ur10.yaml")
    return D.analyse(robot, read_measurements(LAB_DIR / "ur10_bar.csv", robot), 0.01, gain=False)


def _verdict_sentence(v: dict) -> str:
    """The report's verdict paragraph (its first template line) rendered with the report's filters."""
    import jinja2

    from stiffcal.report import html as report

    lines = (Path(report.TEMPLATE_DIR) / "report.html.j2").read_text().splitlines()
    line = next(t for t in lines if t.startswith("<p><b>Verdict:"))
    env = jinja2.Environment(undefined=jinja2.StrictUndefined)
    env.filters["num"] = report.fmt
    return env.from_string(line).render(v=v)


def test_verdict_p_value_names_the_set_it_is_about(lab3_verdict):
    """A verdict that names a cause beside indistinguishable ones gives the adjusted p of the intersection
    "none of them is needed", which is never above any member's own adjusted p (the closed test rejects an
    intersection before its members); the JSON and the report say so, and say when no member is needed on its
    own (the 3-link coupling case: joint_coupling's own adjusted p 0.45 beside p = 2.7e-204 for the set; the clean
    UR10 under a loading bar was a second case, a false alarm of the global test at p = 0.008, until its moments'
    offset test, at p = 0.009, explained the same rows: an effect outside the catalogue, the verdict's explanation)."""
    v = lab3_verdict
    assert v["indistinguishable_from"]
    members = [v["cause"], *v["indistinguishable_from"]]
    assert v["p_value_of"] == members
    own = [v["tests"][c]["adjusted_p_value"] for c in members]
    assert v["p_value"] <= min(own) + 1e-15 and v["p_value"] <= v["alpha"]
    assert all(c in v["p_value_statement"] for c in members) and "at least one of" in v["p_value_statement"]
    alone = [v["tests"][c]["significant"] for c in members]
    assert not any(alone) and "none of them is needed on its own" in v["p_value_statement"]
    html = _verdict_sentence(v)
    assert "at least one of" in html and "cannot be told apart" in html
    assert "none of them is needed on its own" in html


def test_the_report_renders_a_gain_whose_statistics_are_null():
    """A fresh user's Panda workflow: the report job crashed (TypeError: float * NoneType) on a verdict whose
    gain.optimal_plan_extended_rms_m was null, as the contract allows, and took the archive with it. The report's
    gain paragraph (its template lines, with the report's filters) renders every null statistic as words."""
    import jinja2

    from stiffcal.report import html as report

    text = (Path(report.TEMPLATE_DIR) / "report.html.j2").read_text()
    macro = next(t for t in text.splitlines() if t.startswith("{% macro um("))
    start = text.index("{% if v.gain %}")
    end = text.index("{% endif %}", text.index("</p>", text.index("would give", start)))
    block = text[start:end + len("{% endif %}")]
    env = jinja2.Environment(undefined=jinja2.StrictUndefined)
    env.filters["num"] = report.fmt
    gain = {"loco_ratio": 0.5, "loco_rms_nominal_m": 2e-5, "loco_rms_extended_m": 1e-5, "test_pose_rms_nominal_m": 3e-5,
            "test_pose_model_error_m": 1e-5, "test_pose_rms_extended_m": None, "optimal_plan_extended_deg": [[0, 1]],
            "optimal_plan_extended_rms_m": None, "nominal_plan_deg": [[1, 2]],
            "nominal_plan_under_extended_rms_m": None}
    html = env.from_string(macro + block).render(v={"gain": gain, "extended": {"cause": "backlash"}})
    assert "O<sub>t</sub> infinite" in html and "not computed" in html and "no estimate of the extension" in html


def test_gain_statistic_of_a_singular_plan_is_the_variance_of_what_it_estimates():
    """On the UR10 loading-bar data the nominal model's plan of 4 poses under one test load does not identify the
    extended model (its information matrix, built here from model_columns, is singular), and the gain said null.
    The test pose's deflection X_t b is estimable from it all the same (X_t lies in the plan's row space, checked
    here by the ranks), so its variance is sigma^2 tr(X_t M^+ X_t^T) for any generalised inverse (Searle 1971,
    sec. 5.4), computed here as ||X_t A^+||^2 by numpy's least squares on unit-norm columns at the printed poses
    (rounded to 1e-3 deg: the gain's own value at the unrounded ones agrees to 1e-4); a statistic that is not finite
    would still be null with a note (the contract)."""
    robot = load_robot(LAB_DIR / "ur10.yaml")
    meas = read_measurements(LAB_DIR / "ur10_bar.csv", robot)
    load = np.array([0.0, 0.0, -300.0])
    qt = np.radians([10, -60, 80, -100, -90, 0])
    v = D.analyse(robot, meas, 0.01, test_pose=qt, test_force=load)
    g = v["gain"]
    causes = v["extended"]["causes"]
    X = D.model_columns(robot, np.radians(g["nominal_plan_deg"]), np.tile(load, (len(g["nominal_plan_deg"]), 1)),
                        causes)
    A = X.reshape(-1, X.shape[-1])
    norm = np.linalg.norm(A, axis=0)
    norm = np.where(norm > 0, norm, 1.0)
    As = A / norm
    Xt = D.model_columns(robot, qt[None], load[None], causes, predict=True, observed=D.Observed().at_tool(robot))[0]
    Xts = Xt / norm
    assert np.linalg.matrix_rank(As) < A.shape[1]
    assert np.linalg.matrix_rank(np.vstack([As, Xts])) == np.linalg.matrix_rank(As)
    ot = np.sum(np.linalg.lstsq(As.T, Xts.T, rcond=None)[0] ** 2)  # ||X_t A^+||^2 = tr(X_t (A^T A)^+ X_t^T)
    assert D._ot_of(X, Xt) == pytest.approx(ot, rel=1e-9)
    assert g["nominal_plan_under_extended_rms_m"] == pytest.approx(v["nominal"]["sigma_m"] * np.sqrt(ot), rel=1e-4)
    for key in ("optimal_plan_extended_rms_m", "nominal_plan_under_extended_rms_m"):
        assert g[key] is not None or any(n.startswith(f"gain.{key} is left out") for n in v["notes"])


# --- the unloaded rows: a blunder among them is named, a common shift is the zero point that moved --------------

def test_a_blunder_in_an_unloaded_row_of_the_ur10_file_is_named(ur10_verdict):
    """make_ur10.py adds (0, -0.6, 0.3) mm to data row 40, an unloaded row: the verdict names it (it used to say
    only that the zero point moved) and the other unloaded rows, exactly zero, are the reference."""
    zp = ur10_verdict["zero_point"]
    assert zp["outlier_rows"] == [40]
    assert "row 42 (data row 40) stands out" in zp["note"] and "zero point moved" not in zp["note"]


# (the unloaded rows' blunder screen and zero-point test over seeds: tests/test_errormodel.py)


# --- common file mistakes the reader names ------------------------------------------------------------------------

def _lab_file(tmp_path, name, edit, src="lab_3r_coupling.csv"):
    """A copy of a lab file with ``edit`` (header list, rows list of lists) -> (header, rows) applied."""
    lines = (LAB_DIR / src).read_text().splitlines()
    header, rows = edit(lines[0].split(","), [ln.split(",") for ln in lines[1:]])
    path = tmp_path / name
    path.write_text("\n".join(",".join(r) for r in [header, *rows]) + "\n")
    return path


@pytest.mark.parametrize("turn", [False, True])
def test_angles_in_radians_in_degree_columns_are_named(tmp_path, turn):
    """The UR10 file with its joint angles written in radians under q_*_deg: read with a note that they look like
    radians (every |q| < 6.4 deg over 160 rows of a robot whose joints range over 720 deg), and refused by the
    analysis, whose nominal model then misfits grossly (before, a verdict beside the note); the original file has
    no such note. ``turn``: the radians as a controller reports them from 0 to 2 pi (a fresh user's Kinova Jaco2:
    angles 0.8-5.9 were analysed to `unexplained` with a calibrated.yaml). Poses truly within 3 deg of the zero
    pose are analysed (the next test)."""
    robot = load_robot(LAB_DIR / "ur10.yaml")

    def to_rad(header, rows):
        cols = [i for i, c in enumerate(header) if c.startswith("q_")]
        wrap = (lambda a: a % (2 * np.pi)) if turn else (lambda a: a)
        return header, [[f"{wrap(np.radians(float(v))):.6f}" if i in cols else v for i, v in enumerate(r)]
                        for r in rows]

    meas = read_measurements(_lab_file(tmp_path, "rad.csv", to_rad, "ur10_bar.csv"), robot)
    assert any("q_shoulder_pan_joint_deg" in n and "160 rows" in n and "look like radians" in n for n in meas.notes)
    with pytest.raises(InputError, match=r"rad.csv.*columns q_shoulder_pan_joint_deg.*80 rows.*misfits.*look "
                                         r"like radians"):
        D.analyse(robot, meas, 0.01, gain=False)
    assert not any("radians" in n for n in read_measurements(LAB_DIR / "ur10_bar.csv", robot).notes)


def test_a_stretched_arm_with_a_real_effect_is_not_refused_as_radians():
    """A fresh user's planar 3R with masses, measured within 6 deg of its stretched-out zero pose under hanging masses
    with a real 50 um offset along the vertical (its own simulator): refused as "angles in radians" (every angle near
    zero, the nominal model misfitting: the offset) in 8 of 8 logs, the same arms' clean logs analysed. The angles
    read as radians fit no better, so they are degrees: the offset is named, with a note."""
    robot = load_robot(NEWUSER / "r3_masses.yaml")
    meas = read_measurements(NEWUSER / "r3_stretched_offset_s1.csv", robot)
    assert np.abs(np.degrees(meas.q)).max() < 6.4
    v = D.analyse(robot, meas, 0.01, gain=False)
    assert v["cause"] == "measurement_offset"
    assert any("read as radians they fit no better" in n for n in v["notes"])


def test_poses_within_three_degrees_of_a_bent_home_pose_are_analysed(rng):
    """A fresh user's 6-axis arm measured within +-3 deg of its zero pose (bent by its DH offsets) was refused as
    "radians in degree columns": the data are valid, the nominal model fits them (no refusal), and the compliances
    are within their intervals of the truth in at least 5 of the 6 joints."""
    robot = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    q = np.radians(rng.uniform(-3.0, 3.0, (40, robot.n_joints)))
    q = np.repeat(q, 3, axis=0)
    f = np.tile([[600.0, 0.0, 0.0], [0.0, 600.0, 0.0], [0.0, 0.0, -600.0]], (40, 1))
    k = R.compliances(robot)
    dp = T.simulate(robot, T.Truth(k), q, f, 1e-5, rng)
    v = D.analyse(robot, Measurements.from_arrays(q, f, dp), 0.01, gain=False)
    nom = v["nominal"]
    inside = np.abs(np.array(nom["k"]) - k[np.array(nom["k_joints"]) - 1]) <= np.array(nom["k_ci95"])
    assert inside.sum() >= len(inside) - 1, (nom["k"], nom["k_ci95"])


def test_forces_in_kilonewtons_are_suspected_when_every_row_looks_unloaded(tmp_path):
    """The 3-link lab file with forces and moments in kN / kN m (0.1 and 0.25): every row is within the force
    resolution; the message says so, gives the resolution and the largest force, and suggests kN."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")

    def to_kn(header, rows):
        cols = [header.index(c) for c in ("fx_N", "fy_N", "mz_Nm")]
        return header, [[f"{float(v) / 1000:.4f}" if i in cols else v for i, v in enumerate(r)] for r in rows]

    with pytest.raises(InputError, match=r"every row is unloaded.*largest force component is 0.25 N, below the force "
                                         r"resolution of 0.5 N: if the forces are in kN") as err:
        read_measurements(_lab_file(tmp_path, "kn.csv", to_kn), robot)
    assert "kn.csv" in str(err.value)


@pytest.mark.parametrize("sep, what", [(";", "';' \\(semicolons\\)"), ("\t", "tabs")])
def test_a_file_separated_by_another_character_is_named(tmp_path, sep, what):
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = tmp_path / "sep.csv"
    path.write_text((LAB_DIR / "lab_3r_coupling.csv").read_text().replace(",", sep))
    with pytest.raises(InputError, match=f"sep.csv.*missing columns: the header is one column separated by {what}.*"
                                         "must be comma-separated"):
        read_measurements(path, robot)


def test_a_column_name_given_twice_is_refused_naming_it(tmp_path):
    """pandas would read the second dx_m as 'dx_m.1' and the message would be about an unknown column; the
    reader names the repeated column and where it is."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = _lab_file(tmp_path, "twice.csv", lambda h, rows: (h + ["dx_m"], [r + [r[-1]] for r in rows]))
    with pytest.raises(InputError, match=r"twice.csv.*column dx_m.*more than once: dx_m \(header columns 11, 12\)"):
        read_measurements(path, robot)


def test_absolute_positions_and_millimetres_labelled_metres_are_refused(tmp_path):
    """Absolute positions in the d*_m columns (each loaded row 0.5 m off) and the file's deflections (about 0.2 mm)
    written in mm under columns in m: both over 2 % of the 3-link arm's 1.15 m reach, refused naming the columns;
    so are deflections 200 times their size (2-10 % of the reach; before, these were read and only noted), and
    by the analysis too when given as arrays."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")

    def shifted(by, scale):
        def edit(h, rows):
            cols = [h.index(c) for c in ("dx_m", "dy_m")]
            loaded = [any(float(r[h.index(f)]) != 0 for f in ("fx_N", "fy_N", "mz_Nm")) for r in rows]
            return h, [[f"{float(v) * scale + (by if on else 0.0):.6e}" if i in cols else v for i, v in enumerate(r)]
                       for r, on in zip(rows, loaded)]
        return edit

    for name, by, scale in (("absolute.csv", 0.5, 1.0), ("mm.csv", 0.0, 1000.0), ("large.csv", 0.0, 200.0)):
        with pytest.raises(InputError, match=rf"{name}.*columns dx_m, dy_m.*expected deflections.*% of the arm's "
                                             r"reach.*absolute positions, or millimetres"):
            read_measurements(_lab_file(tmp_path, name, shifted(by, scale)), robot)

    def one_in_mm(h, rows):  # a fresh user's dz_m alone in mm: the column is named, with each column's median
        j = h.index("dy_m")
        return h, [[f"{float(v) * 1000.0:.6e}" if i == j else v for i, v in enumerate(r)] for r in rows]
    with pytest.raises(InputError, match=r"one.csv: field 'column dy_m'.*millimetres.*dy_m [0-9.e-]+ m in the median, "
                                         r"the other column\(s\) [0-9.e-]+ m"):
        read_measurements(_lab_file(tmp_path, "one.csv", one_in_mm), robot)
    meas = read_measurements(LAB_DIR / "lab_3r_coupling.csv", robot)
    large = Measurements.from_arrays(meas.q, meas.force, meas.dp * 200.0, moment=meas.moment)
    size = np.median(np.linalg.norm(large.dp, axis=1)) / robot.reach_m
    assert 0.02 < size < 0.10, size
    with pytest.raises(InputError, match=r"% of the arm's reach"):
        D.analyse(robot, large, gain=False)


@pytest.mark.parametrize("edit, words", [
    (lambda h, rows: ([], []), r"empty.csv.*the file is empty: expected a CSV table"),
    (lambda h, rows: (h, rows[:3] + [[f'"{v.replace(".", ",")}"' if j == h.index("q2_deg") else v
                                      for j, v in enumerate(rows[3])]] + rows[4:]),
     r"empty.csv.*row 5 \(data row 3\), column q2_deg.*a decimal comma\? write numbers with a decimal point"),
    (lambda h, rows: (h, rows[:3] + [[f'"{float(v):.2e}"'.replace(".", ",") if j == h.index("dx_m") else v
                                      for j, v in enumerate(rows[3])]] + rows[4:]),  # a fresh user's '-8,44e-05'
     r"empty.csv.*row 5 \(data row 3\), column dx_m.*got '[-0-9]+,[0-9]+e[-+][0-9]+': a decimal comma\?"),
])
def test_an_empty_file_and_a_decimal_comma_are_named(tmp_path, edit, words):
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = _lab_file(tmp_path, "empty.csv", edit)
    if not path.read_text().strip():
        path.write_text("")
    with pytest.raises(InputError, match=words):
        read_measurements(path, robot)


def test_a_latin1_file_is_named_with_its_row_and_a_trailing_comma_is_a_note(tmp_path):
    """A degree sign written in Latin-1 on data row 3 (file row 5): the message names row 5 and says to save the
    file as UTF-8; a comma at the end of every line (an empty header cell) is ignored with one note, not named as
    an unused column 'Unnamed: 11'."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = _lab_file(tmp_path, "latin.csv", lambda h, rows: (h + ["remark"], [r + ["" if i != 3 else "25 C"]
                                                                             for i, r in enumerate(rows)]))
    path.write_bytes(path.read_bytes().replace(b"25 C", "25 \u00b0C".encode("latin-1")))
    with pytest.raises(InputError, match=r"latin.csv.*row 5.*not UTF-8 text: byte 0xb0.*save it as UTF-8"):
        read_measurements(path, robot)
    trailing = _lab_file(tmp_path, "trailing.csv", lambda h, rows: (h + [""], [r + [""] for r in rows]))
    notes = read_measurements(trailing, robot).notes
    assert any("without a name and blank in every row (a comma at the end of every line?)" in n for n in notes)
    assert not any("Unnamed" in n for n in notes), notes


def test_joint_columns_named_as_ros_logs_them_get_the_naming_hint(tmp_path):
    """Columns named by the joints alone (a ROS joint_states export) are not read as angles: the message names them
    and says how to name them (q_<name>_deg or q<i>_deg)."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    names = robot.joint_names
    path = _lab_file(tmp_path, "ros.csv", lambda h, rows: ([names[int(c[1]) - 1] if re.fullmatch(r"q\d_deg", c)
                                                             else c for c in h], rows))
    with pytest.raises(InputError, match=rf"ros.csv.*missing column.*the robot's joint names without unit: name each "
                                         rf"q_<name>_deg \('q_{re.escape(names[2])}_deg'"):
        read_measurements(path, robot)


@pytest.mark.parametrize("char, column", [("\x00", "pose_id"), ("\x1b", "dx_m"), ("\x7f", "q2_deg")])
def test_a_control_character_in_a_cell_is_refused_naming_row_and_column(tmp_path, char, column):
    """A NUL inside a pose_id would make one configuration's rows two configurations, silently; an escape or DEL
    in a number is a damaged file: each is named by row and column (the character's code point too)."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")

    def damage(h, rows):
        j = h.index(column)
        rows = [list(r) for r in rows]
        rows[3][j] = rows[3][j][:1] + char + rows[3][j][1:]
        return h, rows

    path = _lab_file(tmp_path, "ctrl.csv", damage)
    with pytest.raises(InputError, match=rf"ctrl.csv.*row 5 \(data row 3\), column {column}.*control character "
                                         rf"\(U\+{ord(char):04X}\)"):
        read_measurements(path, robot)


@pytest.mark.parametrize("extra, words", [(lambda r: r + ["7"], "got 12: a comma too many"),
                                          (lambda r: r[:-1], "got 10: a comma too few")])
def test_a_row_with_a_field_too_many_or_too_few_is_refused(tmp_path, extra, words):
    """One data row with a surplus field: pandas would take the first column of every row as the index and shift
    the columns (reading q2 as q1); one row short of a field: a blank cell. Both are named by their row."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = _lab_file(tmp_path, "ragged.csv", lambda h, rows: (h, rows[:3] + [extra(rows[3])] + rows[4:]))
    with pytest.raises(InputError, match=rf"ragged.csv.*row 5 \(data row 3\).*expected 11 fields.*{words}"):
        read_measurements(path, robot)


def test_exact_duplicate_rows_are_named_and_kept(tmp_path):
    """Loaded data row 1 pasted again at the end: a note names both file rows; the row is kept (a replicate)."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")
    path = _lab_file(tmp_path, "dup.csv", lambda h, rows: (h, rows + [rows[1]]))
    meas = read_measurements(path, robot)
    n = len((LAB_DIR / "lab_3r_coupling.csv").read_text().splitlines()) - 1
    note = [x for x in meas.notes if "repeat an earlier row exactly" in x]
    assert len(note) == 1 and f"row {n + 2} (data row {n}) repeats row 3 (data row 1)" in note[0]
    assert n in meas.rows and len(np.unique(meas.group[np.isin(meas.rows, [1, n])])) == 1
    assert not any("repeat an earlier" in x for x in read_measurements(LAB_DIR / "lab_3r_coupling.csv", robot).notes)


def test_angles_outside_the_joint_limits_are_named(tmp_path):
    """lab_3r.yaml limits joint 2 to [-150, 150] deg: configuration cfg0 moved to q2 = 155 deg is named with its
    rows (every row of cfg0 is checked against the limits independently here)."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")

    def move(header, rows):
        i, p = header.index("q2_deg"), header.index("pose_id")
        return header, [[("155" if k == i and r[p] == "cfg0" else v) for k, v in enumerate(r)] for r in rows]

    path = _lab_file(tmp_path, "lim.csv", move)
    moved = [k for k, ln in enumerate(path.read_text().splitlines()[1:]) if ln.split(",")[1] == "cfg0"]
    note = [x for x in read_measurements(path, robot).notes if "outside the joint limits" in x]
    assert len(note) == 1 and note[0].startswith("q2_deg is outside the joint limits")
    assert f"[-150, 150] deg) in {len(moved)} rows {moved[0] + 2}, {moved[1] + 2}" in note[0]
    assert not any("joint limits" in x for x in read_measurements(LAB_DIR / "lab_3r_coupling.csv", robot).notes)


@pytest.mark.parametrize("q2, named", [("150.0005", False), ("150.01", True)])
def test_an_angle_at_a_limit_in_the_logged_digits_is_not_named(tmp_path, q2, named):
    """A plan's pose at a joint limit, logged to the controller's digits, may print a few 1e-4 deg beyond it (a fresh
    user's iiwa: a URDF limit of 3.05432619 rad logged as 175.0000 deg was named on 32 rows): within
    LIMIT_TOLERANCE_DEG no note, beyond it the note."""
    robot = load_robot(LAB_DIR / "lab_3r.yaml")

    def move(header, rows):
        i, p = header.index("q2_deg"), header.index("pose_id")
        return header, [[(q2 if k == i and r[p] == "cfg0" else v) for k, v in enumerate(r)] for r in rows]

    notes = read_measurements(_lab_file(tmp_path, "lim.csv", move), robot).notes
    assert any("outside the joint limits" in x for x in notes) == named


def test_a_joint_whose_axis_passes_through_the_measured_point_is_left_out_with_a_note():
    """The new user's UR10 (tool point on wrist 3's axis), positions only: the Jacobian's column of wrist 3 is
    zero at every pose of the file (checked directly), the verdict lists joint 6 as not identifiable and says
    why in a note (docs/measured-data.md: left out "with a note")."""
    from stiffcal.measured.measurements import read_measurements

    lab = LAB_DIR
    robot = load_robot(lab / "ur10.yaml")
    meas = read_measurements(lab / "ur10_bar.csv", robot)
    assert np.abs(robot.jacobian(meas.q)[..., 5]).max() < 1e-12
    v = D.analyse(robot, meas, gain=False)
    assert v["nominal"]["not_identifiable_joints"] == [6]
    assert any("wrist_3_joint (joint 6)" in n and "not_identifiable_joints" in n for n in v["notes"])


@pytest.mark.parametrize("p_min, weighted", [(0.05, False), (0.004, False), (2e-5, False), (0.004, True)])
def test_min_p_value_equals_a_brute_force_monte_carlo_of_its_null(p_min, weighted):
    """The closed test's min-P p-value (importance sampling) against a plain Monte Carlo of the same null:
    F-tests of overlapping column blocks added to one common model, sharing a chi^2 error variance; with
    weights (a block and its parameters alone, as the closed test weights them), P(some p_m <= w_m p_min)."""
    rng = np.random.default_rng(3)
    P, df = 14, 30
    X = rng.standard_normal((P, 9))
    X[:, 5:7] = X[:, 2:4] + 0.4 * rng.standard_normal((P, 2))  # two causes that look alike
    base = np.linalg.qr(X[:, :2])[0]
    blocks = [[2, 3, 4], [5, 6], [7, 8]] + ([[2], [3], [4]] if weighted else [])
    spaces = [D._beyond(base, np.linalg.qr(X[:, list(range(2)) + cols])[0]) for cols in blocks]
    w = np.array([0.5 / 3, 1 / 3, 1 / 3] + [0.5 / 9] * 3) if weighted else np.ones(3)
    r = np.array([W.shape[1] for W in spaces])
    n = 300_000
    z = rng.standard_normal((n, P))
    s2 = rng.chisquare(df, n) / df
    p = np.stack([stats.f.sf(np.sum((z @ W) ** 2, 1) / k / s2, k, df) for W, k in zip(spaces, r)], -1)
    brute = np.mean((p / w).min(axis=1) <= p_min)
    estimate = D.min_p_value(p_min, spaces, df, weights=w if weighted else None)
    assert w.max() * p_min <= estimate <= w.sum() * p_min
    assert estimate < 0.95 * w.sum() * p_min  # correlated tests: below Bonferroni
    sd = np.hypot(np.sqrt(brute * (1 - brute) / n), 1.5 * estimate / np.sqrt(D.MIN_P_DRAWS))
    if brute * n >= 50:
        assert abs(estimate - brute) < 4 * sd, (estimate, brute)
    else:  # too rare for the brute force: the sampler's own standard error, from independent seeds
        runs = [D.min_p_value(p_min, spaces, df, rng=np.random.default_rng(s)) for s in range(8)]
        assert np.std(runs) < 0.05 * np.mean(runs)


def test_a_blunder_is_found_where_the_noise_grows_with_the_distance(paper_robot, tmp_path):
    """A gross blunder (25 sigma) among few replicate pairs with tracker noise that grows with the distance:
    its wild replicate variance must not be read as distance-dependent noise that hides it (found by a new
    user: 17 of 122 blunders missed). Rate over seeds, against the known blunder row."""
    pr = T.Protocol("tracker pairs", sigma_m=5e-6, sigma_per_m=1e-5, tracker_m=(1.5, 0.5, 0.0))
    found = 0
    for seed in range(12):
        rng = np.random.default_rng(900 + seed)
        log = T.lab_log(paper_robot, pr, rng, n_configs=9)
        row = int(rng.integers(len(log.q)))
        bad = {row: 25 * log.sigma[row] * T.random_directions(rng, 1, 2)[0]}
        dp = T.measure(paper_robot, T.Truth(R.compliances(paper_robot)), log, rng, blunders=bad)
        path = tmp_path / f"b{seed}.csv"
        path.write_text(T.lab_csv(paper_robot, log, dp), encoding="utf-8")
        v = D.analyse(paper_robot, read_measurements(path, paper_robot), gain=False)
        found += v["outlier_rows"] == [row]
    assert found >= 11, found


def test_a_shared_reference_reading_is_modelled_not_taken_for_an_effect(arms, tmp_path):
    """Displacements of a configuration taken from one reference reading share its error (a common lab
    protocol; a new user's clean data gave 33 false alarms in 40). Simulated with that protocol, clean data
    must raise false alarms at most at alpha (without the correction: 24 of 24), a hidden effect is still
    named, and the verdict says what it did."""
    protocol = "4 directions x 2, shared reference"
    clean = [R.run_case(arm, arms[arm], protocol, (), 7000 + s, workdir=str(tmp_path))
             for arm in ("2-link", "3-link") for s in range(6)]
    assert _binomial_consistent(sum(r.false_alarm for r in clean), len(clean), 0.01), [r.verdict_with_pose_id["cause"]
                                                                                       for r in clean]
    assert all(any("share the errors of their reference readings" in n for n in r.verdict_with_pose_id["notes"])
               for r in clean)
    hidden = [R.run_case("2-link", arms["2-link"], protocol, ("backlash",), 7100 + s, size_range=(0.3, 1.0),
                         workdir=str(tmp_path)) for s in range(4)]
    assert all(r.named("backlash") and r.agree for r in hidden if r.power["backlash"] >= 0.9)


NEWUSER = Path(__file__).parent / "data" / "newuser"


def test_a_new_users_data_sets_give_the_verdicts_of_their_readme(paper_robot):
    """Data from an independent simulator (tests/data/newuser/README.md)."""
    r3 = load_robot(NEWUSER / "planar_3r.yaml")
    v = D.analyse(r3, read_measurements(NEWUSER / "r3_push4_nonlinear_M_s182_pid.csv", r3), gain=False)
    assert v["cause"] in D.CAUSES and v["p_value"] <= v["alpha"]
    assert "nonlinear_joint_stiffness" in {*v["causes"], *v["indistinguishable_from"]}
    v = D.analyse(paper_robot, read_measurements(NEWUSER / "r2_hangrep_clean_0_s102_pid.csv", paper_robot), gain=False)
    assert v["outlier_rows"] == [36] and v["cause"] == "none"
    r4 = load_robot(NEWUSER / "planar_4r.yaml")
    v = D.analyse(r4, read_measurements(NEWUSER / "r4_hang3_refconfig_clean_s27.csv", r4), gain=False)
    assert v["cause"] == "none" and v["nominal"]["noise_varies"] is None, (v["cause"], v["p_value"])
    assert any("the likelihood does not confirm it" in n for n in v["notes"])
    for name in ("r2_hangrep_sharedref_once_s0.csv", "r2_push4rep_sharedref_once_s2.csv"):
        v = D.analyse(paper_robot, read_measurements(NEWUSER / name, paper_robot), gain=False)
        assert v["cause"] == "none" and any("share the errors of their reference readings" in n for n in v["notes"]), (
            name, v["cause"])


# --- the extended model: parameters the data do not determine, joint compliances below zero -------------------

def _brute_force_estimable(X: np.ndarray, j: int) -> bool:
    """e_j is in the row space of X when appending it as a row leaves the rank unchanged (numpy's rank)."""
    e = np.zeros((1, X.shape[1]))
    e[0, j] = 1.0
    return np.linalg.matrix_rank(np.vstack([X, e])) == np.linalg.matrix_rank(X)


def test_estimability_equals_a_brute_force_rank_computation(rng):
    """Designs [A, B_1 M_1, ..., 0]: A (40, q) integer, each B_i a few of A's columns (disjoint blocks) and M_i
    nonzero integer mixtures, sometimes a zero column. Estimable parameters: a brute-force rank test per column;
    the groups that cannot be separated: the blocks with their mixtures, by construction (union-find); a
    determined combination must pass the same rank test. The code under test sees the columns scaled by factors
    from 1e-8 to 1e2 (estimability does not depend on the units)."""
    seen = {"estimable": 0, "groups": 0, "several groups": 0, "combinations": 0, "without": 0}
    for _ in range(30):
        q = int(rng.integers(4, 8))
        A = rng.integers(-4, 5, (40, q)).astype(float)
        cols, parent = [A], list(range(q))
        blocks = np.array_split(rng.permutation(q)[: int(rng.integers(1, q))], int(rng.integers(1, 3)))
        for block in blocks:
            if not block.size:
                continue
            for s in block[1:]:
                parent[int(s)] = int(block[0])
            for _ in range(int(rng.integers(1, 3))):
                m = rng.choice([-3.0, -2.0, -1.0, 1.0, 2.0, 3.0], block.size)
                cols.append((A[:, block] @ m)[:, None])
                parent.append(int(block[0]))
        if rng.random() < 0.3:
            cols.append(np.zeros((40, 1)))
            parent.append(len(parent))
        X = np.hstack(cols)

        def root(i):
            while parent[i] != i:
                i = parent[i]
            return i

        scale = 10.0 ** rng.uniform(-8, 2, X.shape[1])
        ok, groups = D.estimability(X * scale)
        assert ok.tolist() == [_brute_force_estimable(X, j) for j in range(X.shape[1])]
        bad = np.flatnonzero(~ok)
        expected = sorted(sorted(int(i) for i in bad if root(i) == r) for r in {root(int(i)) for i in bad})
        assert sorted(sorted(g.members.tolist()) for g in groups) == expected
        norm = np.linalg.norm(X * scale, axis=0)
        norm[norm == 0] = 1.0
        for g in groups:
            if g.combination is not None:  # lambda (in the units of X * scale) lies in the row space of X * scale
                lam = np.zeros(X.shape[1])
                lam[g.members] = g.combination
                assert np.linalg.matrix_rank(np.vstack([X * scale / norm, lam / norm])) == np.linalg.matrix_rank(X)
        seen["estimable"] += int(ok.sum())
        seen["groups"] += len(groups)
        seen["several groups"] += len(groups) > 1
        seen["combinations"] += sum(g.combination is not None for g in groups)
        seen["without"] += sum(g.combination is None for g in groups)
    assert min(seen.values()) > 0, seen  # every kind of case occurred


def test_a_link_bending_like_a_joint_is_not_estimable_and_its_combination_is(paper_robot):
    """A planar 2-link arm measured at the tool point: the last link bending under the force at its end moves the
    tool as joint 2 turning does, (L2^3 / 3) c2 against L2^2 k2 (Euler-Bernoulli cantilever), so k2 and c2 are not
    estimable and only k2 + (L2 / 3) c2 is; k1 and c1 are, and each interval covers the simulator's truth."""
    k, c = np.array([1e-6, 2e-6]), np.array([1e-5, 1e-5])
    v = D.analyse(paper_robot, _simulated(paper_robot, T.Truth(k, link_bending=c), 2), gain=False)
    ext = v["extended"]
    assert ext["causes"] == ["link_compliance"] and v["tests"]["link_compliance"]["extra_parameters"] == 1
    assert ext["k"][1] is None and ext["k_ci95"][1] is None
    assert ext["parameters"][1] is None and ext["parameters_ci95"][1] is None
    assert abs(ext["k"][0] - k[0]) <= ext["k_ci95"][0] and abs(ext["parameters"][0] - c[0]) <= ext["parameters_ci95"][0]
    (group,) = ext["not_estimable"]
    assert group["parameters"] == ["k2", "c2_1/(N m^2)"]
    L2 = paper_robot.links_m[1]
    assert group["combination"]["k2"] == 1.0 and group["combination"]["c2_1/(N m^2)"] == pytest.approx(L2 / 3, rel=1e-9)
    assert abs(group["value"] - (k[1] + L2 / 3 * c[1])) <= group["ci95"]
    assert any("k2 and c2 cannot be separated" in n and "k2 + 0.133 c2" in n for n in v["notes"]), v["notes"]


def _coupling_case(robot):
    k, k12 = np.array([1e-6, 2e-6]), 8.5e-7
    meas = _simulated(robot, T.Truth(k, coupling=np.array([[0.0, k12], [k12, 0.0]])), 4)
    return k, k12, meas


def test_an_extension_with_a_negative_joint_compliance_gives_way_to_an_equivalent_physical_one(paper_robot):
    """Joint coupling on a planar 2-link arm: link_compliance spans the same deflections and comes first in the
    catalogue, but it holds the coupling only with k1' = k1 - a k12 / g < 0, where J1 tau1 a + ... + (J1 tau2 +
    J2 tau1) g is the truth's bending of link 1 (stiffcal.testing.truth) regressed on the joint model's columns. The
    extended model then holds joint_coupling, whose intervals cover the simulator's k1, k2, k12."""
    k, k12, meas = _coupling_case(paper_robot)
    v = D.analyse(paper_robot, meas, gain=False)
    assert v["cause"] == "joint_coupling" and v["causes"] == ["joint_coupling"]
    assert v["equivalent_combinations"] == [["link_compliance"]] and v["indistinguishable_from"] == ["link_compliance"]
    ext = v["extended"]
    assert ext["causes"] == ["joint_coupling"] and ext["not_estimable"] == []
    assert np.all(np.abs(np.array(ext["k"]) - k) <= np.array(ext["k_ci95"]))
    assert abs(ext["parameters"][0] - k12) <= ext["parameters_ci95"][0]
    # the passed-over model's k1, from the physics: the truth's link-1 bending in the joint model's columns
    J, tau = paper_robot.jacobian(meas.q), T.joint_torques(paper_robot, meas.q, meas.force)
    J1, J2 = J[:, :, 0], J[:, :, 1]
    cols = np.stack([J1 * tau[:, :1], J2 * tau[:, 1:], J1 * tau[:, 1:] + J2 * tau[:, :1]], -1).reshape(-1, 3)
    bend = T.link_bending_displacement(paper_robot, meas.q, meas.force, np.array([1.0, 0.0])).ravel()
    a, _, g = np.linalg.lstsq(cols, bend, rcond=None)[0]
    k1_link = k[0] - a * k12 / g
    assert k1_link < 0
    note = next(n for n in v["notes"] if "not the physical extension" in n)
    shown = float(note.split("k1 = ")[1].split(" +- ")[0])
    half = float(note.split(" +- ")[1].split(" ")[0])
    assert shown + half < 0 and abs(shown - k1_link) <= half, note


def test_an_extension_with_a_negative_joint_compliance_and_no_alternative_is_named_not_physical(paper_robot):
    """The same data with closed testing's alternatives withheld: the chosen link_compliance is kept, and the note
    names its negative k1 and says the extension is not physical; with the alternative it gives way to it."""
    _, _, meas = _coupling_case(paper_robot)
    des = D.build_design(paper_robot, meas)
    noise = D.noise_variance(des, meas)
    sel = D.closed_testing(des, D.CAUSES, noise, lambda S, f: None, 0.01)
    chosen, *rest = sel.explanations
    assert chosen == {"link_compliance"} and rest[0] == {"joint_coupling"}
    ob = D.Observed.of(paper_robot, meas)
    plug_in = D.Intervals(float(np.sqrt(noise.s2)), noise.df)  # independent rows: nothing estimated but sigma
    pick, others, notes = D.physical_choice(des, sel, chosen, [], lambda S: plug_in, paper_robot, ob, [])
    assert pick == chosen and others == []
    assert any("k1 = -" in n and "not physical" in n and "k2 and c2 cannot be separated" not in n for n in notes), notes
    pick, others, notes = D.physical_choice(des, sel, chosen, [rest[0]], lambda S: plug_in, paper_robot, ob, [])
    assert pick == {"joint_coupling"} and others == [chosen]


# --- forces in kN below the resolution in some rows, pose_id relabelled, misspelled columns (new user 21) ----

def _hanging_log(robot, seed, magnitudes, k, n_configs=12, interleaved=False):
    """A simulated lab log (stiffcal.testing.truth): hanging loads, each load sequence measured twice, an unloaded
    reference row before every loaded one (zero force, zero displacement), and the displacements."""
    rng = np.random.default_rng(seed)
    protocol = T.Protocol("hanging", magnitudes_N=magnitudes, repeats=2, unloaded_rows=True, interleaved=interleaved)
    log = T.lab_log(robot, protocol, rng, n_configs)
    return log, T.measure(robot, T.Truth(np.asarray(k)), log, rng), rng


def test_forces_in_kilonewtons_below_the_resolution_in_some_rows_are_refused(tmp_path, paper_robot):
    """Loads of 150, 300 and 600 N written in kN under fx_N, fy_N: the 0.15 and 0.3 rows fall below the 0.5 N
    resolution (they used to become unloaded rows of up to 340 um and a zero point that 'moved'). Refused over
    20 seeds, naming the file, the rows below the resolution (counted from the generated loads) and kN; the
    same logs in newtons are read with exactly the generated reference rows as the zero point."""
    for seed in range(20):
        log, dp, _ = _hanging_log(paper_robot, seed, (150.0, 300.0, 600.0), [1.5e-6, 3e-6])
        below = int(np.sum(log.loaded & (np.linalg.norm(log.force, axis=1) < 500.0)))
        kn = _write(tmp_path, T.lab_csv(paper_robot, replace(log, force=log.force / 1000), dp), f"kn{seed}.csv")
        with pytest.raises(InputError) as err:
            read_measurements(kn, paper_robot)
        msg = str(err.value)
        assert msg.startswith(str(kn)) and "'columns fx_N, fy_N'" in msg and "kN" in msg
        assert f"{below} row(s) classed as unloaded" in msg
        meas = read_measurements(_write(tmp_path, T.lab_csv(paper_robot, log, dp), f"n{seed}.csv"), paper_robot)
        assert len(meas.zero_rows) == int(np.sum(~log.loaded)) and meas.n_rows == int(np.sum(log.loaded))
        assert np.all(meas.zero_dp == 0)


def test_one_force_column_in_kilonewtons_is_refused(tmp_path, root):
    """A fresh user's hand-held gauge log with fx_N, fy_N in newtons and fz_N in kN (pushes of about 300 N along
    +-z written 0.3): every z push fell below the resolution and became an unloaded row of ~200 um, read as a
    shared reference error (verdict `none`, exit 0). Refused over 10 seeds of the simulator's gauge on the 6-axis
    arm, naming the file, fz_N, the z pushes (counted from the generated loads) and kN; the same logs in newtons
    are read with exactly the generated unloaded rows, and so are logs whose reference rows carry a load cell's
    reading of up to +-0.3 N in fz beside the noise (genuine zero points)."""
    robot = R.robots(root)["6-axis"]
    pr = R.PROTOCOLS["gauge +-axes, reference per visit, half revisited"]
    for seed in range(10):
        rng = np.random.default_rng(seed)
        log = T.lab_log(robot, pr, rng, 10)
        dp = T.measure(robot, T.Truth(R.compliances(robot)), log, rng)
        force = log.force.copy()
        force[:, 2] /= 1000
        z = int(np.sum(log.loaded & (np.abs(log.force[:, 2]) > 1.0)))
        kn = _write(tmp_path, T.lab_csv(robot, replace(log, force=force), dp), f"kn{seed}.csv")
        with pytest.raises(InputError) as err:
            read_measurements(kn, robot)
        msg = str(err.value)
        assert msg.startswith(str(kn)) and "'columns fz_N'" in msg and "fz_N looks like kN" in msg, msg
        assert f"{z} row(s) classed as unloaded" in msg
        meas = read_measurements(_write(tmp_path, T.lab_csv(robot, log, dp), f"n{seed}.csv"), robot)
        assert len(meas.zero_rows) == int(np.sum(~log.loaded)) and meas.n_rows == int(np.sum(log.loaded))
        ref = ~log.loaded
        cell = log.force.copy()
        cell[ref, 2] = rng.uniform(-0.3, 0.3, ref.sum())
        meas = read_measurements(_write(tmp_path, T.lab_csv(robot, replace(log, force=cell), dp), f"c{seed}.csv"),
                                 robot)
        assert len(meas.zero_rows) == int(ref.sum()) and meas.n_rows == int(np.sum(log.loaded))


def test_reference_rows_with_a_load_cell_reading_below_the_resolution_are_the_zero_point(tmp_path, paper_robot):
    """Genuine unloaded rows are not taken for kN: a soft arm under small loads (2, 5, 10 N, numbers a kN file
    could hold, compliances such that a reading of 0.3 N would deflect it by about the noise), the reference rows
    carrying a load-cell reading of up to +-0.3 N and a displacement of pure tracker noise (10 um), over 100
    seeds: every file is read, with every reference row as the zero point."""
    for seed in range(100):
        log, dp, rng = _hanging_log(paper_robot, seed, (2.0, 5.0, 10.0), [1.2e-4, 2.4e-4])
        ref = ~log.loaded
        force = log.force.copy()
        force[ref] = rng.uniform(-0.3, 0.3, (ref.sum(), 2))
        dp[ref] = rng.normal(0.0, 1e-5, (ref.sum(), 2))
        path = _write(tmp_path, T.lab_csv(paper_robot, replace(log, force=force), dp), f"cell{seed}.csv")
        meas = read_measurements(path, paper_robot)
        assert len(meas.zero_rows) == int(ref.sum()) and meas.n_rows == int(np.sum(log.loaded))


def test_a_second_pass_relabelled_is_one_configuration_per_joint_configuration(tmp_path, paper_robot):
    """The plan measured twice (interleaved), the second pass labelled C<i>b: configurations are the generated
    joint configurations (12, not 24), the rows of each are those generated there, labels 'C<i>/C<i>b', and a
    note names the merged labels. Rows sharing a label but not their angles are still refused."""
    log, dp, _ = _hanging_log(paper_robot, 3, (150.0, 300.0, 600.0), [1.5e-6, 3e-6], interleaved=True)
    lines = T.lab_csv(paper_robot, log, dp).splitlines()
    second = np.arange(len(log.q)) >= len(log.q) // 2  # interleaved: the second half repeats the plan
    rows = [("C" + ln.split(",", 1)[0] + ("b" if s else "")) + "," + ln.split(",", 1)[1]
            for ln, s in zip(lines[1:], second)]
    meas = read_measurements(_write(tmp_path, "\n".join([lines[0], *rows]) + "\n"), paper_robot)
    loaded = np.flatnonzero(log.loaded)
    assert meas.n_configurations == len(np.unique(log.config)) == 12
    # the same partition of the loaded rows as the generated configurations
    assert len({(a, b) for a, b in zip(meas.config, log.config[loaded])}) == 12
    assert meas.config_labels == tuple(f"C{c + 1}/C{c + 1}b" for c in dict.fromkeys(log.config[loaded]))
    note = [n for n in meas.notes if "several pose_id labels name the same joint angles" in n]
    assert len(note) == 1 and "C1 and C1b" in note[0] and "12 configurations, 24 labels" in note[0]
    bad = rows[:]
    bad[-1] = bad[-1].split(",", 1)[0] + ",1.5," + bad[-1].split(",", 2)[2]  # a C<i>b row moved to q1 = 1.5 deg
    with pytest.raises(InputError, match="pose_id 'C.*b' labels one robot configuration"):
        read_measurements(_write(tmp_path, "\n".join([lines[0], *bad]) + "\n", "bad.csv"), paper_robot)


@pytest.mark.parametrize("header", ["pose id", "Pose-ID", "POSE_ID", "pose_idd"])
def test_a_misspelled_pose_id_is_named_with_the_likely_name(tmp_path, paper_robot, header):
    meas = read_measurements(_write(tmp_path, LAB.replace("pose_id", header, 1)), paper_robot)
    note = [n for n in meas.notes if "not used by the analysis" in n]
    assert len(note) == 1 and f"{header!r} looks like pose_id" in note[0]
    assert meas.n_configurations == 2 and not meas.labelled  # configurations from the joint angles


@pytest.mark.parametrize("column, likely", [("DX_M", "dx_m"), ("Dy-m", "dy_m"), ("q 1 deg", "q1_deg")])
def test_a_misspelled_column_the_analysis_reads_is_refused_with_the_likely_name(tmp_path, paper_robot, column, likely):
    path = _write(tmp_path, LAB.replace(likely, column, 1))
    with pytest.raises(InputError) as err:
        read_measurements(path, paper_robot)
    assert str(err.value).startswith(f"{path}: field 'column {column}'") and f"looks like {likely}" in str(err.value)


def test_a_spreadsheet_s_headers_comments_and_utf16_are_named_for_what_they_are(tmp_path, paper_robot):
    """Another lab's ways of writing the CSV (a fresh user's KR 210 logs): units in brackets, every column named at
    once (one run per column before), and a displacement in mm told to convert, not just to rename (the advice
    'rename dx [mm] to dx_m' read millimetres as metres); a comment line before the header; Excel's 'Unicode text'
    (UTF-16, its byte-order mark read as Latin-1 before); an ISO-8601 time under timestamp_s."""
    header = LAB.splitlines()[0]
    brackets = header.replace("q1_deg", "q1 [deg]").replace("dx_m", "dx [mm]").replace("dy_m", "dy [mm]")
    with pytest.raises(InputError) as err:
        read_measurements(_write(tmp_path, LAB.replace(header, brackets, 1)), paper_robot)
    msg = str(err.value)
    assert "columns q1 [deg], dx [mm], dy [mm]'" in msg and "'q1 [deg]' looks like q1_deg;" in msg
    assert "'dx [mm]' looks like dx_m in mm (convert it to m)" in msg
    with pytest.raises(InputError, match=r"row 1'.*the first line \('# cell 3'\) is a comment"):
        read_measurements(_write(tmp_path, "# cell 3\n" + LAB, "comment.csv"), paper_robot)
    lines = LAB.splitlines()
    iso = "\n".join([lines[0] + ",timestamp_s"] + [ln + f",2024-03-05T08:0{i}:00" for i, ln in enumerate(lines[1:])])
    with pytest.raises(InputError, match=r"column timestamp_s'.*a date or clock time\? give the time in seconds"):
        read_measurements(_write(tmp_path, iso + "\n", "iso.csv"), paper_robot)
    path = tmp_path / "utf16.csv"
    path.write_bytes(LAB.encode("utf-16"))  # with its byte-order mark, as Excel writes it
    assert path.read_bytes()[:2] in (b"\xff\xfe", b"\xfe\xff")
    with pytest.raises(InputError, match="not UTF-8 text: UTF-16"):
        read_measurements(path, paper_robot)


def test_misspelled_optional_columns_are_refused_and_other_columns_get_no_suggestion(tmp_path, paper_robot):
    """'Target' (the targets would be dropped: every row taken for the tool point) and 'MZ_Nm' beside mx_Nm,
    my_Nm (the moment would be dropped) are refused naming the likely column; the UR10 file's timestamp and
    temperature_C are noted as unused, the timestamp with the name the analysis reads it under (timestamp_s)."""
    lines = LAB.splitlines()
    text = "\n".join([lines[0] + ",Target"] + [ln + ",tool" for ln in lines[1:]]) + "\n"
    with pytest.raises(InputError, match="column Target'.*looks like target"):
        read_measurements(_write(tmp_path, text), paper_robot)
    robot = load_robot(LAB_DIR / "ur10.yaml")
    ur10 = (LAB_DIR / "ur10_bar.csv").read_text()
    with pytest.raises(InputError, match="column MZ_Nm'.*looks like mz_Nm"):
        read_measurements(_write(tmp_path, ur10.replace("mz_Nm", "MZ_Nm", 1), "mz.csv"), robot)
    notes = read_measurements(LAB_DIR / "ur10_bar.csv", robot).notes
    assert any("timestamp, temperature_C not used" in n for n in notes)
    assert any("'timestamp' looks like timestamp_s" in n for n in notes)  # a log column: a suggestion, not a refusal
    assert not any("'temperature_C' looks like" in n for n in notes)


@pytest.mark.parametrize("n_configs, pose_id", [(12, True), (60, True), (12, False)])
def test_the_residual_figure_labels_configurations_by_pose_id_and_marks_the_blunders(tmp_path, paper_robot,
                                                                                     n_configs, pose_id):
    """fig_residuals on a simulated log with pose_id labels P001 ...: the configuration axis carries the labels in
    file order (one in two beyond 40 configurations), integers without pose_id; the rows named as blunders are
    drawn with their own marker at their configuration and residual (clipped to the axis when far off) and listed
    in the legend."""
    import matplotlib.pyplot as plt

    from stiffcal.report import plots

    rng = np.random.default_rng(n_configs)
    log = T.lab_log(paper_robot, T.Protocol("directions", magnitudes_N=(200.0, 400.0), n_directions=3, repeats=2),
                    rng, n_configs)
    dp = T.measure(paper_robot, T.Truth(np.array([1.5e-6, 3e-6])), log, rng)
    lines = T.lab_csv(paper_robot, log, dp, pose_id=pose_id).splitlines()
    if pose_id:
        lines[1:] = [f"P{int(ln.split(',', 1)[0]):03d}," + ln.split(",", 1)[1] for ln in lines[1:]]
    meas = read_measurements(_write(tmp_path, "\n".join(lines) + "\n"), paper_robot)
    resid = rng.normal(0.0, SIGMA, (meas.n_rows, 2))
    blunders = [5, 40]
    resid[40, 0] = 50 * SIGMA  # far off the others: drawn at the edge of the axis
    fig = plots.fig_residuals(meas, {"q1 [deg]": np.degrees(meas.q[:, 0])}, resid, SIGMA, "t", outlier_rows=blunders)
    fig.canvas.draw()
    ax0 = fig.axes[0]
    ticks = [t.get_text() for t in ax0.get_xticklabels()]
    if pose_id:
        first = list(dict.fromkeys(log.config))  # configurations in file order
        step = 1 if n_configs <= 40 else 2
        assert ticks == [f"P{c + 1:03d}" for c in first][::step]
    else:
        assert all(t.lstrip("−-").isdigit() for t in ticks) and meas.config_labels[0].startswith("q = (")
    legend = [t.get_text() for t in ax0.get_legend().get_texts()]
    assert "blunder (outlier_rows): data rows 5, 40" in legend
    red = plt.matplotlib.colors.to_rgb(plots.OUTLIER_STYLE["color"])
    marked = [c for c in ax0.collections if len(c.get_facecolor()) == 1 and np.allclose(c.get_facecolor()[0][:3], red)]
    xy = np.vstack([c.get_offsets() for c in marked])
    assert len(xy) == 2 * len(blunders)  # dx and dy of each blunder row
    for k, row in enumerate(blunders):
        at = np.flatnonzero(meas.rows == row)[0]
        assert np.all(np.abs(xy[k::2][:, 0] - meas.config[at]) <= 0.35 + 1e-9)
    lo, hi = ax0.get_ylim()
    assert hi < 50 * SIGMA * 1e6 and np.isclose(xy[:, 1].max(), 1.15 * max(np.abs(np.delete(resid, blunders, 0)).max(),
                                                                             2 * SIGMA) * 1e6)
    plt.close(fig)


@pytest.mark.parametrize("protocol", ["loading bar x3, reference per visit, 2 passes", "3-D pushes x 2, repeated"])
def test_a_joint_that_moves_no_measured_point_has_no_cause_parameter(tmp_path, root, protocol):
    """A UR5 from its URDF (its inertias preload the gears), the tool point where the last axes leave it still: a
    fresh user's log gave b6 = -2.6e6 rad +- 1.7e7 from round-off, then a next round whose RMS was infinite (the
    JSON refused it: no verdict written) and a calibrated file that `predict` refused. The simulator's backlash of
    60 urad on joints 3 and 4 (loading bar: a wrench, and 3-D pushes: a force): `backlash` named; every joint that
    moves the tool point by round-off only (found here by central differences of the forward kinematics, not by the
    code's rule) has its backlash null and listed as not estimable, b3 and b4 within 3 s.d. of the truth; with a test
    pose the next round's figures are finite and the calibrated file predicts."""
    robot = load_robot(root / "tests/data/urdf/ur5_cont.urdf")
    k = R.compliances(robot)
    rng = np.random.default_rng(4)
    log = T.lab_log(robot, R.PROTOCOLS[protocol], rng, 20)
    gap = np.zeros(robot.n_joints)
    gap[2] = gap[3] = 1.2e-4  # b_i = gap_i / 2
    path = _write(tmp_path, T.lab_csv(robot, log, T.measure(robot, T.Truth(k, gap=gap), log, rng)))
    h = 1e-6
    fd = np.stack([np.linalg.norm(robot.fk(log.q + h * e)[:, :3] - robot.fk(log.q - h * e)[:, :3]) / (2 * h)
                   for e in np.eye(robot.n_joints)])
    still = np.flatnonzero(fd <= 1e-9 * fd.max())
    assert robot.n_joints - 1 in still  # the case this test is for
    out = tmp_path / "out"
    assert main(["discrepancy", "--robot", str(root / "tests/data/urdf/ur5_cont.urdf"), "--data", str(path), "--out",
                 str(out), "--test-pose-deg", "0,-90,90,-90,-90,0", "--force-N", "0,0,-100", "--no-figures",
                 "--quiet"]) == 0
    v = json.loads((out / "verdict.json").read_text())
    e = v["extended"]
    assert v["cause"] == "backlash"
    b = dict(zip(e["parameter_names"], zip(e["parameters"], e["parameters_ci95"])))
    absent = {n for group in e["not_estimable"] for n in group["parameters"]}
    for j in still:
        assert b[f"b{j + 1}_rad"] == (None, None) and f"b{j + 1}_rad" in absent
    for j in (2, 3):
        value, half = b[f"b{j + 1}_rad"]
        assert abs(value - gap[j] / 2) <= 3 * half / 1.96, (j, value, half)
    assert all(np.isfinite(v["next_round"][key]) for key in ("rms_prior_m", "rms_next_m", "lower_bound_rms_m"))
    poses = _write(tmp_path, "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N,fy_N,fz_N\n0,-90,90,-90,-90,0,0,0,-100\n",
                   "poses.csv")
    assert main(["predict", "--robot", str(out / "calibrated.yaml"), "--poses", str(poses), "--out",
                 str(tmp_path / "pred.csv"), "--quiet"]) == 0


def test_a_joint_the_loads_turn_only_by_round_off_is_not_identifiable(tmp_path):
    """A fresh user's UR10 (example-robot-data's URDF, whose 1.57079632679 is pi/2 to 5e-12) with the load point on
    wrist 3's axis and two targets beside it: the loads turn wrist 3 by round-off only (its torque checked here
    to be 1e-9 of the others'), so its compliance is not identifiable. Before, the column-scaled fit gave it full
    rank: k6 = +-3e5 rad/(N m), written into calibrated.yaml (then refused by predict) and an infinite next round
    (a crash of the strict JSON). Compliances 1-5 against the simulator's truth, every next-round figure finite."""
    from real_arms import robots_dir

    root = robots_dir()
    if root is None:
        pytest.skip("example-robot-data is not installed (requirements-test.lock)")
    path = tmp_path / "ur10.yaml"
    path.write_text(f"name: ur10-lab\nkind: urdf\nurdf: {root / 'ur_description/urdf/ur10_robot.urdf'}\n"
                    "base_frame: base_link\ntip_frame: tool0\ntool_m: [0.0, 0.0, 0.12]\n"
                    "targets:\n  A: [0.07, 0.0, 0.08]\n  B: [-0.05, 0.06, 0.08]\n", encoding="utf-8")
    robot = load_robot(path)
    k = np.array([1.5e-6, 1.0e-6, 2.0e-6, 3.0e-6, 4.0e-6, 2.5e-6])
    rng = np.random.default_rng(1)
    pushes = replace(R.PROTOCOLS["3-D pushes x 2, once"], magnitudes_N=(200.0,), targets=("A", "B"),
                     reference="configuration", passes=2, revisit_fraction=0.3, zero_rows=True, repeatability_m=1e-5)
    log = T.lab_log(robot, pushes, rng, 30)
    tau = np.abs(D.torques(robot, log.q, log.force))
    assert tau[:, 5].max() < 1e-9 * tau[:, :5].max()
    data = tmp_path / "log.csv"
    data.write_text(T.lab_csv(robot, log, T.measure(robot, T.Truth(k), log, rng)), encoding="utf-8")
    v = D.run(robot, str(data), str(tmp_path / "out"), 0.01, test_pose=np.radians([20, -100, 90, -80, -90, 30]),
              test_force=np.array([100.0, -100.0, -200.0]))
    nom = v["nominal"]
    assert nom["not_identifiable_joints"] == [6] and nom["k_joints"] == [1, 2, 3, 4, 5]
    assert np.all(np.abs(np.array(nom["k"]) - k[:5]) < 1.5 * np.array(nom["k_ci95"]))
    assert all(x is not None and np.isfinite(x) for key, x in v["next_round"].items() if key.startswith("rms_"))
    assert 5 not in load_robot(tmp_path / "out" / "calibrated.yaml").calibration.k_joints  # it reloads (predict)


def test_in_row_space_against_the_rank_of_the_stacked_matrix(rng):
    """Estimable predictions (Searle 1971, sec. 5.4): C b is estimable iff rank [X; C] = rank X, computed here on
    integer matrices (exact ranks), for designs whose columns differ in scale by 1e8 (scaled as the fit scales
    them), with a zero column."""
    for _ in range(30):
        B = rng.integers(-3, 4, (12, 4)).astype(float)
        X = np.hstack([B, B[:, :2] @ rng.integers(-2, 3, (2, 2)), np.zeros((12, 1))])  # rank 4 of 7
        C = rng.integers(-3, 4, (2, 7)).astype(float)
        if rng.random() < 0.5:  # a combination of X's rows: estimable
            C = rng.integers(-2, 3, (2, 12)).astype(float) @ X
        expect = np.linalg.matrix_rank(np.vstack([X, C])) == np.linalg.matrix_rank(X)
        units = np.array([1e-6, 1.0, 1e2, 1e-3, 1.0, 1e2, 1.0])
        assert D.in_row_space(X * units, C * units) == expect


@pytest.mark.parametrize("column, factor, words", [
    ("rx_rad", 180 / np.pi, r"columns rx_rad, ry_rad, rz_rad.*rotations in radians.*compliances ([0-9.e+]+) times"),
    ("rx_rad", 1e3, r"columns rx_rad, ry_rad, rz_rad.*rotations in radians.*compliances ([0-9.e+]+) times.*mrad"),
    ("mx_Nm", 1e3, r"columns mx_Nm, my_Nm, mz_Nm.*moments in N m.*divided by 1000.*N mm")])
def test_rotations_and_moments_in_another_unit_are_refused(tmp_path, column, factor, words):
    """A fresh user's 6-DoF probe log (a loading bar's wrenches, the tool's orientation) with the rotations in
    degrees or mrad under *_rad columns, or the moments in N mm under *_Nm: each was analysed to a confident
    `unexplained` (every cause, 13 blunders, a drift of 3e4 um per 3600 rows); refused naming the columns. The
    log as written gives a verdict."""
    robot = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    rng = np.random.default_rng(3)
    protocol = replace(R.PROTOCOLS["loading bar x3, reference per visit, 2 passes"], orientation=True)
    log = T.lab_log(robot, protocol, rng, 20)
    text = T.lab_csv(robot, log, T.measure(robot, T.Truth(R.compliances(robot)), log, rng))
    good = tmp_path / "good.csv"
    good.write_text(text, encoding="utf-8")
    assert D.analyse(robot, read_measurements(good, robot), 0.01, gain=False)["cause"] in D.CAUSES + ("none",)
    lines = text.splitlines()
    head = lines[0].split(",")
    cols = [i for i, c in enumerate(head) if c[0] == column[0] and c[2:] == column[2:]]
    assert len(cols) == 3
    rows = [[f"{float(v) * factor:.9g}" if i in cols else v for i, v in enumerate(r.split(","))] for r in lines[1:]]
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n", encoding="utf-8")
    with pytest.raises(InputError, match=words) as err:
        D.analyse(robot, read_measurements(bad, robot), 0.01, gain=False)
    if column == "rx_rad":  # the ratio it states is the unit's factor, within the noise's 10 %
        assert abs(float(re.search(words, str(err.value)).group(1)) / factor - 1) < 0.1


def test_a_loading_bar_s_moments_in_N_mm_are_refused_by_their_lever():
    """A fresh user's UR3 with a loading bar 0.15 m long and two targets, its moments logged in N mm: the nominal
    model fitted both units about as well (its compliances shrank 100-fold), so the residual test passed and the
    verdict named causes. The moments of a bar are (R r) x F, r fixed in the tip frame (R its rotation, from the
    arm's kinematics here): in N mm the bar is 150 m long, 20 times and more the 6-axis arm's reach; refused naming
    the columns; in N m (0.15 m) accepted by this check."""
    robot = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    rng = np.random.default_rng(1)
    q = rng.uniform(-1.0, 1.0, (30, 6))
    F = np.column_stack([np.zeros(30), np.zeros(30), -rng.choice([49.0, 98.0, 196.0], 30)])
    r = np.array([0.15, 0.0, 0.0])
    dp = rng.normal(0.0, 1e-5, (30, 3))  # the residual test sees nothing in noise alone
    ob = D.Observed()
    Rt, _ = robot.tool_frame(q)
    M = np.cross(np.einsum("nij,j->ni", Rt, r), F)
    for factor in (1.0, 1e3):
        meas = Measurements.from_arrays(q, F, dp, moment=factor * M)
        if factor == 1.0:
            D._check_moment_unit(robot, meas, ob)
            continue
        with pytest.raises(InputError, match=r"columns mx_Nm, my_Nm, mz_Nm.*applied 150 m from the tool point.*N mm"):
            D._check_moment_unit(robot, meas, ob)


def test_pure_moments_in_N_mm_are_named_against_the_robot_files_compliances(tmp_path):
    """Noticed last stop: a loading bar's pure moments (no force) logged in N mm under *_Nm columns scale every
    compliance by 1/1000 and fit as well as in N m, so no misfit shows it; against the robot file's own compliances
    the note names the moments (it named only micrometres and mN). The log in N m gets no such note."""
    robot = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    k = R.compliances(robot)
    robot = replace(robot, compliances=k)
    rng = np.random.default_rng(3)
    log = T.lab_log(robot, R.PROTOCOLS["loading bar x3, reference per visit, 2 passes"], rng, 20)
    log = replace(log, force=np.zeros_like(log.force), r_force=np.zeros_like(log.r_force))
    lines = T.lab_csv(robot, log, T.measure(robot, T.Truth(k), log, rng)).splitlines()
    cols = [i for i, c in enumerate(lines[0].split(",")) if c in ("mx_Nm", "my_Nm", "mz_Nm")]
    for factor in (1.0, 1e3):
        rows = [",".join(f"{float(v) * factor:.9g}" if i in cols else v for i, v in enumerate(r.split(",")))
                for r in lines[1:]]
        path = tmp_path / f"moments_{factor:g}.csv"
        path.write_text("\n".join([lines[0]] + rows) + "\n", encoding="utf-8")
        notes = D.analyse(robot, read_measurements(path, robot), 0.01, gain=False)["notes"]
        named = [n for n in notes if "about 0.001 times the robot file's" in n and "moments in N mm" in n]
        assert len(named) == (factor > 1), notes


def test_the_p_value_is_about_the_principal_cause_not_a_second_causes_stand_ins():
    """A fresh user's 6-DoF log with a tracker offset (tests/data/newuser/kr210_6dof_offset_s2.csv): the verdict
    names measurement_offset and beside it link_compliance, for which joint_coupling and backlash stand in equally
    well. The statement said "the data need at least one of {measurement_offset, joint_coupling, backlash}", as if
    the offset could be replaced, and left link_compliance out; the p-value is the offset's own (it cannot be
    replaced), and the statement names the second cause with its stand-ins. The second is the physical one among
    them: link_compliance fits with c6 below zero beyond its interval (a link bending against its load), so backlash
    holds the place, link_compliance and joint_coupling standing in for it."""
    robot = load_robot(Path(__file__).resolve().parents[1] / "config/robots/kuka_kr210_r2700.yaml")
    v = D.analyse(robot, read_measurements(NEWUSER / "kr210_6dof_offset_s2.csv", robot), 0.01, gain=False)
    assert v["cause"] == "measurement_offset" and v["causes"][1:] == ["backlash"]
    assert all("measurement_offset" in S for S in v["equivalent_combinations"])
    assert v["p_value_of"] == ["measurement_offset"]
    assert v["p_value"] == v["tests"]["measurement_offset"]["adjusted_p_value"]
    statement = v["p_value_statement"]
    assert "at least one of" not in statement and "backlash (or, equally well, " in statement
    stand_ins = ("link_compliance", "joint_coupling")
    assert all(c in statement.split("backlash (or, equally well, ")[1] for c in stand_ins)
    assert any("not link_compliance+measurement_offset" in n and "c6_1/(N m^2) = -" in n for n in v["notes"])
    # each stand-in's separation advice is about the cause it stands in for
    assert all("backlash" in v["separation"][c] for c in stand_ins)


def test_valid_logs_that_looked_like_unit_mistakes_are_analysed(tmp_path, paper_robot):
    """Two valid logs a fresh user found refused: (a) pure moments from a torque wrench on the 6-axis arm with a
    load cell reading 2 N of force noise beside them (the end-effector compliance divided the moment's deflection
    by that noise: 1.2e-4 m/N, "forces in kN?"); (b) five replicates per (pose, load) printed to 1 um with 1 um of
    noise and no timestamps, where readings coincide by chance (refused as "a log pasted twice"). Both are analysed
    now, the compliances within their intervals of the truth (all but one joint)."""
    robot = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    rng = np.random.default_rng(11)
    k = R.compliances(robot)
    q = np.repeat(np.radians(rng.uniform(-120, 120, (12, robot.n_joints))), 6, axis=0)
    m = np.tile(np.vstack([300.0 * np.eye(3), -300.0 * np.eye(3)]), (12, 1))
    force = rng.normal(0.0, 2.0, (len(q), 3))
    dp = T.simulate(robot, T.Truth(k), q, force, 1e-5, rng, moment=m)
    v = D.analyse(robot, Measurements.from_arrays(q, force, dp, moment=m), 0.01, gain=False)
    nom = v["nominal"]
    inside = np.abs(np.array(nom["k"]) - k[np.array(nom["k_joints"]) - 1]) <= np.array(nom["k_ci95"])
    assert inside.sum() >= len(inside) - 1, (nom["k"], nom["k_ci95"])
    kp = np.array([1.6e-6, 3.3e-6])
    qd = np.repeat(rng.uniform(-150, 150, (9, 2)), 20, axis=0)
    f = np.tile(np.repeat([[20.0, 0.0], [-20.0, 0.0], [0.0, 20.0], [0.0, -20.0]], 5, axis=0), (9, 1))
    dp = np.round(T.simulate(paper_robot, T.Truth(kp), np.radians(qd), f, 1e-6, rng), 6)
    path = tmp_path / "coarse.csv"
    rows = [f"{a:.4f},{b:.4f},{c:g},{d:g},{x:.6f},{y:.6f}\n" for (a, b), (c, d), (x, y) in zip(qd, f, dp)]
    path.write_text("q1_deg,q2_deg,fx_N,fy_N,dx_m,dy_m\n" + "".join(rows), encoding="utf-8")
    meas = read_measurements(path, paper_robot)
    assert any("repeat an earlier row exactly" in n for n in meas.notes)  # some readings coincide by chance
    v = D.analyse(paper_robot, meas, 0.01, gain=False)
    assert np.all(np.abs(np.array(v["nominal"]["k"]) - kp) <= 2 * np.array(v["nominal"]["k_ci95"]))


def test_deflections_large_enough_for_second_order_kinematics_are_corrected(paper_robot):
    """A fresh user's soft arm (a Jaco2 under 6 kg, a Panda after it, exact statics) got link bending and coupling
    named for the geometry's change under load, which the first-order model (eq. 4) leaves out. The 2-link arm's
    exact statics written here in closed form (links 0.6 and 0.4 m, no weight: dq = k J(q + dq)^T F, a fixed point,
    and the tool point's exact motion): the rows are corrected, the note's figure within 2 % of the second-order part
    at the true compliances, and the verdict none; a stiff arm under the same loads is not corrected."""
    links = np.array([0.6, 0.4])

    def fk(q):
        c = np.cumsum(q, axis=1)
        return np.column_stack([np.cos(c) @ links, np.sin(c) @ links])

    def jac(q):
        c = np.cumsum(q, axis=1)
        dx = np.column_stack([-links[0] * np.sin(c[:, 0]) - links[1] * np.sin(c[:, 1]), -links[1] * np.sin(c[:, 1])])
        dy = np.column_stack([links[0] * np.cos(c[:, 0]) + links[1] * np.cos(c[:, 1]), links[1] * np.cos(c[:, 1])])
        return np.stack([dx, dy], axis=1)

    rng = np.random.default_rng(2)
    q = np.repeat(rng.uniform(-2.5, 2.5, (30, 2)), 4, axis=0)
    f = np.tile([[300.0, 0.0], [-300.0, 0.0], [0.0, 300.0], [0.0, -300.0]], (30, 1))
    for k, corrected in ((np.array([2e-5, 4e-5]), True), (np.array([1.5e-6, 3e-6]), False)):
        dq = np.zeros_like(q)
        for _ in range(50):
            dq = k * np.einsum("ndj,nd->nj", jac(q + dq), f)
        exact = fk(q + dq) - fk(q)
        noisy = exact + rng.normal(0.0, 1e-5, exact.shape)
        v = D.analyse(paper_robot, Measurements.from_arrays(q, f, noisy), 0.01, gain=False)
        found = [n for n in v["notes"] if n.startswith(D.GEOMETRY_NOTE)]
        assert bool(found) == corrected, v["notes"]
        if corrected:
            first = np.einsum("ndj,nj->nd", jac(q), k * np.einsum("ndj,nd->nj", jac(q), f))
            expect = np.sqrt(np.mean((exact - first) ** 2))
            said = float(re.search(r"\(([0-9.e+-]+) um RMS", found[0]).group(1)) * 1e-6
            assert abs(said / expect - 1) < 0.02, (said, expect)
            assert v["cause"] == "none", v["causes"]


def test_a_negative_backlash_gap_is_not_read_as_a_gear():
    """A fresh user's clean log named backlash with b2 = -1.5e-5 +- 0.8e-5 rad (a negative gap, no gear's) and said
    nothing. The note names a gap below zero beyond its interval, and only such a gap."""
    ext = {"causes": ["backlash"], "parameter_names": ["b1_rad", "b2_rad"], "parameters": [2e-5, -1.5e-5],
           "parameters_ci95": [0.5e-5, 0.8e-5]}
    notes = D._negative_gap_note(ext)
    assert len(notes) == 1 and "b2_rad = -1.5e-05" in notes[0] and "b1_rad" not in notes[0]
    assert D._negative_gap_note({**ext, "parameters": [2e-5, -0.5e-5]}) == []
    assert D._negative_gap_note({**ext, "causes": ["joint_coupling"]}) == []


def _real_arm_file(tmp_path, name: str, rest: str) -> Path:
    """A robot file of example-robot-data's arm ``name`` (tests/real_arms.py: its URDF and base frame; ``rest``: the
    tip frame, tool point and other keys, as YAML lines), or the test skipped where the package is not installed."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import real_arms

    if real_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    urdf, _, base = real_arms.ARMS[name][:3]
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"name: {name}\nkind: urdf\nurdf: {real_arms.robots_dir() / urdf}\nbase_frame: {base}\n" + rest,
                    encoding="utf-8")
    return path


def test_a_tracker_axis_flipped_is_named_as_a_frame_to_check(tmp_path):
    """A fresh user's Panda under hanging masses with the tracker's y axis flipped (tests/data/newuser/README.md):
    not refused (the nominal compliances stay positive), and the verdict was unexplained with four joints below zero
    in the extended model, a drift of 1e4 um/h and only a backlash note mentioning a frame or sign error. Now the
    note on the extended model's negative compliances, with two or more below zero, says to check the frames
    first; the same log with y as the simulator wrote it (flipped back) has no such note."""
    path = _real_arm_file(tmp_path, "panda", "tip_frame: panda_hand_tcp\ntool_m: [0.0, 0.0, 0.02]\n"
                                 f"compliances_rad_per_Nm: {[3.0e-5] * 7}\n")
    robot = load_robot(path)
    flipped = NEWUSER / "panda_hang_y_flipped.csv"
    text = flipped.read_text(encoding="utf-8").splitlines()
    col = text[0].split(",").index("dy_m")
    right = tmp_path / "right.csv"
    right.write_text("\n".join([text[0]] + [",".join(f[:col] + [repr(-float(f[col]) + 0.0)] + f[col + 1:])
                                            for f in (line.split(",") for line in text[1:])]) + "\n", encoding="utf-8")
    words = "check the frames first: a tracker axis flipped"
    v = D.analyse(robot, read_measurements(flipped, robot), 0.01, gain=False)
    assert v["cause"] != "none" and any(words in n for n in v["notes"]), v["notes"]
    v = D.analyse(robot, read_measurements(right, robot), 0.01, gain=False)
    assert not any(words in n for n in v["notes"])


def test_a_loading_bar_on_a_soft_arm_is_corrected_with_its_lever_turning(tmp_path):
    """A fresh user's Panda (example-robot-data, tip panda_link8, tool point 0.12 m along its z; compliances
    2.4e-4..9e-4 rad/(N m), its own pinocchio simulator of the exact statics with the URDF's weights): masses of 2
    and 4 kg on a bar 0.3 m along the tool's x, every loaded reading with its own reference, tracker noise 10 um;
    the tool point moves up to 19 mm. Clean logs raised a false alarm in 10 of 10 seeds: the second-order correction
    held the bar's moment fixed in the base frame, and the flange joint, which cannot move the tool point on its
    axis, at zero compliance, where the bar turns with the tool (12 um at the tool point from joint 7 alone). With the
    lever fixed to the tool and the robot file's compliance for the joints the data cannot identify, seeds 0 and 5
    (an 'unexplained' and a joint_coupling at p = 6e-4 with the first half of the fix) say none, and the load's
    direction is not flagged. The bar's lever (0.3 m along the tool's x) is found from the logged moments, and the
    next round is planned under the bar's masses (lab_loads; before, under the test load, and 29 of the verdict's
    planned poses put the user's bar, cable or mass through the table, the wall or the arm), and its predictions
    under the bar are not flagged for the flange joint, which the bar turns but which moves nothing at the tool
    point (4 of 5 of the user's rows were flagged 'determined False'). The same user's log with
    the bar's masses pulled 3 deg off the vertical: the load-direction test's angle is 3 deg (its regressors turn the
    moment with the force: 3.7 deg before)."""
    path = _real_arm_file(tmp_path, "panda", "tip_frame: panda_link8\ntool_m: [0.0, 0.0, 0.12]\ngravity: [0, 0, -1]\n"
                                 "compliances_rad_per_Nm: [2.0e-4, 3.0e-4, 4.0e-4, 5.0e-4, 6.0e-4, 8.0e-4, 1.0e-3]\n")
    import stiffcal
    from stiffcal.measured import calibrated as C

    robot = load_robot(path)
    meas = read_measurements(NEWUSER / "panda_bar_clean_s0.csv", robot)
    assert D.bar_lever(robot, meas.q, D.load_of(meas)) == pytest.approx([0.3, 0.0, 0.0], abs=1e-5)  # the user's bar
    loads = D.lab_loads(robot, meas)  # the next round's loads: the bar, its masses' cable kept free in the cell
    assert loads.hanging and loads.arm == pytest.approx([0.3, 0.0, 0.0], abs=1e-5)
    assert sorted(np.round(-loads.wrenches[:, 2], 3)) == pytest.approx([19.613, 39.227], abs=1e-3)
    for seed in (0, 5):
        v = stiffcal.analyse_measurements(str(path), str(NEWUSER / f"panda_bar_clean_s{seed}.csv"),
                                          out=str(tmp_path / f"out{seed}"), figures=False)
        assert v["cause"] == "none", (seed, v["cause"], v["p_value"])
        assert any(n.startswith(D.GEOMETRY_NOTE) for n in v["notes"]), v["notes"]
        assert v["diagnostics"]["load_direction"]["p_value"] > 0.01
    v = D.analyse(robot, read_measurements(NEWUSER / "panda_bar_tilt3deg_s0.csv", robot), 0.01, gain=False)
    assert abs(v["diagnostics"]["load_direction"]["angle_deg"] - 3.0) < 0.15  # 3.7 deg with the moment not turned
    # the flange joint (not identified: the tool point is on its axis) is turned by the bar but moves nothing there:
    # the calibrated model's predictions under the bar rest on what the data determined
    pred = C.predict(load_robot(tmp_path / "out0" / "calibrated.yaml"), meas.q[1:40:8], D.load_of(meas)[1:40:8])
    assert pred.determined.all() and not any("determined False" in n for n in pred.notes), pred.notes


def test_a_second_order_part_below_the_nominal_residuals_is_corrected_where_it_shows(tmp_path):
    """A fresh user's UR10 (example-robot-data, compliances 2e-5..1e-4 rad/(N m)) under gauge pushes of 50 N along
    +-x, y, z, a reference per visit, two passes, its own pinocchio simulator of the exact statics: the second-order
    part was 0.30 of the noise (RMS), below 0.3 of the nominal fit's residuals, which an offset or the noise inflates,
    so the correction was skipped and a clean log named joint_coupling (p = 0.0044), a 20-um tracker offset
    measurement_offset with a second cause beside it. Gated on the union's residuals (the noise's scale) at 0.2, the
    clean log says none and the offset log names the offset alone."""
    robot = load_robot(_real_arm_file(tmp_path, "ur10", "tip_frame: tool0\ntool_m: [0.0, 0.0, 0.1]\n"
                                      "compliances_rad_per_Nm: [2.0e-5, 2.5e-5, 4.0e-5, 8.0e-5, 1.0e-4, 1.0e-4]\n"))
    for name, causes in (("clean_s2", []), ("offset_s101", ["measurement_offset"])):
        v = D.analyse(robot, read_measurements(NEWUSER / f"ur10_push_{name}.csv", robot), 0.01, gain=False)
        assert any(n.startswith(D.GEOMETRY_NOTE) for n in v["notes"]), (name, v["notes"])
        assert v["causes"] == causes and not v["indistinguishable_from"], (name, v["cause"], v["causes"])


def test_moments_logged_in_the_tool_frame_are_refused(tmp_path):
    """A fresh user's UR10 bar log with its moments in the tool frame was analysed as logged: joint_coupling at
    p = 3.6e-88, a negative compliance and a wrong calibrated.yaml, with generic notes only. A mass's moment about the
    tool point is normal to its force in the base frame. The 6-axis arm under the simulator's loading bar: as logged
    (base frame) it is analysed; its moments turned into the tool frame (R(q)^T M, the truth's poses) are refused,
    the message naming the moment columns."""
    arm = R.robots(Path(__file__).resolve().parents[1])["6-axis"]
    rng = np.random.default_rng(7)
    log = T.lab_log(arm, R.PROTOCOLS["loading bar x3, reference per visit, 2 passes"], rng, 12)
    dp = T.measure(arm, T.Truth(R.compliances(arm)), log, rng)
    base = tmp_path / "base.csv"
    base.write_text(T.lab_csv(arm, log, dp), encoding="utf-8")
    D.check_moment_frame(arm, read_measurements(base, arm))  # as the contract has it: no complaint
    Rq = np.asarray(arm.tool_frame(log.q)[0], float)
    tool = replace(log, moment=np.einsum("nji,nj->ni", Rq, log.moment))
    path = tmp_path / "tool.csv"
    path.write_text(T.lab_csv(arm, tool, dp), encoding="utf-8")
    with pytest.raises(InputError, match="look like the tool frame's") as err:
        D.analyse(arm, read_measurements(path, arm), 0.01, gain=False)
    assert err.value.field == "columns mx_Nm, my_Nm, mz_Nm"


def test_discriminate_plans_under_the_data_s_loading_bar_its_moment_turning_with_the_tool(tmp_path):
    """A fresh user's bar log (an IRB 6640, 15 configurations, 45 distinct wrenches) was refused for its count of
    loads: each logged wrench is the bar's at one pose, and the plan held each point's wrench fixed. The Panda bar
    log: the default loads are the bar's masses at the lever the data give (0.3 m along the tool's x, as the log was
    made), and every point of the plan (here the O_t plan, with the test pose) carries the moment the bar applies at
    its own pose, (R(q) r) x F with R from Pinocchio's forward kinematics of the URDF; its O_t is at least the
    certified lower bound."""
    import pinocchio as pin

    from stiffcal.measured import discrimination as X

    path = _real_arm_file(tmp_path, "panda", "tip_frame: panda_link8\ntool_m: [0.0, 0.0, 0.12]\ngravity: [0, 0, -1]\n"
                                 "compliances_rad_per_Nm: [2.0e-4, 3.0e-4, 4.0e-4, 5.0e-4, 6.0e-4, 8.0e-4, 1.0e-3]\n")
    robot = load_robot(path)
    out = X.planned(robot, str(NEWUSER / "panda_bar_clean_s0.csv"), 3,
                    test_pose=np.radians([0, 30, 0, -120, 0, 150, 45]), test_force=np.array([0.0, 0.0, -30.0]),
                    effort=X.Effort(pool_log2=7, search_log2=8, n_starts=1, rounds=1)).to_dict()
    assert out["loads"]["kind"] == "bar" and "loading bar" in out["loads"]["description"]
    assert out["loads"]["bar_end_m"] == pytest.approx([0.3, 0.0, 0.0], abs=1e-5)
    model = pin.buildModelFromUrdf(str(robot.urdf_info["path"]))
    data, frame = model.createData(), model.getFrameId("panda_link8")
    plan = out["ot_plan"]
    for pt in plan["points"]:
        pin.framesForwardKinematics(model, data, np.r_[np.radians(pt["pose_deg"]), np.zeros(model.nq - 7)])
        want = np.cross(data.oMf[frame].rotation @ [0.3, 0.0, 0.0], pt["force_N"])
        assert pt["moment_Nm"] == pytest.approx(want, abs=2e-4)  # the moment's printed digits
    assert plan["O_t_m2"] >= plan["lower_bound_m2"] * (1 - 1e-9) and plan["lower_bound_m2"] >= 0.0


def _ur5_two_smrs(tmp_path):
    """A fresh user's UR5 robot file (example-robot-data's URDF, SMRs A and B; tests/data/newuser/README.md), or the
    test skipped where the package is not installed."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import real_arms

    if real_arms.robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    path = tmp_path / "ur5.yaml"
    path.write_text(f"name: ur5\nkind: urdf\nurdf: {real_arms.robots_dir()}/ur_description/urdf/ur5_robot.urdf\n"
                    "base_frame: base_link\ntip_frame: tool0\ntool_m: [0, 0, 0]\ntargets:\n  A: [0.03, 0.0, 0.05]\n"
                    "  B: [-0.03, 0.0, 0.05]\ncompliances_rad_per_Nm: [3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6, 3.0e-6]"
                    "\ngravity: [0, 0, -1]\n", encoding="utf-8")
    return load_robot(path)


def test_one_load_read_by_two_targets_is_one_load_per_configuration(tmp_path):
    """Replicate groups are per target: a fresh user's logs with two SMRs reported 6 loads per configuration for 3
    masses, and one mass per configuration read by both SMRs would count 2, leaving the one-load warning silent.
    The UR5 log (3 masses, counted here with pandas) and the same log with the 15 kg rows only."""
    import pandas as pd

    robot = _ur5_two_smrs(tmp_path)
    df = pd.read_csv(NEWUSER / "ur5_smr_clean_s12.csv")
    masses = df[df.fz_N != 0].groupby("pose_id").fz_N.nunique()
    assert read_measurements(NEWUSER / "ur5_smr_clean_s12.csv", robot).structure()["loads_per_configuration"] == {
        "min": int(masses.min()), "median": float(masses.median()), "max": int(masses.max())}
    one = df[(df.fz_N == 0) | (df.fz_N == df.fz_N.min())]
    one.to_csv(tmp_path / "one.csv", index=False)
    v = D.analyse(robot, read_measurements(tmp_path / "one.csv", robot), 0.01, gain=False)
    assert v["structure"]["loads_per_configuration"]["max"] == 1 and v["diagnostics"]["one_load_per_configuration"]


def test_a_negative_compliance_is_no_joint_s_in_the_geometry_correction(tmp_path):
    """A fresh user's UR5 (example-robot-data, two SMRs, 5-15 kg hung at the flange, a reference per configuration
    reused on a shuffled second pass; its own Pinocchio simulator of the exact statics, compliances 1.2e-6..5e-6):
    on one clean log the nominal fit puts k_wrist_1 at -1e-5, and the correction's first order kept that negative
    compliance while its exact motion took it as zero, so the rows were 'corrected' by 27 um RMS and the wrist
    compliance came out 10 sd off, with a note blaming the data. The second-order part at the fit's compliances is
    now within a factor 3 of the part at the simulator's true compliances (0.014 um: no correction), and the verdict
    has neither the correction's note nor a negative compliance beyond its interval."""
    robot = _ur5_two_smrs(tmp_path)
    meas = read_measurements(NEWUSER / "ur5_smr_clean_s12.csv", robot)
    ob = D.reduced(robot, D.Observed.of(robot, meas), D.check_identifiable(robot, meas, D.Observed.of(robot, meas)))
    des = D.build_design(robot, meas, ob)
    beta = D.fit(des.X0, des.y).beta
    assert beta.min() < -5e-6  # the fit's negative wrist compliance
    truth = np.array([2.0e-6, 1.2e-6, 1.8e-6, 3.5e-6, 4.0e-6, 5.0e-6])[np.asarray(ob.model_params(robot))]
    rms = [np.sqrt(np.mean(D.second_order_part(robot, meas, ob, k) ** 2)) for k in (beta, truth)]
    assert rms[1] < 1e-7 and rms[0] < 3 * rms[1], rms
    assert D.geometry_corrected(robot, meas, ob, des)[1] is False
    v = D.analyse(robot, meas, 0.01, gain=False)
    assert not any(n.startswith(D.GEOMETRY_NOTE) or "negative compliance" in n for n in v["notes"])


def test_a_blunder_in_any_direction_is_named_by_its_residual_vector(root):
    """A fresh user's KR 210 under a hand-held gauge (its own simulator): a 0.3 mm blunder in a random direction on
    data row 37 (its simulator's record), 9 sd of the rows' scatter, whose largest coordinate alone stayed below the
    screen's threshold (the screen missed 7 of 30 such logs). The residual vector's length names that row and no
    other; the clean twin (the same seed without the blunder) has none."""
    robot = load_robot(root / "config/robots/kuka_kr210_r2700_urdf.yaml")
    for name, want in (("kr210_gauge_blunder_s7.csv", [37]), ("kr210_gauge_clean_s7.csv", [])):
        meas = read_measurements(NEWUSER / name, robot)
        ob = D.reduced(robot, D.Observed.of(robot, meas), D.check_identifiable(robot, meas, D.Observed.of(robot, meas)))
        found = D.find_blunders(D.build_design(robot, meas, ob), meas.n_rows, 0.01)
        assert [int(meas.rows[i]) for i in found] == want, name


def test_a_drift_larger_than_every_deflection_is_said_to_be_no_tracker_s(tmp_path):
    """A fresh user's Panda bar log with a joint coupling (5 configurations, no drift simulated): the drift test
    reported 32 m/h at p = 1.8e-70 as "a drift of the tracker?". Over the longest time since a reference that drift
    moves a reading more than the largest deflection of the file (read here with pandas): the note says no tracker
    drifts so, and the time regressor takes up a misfit."""
    import pandas as pd

    path = _real_arm_file(tmp_path, "panda", "tip_frame: panda_link8\ntool_m: [0.0, 0.0, 0.0]\ngravity: [0, 0, -1]\n"
                                 "compliances_rad_per_Nm: [3.0e-4, 2.0e-4, 4.0e-4, 3.0e-4, 8.0e-4, 6.0e-4, 9.0e-4]\n")
    robot = load_robot(path)
    v = D.analyse(robot, read_measurements(NEWUSER / "panda_bar_coupling_s1.csv", robot), 0.01, gain=False)
    time = v["diagnostics"]["time"]
    df = pd.read_csv(NEWUSER / "panda_bar_coupling_s1.csv")
    largest = np.sqrt((df[["dx_m", "dy_m", "dz_m"]] ** 2).sum(axis=1)).max()
    span_h = (df.timestamp_s.max() - df.timestamp_s.min()) / 3600.0
    assert time["p_value"] < 0.01 and np.linalg.norm(time["rate_m_per_h"]) * span_h > largest
    assert any("more than the largest deflection measured: no tracker drifts so" in n for n in v["notes"])
    assert not any("a drift of the tracker (or of the zero point)" in n for n in v["notes"])


def test_a_blunder_the_union_model_absorbs_is_named_by_its_leverage():
    """A fresh user's iiwa (its own URDF and pinocchio simulator) under 5, 10 and 20 kg, a reference per visit, half
    the configurations revisited: a 0.2 mm blunder in a random direction (13 sd) on data row 95 (a 20 kg row, which
    the union model's cubic stiffness loads most) and on row 75 (a configuration visited once), the rows of the
    simulator's record. The plain residual length missed both; studentised by the row's leverage it names that row
    and no other. The clean twin (the same seed, no blunder) has none, and the leverage statistic equals the
    deleted residual's Mahalanobis length (a refit without the row, brute force)."""
    robot = load_robot(NEWUSER / "iiwa14_h53.yaml")
    for name, want in (("iiwa_hang_blunder_row95_s405.csv", [95]), ("iiwa_hang_blunder_row75_s201.csv", [75]),
                       ("iiwa_hang_clean_s405.csv", [])):
        meas = read_measurements(NEWUSER / name, robot)
        ob = D.reduced(robot, D.Observed.of(robot, meas), D.check_identifiable(robot, meas, D.Observed.of(robot, meas)))
        des = D.build_design(robot, meas, ob)
        found = D.find_blunders(des, meas.n_rows, 0.01)
        assert [int(meas.rows[i]) for i in found] == want, name
    X, y, d = des.union(), des.y, des.d
    f = D.fit(X, y)
    e = (y - X @ f.beta).reshape(-1, d)
    lengths = D._studentised_lengths(X.reshape(-1, d, X.shape[1]), f, e)
    for i in (3, 40, 95):
        rest = np.ones(len(y), bool)
        rest[i * d:(i + 1) * d] = False
        g = D.fit(X[rest], y[rest])
        Xi = X[~rest]
        r = y[~rest] - Xi @ g.beta  # the deleted residual, covariance sigma^2 (I + X_i (X^T X)_(i)^-1 X_i^T)
        V = np.eye(d) + Xi @ g.cov_unscaled @ Xi.T
        assert lengths[i] == pytest.approx(np.sqrt(r @ np.linalg.solve(V, r)), rel=1e-6)


def test_a_pulley_tilting_the_load_is_named_as_outside_the_catalogue_whatever_the_closed_test_found():
    """A fresh user's planar 4R in its vertical plane (its own simulator): a hand-held gauge whose every push is
    tilted 8 deg by a pulley. Seed 1's closed test found a lack of fit with no cause (``unexplained`` with no word of
    what); seed 11's found nothing (``none``, the tilt at p = 1e-11 only a note). Both now name the tilt
    (``outside_catalogue``) with its angle near the simulator's 8 deg, and not the load offset that also moves a planar
    arm's tool (the tilt adds to it, it adds nothing to the tilt)."""
    robot = load_robot(NEWUSER / "planar_4r_vertical.yaml")
    for name in ("r4v_pulley8deg_s1.csv", "r4v_pulley8deg_s11.csv"):
        v = D.analyse(robot, read_measurements(NEWUSER / name, robot), 0.01, gain=False)
        diag = v["diagnostics"]
        assert v["cause"] == "unexplained" and diag["outside_catalogue"] == ["load_direction"], name
        assert 6.0 < diag["load_direction"]["angle_deg"] < 10.0 and v["p_value"] < 1e-6
        assert diag["load_offset"]["beyond_load_direction_p"] > 0.01 > diag["load_direction"]["beyond_load_offset_p"]
        assert "the load acts in its logged direction" in v["p_value_statement"]


def test_an_arm_analysed_without_its_masses_is_said_to_be_taken_as_weightless():
    """A fresh user's 150 kg-class arm in modified DH (its own simulator, gravity-preloaded backlash on joints 2 and 3,
    hanging masses, a reference per configuration reused on a second pass). With the robot file's masses the backlash
    is named; without them the verdict goes wrong and a note says the arm was taken as weightless. On the same arm
    with loads that never reverse a joint's total torque, a note says backlash was not tested at all."""
    masses, bare = load_robot(NEWUSER / "mdh150_masses.yaml"), load_robot(NEWUSER / "mdh150_nomass.yaml")
    data = NEWUSER / "mdh150_backlash_s1.csv"
    v = D.analyse(masses, read_measurements(data, masses), 0.01, gain=False)
    assert v["cause"] == "backlash" and not any("took the arm as weightless" in n for n in v["notes"])
    v = D.analyse(bare, read_measurements(data, bare), 0.01, gain=False)
    assert v["cause"] != "backlash" and any("took the arm as weightless" in n for n in v["notes"])
    unreversed = NEWUSER / "mdh150_backlash_unreversed_s1.csv"
    v = D.analyse(masses, read_measurements(unreversed, masses), 0.01, gain=False)
    assert v["cause"] == "none" and any("backlash is not tested at all" in n for n in v["notes"])


def test_a_joint_turned_only_by_the_loads_printed_digits_is_not_identified(root):
    """A fresh user's KR 210 pushed by hand through a flange force/torque sensor, the push on joint 6's axis, the
    wrench logged to 0.001 N and 0.0001 N m (its own simulator): joint 6 is turned only by those digits (its torque
    1e-7 of the largest, computed here from the log's wrench with the robot's Jacobian), and its compliance was fitted
    to them and the clean log refused as a unit error. Joint 6 is now not identifiable, and the verdict is none."""
    robot = load_robot(root / "config/robots/kuka_kr210_r2700.yaml")
    meas = read_measurements(NEWUSER / "kr210_ft_rounded_clean_s102.csv", robot)
    tau = np.abs(D.torques(robot, meas.q, D.load_of(meas))).max(axis=0)
    assert 1e-9 < tau[5] / tau.max() < 1e-6, tau
    assert D.check_identifiable(robot, meas).tolist() == [5]
    v = D.analyse(robot, meas, 0.01, gain=False)
    assert v["cause"] == "none" and v["nominal"]["not_identifiable_joints"] == [6]


def test_loads_logged_in_a_force_torque_sensor_s_frame_are_refused_naming_the_frame(root):
    """The same user's KR 210 logs with the wrench left in the flange sensor's frame (its simulator's record): read
    as logged, `unexplained` with four false causes in 12 of 12 and a calibrated.yaml with k3 a fifth of its truth.
    Refused, naming the load columns and the frame; the same log in the base frame (the clean twin) is analysed."""
    _refused_then_clean(load_robot(root / "config/robots/kuka_kr210_r2700.yaml"), [
        ("kr210_ft_sensorframe_s101.csv", r"columns fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm.*base frame.*times better "
                                          r".*turned from the tip frame")], "kr210_ft_clean_s101.csv")


def _refused_then_clean(robot, refused: list[tuple[str, str]], clean: str) -> None:
    """Each log of ``refused`` (file in NEWUSER, message pattern) refused by the analysis with that message, and the
    clean twin ``clean`` analysed to none."""
    for name, pattern in refused:
        with pytest.raises(InputError, match=pattern):
            D.analyse(robot, read_measurements(NEWUSER / name, robot), 0.01, gain=False)
    assert D.analyse(robot, read_measurements(NEWUSER / clean, robot), 0.01, gain=False)["cause"] == "none"


def _erd_robot(directory, name: str, urdf: str, base: str, tip: str, extra: str):
    """A fresh user's robot file for a URDF of example-robot-data (``urdf`` under its robots folder, the chain from
    ``base`` to ``tip``, further keys ``extra``), loaded; the test is skipped without the package."""
    from real_arms import robots_dir

    if robots_dir() is None:
        pytest.skip("example-robot-data is not installed")
    path = Path(directory) / f"{name}.yaml"
    path.write_text(f"name: {name}\nkind: urdf\nurdf: {robots_dir() / urdf}\nbase_frame: {base}\ntip_frame: {tip}\n"
                    + extra, encoding="utf-8")
    return load_robot(path)


def _ur5_on_a_bar(directory):
    """A fresh user's UR5 (example-robot-data's URDF) with a 1.5 kg loading bar and two SMRs on it, its robot file."""
    return _erd_robot(directory, "lab-ur5", "ur_description/urdf/ur5_robot.urdf", "base_link", "tool0",
                      "tool_m: [0.0, 0.0, 0.05]\n"
                      "compliances_rad_per_Nm: [1.0e-5, 1.2e-5, 1.5e-5, 3.0e-5, 3.0e-5, 4.0e-5]\n"
                      "targets: {A: [0.15, 0.0, 0.07], B: [0.35, 0.0, 0.07]}\npayload_kg: 1.5\n"
                      "payload_com_m: [0.2, 0.0, 0.05]\ngravity: [0, 0, -1]\n")


def test_a_force_axis_of_the_wrong_sign_or_a_turned_base_frame_is_refused(tmp_path):
    """A fresh user's UR5 (its own pinocchio simulator: masses of 2-8 kg on a loading bar, two SMRs, a reference per
    visit, revisits) logged with fz of the wrong sign (the moments right), or everything in the UR controller's
    ``base`` frame, base_link turned 180 deg about z: read as logged, `unexplained` with a drift of thousands of um/h
    named and the wrist compliances 11-17 times their truth in calibrated.yaml (10 of 10 seeds). Both refused, naming
    the column and the turn; the clean twin is analysed as before (none)."""
    _refused_then_clean(_ur5_on_a_bar(tmp_path), [
        ("ur5_bar_flipfz_s1.csv", r"columns fz_N'.* times better .*with fz_N negated"),
        ("ur5_bar_urbase_s1.csv", r"columns dx_m, dy_m, dz_m, fx_N.*mz_Nm'.*base frame \(base_link\).*displacements "
                                  r"and loads all turned 180 deg about the base's z axis")], "ur5_bar_clean_s1.csv")


def test_displacements_alone_turned_are_refused_and_a_weaker_frame_fault_is_noted(tmp_path):
    """Another fresh user's planar 3R under hanging masses with the tracker's displacements turned 90 deg in the plane
    and the loads logged right: `unexplained` with false causes and a drift of 1.8e4 um/h in 9 of 9 (only the
    displacements and loads turned together were tried). Refused, naming the displacement columns. Its stiffer UR5
    (deflections 20-40 um beside 5 um of noise) pushed along +-x, +-y, +-z with fz negated fitted 4.4 times better
    negated, under the ten times of a refusal: `unexplained` with false causes in silence in 6 of 8; now a note
    names the column, and the clean twin has none."""
    r3 = load_robot(NEWUSER / "r3_masses.yaml")
    with pytest.raises(InputError, match=r"columns dx_m, dy_m'.*displacements alone turned 90 deg"):
        D.analyse(r3, read_measurements(NEWUSER / "r3_hang_displacements_turned90_s1.csv", r3), 0.01, gain=False)
    ur5 = _erd_robot(tmp_path, "ur5", "ur_description/urdf/ur5_robot.urdf", "base_link", "tool0",
                     "tool_m: [0.0, 0.05, 0.10]\n"
                     "compliances_rad_per_Nm: [1.0e-5, 1.0e-5, 1.5e-5, 3.0e-5, 3.0e-5, 4.0e-5]\n"
                     "gravity: [0, 0, -1]\n")
    notes = D.prepare(ur5, read_measurements(NEWUSER / "ur5_stiff_push_fzneg_s2.csv", ur5)).notes
    assert any(n.startswith("analysed as logged, but the nominal model fits the data") and "fz_N negated" in n
               for n in notes), notes
    clean = D.prepare(ur5, read_measurements(NEWUSER / "ur5_stiff_push_clean_s2.csv", ur5)).notes
    assert not any(n.startswith("analysed as logged") for n in clean)


def test_one_displacement_column_in_millimetres_is_refused(tmp_path):
    """A fresh user's 6R arm in standard DH with masses (its own simulator: hanging 5-20 kg, a reference per
    configuration reused on a second pass, timestamps only) logged dz, or dx, in millimetres under a `_m` label: read
    as logged, `unexplained` with four false causes and k2 2700 times its truth in calibrated.yaml (all three columns
    in mm were refused by their size, one was not). Refused, naming the column; the clean log itself is analysed."""
    import pandas as pd

    robot = load_robot(NEWUSER / "arm6_dh_masses.yaml")
    clean = NEWUSER / "arm6_clean_s1.csv"
    for col in ("dz_m", "dx_m"):
        df = pd.read_csv(clean)
        df[col] *= 1000.0
        df.to_csv(tmp_path / f"{col}.csv", index=False)
        with pytest.raises(InputError, match=rf"columns {col}'.* times better .*with {col} divided by 1000"):
            D.analyse(robot, read_measurements(tmp_path / f"{col}.csv", robot), 0.01, gain=False)
    assert D.analyse(robot, read_measurements(clean, robot), 0.01, gain=False)["cause"] == "none"


def test_a_clock_in_another_unit_or_under_another_name_is_named(tmp_path):
    """The same user's 3-hour campaign with its timestamps in milliseconds (read as a drift of 0.04 um/h at p = 5e-17)
    or in hours (1.4e5 um/h), no word of the unit; its column named time_s only 'not used'. Each is named: the span
    in days, the readings' step in seconds, time_s as timestamp_s's misspelling; the seconds themselves pass."""
    import pandas as pd

    robot = load_robot(NEWUSER / "arm6_dh_masses.yaml")
    df = pd.read_csv(NEWUSER / "arm6_clean_s1.csv")
    hours = np.ptp(df["timestamp_s"]) / 3600.0
    assert 1.0 < hours < 5.0  # the campaign: hours in seconds

    def notes(frame, name):
        frame.to_csv(tmp_path / name, index=False)
        return " ".join(read_measurements(tmp_path / name, robot).notes)

    assert "timestamp_s" not in notes(df, "s.csv")
    assert f"spans {hours * 1000 / 24:.3g} days" in notes(df.assign(timestamp_s=df.timestamp_s * 1000), "ms.csv")
    step = float(np.median(np.diff(np.sort(df.timestamp_s / 3600))[np.diff(np.sort(df.timestamp_s)) > 0]))
    assert f"readings {step:.3g} s apart" in notes(df.assign(timestamp_s=df.timestamp_s / 3600), "h.csv")
    assert "'time_s' looks like timestamp_s" in notes(df.rename(columns={"timestamp_s": "time_s"}), "name.csv")
    # a drift of 40 um/h logged without a clock: found in row order, and the statement says per rows, not per hour
    v = D.analyse(robot, read_measurements(NEWUSER / "arm6_drift40_no_time.csv", robot), 0.01, gain=False)
    assert v["diagnostics"]["outside_catalogue"] == ["time"] and v["diagnostics"]["time"]["clock"] == "row order"
    assert "um per 3600 rows)" in v["p_value_statement"] and "um/h" not in v["p_value_statement"]


def test_a_named_drift_of_the_tracker_is_not_the_model_s_error(tmp_path):
    """The same user's arm with the tracker drifting 40 um/h along x over 3 hours: the drift named (the verdict
    unexplained by it alone), then put into calibrated.yaml's model_error_m as 30 um, and predictions' sd 6 times their
    error. The drift's own mean square, rate^2 (t - t_ref)^2 / d over the loaded rows (t_ref: the configuration's
    exact-zero reference row, found here from the file), is not the model's error."""
    import pandas as pd

    robot = load_robot(NEWUSER / "arm6_dh_masses.yaml")
    data = NEWUSER / "arm6_drift40_s1.csv"
    pre = D.prepare(robot, read_measurements(data, robot))
    v = D.verdict_of(robot, pre)
    diag = v["diagnostics"]
    rate = np.asarray(diag["time"]["rate_m_per_h"])
    assert diag["outside_catalogue"] == ["time"] and abs(rate[0] - 40e-6) < 6e-6, rate
    df = pd.read_csv(data).sort_values("timestamp_s", kind="stable")
    q = df.filter(like="_deg").round(6).astype(str).agg(",".join, axis=1)
    zero = (df[["fx_N", "fy_N", "fz_N"]] == 0).all(axis=1)
    t_ref = df[zero].groupby(q[zero])["timestamp_s"].min()
    since = (df.timestamp_s - q.map(t_ref))[~zero].to_numpy()
    expect = np.mean(since**2) * float(rate @ rate) / 3600**2 / 3
    assert D.tracker_drift_ms(pre, diag) == pytest.approx(expect, rel=1e-9)
    _, cal = D.complete(robot, pre, v, data)
    held = v["held_out"]
    rms, right = held["rms_nominal_m"], held["rms_expected_nominal_m"]
    baseline = max(right**2, cal.sigma_m**2 + expect)  # a right model's error, which may hold the drift already
    assert cal.model_error_m == pytest.approx(np.sqrt(max(rms**2 - baseline, 0.0)), rel=1e-9, abs=1e-12)
    # 30 um with the noise alone taken out, 14 um with the drift too, 0 now that the shared reference errors are not
    # counted as the model's (the simulator's model is exact)
    assert cal.model_error_m < 0.5 * np.sqrt(rms**2 - cal.sigma_m**2)


def test_a_drift_beside_a_named_cause_is_said_to_be_what_is_left():
    """The same user's arm with a nonlinear stiffness at joint 2 and a drift of 20 um/h: `unexplained` by the lack of
    fit beside nonlinear_joint_stiffness, the statement saying only that something the catalogue does not describe
    is left, the drift (p = 1e-9) in a note. The statement now names the drift as what is left may be, with its rate
    (20 um/h along x in the simulator)."""
    robot = load_robot(NEWUSER / "arm6_dh_masses.yaml")
    v = D.analyse(robot, read_measurements(NEWUSER / "arm6_nl2_drift20_s1.csv", robot), 0.01, gain=False)
    assert v["cause"] == "unexplained" and "nonlinear_joint_stiffness" in v["causes"]
    rate = np.linalg.norm(v["diagnostics"]["time"]["rate_m_per_h"]) * 1e6
    assert 12 < rate < 28 and f"the rows drift beyond the chosen causes ({rate:.3g} um/h" in v["p_value_statement"]


def test_a_hanger_left_out_of_the_log_is_named_with_its_mass(tmp_path):
    """The UR5 user's 1.5 kg hanger hung with the masses at the bar's end and not logged: `unexplained` in 10 of 10
    logs with a drift of 4,700 um/h named, no word of a load, and in 6 the extended model (wrist compliances up to
    5.6 times their truth) in calibrated.yaml. The verdict now names the missing load (diagnostics.unlogged_load,
    refitted with the compliances: its mass within 5 % of the simulator's 1.5 kg, along gravity) as what explains
    the data, and calibrated.yaml holds the nominal model; on the clean twin the test finds nothing."""
    robot = _ur5_on_a_bar(tmp_path)
    pre = D.prepare(robot, read_measurements(NEWUSER / "ur5_bar_hanger_s1.csv", robot))
    v = D.verdict_of(robot, pre, gain=False)
    un = v["diagnostics"]["unlogged_load"]
    assert v["cause"] == "unexplained" and v["diagnostics"]["outside_catalogue"] == ["unlogged_load"]
    assert un["p_value"] < 1e-10 and un["mass_kg"] == pytest.approx(1.5, rel=0.05)
    np.testing.assert_allclose(un["force_N"][:2], 0.0, atol=1e-12)  # hanging masses: along gravity alone
    assert D.complete(robot, pre, v, NEWUSER / "ur5_bar_hanger_s1.csv")[1].causes == ()
    clean = D.analyse(robot, read_measurements(NEWUSER / "ur5_bar_clean_s1.csv", robot), 0.01, gain=False)
    assert clean["diagnostics"]["unlogged_load"]["p_value"] > 0.01 and abs(clean["diagnostics"]["unlogged_load"][
        "mass_kg"]) < 0.05


def test_a_soft_arm_under_a_scattered_gauge_is_corrected_for_its_geometry(tmp_path):
    """A fresh user's Jaco2 (example-robot-data; compliances 2.2e-4..2e-3 rad/(N m), its weight from the URDF) under a
    hand-held gauge 3 deg off axis, its own pinocchio simulator of the exact statics: the second-order part (7 um)
    was below 0.2 of the union's residuals (65 um, the scattered loads' and the references' shared errors in them),
    so the rows were left first-order and the held-out predictions' z came out 2-3. The noise the error model finds
    (21 um) is now the scale: the rows are corrected, and the compliances come closer to the simulator's truth (RMS
    of their z over the identified joints, the 95 % half-width / 1.96 as sd) than uncorrected."""
    robot = _erd_robot(tmp_path, "jaco2", "kinova_description/robots/kinova.urdf", "base", "j2s6s200_end_effector",
                       "tool_m: [0.0, 0.0, 0.0]\ncompliances_rad_per_Nm: [5.0e-4, 3.0e-4, 6.0e-4, 1.2e-3, 1.2e-3, "
                       "1.5e-3]\ngravity: [0, 0, -1]\n")
    meas = read_measurements(NEWUSER / "jaco2_gauge_exact_s3.csv", robot)
    truth = np.array([6e-4, 2.2e-4, 7.5e-4, 1.0e-3, 1.6e-3, 2.0e-3])  # the simulator's

    def z_rms(pre):
        v = D.verdict_of(robot, pre, gain=False)["nominal"]
        k, ci, j = (np.array(v[key]) for key in ("k", "k_ci95", "k_joints"))
        return float(np.sqrt(np.mean(((k - truth[j - 1]) / (ci / 1.96)) ** 2)))

    pre = D.prepare(robot, meas)
    assert any(n.startswith(D.GEOMETRY_NOTE) and "noise the rows' error model finds" in n for n in pre.notes)
    first_order = D.prepare(robot, meas, geometry_scale=1.0)  # a scale of 1 m: never corrected
    assert not any(n.startswith(D.GEOMETRY_NOTE) for n in first_order.notes)
    assert z_rms(pre) < z_rms(first_order) and z_rms(pre) < 2.0, (z_rms(pre), z_rms(first_order))


def test_a_forgotten_hook_beside_real_causes_or_a_drift_is_said(tmp_path):
    """A fresh user's Panda (example-robot-data, the URDF's weights, exact statics in its own simulator), hanging
    masses with a 0.8 kg hook forgotten in the log: beside a real backlash the load was found (p = 2e-16 beyond the
    chosen causes) and said nowhere, calibrated.yaml extended with a false coupling; beside a drift of 30 um/h the
    verdict named the load and the statement left the drift (p = 4e-5) out. Now a note names the load beside the
    causes, and the statement names the drift beside the load."""
    robot = _erd_robot(tmp_path, "panda", "panda_description/urdf/panda.urdf", "panda_link0", "panda_hand_tcp",
                       "compliances_rad_per_Nm: [2.0e-6, 2.0e-5, 6.0e-6, 1.2e-5, 4.0e-6, 1.5e-5, 8.0e-6]\n"
                       "gravity: [0, 0, -1]\n")
    v = D.analyse(robot, read_measurements(NEWUSER / "panda_hook_backlash_s5.csv", robot), 0.01, gain=False)
    un = v["diagnostics"]["unlogged_load"]
    assert un["beyond_chosen_p"] < 1e-6 and un["chosen_beyond_p"] < 0.01 and 0.6 < un["mass_kg"] < 1.0
    assert any(n.startswith("beside ") and "a constant load missing from the log adds to the fit" in n
               for n in v["notes"]), v["notes"]
    v = D.analyse(robot, read_measurements(NEWUSER / "panda_hook_drift_s1.csv", robot), 0.01, gain=False)
    assert v["diagnostics"]["outside_catalogue"] == ["unlogged_load"] and v["diagnostics"]["time"]["p_value"] < 0.01
    assert "the rows drift beyond the chosen causes (" in v["p_value_statement"]


def test_a_joint_the_loads_reverse_in_few_rows_is_named(tmp_path):
    """The Panda user's backlash of 0.3 mrad at joint 5, its hook logged: `none` in 2 of 6 logs with a note naming only
    the joints whose torque never reverses, and no word that joint 5 reverses in a few rows only. A note now names
    the joints reversed in fewer than a fifth of the rows, with their count; joint 5's equals the rows where the load
    turns the sign of its total torque (the URDF's weight torques plus the load's, computed here)."""
    robot = _erd_robot(tmp_path, "panda", "panda_description/urdf/panda.urdf", "panda_link0", "panda_hand_tcp",
                       "compliances_rad_per_Nm: [2.0e-6, 2.0e-5, 6.0e-6, 1.2e-5, 4.0e-6, 1.5e-5, 8.0e-6]\n"
                       "gravity: [0, 0, -1]\n")
    pre = D.prepare(robot, read_measurements(NEWUSER / "panda_hook_logged_backlash_s3.csv", robot))
    weight = robot.gravity_torques(pre.m.q)[:, 4]
    total = D.torques(robot, pre.m.q, D.load_of(pre.m))[:, 4] + weight
    n = int(np.sum(np.sign(total) != np.sign(weight)))
    assert 0 < n < 0.2 * pre.m.n_rows and D.backlash_rows(robot, pre)[4] == n
    v = D.verdict_of(robot, pre, gain=False)
    assert any("in few rows: a backlash there is tested with little power" in x
               and f"panda_joint5 ({n} of {pre.m.n_rows} rows)" in x for x in v["notes"]), v["notes"]


def test_moments_logged_about_the_sensor_are_named_as_a_load_offset(root):
    """The same user's KR 210 with the moments taken about the flange sensor's origin instead of the tool point
    (seed 102: before, `none` with k4 and k5 at 0.5-0.64 of the truth). The verdict is `unexplained` naming the
    load offset, found far from alpha, at about the tool point's offset from the flange (-tool_m in the tip frame,
    the simulator's; first order, so within 0.1 m)."""
    robot = load_robot(root / "config/robots/kuka_kr210_r2700.yaml")
    v = D.analyse(robot, read_measurements(NEWUSER / "kr210_ft_moment_about_sensor_s102.csv", robot), 0.01,
                  gain=False)
    assert v["cause"] == "unexplained" and v["diagnostics"]["outside_catalogue"] == ["load_offset"]
    r = np.array(v["diagnostics"]["load_offset"]["offset_m"])
    assert v["p_value"] < 1e-6 and np.linalg.norm(r + np.asarray(robot.tool_m)) < 0.1, r


def test_two_visits_back_to_back_without_a_visit_column_are_named(tmp_path):
    """A fresh user's UR10 (two SMRs, hanging masses, a reference per configuration reused on a shuffled second pass;
    its own pinocchio simulator): the second pass began at C18, where the first ended, and without a visit column the
    two visits were read as one in silence. The note names that visit (its rows: those of C18, found here from the
    file), and no other; the verdict is the clean log's none."""
    import pandas as pd

    path = _real_arm_file(tmp_path, "ur10", "tip_frame: tool0\ntool_m: [0.0, 0.0, 0.1]\ntargets:\n"
                          "  A: [0.04, 0.0, 0.1]\n  B: [-0.04, 0.0, 0.1]\ngravity: [0, 0, -1]\n")
    robot = load_robot(path)
    data = NEWUSER / "ur10_two_smr_refconfig_nocols_s8.csv"
    v = D.analyse(robot, read_measurements(data, robot), 0.01, gain=False)
    notes = [n for n in v["notes"] if "two visits back to back" in n]
    df = pd.read_csv(data)
    rows = df.index[df.pose_id == "C18"].to_numpy()
    assert v["cause"] == "none" and len(notes) == 1 and notes[0].startswith("1 visit(s)")
    assert f"(data rows {', '.join(map(str, rows[:5]))}, ...)" in notes[0]


def test_a_p_value_below_the_smallest_double_is_stated_as_such():
    """A fresh user's backlash of 0.002 rad on a Jaco2 came out with p_value 0.0 (below the smallest double) and the
    statement "adjusted p = 0": it now reads "< 1e-300"; a representable p is stated as before."""
    assert D.p_value_statement("backlash", ["backlash"], 0.0, {"backlash": 0.0}, 0.01).startswith(
        "adjusted p < 1e-300 of 'backlash is not needed'")
    assert D.p_value_statement("backlash", ["backlash"], 3e-45, {"backlash": 3e-45}, 0.01).startswith(
        "adjusted p = 3e-45 of 'backlash is not needed'")
    assert "adjusted p < 1e-300 of 'nothing outside" in D.p_value_statement("unexplained", ["lack_of_fit"], 0.0, {},
                                                                             0.01)


def _ur10_lab(directory):
    """A fresh user's UR10 (example-robot-data's URDF, tool point 0.1 m along tool0's z, the lab's guessed
    compliances), its robot file."""
    return _erd_robot(directory, "ur10-lab", "ur_description/urdf/ur10_robot.urdf", "base_link", "tool0",
                      "tool_m: [0.0, 0.0, 0.10]\n"
                      "compliances_rad_per_Nm: [2.0e-6, 2.0e-6, 3.0e-6, 1.0e-5, 1.0e-5, 1.0e-5]\ngravity: [0, 0, -1]\n")


def test_the_base_tilt_law_is_a_rigid_turn_and_the_regressors_are_the_simulators(tmp_path):
    """The simulator's compliant base (``Truth.base_tilt``): every point moves as the whole arm turned by the small
    rotation w about the pivot (scipy's rotation of the forward kinematics' points, to second order in w), w = c P M
    with M the load's moment about the pivot, summed here by hand over the force and the bar's moment. The analysis's
    regressors (``_base_columns``, per unit of c, c h, c h^2) give the simulator's motion at two targets with the tool's
    rotation under a loading bar's wrench."""
    from scipy.spatial.transform import Rotation

    robot = _erd_robot(tmp_path, "ur10-targets", "ur_description/urdf/ur10_robot.urdf", "base_link", "tool0",
                       "tool_m: [0.0, 0.0, 0.10]\ntargets: {A: [0.05, 0.0, 0.12], B: [-0.05, 0.02, 0.12]}\n"
                       "compliances_rad_per_Nm: [2.0e-6, 2.0e-6, 3.0e-6, 1.0e-5, 1.0e-5, 1.0e-5]\n"
                       "gravity: [0, 0, -1]\n")
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (12, 6))
    F = rng.normal(0, 100.0, (12, 3))
    Mt = rng.normal(0, 20.0, (12, 3))
    c, h = 3e-7, 0.6
    truth = T.Truth(np.full(6, 1e-12), base_tilt=(c, h))
    pivot = np.array([0.0, 0.0, -h])
    x = T.target_world(robot, q, None, None)
    M = np.array([np.cross(xi - pivot, f) + m for xi, f, m in zip(x, F, Mt)])
    M[:, 2] = 0.0  # the horizontal part: the base turns about horizontal axes only
    pts = T.target_world(robot, q, np.arange(12) % 2, ("A", "B"))
    disp, rot = T.base_tilt_motion(robot, truth, q, F, Mt, pts)
    turned = np.array([Rotation.from_rotvec(c * m).apply(p - pivot) + pivot for m, p in zip(M, pts)])
    assert np.allclose(rot, c * M, rtol=1e-12, atol=0)
    assert np.abs(disp - (turned - pts)).max() <= 2 * (c * np.abs(M).max()) ** 2 * np.abs(pts - pivot).max()
    # the analysis's columns against the simulator's deflection with and without the base, at the targets with rotation
    target = np.arange(12) % 2
    moved = (T.deflection(robot, truth, q, F, Mt, target, ("A", "B"), orientation=True)
             - T.deflection(robot, replace(truth, base_tilt=None), q, F, Mt, target, ("A", "B"), orientation=True))
    cols = ["pose_id", *robot.joint_columns("q", "_deg"), "target", "fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm",
            "dx_m", "dy_m", "dz_m", "rx_rad", "ry_rad", "rz_rad"]
    rows = [[f"P{i}", *np.degrees(q[i]), "AB"[target[i]], *F[i], *Mt[i], *np.zeros(6)] for i in range(12)]
    path = tmp_path / "bar.csv"
    path.write_text(",".join(cols) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    meas = read_measurements(path, robot)
    ob = D.Observed.of(robot, meas)
    pre = SimpleNamespace(m=meas, ob=ob, w=np.ones(12))
    X = D._base_columns(robot, pre)
    assert np.allclose(X @ np.array([c, c * h, c * h * h]), moved, rtol=1e-9, atol=1e-15)
    # a base compliant by c_x about the base's x axis and c_y about its y (gravity along -z): w = (c_x M_x, c_y M_y, 0)
    cx, cy = 5e-7, 1e-7
    plate = replace(truth, base_tilt=(cx, cy, h))
    disp, rot = T.base_tilt_motion(robot, plate, q, F, Mt, pts)
    assert np.allclose(rot, M * [cx, cy, 0.0], rtol=1e-12, atol=0)
    moved = (T.deflection(robot, plate, q, F, Mt, target, ("A", "B"), orientation=True)
             - T.deflection(robot, replace(truth, base_tilt=None), q, F, Mt, target, ("A", "B"), orientation=True))
    E = D._horizontal_basis(robot)[1]  # the analysis's axes: C = E^T diag(c_x, c_y, 0) E, components C11, C22, C12
    C = E.T @ np.diag([cx, cy, 0.0]) @ E
    coef = np.array([C[0, 0], C[1, 1], C[0, 1]])
    assert np.allclose(D._base_columns(robot, pre, axes=True) @ np.concatenate([coef, coef * h, coef * h * h]), moved,
                       rtol=1e-9, atol=1e-15)
    soft, axis = D._principal(robot, C)
    assert np.allclose(soft, [cx, cy], rtol=1e-12) and np.allclose(axis, [1.0, 0.0, 0.0], atol=1e-12)


def test_a_compliant_pedestal_is_named_outside_the_catalogue(tmp_path):
    """A fresh user's UR10 on a pedestal (its own simulator: the base tilts about horizontal axes through a pivot
    0.6 m below it by c = 4e-7 rad/(N m) times the load's moment about the pivot, 15-87 um at the tool under 10 kg;
    hanging masses 2-10 kg on a 0.3 kg hook, a reference per visit, two passes, 15 um noise): `joint_coupling` at
    p = 0.0036, no warning (13 of 20 logs named a false catalogue cause, the rest `none` with the shoulder's
    compliance 22-30 % high). Now `unexplained` with the base named and its compliance and pivot found; beside a real
    backlash, the backlash is named and the base is noted; the clean twin says `none` without the note."""
    robot = _ur10_lab(tmp_path)
    verdicts = {}
    for name in ("ur10_pedestal_s1.csv", "ur10_pedestal_backlash_s3.csv", "ur10_pedestal_clean_s1.csv"):
        out = tmp_path / name
        assert main(["discrepancy", "--robot", robot.source, "--data", str(NEWUSER / name), "--out", str(out),
                     "--no-figures", "--quiet"]) == 0
        verdicts[name] = json.loads((out / "verdict.json").read_text())
    v = verdicts["ur10_pedestal_s1.csv"]
    base = v["diagnostics"]["base_compliance"]
    assert v["cause"] == "unexplained" and v["diagnostics"]["outside_catalogue"] == ["base_compliance"]
    assert base["p_value"] < 1e-6 and 2e-7 < base["compliance_rad_per_Nm"] < 8e-7
    assert 0.1 < base["pivot_depth_m"] < 1.2
    assert "base of compliance" in v["p_value_statement"] or "the base stays put" in v["p_value_statement"]
    # calibrated.yaml's compliances absorb the tilt (a fresh user's IRB 4600: k2 3.5 times its truth, no word)
    absorbed = "calibrated.yaml's compliances are the nominal model's fitted to rows moved by a base that tilts"
    assert any(n.startswith(absorbed) for n in v["notes"]), v["notes"]
    v = verdicts["ur10_pedestal_backlash_s3.csv"]
    assert v["cause"] == "backlash" and any("tilt of the whole robot" in n and "beyond backlash" in n
                                            for n in v["notes"]), v["notes"]
    v = verdicts["ur10_pedestal_clean_s1.csv"]
    assert v["cause"] == "none" and v["diagnostics"]["base_compliance"]["p_value"] > 0.01
    assert not any("tilt of the whole robot" in n or n.startswith(absorbed) for n in v["notes"])


def test_a_base_tilt_is_not_taken_for_a_real_cause_or_found_in_clean_data(tmp_path):
    """stiffcal's own simulator, the same UR10 under hanging masses of 2-10 kg, a reference per visit, two passes:
    a compliant base alone is `unexplained` with the base named (2 of 2 seeds), a coupled pair of joints alone is
    still `joint_coupling` without a base note, clean data `none` (2 of 2 each)."""
    robot = _ur10_lab(tmp_path)
    protocol = replace(R.PROTOCOLS["hanging x3, reference per visit, 2 passes"], magnitudes_N=(19.6, 49.0, 98.1),
                       sigma_m=1.5e-5, sigma_per_m=0.0)
    k = np.array([3.0e-6, 2.5e-6, 4.0e-6, 1.2e-5, 1.2e-5, 1.5e-5])
    C = np.zeros((6, 6))
    C[1, 2] = C[2, 1] = 0.3 * np.sqrt(k[1] * k[2])
    truths = {"base": T.Truth(k, base_tilt=(4e-7, 0.6)), "coupling": T.Truth(k, coupling=C), "clean": T.Truth(k)}
    for seed in (0, 1):
        for name, truth in truths.items():
            rng = np.random.default_rng(seed)
            log = T.lab_log(robot, protocol, rng, 30)
            path = _write(tmp_path, T.lab_csv(robot, log, T.measure(robot, truth, log, rng)))
            v = D.analyse(robot, read_measurements(path, robot), 0.01)
            noted = any("tilt of the whole robot" in n for n in v["notes"])
            if name == "base":
                assert v["cause"] == "unexplained" and v["diagnostics"]["outside_catalogue"] == ["base_compliance"]
            else:
                assert v["causes"] == ([] if name == "clean" else ["joint_coupling"]) and not noted, (name, seed)


def test_a_base_stiffer_about_one_axis_is_named_with_its_softest_axis(tmp_path):
    """A fresh user's KR 210 on a plate stiffer about one horizontal axis than the other: `none` in 5 of 5 logs under
    a loading bar, the base's test (one compliance about every horizontal axis) short of its level. stiffcal's own
    simulator, the UR10 on a base 15 times softer about x than about y (c_x = 3e-7, c_y = 2e-8 rad/(N m), pivot 0.5 m
    down) under a loading bar, a reference per visit, two passes: `unexplained` with the base named in 6 of 6 seeds
    (5 of 6 with the isotropic test alone; `none` in the sixth, seed 4, tested here), its softest axis the base's x
    and its principal compliances near the truth; under hanging masses 4 of 6 (1 of 6 before)."""
    robot = _ur10_lab(tmp_path)
    protocol = replace(R.PROTOCOLS["loading bar x3, reference per visit, 2 passes"], magnitudes_N=(19.6, 49.0, 98.1),
                       sigma_m=1.5e-5, sigma_per_m=0.0)
    k = np.array([3.0e-6, 2.5e-6, 4.0e-6, 1.2e-5, 1.2e-5, 1.5e-5])
    for seed in (3, 4):
        rng = np.random.default_rng(seed)
        log = T.lab_log(robot, protocol, rng, 30)
        path = _write(tmp_path, T.lab_csv(robot, log, T.measure(robot, T.Truth(k, base_tilt=(3e-7, 2e-8, 0.5)), log,
                                                                rng)))
        v = D.analyse(robot, read_measurements(path, robot), 0.01, gain=False)
        base = v["diagnostics"]["base_compliance"]
        assert v["cause"] == "unexplained" and v["diagnostics"]["outside_catalogue"] == ["base_compliance"], seed
        soft, stiff = base["principal_compliances_rad_per_Nm"]
        assert abs(base["softest_axis"][0]) > 0.95 and 1.5e-7 < soft < 6e-7 and abs(stiff) < soft / 2, base
        assert any("about the horizontal axis (" in n for n in v["notes"])


def test_a_tilting_base_and_a_bending_link_that_hanging_masses_cannot_tell_apart_are_said_to_be(tmp_path):
    """A fresh user's iiwa under hanging masses: a tilting base and link_compliance each explained the data as well as
    the other (the base's columns lie in the links' span), and the verdict named link_compliance beside a note saying
    it only absorbed the base, whichever was true (a real bending link told to stiffen its mounting). With stiffcal's
    own simulator of the iiwa (tests/data/newuser/iiwa14_h53.yaml): a tilting base gives link_compliance with a note
    that the two cannot be told apart; a bending link gives link_compliance, the base adding nothing and no note."""
    robot = load_robot(NEWUSER / "iiwa14_h53.yaml")
    k = np.array([4, 4, 6, 6, 12, 12, 15]) * 1e-6
    protocol = replace(R.PROTOCOLS["hanging x3, reference per visit, 2 passes"], magnitudes_N=(19.6, 49.0, 98.1),
                       sigma_m=1.5e-5, sigma_per_m=0.0)
    for truth, tie in ((T.Truth(k, base_tilt=(6e-7, 0.7)), True),
                       (T.Truth(k, link_bending=np.full(robot.n_segments, 2e-5)), False)):
        rng = np.random.default_rng(0)
        log = T.lab_log(robot, protocol, rng, 20)
        path = _write(tmp_path, T.lab_csv(robot, log, T.measure(robot, truth, log, rng)))
        v = D.analyse(robot, read_measurements(path, robot), 0.01)
        base = v["diagnostics"]["base_compliance"]
        assert v["causes"] == ["link_compliance"] and base["p_value"] < 1e-6
        assert not v["diagnostics"]["outside_catalogue"]
        said = [n for n in v["notes"] if "tilt of the whole robot" in n]
        assert (len(said) == 1 and "cannot be told apart" in said[0] and "may only absorb" not in said[0]) == tie
        assert bool(said) == tie, said


def test_a_warned_effect_outside_the_catalogue_adds_the_models_error_to_predictions(tmp_path):
    """A fresh user's KR 210 (tests/data/newuser/kr210_masses.yaml, its own simulator: hanging masses of 50-300 kg, a
    reference per visit, two passes) on a plate that tilts 2.5e-9 rad/(N m) about a pivot 0.3 m below the base: `none`
    with a note of the tilt at p = 0.004, and calibrated.yaml without a model error, its predictions' sd a third of
    their held-out error. The warned effect now puts the leave-one-configuration-out error beyond a right model's into
    ``model_error_m``; the clean twin, warned of nothing, has none."""
    import yaml

    robot = NEWUSER / "kr210_masses.yaml"
    for name, warned in (("kr210_plate_tilt_s1.csv", True), ("kr210_plate_clean_s1.csv", False)):
        out = tmp_path / name
        assert main(["discrepancy", "--robot", str(robot), "--data", str(NEWUSER / name), "--out", str(out),
                     "--no-figures", "--quiet"]) == 0
        v = json.loads((out / "verdict.json").read_text())
        cal = yaml.safe_load((out / "calibrated.yaml").read_text())["calibration"]
        assert v["cause"] == "none" and (v["diagnostics"]["base_compliance"]["p_value"] <= 0.01) == warned
        held, right = v["held_out"]["rms_nominal_m"], v["held_out"]["rms_expected_nominal_m"]
        if warned:  # model_error is the held-out RMS beyond a right model's (no drift here)
            assert cal["model_error_m"] == pytest.approx(np.sqrt(held**2 - right**2), rel=1e-6)
        else:
            assert "model_error_m" not in cal


@pytest.mark.parametrize("arm, i", [("2-link", 10), ("3-link", 8)])
def test_a_link_that_would_bend_against_its_load_is_not_the_physical_extension(root, tmp_path, arm, i):
    """A planar arm's coupled joints are described as well by a bending link (the two coincide in the plane), and the
    golden logs of a coupled pair (tools/golden.py) named link_compliance with c1 = -3.8e-6 +- 0.7e-6 per N m^2 in 11
    of 28: a link that bends against its load, which none does. The physical extension among the equivalent ones now
    excludes a negative link compliance as it did a negative joint compliance: joint_coupling, with link_compliance
    indistinguishable from it and a note saying why."""
    arms = R.robots(root)
    protocol = R.protocols_for(arms[arm])[i]
    log, dp, _ = R.simulate_case(arms[arm], protocol, ("joint_coupling",), 900 + i, 40, (0.3, 1.0))
    path = _write(tmp_path, T.lab_csv(arms[arm], log, dp, pose_id=True))
    v = D.analyse(arms[arm], read_measurements(path, arms[arm]), 0.01)
    assert v["cause"] == "joint_coupling" and v["indistinguishable_from"] == ["link_compliance"], v["causes"]
    assert any(n.startswith("the extended model holds joint_coupling, not link_compliance")
               and re.search(r"c[12]_1/\(N m\^2\) = -", n) for n in v["notes"]), v["notes"]
