"""How often the discrepancy analysis is right: hidden effects in simulated laboratory data, over seeds.

A *case* is a robot, a measurement protocol (:class:`stiffcal.truth.Protocol`: hanging weights, pushes in
several directions, 3-D pushes, one random load; the load sequence repeated or not, replicates
interleaved in time, unloaded reference rows, tracker noise growing with distance), a set of hidden
effects (:mod:`stiffcal.truth`, written from the physics and independent of the analysis's regressors) and
a seed. Its log is written as the CSV a lab would write, with and without ``pose_id``, read back with
:func:`stiffcal.measurements.read_measurements` and analysed; both variants must give the same verdict.

Each effect is scaled so that the RMS of its displacement, less what the nominal model absorbs, is a random
multiple (log-uniform) of the noise, so cases range from invisible to obvious. Whether a case *should* be
found is decided by an **oracle**: the most powerful test of that one effect, which knows its exact shape
(its noise-free displacement vector e): the one-degree-of-freedom F-test of e against the nominal model
(and the other hidden effects), with the noise known row by row. Its power at level alpha is
1 - F'(F_crit; 1, df, lambda), lambda = |(I - P) W e|^2 with W the whitening by the noise and P the
projection on the whitened nominal columns (Scheffe, *The Analysis of Variance*, 1959, sec. 2.8). The
analysis is required to name an effect in at least 95 % of the cases where the oracle's power is at least
0.9, and to raise at most alpha false alarms on clean data. A weaker oracle, which knows which cause is
present but not its parameters (the F-test of that cause's regressors at level alpha), is also reported.
For effects outside the catalogue the oracle tests the part of e that no catalogue cause explains, and the
expected verdict is ``unexplained``.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import stats

from . import discrepancy as D
from . import truth as T
from .measurements import read_measurements
from .robot import Robot, load_robot, planar_robot

#: the effects a case can hide; the last two are outside the catalogue
EFFECTS = ("link_compliance", "joint_coupling", "nonlinear_joint_stiffness", "backlash", "measurement_offset",
           "drift", "modulation")
OUTSIDE = ("drift", "modulation")

PROTOCOLS = {
    "hanging x4, repeated": T.Protocol("hanging x4, repeated"),
    "hanging x4, once": T.Protocol("hanging x4, once", repeats=1),
    "4 directions x 2, repeated": T.Protocol("4 directions x 2, repeated", loads="directions",
                                             magnitudes_N=(250.0, 600.0)),
    "4 directions x 2, interleaved": T.Protocol("4 directions x 2, interleaved", loads="directions",
                                                magnitudes_N=(250.0, 600.0), interleaved=True),
    "3-D pushes x 2, repeated": T.Protocol("3-D pushes x 2, repeated", loads="pushes3d", n_directions=3,
                                           magnitudes_N=(400.0, 1000.0)),
    "3-D pushes x 2, once": T.Protocol("3-D pushes x 2, once", loads="pushes3d", n_directions=3,
                                       magnitudes_N=(400.0, 1000.0), repeats=1),
    "random load x3, unloaded rows, tracker": T.Protocol("random load x3, unloaded rows, tracker", loads="random",
                                                         magnitudes_N=(100.0, 400.0), repeats=3,
                                                         unloaded_rows=True, sigma_m=5e-6, sigma_per_m=5e-6),
    "hanging x4, unloaded rows, tracker": T.Protocol("hanging x4, unloaded rows, tracker", unloaded_rows=True,
                                                     sigma_m=5e-6, sigma_per_m=5e-6),
    "4 directions x 2, shared reference": T.Protocol("4 directions x 2, shared reference", loads="directions",
                                                     magnitudes_N=(250.0, 600.0), unloaded_rows=True,
                                                     reference="configuration"),
}


def robots(root: str | Path) -> dict[str, Robot]:
    """The arms of the study: the paper's 2-link arm, a 3-link planar arm and the 6-axis KUKA of the config."""
    root = Path(root)
    return {"2-link": load_robot(root / "config/robots/paper_2r.yaml"),
            "3-link": planar_robot([0.5, 0.4, 0.3], "3-link"),
            "6-axis": load_robot(root / "config/robots/kuka_kr210_r2700.yaml")}


def compliances(robot: Robot) -> np.ndarray:
    """The true joint compliances [rad/(N m)]: the robot file's, else 1.5e-6 .. 3e-6 (tenths of a millimetre
    under a few hundred newtons for a metre-long arm)."""
    return robot.compliances if robot.compliances is not None else np.linspace(1.5e-6, 3e-6, robot.n_joints)


def protocols_for(robot: Robot) -> list[str]:
    """The protocols that make sense for the robot: hanging weights for a planar arm in its vertical plane
    (on a spatial arm with a vertical first axis they never load joint 1, which the analysis refuses with
    that reason), 3-D pushes for a spatial arm."""
    spatial = robot.task_dim == 3
    return [p for p, pr in PROTOCOLS.items()
            if (pr.loads == "pushes3d") == spatial or pr.loads in ("directions", "random")]


def _unit_truth(effect: str, robot: Robot, k: np.ndarray, rng: np.random.Generator, log: T.LabLog) -> T.Truth:
    """A truth with the effect at an arbitrary size (scaled afterwards by :func:`_scaled_truth`)."""
    n, d = robot.n_joints, robot.task_dim
    if effect == "measurement_offset":
        return T.Truth(k, offset=T.random_directions(rng, 1, d)[0] * 1e-5)
    if effect == "joint_coupling":
        i, j = sorted(rng.choice(n, 2, replace=False))
        c = np.zeros((n, n))
        c[i, j] = c[j, i] = 0.1 * np.sqrt(k[i] * k[j]) * rng.choice([-1.0, 1.0])
        return T.Truth(k, coupling=c)
    if effect == "nonlinear_joint_stiffness":
        tau = np.abs(T.joint_torques(robot, log.q[log.loaded], log.force[log.loaded])).max(axis=0)
        return T.Truth(k, tau_max=np.maximum(tau, 1e-9) / 0.3)
    if effect == "backlash":
        return T.Truth(k, gap=np.full(n, 1e-5))
    if effect == "link_compliance":
        return T.Truth(k, link_bending=np.full(robot.n_segments, 1e-7))
    if effect == "drift":
        return T.Truth(k, drift=T.random_directions(rng, 1, d)[0] * 1e-7)
    if effect == "modulation":
        return T.Truth(k, modulation=rng.uniform(0.05, 0.15, n) * rng.choice([-1.0, 1.0], n))
    raise ValueError(effect)


def _effect_displacement(robot, truth: T.Truth, base: T.Truth, log: T.LabLog) -> np.ndarray:
    rows = log.loaded
    order = np.flatnonzero(np.ones(len(log.q)))[rows]
    return (T.physics(robot, truth, log.q[rows], log.force[rows], order)
            - T.physics(robot, base, log.q[rows], log.force[rows], order))


def _scaled_truth(effect: str, truth: T.Truth, base: T.Truth, robot, log, target_rms: float) -> T.Truth:
    """Scale the effect's parameter so that the RMS of its displacement, less what the nominal model absorbs
    (its projection on the nominal columns), is ``target_rms`` [m]."""
    def with_scale(s: float) -> T.Truth:
        if effect == "nonlinear_joint_stiffness":  # tau_max / s: a stronger softening, not linear in s
            return replace(truth, tau_max=truth.tau_max / s)
        field = {"measurement_offset": "offset", "joint_coupling": "coupling", "backlash": "gap",
                 "link_compliance": "link_bending", "drift": "drift", "modulation": "modulation"}[effect]
        return replace(truth, **{field: getattr(truth, field) * s})

    rows = log.loaded
    X0 = D._stack(D.nominal_columns(robot, log.q[rows], log.force[rows]))
    Q = np.linalg.qr(X0)[0]

    def rms(s):  # of the part the nominal model cannot absorb
        e = _effect_displacement(robot, with_scale(s), base, log).ravel()
        return float(np.sqrt(np.mean((e - Q @ (Q.T @ e)) ** 2)))

    if effect != "nonlinear_joint_stiffness":
        return with_scale(target_rms / rms(1.0))
    lo, hi = 1e-6, 3.0  # tau_max = max|tau| / (0.3 s) stays above the largest torque for s < 3.33
    if rms(hi) < target_rms:
        return with_scale(hi)
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if rms(mid) < target_rms else (lo, mid)
    return with_scale(hi)


def oracle_power(robot: Robot, log: T.LabLog, e: np.ndarray, others: list[np.ndarray], alpha: float, df: int,
                 against_catalogue: bool = False, block: str | None = None) -> float:
    """Power of an oracle test of one effect (module docstring). e: (N_loaded, d) [m] its displacement;
    others: the displacements of the other hidden effects (kept in the oracle's model); df: the error
    degrees of freedom of the analysis; against_catalogue: project out every catalogue cause too (for an
    effect outside the catalogue).

    block=None: the exact-shape oracle, a 1-degree-of-freedom F-test of e itself. block=<cause>: the weaker
    cause-block oracle, which knows which catalogue cause is present but not its parameters: the F-test of
    that cause's regressors (rank r) at level alpha, without multiplicity, noncentrality = the part of e in
    their span beyond the nominal model."""
    rows = log.loaded
    q, f = log.q[rows], log.force[rows]
    white = _whitening(log)
    causes = D.CAUSES if against_catalogue else ()
    X = D._stack(white(D.model_columns(robot, q, f, causes)))
    if others:
        X = np.hstack([X, D._stack(white(np.stack(others, -1)))])
    y = D._stack(white(e[..., None]))[:, 0]

    def rss(A):
        return float(np.sum((y - A @ np.linalg.lstsq(A, y, rcond=None)[0]) ** 2))

    if block is None:
        lam, r = rss(X), 1
    else:
        B = D._stack(white(D.cause_columns(block, robot, q, f)))
        r = np.linalg.matrix_rank(np.hstack([X, B])) - np.linalg.matrix_rank(X)
        lam = rss(X) - rss(np.hstack([X, B]))
        if r == 0:
            return 0.0
    crit = stats.f.isf(alpha, r, df)
    return float(stats.ncf.sf(crit, r, df, max(lam, 0.0)))


def _whitening(log: T.LabLog):
    """The map A (N_loaded, d, k) -> Sigma^(-1/2) A for the true noise of the log's loaded rows: independent
    with sigma per row, or with a shared reference (:class:`stiffcal.truth.Protocol`) the error of one reading
    common to the rows of a configuration (and target): per configuration the Cholesky factor of
    diag(sigma_r^2) + sigma_ref^2 J, sigma_ref the noise at the configuration's first reading."""
    rows = np.flatnonzero(log.loaded)
    sig = log.sigma[rows]
    if not log.shared_reference:
        return lambda A: A / sig[:, None, None]
    target = np.zeros(len(log.q), int) if log.target is None else log.target
    key = np.unique(np.column_stack([log.config, target]), axis=0, return_inverse=True)[1].ravel()
    blocks = []
    for k in np.unique(key[rows]):
        mine = np.flatnonzero(key[rows] == k)
        ref = log.sigma[np.flatnonzero(key == k)[0]]
        chol = np.linalg.cholesky(np.diag(sig[mine] ** 2) + ref**2)
        blocks.append((mine, np.linalg.inv(chol)))

    def white(A):
        out = np.empty_like(A, dtype=float)
        for mine, Wc in blocks:
            out[mine] = np.einsum("ij,j...->i...", Wc, A[mine])
        return out
    return white


@dataclass(frozen=True)
class CaseResult:
    """One analysed case: the hidden effects, each effect's oracle power (exact shape; ``power_block``: the
    cause-block oracle, catalogue causes only), both verdicts."""
    robot: str
    protocol: str
    effects: tuple[str, ...]
    seed: int
    power: dict
    verdict_with_pose_id: dict
    verdict_without: dict
    power_block: dict = field(default_factory=dict)

    @property
    def agree(self) -> bool:
        keys = ("cause", "causes", "indistinguishable_from", "outlier_rows")
        return all(self.verdict_with_pose_id[k] == self.verdict_without[k] for k in keys)

    def named(self, effect: str) -> bool:
        """The verdict names the effect: an effect outside the catalogue as ``unexplained``; a catalogue
        cause in ``causes`` or ``indistinguishable_from`` (a span that coincides with a named cause's), in a
        verdict that is not ``unexplained``."""
        v = self.verdict_with_pose_id
        if effect in OUTSIDE:
            return v["cause"] == "unexplained"
        return v["cause"] != "unexplained" and effect in {*v["causes"], *v["indistinguishable_from"]}

    @property
    def false_alarm(self) -> bool:
        return self.verdict_with_pose_id["cause"] != "none"


def run_case(robot_name: str, robot: Robot, protocol: str, effects: tuple[str, ...], seed: int,
             alpha: float = 0.01, n_configs: int = 40, size_range=(0.02, 1.0), workdir: str | None = None
             ) -> CaseResult:
    """Simulate one case (module docstring), analyse both CSV variants, and return the verdicts and the
    oracle power of each hidden effect. Effect sizes: RMS displacement log-uniform in ``size_range`` times
    the median noise."""
    rng = np.random.default_rng(seed)
    pr = PROTOCOLS[protocol]
    log = T.lab_log(robot, pr, rng, n_configs)
    k = compliances(robot)
    base = T.Truth(k)
    truth, disp = base, {}
    sigma = float(np.median(log.sigma))
    for eff in effects:
        unit = _unit_truth(eff, robot, k, rng, log)
        size = sigma * float(np.exp(rng.uniform(*np.log(size_range))))
        scaled = _scaled_truth(eff, unit, base, robot, log, size)
        disp[eff] = _effect_displacement(robot, scaled, base, log)
        truth = _merge(truth, scaled)
    dp = T.measure(robot, truth, log, rng)
    verdicts = []
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        for with_id in (True, False):
            path = Path(tmp) / f"case{int(with_id)}.csv"
            path.write_text(T.lab_csv(robot, log, dp, pose_id=with_id), encoding="utf-8")
            meas = read_measurements(path, robot)
            verdicts.append(D.analyse(robot, meas, alpha, gain=False))
    df = verdicts[0]["nominal"]["sigma_df"]
    others = {e: [disp[o] for o in effects if o != e] for e in effects}
    power = {e: oracle_power(robot, log, disp[e], others[e], alpha, df, e in OUTSIDE) for e in effects}
    block = {e: oracle_power(robot, log, disp[e], others[e], alpha, df, block=e) for e in effects if e not in OUTSIDE}
    return CaseResult(robot_name, protocol, tuple(effects), seed, power, *verdicts, block)


def _merge(a: T.Truth, b: T.Truth) -> T.Truth:
    """The truth with the effects of both (the fields b sets that a does not)."""
    fields = {f: getattr(b, f) for f in ("coupling", "tau_max", "gap", "link_bending", "offset", "drift", "modulation")
              if getattr(b, f) is not None}
    return replace(a, **fields)


def rates(results: list[CaseResult], min_power: float = 0.9, oracle: str = "exact") -> dict:
    """Per hidden effect: cases where the oracle's power >= min_power (``oracle``: "exact" shape, or "block" of
    the cause's regressors, which falls back to the exact one outside the catalogue), how many of those the
    verdict names, and the rate; for clean cases (no effect): the false-alarm count and rate; and the share of
    cases where the two CSV variants agree."""
    out: dict = {}
    for r in results:
        if not r.effects:
            row = out.setdefault("clean", {"cases": 0, "false_alarms": 0})
            row["cases"] += 1
            row["false_alarms"] += r.false_alarm
        for e in r.effects:
            row = out.setdefault(e, {"cases": 0, "qualifying": 0, "named": 0})
            row["cases"] += 1
            power = r.power_block.get(e, r.power[e]) if oracle == "block" else r.power[e]
            if power >= min_power:
                row["qualifying"] += 1
                row["named"] += r.named(e)
    for row in out.values():
        if "qualifying" in row:
            row["rate"] = row["named"] / row["qualifying"] if row["qualifying"] else None
        else:
            row["rate"] = row["false_alarms"] / row["cases"]
    out["variants_agree"] = sum(r.agree for r in results) / max(len(results), 1)
    return out
