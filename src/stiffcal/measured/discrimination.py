"""The next experiment: a plan of measurements that tells rival causes apart, with its predicted power.

When the discrepancy analysis (:mod:`stiffcal.measured.discrepancy`) leaves several combinations of causes that
explain the data equally well (the verdict's ``causes`` and ``equivalent_combinations``), each is a linear
model y = X_S(x) beta_S + e of the displacement at a design point x = (pose, load). This module chooses
the next M design points.

T-optimality (Atkinson & Fedorov 1975, *Biometrika* 62(1), 57-70; several rivals: Atkinson & Fedorov
1975, *Biometrika* 62(2), 289-303). The rival models are fitted to the data; the verdict's own combination
(the closed test's choice: fewest causes, then fewest parameters, a physical one (no negative joint
compliance) first among equals; the smallest residual sum of squares would reward the rival with the most
parameters) is taken as the truth, with its fitted mean mu(x) = X_0(x) beta_0. The
lack of fit of rival j after the old data and the new plan x_1..x_M (each measured R times) is

    Delta_j = min_theta [ sum_old |mu - X_j theta|^2 + R sum_i |mu(x_i) - X_j(x_i) theta|^2 ],

and the plan maximises Delta = min_j Delta_j. For linear spans Delta_j / sigma^2 is the noncentrality of the
F-test of rival j against the model with both spans (Scheffe, *The Analysis of Variance*, 1959, sec. 2.8),
so its power is 1 - F'(F_crit; nu1, nu2, Delta_j / sigma^2), nu1 = rank(X_j, X_0) - rank(X_j), nu2 the
error degrees of freedom. The level is the share the analysis's closed test gives this comparison:
the rival combination S_j stays compatible until the local test of "every cause outside S_j is absent"
rejects, which rejects at least when one of the k_j causes outside S_j (and the lack of fit) is rejected at
alpha / k_j (its min-P test is never more conservative than Bonferroni). The predicted power is that of the
F-test at alpha / k_j, a lower bound: the other members of the local test can only add to the rate of
separation.

Where the truth's span lies inside the rival's at every pose and load (for planar arms a bending link acts
like a compliance block on its joints: ``link_compliance`` and ``joint_coupling`` of a 2-link arm span the
same directions), Delta_j = 0 for every plan of positions: no plan separates them, and the module says so and
names the measurement that would (the end-effector orientation, a second target).

Certificate (the equivalence theorem carried over). Delta_j is the minimum over theta of a sum that is
linear in the design, so for ANY theta and any M-point plan, Delta_j <= old_j(theta) + R M max_x
psi_j(x, theta), psi_j(x, theta) = |mu(x) - X_j(x) theta|^2 [Atkinson & Fedorov 1975, Theorem 1: at the
optimal approximate design xi*, max_x psi_j(x, theta(xi*)) equals Delta_j(xi*)]. By the minimax theorem the
smallest such bound over theta equals the best approximate design's Delta, so it is tight; theta is found by
minimising a smoothed maximum over the candidate pool, and the maximum over x is taken over the whole joint
space (a grid plus polish; for 4+ joints a quasi-random sample plus polish, whose reliability the bound then
shares) for every load. The plan's efficiency is Delta / bound.

The plan. Candidate points are every pose of a grid within the joint limits (quasi-random for 4+ joints)
under every load of the stated set; Fedorov's exchange (Fedorov 1972, ch. 3) picks the plan, scoring every
replacement of one point at once by rank-r updates of the least squares (recursive least squares for Delta,
the Woodbury identity for O_t); the plan is polished in the continuum, and the maxima of psi join the
candidates for a few rounds (the vertex-direction step of Atkinson & Fedorov's algorithm). A model with
backlash (J sign(tau)) jumps where a joint's torque changes sign, which a T-optimal plan would chase although a
real joint sits inside its gap there: points where a joint carries less than :data:`BACKLASH_TORQUE_FLOOR` of
its largest torque are then left out.

Compound plan (one next session, not two). With a test pose, the extended model's compensation error
O_t (eq. 16, the old data's information included) and the discrimination are weighed in one criterion,
the DT-optimality of Atkinson (2008, *J. Statist. Plann. Inference* 138(1), 56-64) with O_t in place of the
determinant:  maximise  kappa log Delta - (1 - kappa) log O_t,  i.e. kappa log Eff_T + (1 - kappa) log Eff_O
up to constants. kappa = 1 is the discriminating plan, kappa = 0 the O_t-optimal plan; the default 0.5
weighs the two efficiencies' logarithms equally (a plan that halves one efficiency must double the other).
O_t's certificate is the convexity bound O_t* >= O_t(plan) - R M (max_x phi(x) - mean_plan phi) with
phi(x) = sigma^2 |X(x) Minv X_t^T|_F^2 (the Frank-Wolfe gap of :mod:`stiffcal.planning.certificate`'s theorem).

Measurement models. The regressors of a new design point come from a :class:`MeasurementModel`: its rows
per point and their columns for a combination of causes. :class:`PositionModel` (the default) is the measured
point's position, the rows of the CSV contract (the old data are always read through it). A model with more
rows per pose (a second target, the orientation: issue 15) plugs in as the ``measurement`` argument of
:func:`discriminate`, :func:`separability`, :func:`build_criterion` and :func:`plan_power`; its columns must
use the parameters of the position model (joint compliances, then each cause's in catalogue order).

Units: angles rad (deg in results), forces N, displacements m, Delta m^2 (weighted rows: in the units of
the median row).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np
from scipy import optimize, stats

from . import discrepancy as D
from ..planning.problem import is_sampled, joint_grids, joint_space_pool, sampled_minimise
from ..errors import InputError
from ..jsonsafe import json_safe
from .measurements import Measurements
from .results import DiscriminationPlan
from ..model.robot import Robot
from ..threads import single_threaded
from ..model.loads import MAX_DATA_LOADS, LoadSet, _numbers, check_lab_loads, sphere_directions  # noqa: F401 (re-exported)
from ..model.loads import load_set as _load_set

#: default weight kappa of the discrimination in the compound criterion (module docstring)
COMPOUND_WEIGHT = 0.5
#: the measurements that can separate causes whose position spans coincide
OTHER_MEASUREMENTS = ("the end-effector orientation", "the position of a second target on another link")


# --- measurement models ------------------------------------------------------------------------------

class MeasurementModel(Protocol):
    """What a plan measures at a design point: ``name``; ``rows(robot)`` per point; ``columns(robot, q (N, n)
    [rad], force (N, d) [N], causes)`` -> (N, rows, p), the regressors of the model nominal + causes."""

    name: str

    def rows(self, robot: Robot) -> int: ...

    def columns(self, robot: Robot, q: np.ndarray, force: np.ndarray, causes=()) -> np.ndarray: ...


@dataclass(frozen=True)
class PositionModel:
    """The measured point's displacement (the CSV contract): ``task_dim`` rows per design point."""

    name: str = "position of the measured point"

    def rows(self, robot: Robot) -> int:
        return robot.task_dim

    def columns(self, robot: Robot, q: np.ndarray, force: np.ndarray, causes=()) -> np.ndarray:
        """(N, rows, p): the regressors of the model nominal + ``causes`` at poses q (N, n) [rad] under
        forces (N, d) [N] (:func:`stiffcal.measured.discrepancy.model_columns`)."""
        return D.model_columns(robot, q, force, causes)


# --- loads: stiffcal.model.loads (LoadSet, sphere_directions; re-exported here) ------------------------------------

def load_set(spec: str | None, d: int, data_forces: np.ndarray | None = None, resolution_N: float = 0.5,
             field_name: str = "--loads", moment_resolution_Nm: float = 0.05, gravity=None) -> LoadSet:
    """:func:`stiffcal.model.loads.load_set` (every kind of load set and its checks), the data's loads grouped by
    :func:`stiffcal.measured.measurements.cluster`."""
    from .measurements import cluster

    return _load_set(spec, d, data_forces, resolution_N, field_name, moment_resolution_Nm, gravity, cluster)



# --- candidate pool ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Effort:
    """How hard the search works: pool_step_deg: candidate grid step (default :data:`POOL_STEP_DEG`);
    pool_log2: 2**pool_log2 quasi-random candidate poses for 4+ joints; search_step_deg: grid step of the
    maxima over the joint space behind the certificates (default :data:`SEARCH_STEP_DEG`); search_log2:
    2**search_log2 quasi-random poses of that search for 4+ joints; n_starts: random starts of the exchange
    besides the greedy one; rounds: pool augmentations by the maxima of psi (vertex-direction steps)."""
    pool_step_deg: float | None = None
    pool_log2: int = 12
    search_step_deg: float | None = None
    search_log2: int = 14
    n_starts: int = 4
    rounds: int = 2


#: default candidate-grid step [deg] per number of joints; 4+ joints: 2**POOL_LOG2 quasi-random poses
POOL_STEP_DEG = {1: 2.0, 2: 5.0, 3: 12.0}
#: default grid step [deg] of the search over the joint space behind the certificates (then polished)
SEARCH_STEP_DEG = {1: 1.0, 2: 2.0, 3: 6.0}


#: a model with backlash (J sign(tau)) jumps where a joint's torque changes sign, and a real joint carries no
#: load inside its gap there: design points where some joint carries less than this fraction of its largest
#: torque over the pool are left out when a model has backlash
BACKLASH_TORQUE_FLOOR = 0.05


@dataclass(frozen=True)
class Pool:
    """Candidate design points: q (K, n) [rad], force (K, w) [N, N m] each point's load at its pose, load (K,) the
    index of each point's load in ``loads`` (L, w); tau_floor (n,) [N m]: the smallest joint torque a point may have
    (zero: no floor); hanging: the loads hang from a cable (masses), kept free in the cell; arm (3,) [m]: for masses
    on a loading bar, the bar's end from the tool point in the tip frame (``loads`` then the masses' forces (L, d),
    and a point's moment about the tool point turns with the tool: :meth:`at`)."""

    q: np.ndarray
    force: np.ndarray
    load: np.ndarray
    loads: np.ndarray
    tau_floor: np.ndarray
    hanging: bool = False
    arm: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.q)

    def at(self, robot: Robot, q: np.ndarray, load: np.ndarray) -> np.ndarray:
        """(k, w): the loads of index ``load`` (k,) at the poses q (k, n) [rad]: as given, or a loading bar's force
        with its moment (R(q) arm) x F (:meth:`stiffcal.model.observation.Loads.at`)."""
        load = np.asarray(load, int)
        if self.arm is None:
            return self.loads[load]
        from ..model.observation import Loads

        W = Loads(self.loads, self.arm).at(robot, q)  # (k, L, w)
        return W[np.arange(len(load)), load]

    @property
    def hang_offset(self) -> np.ndarray | None:
        """Where the hanging masses' cable starts, from the tool point in the tip frame [m] (None: no cable)."""
        return None if not self.hanging else np.zeros(3) if self.arm is None else np.asarray(self.arm, float)

    def joined(self, robot: Robot, q: np.ndarray, load: np.ndarray) -> "Pool":
        """The pool with the points q (k, n) [rad] under the loads of index ``load`` (k,) added (those above
        the torque floor)."""
        load = np.asarray(load, int)
        F = self.at(robot, q, load)
        keep = self.admissible(robot, q, F)
        return replace(self, q=np.vstack([self.q, q[keep]]), force=np.vstack([self.force, F[keep]]),
                       load=np.concatenate([self.load, load[keep]]))

    def admissible(self, robot: Robot, q: np.ndarray, force: np.ndarray) -> np.ndarray:
        """(k,) bool: points q (k, n), force (k, w) whose joint torques are all at least :attr:`tau_floor` and
        whose poses the robot can take in its cell, a hanging mass's cable free (:mod:`stiffcal.model.workcell`)."""
        from ..model.workcell import feasible

        ok = np.all(np.abs(D.torques(robot, q, force)) >= self.tau_floor, axis=-1)
        if robot.cell is not None:
            ok &= feasible(robot, q, self.hang_offset)
        return ok


def _load_index(pool: Pool, forces: np.ndarray) -> np.ndarray:
    """(k,): the index in ``pool.loads`` of each load (k, w) [N, N m] (each must be one of them; a loading bar's by
    its force)."""
    width = pool.loads.shape[1]
    return np.array([int(np.flatnonzero(np.all(np.isclose(pool.loads, f[:width]), axis=1))[0])
                     for f in np.atleast_2d(forces)], int)


def make_pool(robot: Robot, poses: np.ndarray, loads: np.ndarray, causes=(), hanging: bool = False,
              arm: np.ndarray | None = None) -> Pool:
    """Every pose (P, n) [rad] under every load (L, w) [N, N m] (or, with ``arm``, the forces (L, d) of masses on a
    loading bar whose end is ``arm`` (3,) [m] from the tool point in the tip frame: :class:`Pool`); when ``causes``
    include backlash, without the points below :data:`BACKLASH_TORQUE_FLOOR`; in a cell only the poses the robot can
    take there (with ``hanging`` masses, their cable free). Raises :class:`InputError` when no point is left."""
    L = len(loads)
    empty = Pool(np.zeros((0, robot.n_joints)), np.zeros((0, np.shape(loads)[1])), np.zeros(0, int),
                 np.asarray(loads, float), np.zeros(robot.n_joints), hanging, None if arm is None else
                 np.asarray(arm, float))
    if robot.cell is not None:
        from ..model.workcell import feasible, no_pose_reason

        ok = feasible(robot, poses, empty.hang_offset)
        if not ok.any():
            raise InputError(f"none of the {len(poses)} candidate poses within the joint limits can be taken in the "
                             f"cell ({robot.cell.describe()}): {no_pose_reason(robot, poses, empty.hang_offset)}",
                             source=robot.cell.source, field="cell")
        poses = poses[ok]
    q, load = np.repeat(poses, L, axis=0), np.tile(np.arange(L), len(poses))
    F = empty.at(robot, q, load)
    floor = np.zeros(robot.n_joints)
    if "backlash" in causes:
        floor = BACKLASH_TORQUE_FLOOR * np.abs(D.torques(robot, q, F)).max(axis=0)
    keep = np.all(np.abs(D.torques(robot, q, F)) >= floor, axis=-1)  # the poses' feasibility is checked above
    if not keep.any():
        raise InputError("no pose within the joint limits loads every joint under these loads", field="--loads")
    return replace(empty, q=q[keep], force=F[keep], load=load[keep], tau_floor=floor)


def pose_pool(robot: Robot, step_deg: float | None = None, log2_count: int = 12) -> np.ndarray:
    """Candidate poses (P, n) [rad] within the joint limits: the grid of :func:`stiffcal.planning.problem.joint_grids`
    (default step :data:`POOL_STEP_DEG`), or ``2**log2_count`` scrambled-Sobol poses
    (:func:`stiffcal.planning.problem.sample_joint_space`) when the grid would be too large (4+ joints). No symmetry
    reduction: a constant measurement offset is not invariant under the mirror copy of a pose."""
    return joint_space_pool(robot, step_deg or POOL_STEP_DEG.get(robot.n_joints, 30.0), log2_count, max_grid=200_000)


# --- the rival models of a verdict --------------------------------------------------------------------------

@dataclass(frozen=True)
class Rival:
    """One combination of causes fitted to the data: causes (catalogue order); beta (p,) its parameters
    (joint compliances first) [SI]; rss: weighted residual sum of squares [m^2]; multiplicity: k, the
    Bonferroni share of the closed test that decides whether it stays compatible (module docstring)."""

    causes: tuple[str, ...]
    beta: np.ndarray
    rss: float
    multiplicity: int

    @property
    def label(self) -> str:
        return " + ".join(self.causes) or "the nominal model"


@dataclass(frozen=True)
class RivalModels:
    """The rivals of one verdict. models[0] is the truth (the verdict's combination); extended: the verdict's
    combination (the extended model, for O_t); old: the measurements the analysis used (blunders left out);
    weights (N_old,): the analysis's row weights (1 without a variance model); sigma [m] and noise_df: the
    verdict's noise; pure_error: whether the noise comes from replicates (then new replicates add to its
    degrees of freedom); alpha; verdict: the verdict itself; observed: what the old rows measure (their targets
    and the tool's orientation, with the tool point's parameters); error: the analysis's error model of the old
    rows (:class:`stiffcal.measured.errormodel.ErrorModel`: their shared reference readings), whose generalised least
    squares the old rows enter every fit with."""

    robot: Robot
    old: Measurements
    weights: np.ndarray
    models: tuple[Rival, ...]
    extended: tuple[str, ...]
    sigma: float
    noise_df: int
    pure_error: bool
    alpha: float
    verdict: dict
    observed: D.Observed | None = None
    error: object = None

    @property
    def truth(self) -> Rival:
        return self.models[0]

    @property
    def rivals(self) -> tuple[Rival, ...]:
        return self.models[1:]

    def old_rows(self, causes) -> np.ndarray:
        """(N_old r, p): the weighted, whitened stacked regressors of the old data for nominal + causes (every
        measured quantity of the old rows, generalised least squares for their shared errors)."""
        X = D.model_columns(self.robot, self.old.q, D.load_of(self.old), causes, observed=self.observed)
        X = X * self.weights[:, None, None]
        if self.error is not None and self.error.blocks:
            X = self.error.whiten(X)
        return D._stack(X)

    def old_y(self) -> np.ndarray:
        """(N_old r,): the old rows' observations, weighted and whitened as :meth:`old_rows`."""
        ob = self.observed or D.Observed()
        y = D.observations(self.old, ob) * self.weights[:, None]
        if self.error is not None and self.error.blocks:
            y = self.error.whiten_observations(y)
        return y.ravel()

    def old_mean(self, model: Rival | None = None) -> np.ndarray:
        """(N_old r,): the weighted fitted mean of ``model`` (default the truth) on the old rows."""
        m = model or self.truth
        return self.old_rows(m.causes) @ m.beta


def _combination(c) -> tuple[str, ...]:
    return tuple(sorted(c, key=D.CAUSES.index))


def rivals_from_verdict(robot: Robot, meas: Measurements, verdict: dict,
                        combinations: list | None = None, prepared: "D.Prepared | None" = None) -> RivalModels:
    """The rival models of ``verdict`` (from :func:`stiffcal.measured.discrepancy.analyse` on ``meas``): its
    combination and every equivalent combination (or the given ``combinations``), each fitted to the rows
    the analysis used, weighted and whitened as it weighted and whitened them (its noise model and its error
    model of the rows' shared reference readings: :func:`stiffcal.measured.discrepancy.prepare`, recomputed unless
    ``prepared`` is given), with every joint's compliance (a joint the data's loads never turn stays an
    unknown; measurement_offset one bias per position axis, as the plan's rows have). The first (the truth of a
    T-optimal plan) is the verdict's own combination, chosen by the closed
    test for the fewest causes and parameters: the smallest residual sum of squares would reward the rival
    with the most parameters (on clean data, after a false alarm, 15 coupling terms of a 6-axis arm fit the
    noise best). Given ``combinations``: in their order."""
    pre = prepared or D.prepare(robot, meas, float(verdict["alpha"]))
    old = pre.m
    ob = replace(pre.ob_full.take(pre.keep), params=None, n_offsets=robot.task_dim)
    combos = combinations or [verdict["causes"], *verdict["equivalent_combinations"]]
    combos = list(dict.fromkeys(_combination(c) for c in combos))
    testable = [c for c in D.CAUSES if c not in verdict["absorbed_by_nominal"]]
    lof = 1 if verdict.get("lack_of_fit_adjusted_p") is not None else 0
    noise = pre.noise  # the error variance of the analysis's tests; pure error when the replicates gave it
    rm = RivalModels(robot, old, pre.w, (), _combination(verdict["causes"]), float(np.sqrt(noise.s2)), int(noise.df),
                     noise.df_pe > 0, float(verdict["alpha"]), verdict, ob, pre.error)
    y = rm.old_y()
    models = []
    for S in combos:
        f = D.fit(rm.old_rows(S), y)
        k = max(len([c for c in testable if c not in S]) + lof, 1)
        models.append(Rival(S, f.beta, f.rss, k))
    return replace(rm, models=tuple(models))


# --- the criteria on stacked rows ----------------------------------------------------------------------------

def _scale(X: np.ndarray) -> np.ndarray:
    s = np.linalg.norm(X, axis=0)
    return np.where(s > 0, s, 1.0)


@dataclass(frozen=True)
class _Old:
    """The old rows of one model in identifiable coordinates, reduced once: X T = Q R, z = Q^T y,
    rss_out = |y - Q z|^2 (a fit of [old; new rows] then needs only R and z: Golub & Van Loan 5.3). T (p, r)
    maps the model's parameters to r identifiable directions: its columns scaled to unit norm and the
    directions no candidate point or old row excites dropped (a bending link that acts exactly like joint
    compliances, for instance), so the rank-r updates never meet a singular information matrix."""
    R: np.ndarray
    z: np.ndarray
    rss_out: float
    T: np.ndarray

    @classmethod
    def of(cls, X: np.ndarray, y: np.ndarray, X_pool: np.ndarray) -> "_Old":
        """X (N, p) the old rows, y (N,), X_pool (k, p) rows of candidate points (for the directions)."""
        A = np.vstack([X, X_pool])
        scale = _scale(A)
        _, sv, Vt = np.linalg.svd(A / scale, full_matrices=False)
        T = Vt[sv > D.RANK_RTOL * sv[0]].T / scale[:, None]
        Q, R = np.linalg.qr(X @ T)
        z = Q.T @ y
        r = y - Q @ z
        return cls(R, z, float(r @ r), T)

    def fit(self, B: np.ndarray, mu: np.ndarray, ridge: float = 0.0):
        """Least squares of the old rows and new rows B (k, p) (scaled), mu (k,): (rss, theta (p,) scaled,
        (A^T A + ridge s_max^2 I)^-1), A = [R; B]; rank decided as :func:`stiffcal.measured.discrepancy.fit` does."""
        A = np.vstack([self.R, B])
        y = np.concatenate([self.z, mu])
        U, s, Vt = np.linalg.svd(A, full_matrices=False)
        keep = s > D.RANK_RTOL * s[0]
        inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
        theta = Vt.T @ (inv * (U.T @ y))
        r = y - A @ theta
        Minv = (Vt.T / (s**2 + ridge * s[0] ** 2)) @ Vt
        return self.rss_out + float(r @ r), theta, Minv


@dataclass(frozen=True)
class Pair:
    """A truth and a rival (indices into :attr:`RivalModels.models`) and the rival's old rows reduced against
    the truth's old mean."""
    truth: int
    rival: int
    old: _Old


@dataclass
class Criterion:
    """The compound criterion over a candidate pool (module docstring), reduced so that every candidate's
    replacement of one plan point is scored at once.

    pairs: the (truth, rival) comparisons whose smallest lack of fit Delta is maximised; B: per rival index,
    its regressors over the pool (K, r, p) in the identifiable coordinates of its :class:`_Old`; mu: per truth
    index, its
    mean over the pool (K, r) [m]; repeats R; kappa: the weight of the discrimination (1: T-optimal; 0:
    O_t-optimal); ot: (old rows of the extended model, its pool regressors (K, r, p), X_t (d, p)) in its
    identifiable coordinates, or None; sigma [m]; at: (q, force) -> (B, mu, O_t regressors) at any points;
    ridge: relative regularisation of the rank-r updates (a direction the old data leave open)."""
    pairs: list
    B: dict
    mu: dict
    repeats: int
    kappa: float
    ot: tuple | None
    sigma: float
    at: object = None
    ridge: float = 1e-10

    def on(self, q: np.ndarray, force: np.ndarray) -> "Criterion":
        """The criterion over the points q (k, n) [rad], force (k, d) [N] instead of the pool (``at``: the
        function that gives B, mu and the O_t regressors at any points)."""
        B, mu, Bot = self.at(q, force)
        return replace(self, B=B, mu=mu, ot=None if self.ot is None else (self.ot[0], Bot, self.ot[2]))

    @property
    def size(self) -> int:
        return len(next(iter(self.mu.values()))) if self.mu else len(self.ot[1])

    def _rows(self, X: np.ndarray, idx) -> np.ndarray:
        """The plan's stacked rows, each point counted ``repeats`` times: sqrt(R) X[idx] as (m r, ...)."""
        v = np.sqrt(self.repeats) * X[np.asarray(idx, int)]
        return v.reshape((-1,) + X.shape[2:])

    def pair_fit(self, pair: Pair, idx):
        """(Delta [m^2], theta (scaled), Minv) of one pair after the old data and the plan ``idx``."""
        return pair.old.fit(self._rows(self.B[pair.rival], idx), self._rows(self.mu[pair.truth], idx), self.ridge)

    def deltas(self, idx) -> np.ndarray:
        """Delta [m^2] of every pair for the plan ``idx`` (pool indices)."""
        return np.array([self.pair_fit(p, idx)[0] for p in self.pairs])

    def _ot_info(self, idx) -> np.ndarray:
        old, B, _ = self.ot
        A = np.vstack([old.R, self._rows(B, idx)])
        return A.T @ A

    def o_t(self, idx) -> float:
        """O_t [m^2] (eq. 16) of the extended model after the old data and the plan (inf when singular)."""
        if self.ot is None:
            return float("nan")
        Xt = self.ot[2]
        try:
            return float(self.sigma**2 * np.trace(Xt @ np.linalg.solve(self._ot_info(idx), Xt.T)))
        except np.linalg.LinAlgError:
            return float("inf")

    def _combine(self, delta, ot):
        out = 0.0
        if self.kappa > 0:
            out = out + self.kappa * np.log(np.maximum(delta / self.sigma**2, 1e-300))
        if self.kappa < 1:
            out = out - (1 - self.kappa) * np.log(np.maximum(ot / self.sigma**2, 1e-300))
        return out

    def value(self, idx) -> float:
        """kappa log(min Delta / sigma^2) - (1 - kappa) log(O_t / sigma^2), maximised."""
        delta = self.deltas(idx).min() if self.kappa > 0 else 1.0
        return float(self._combine(delta, self.o_t(idx) if self.kappa < 1 else 1.0))

    def scores(self, rest) -> np.ndarray:
        """(K,): :meth:`value` of the plan ``rest`` plus each candidate, by rank-r updates: for every pair
        Delta(c) = Delta(rest) + R e_c^T (I + R B_c Minv B_c^T)^-1 e_c, e_c = mu_c - B_c theta (recursive least
        squares), and O_t(c) = sigma^2 [tr(W Minv) - tr((I + R B_c Minv B_c^T)^-1 R B_c Minv W Minv B_c^T)]
        (Woodbury), W = X_t^T X_t."""
        R = self.repeats
        delta = ot = 1.0
        if self.kappa > 0:
            delta = np.full(self.size, np.inf)
            for pair in self.pairs:
                rss, theta, Minv = self.pair_fit(pair, rest)
                B = self.B[pair.rival]
                e = self.mu[pair.truth] - B @ theta
                S = np.eye(B.shape[1]) + R * (B @ Minv) @ np.swapaxes(B, 1, 2)
                delta = np.minimum(delta, rss + R * np.einsum("kr,kr->k", e, np.linalg.solve(S, e[..., None])[..., 0]))
        if self.kappa < 1:
            _, B, Xt = self.ot
            M = self._ot_info(rest)
            Minv = np.linalg.inv(M + self.ridge * np.trace(M) * np.eye(len(M)))
            W = Xt.T @ Xt
            BM = B @ Minv
            S = np.eye(B.shape[1]) + R * BM @ np.swapaxes(B, 1, 2)
            G = R * (BM @ W) @ np.swapaxes(BM, 1, 2)
            ot = self.sigma**2 * (np.trace(W @ Minv) - np.einsum("kii->k", np.linalg.solve(S, G)))
        return self._combine(delta, ot)


def build_criterion(rm: RivalModels, pool: Pool, pairs: list[tuple[int, int]], repeats: int = 1, kappa: float = 1.0,
                    test_pose=None, test_force=None, measurement=None) -> Criterion:
    """The :class:`Criterion` of the (truth, rival) ``pairs`` of ``rm`` over ``pool``, each point measured
    ``repeats`` times by ``measurement`` (default :class:`PositionModel`); with kappa < 1, the compound
    criterion with the extended model's O_t at ``test_pose`` (n,) [rad] under ``test_force`` (d,) [N]."""
    mm = measurement or PositionModel()
    robot = rm.robot
    used = sorted({i for p in pairs for i in p})
    causes = {i: rm.models[i].causes for i in used} | ({-1: rm.extended} if kappa < 1 else {})
    sample = np.random.default_rng(0).choice(len(pool), min(len(pool), 1024), replace=False)
    probe = {i: D._stack(mm.columns(robot, pool.q[sample], pool.force[sample], c)) for i, c in causes.items()}
    built = [Pair(t, j, _Old.of(rm.old_rows(causes[j]), rm.old_mean(rm.models[t]), probe[j])) for t, j in pairs]
    basis = {p.rival: p.old.T for p in built}
    ot_old = Xt = None
    if kappa < 1:
        Xo = rm.old_rows(rm.extended)
        ot_old = _Old.of(Xo, np.zeros(len(Xo)), probe[-1])
        Xt = D.model_columns(robot, np.atleast_2d(test_pose), np.atleast_2d(test_force), rm.extended, predict=True)[0]
        Xt = Xt @ ot_old.T

    def at(q, F):
        cols = {i: mm.columns(robot, q, F, causes[i]) for i in used}
        B = {j: cols[j] @ T for j, T in basis.items()}
        mu = {t: cols[t] @ rm.models[t].beta for t, _ in pairs}
        Bot = None if ot_old is None else mm.columns(robot, q, F, rm.extended) @ ot_old.T
        return B, mu, Bot

    B, mu, Bot = at(pool.q, pool.force)
    ot = None if ot_old is None else (ot_old, Bot, Xt)
    return Criterion(built, B, mu, int(repeats), float(kappa) if built else 0.0, ot, rm.sigma, at)


# --- the exchange --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Exchanged:
    """indices (M,) into the pool, sorted; value: the criterion; starts tried."""
    indices: np.ndarray
    value: float
    starts: int


def exchange(crit: Criterion, m: int, n_starts: int = 4, seed: int = 0, max_passes: int = 20,
             starts=()) -> Exchanged:
    """Fedorov's exchange (Fedorov 1972, ch. 3) of an m-point plan over the pool, maximising ``crit``: from
    the given ``starts`` (pool indices), the greedy sequential plan (each point the best addition to the old
    data and the points before it) and ``n_starts`` random plans (seeded); each start is exchanged until no
    single replacement improves it, all in lockstep by the project's one exchange engine
    (:func:`stiffcal.planning.plans.exchange_loop`, scored by :meth:`Criterion.scores`); the plan of the largest
    :meth:`Criterion.value` is returned (the first on ties). The old data make every rest plan estimable, so no
    start is singular. Deterministic for a seed."""
    from ..planning.plans import exchange_loop

    K = crit.size
    rng = np.random.default_rng(seed)
    greedy: list[int] = []
    for _ in range(m):
        greedy.append(int(np.argmax(crit.scores(greedy))))
    starts = [np.asarray(s, int) for s in starts] + [np.array(greedy)]
    starts += [rng.choice(K, m, replace=K < m) for _ in range(n_starts)]
    idx = np.array(starts, int)  # (S, m): the plans, exchanged in place

    def loss(ss, js, _):  # the engine minimises: minus the value of each plan with slot j replaced by each candidate
        return np.stack([-crit.scores(np.delete(idx[s], j)) for s, j in zip(ss, js)])

    # the engine's sums of information matrices are not this criterion's: empty ones; the scorer reads the plans
    exchange_loop(loss, [-crit.value(i) for i in idx], np.zeros(idx.shape + (0, 0)), idx, np.zeros((K, 0, 0)),
                  max_passes)
    values = [crit.value(i) for i in idx]
    best = int(np.argmax(values))  # the first on ties
    return Exchanged(np.sort(idx[best]), float(values[best]), len(starts))


def polish(crit: Criterion, robot: Robot, pool: Pool, idx, max_evaluations: int = 600):
    """Polish the exchanged plan ``idx`` in the continuum: L-BFGS-B (finite-difference gradients, at most
    ``max_evaluations`` evaluations of the criterion) on the M n joint angles within the joint limits, every
    point's load held, a point kept above the pool's torque floor by a penalty. Returns (q (M, n) [rad],
    force (M, d) [N], value), never worse than the plan from the pool."""
    from ..planning.problem import _is_full_turn
    from ..model.workcell import feasible

    q0, F0 = pool.q[np.asarray(idx, int)], pool.force[np.asarray(idx, int)]
    m, n = q0.shape
    floor = np.where(pool.tau_floor > 0, pool.tau_floor, 1.0)
    load = pool.load[np.asarray(idx, int)]

    def wrench(q):  # a loading bar's moment turns with the tool: each point's load at its pose
        return F0 if pool.arm is None else pool.at(robot, q, load)

    def value(q):
        return crit.on(q, wrench(q)).value(np.arange(m))

    v0 = value(q0)

    def f(z):
        q = z.reshape(m, n)
        if robot.cell is not None and not feasible(robot, q, pool.hang_offset).all():
            return -v0 + 1e3 * (abs(v0) + 1.0)  # out of the cell: refused (the line search backtracks; checked below)
        short = np.maximum(pool.tau_floor - np.abs(D.torques(robot, q, wrench(q))), 0.0) / floor
        return -value(q) + 1e3 * float(short.sum())

    lims = robot.joint_limits_rad
    bounds = [(None, None) if _is_full_turn(*lims[j]) else tuple(lims[j]) for j in range(n)] * m
    res = optimize.minimize(f, q0.ravel(), method="L-BFGS-B", bounds=bounds,
                            options=dict(maxfun=max_evaluations, maxiter=max_evaluations))
    q = res.x.reshape(m, n)
    if pool.admissible(robot, q, wrench(q)).all() and np.isfinite(res.fun):
        v = value(q)
        if v > v0:
            return q, wrench(q), float(v)
    return q0, F0, float(v0)


def _optimise(crit: Criterion, robot: Robot, pool: Pool, m: int, n_starts: int, seed: int, known=()):
    """Exchange over the pool with the ``known`` plans ((q (m, n) [rad], force (m, d)) each) added to it and
    used as starts, then :func:`polish`: the result is at least as good as every known plan. Returns (q, force)."""
    if known:
        q = np.vstack([k[0] for k in known])
        pool = pool.joined(robot, q, _load_index(pool, np.vstack([k[1] for k in known])))
        crit = replace(crit, **dict(zip(("B", "mu", "ot"), _arrays(crit, pool))))
    starts = [len(pool) - m * len(known) + m * i + np.arange(m) for i in range(len(known))]
    return polish(crit, robot, pool, exchange(crit, m, n_starts, seed, starts=starts).indices)[:2]


def _arrays(crit: Criterion, pool: Pool):
    """(B, mu, ot) of ``crit`` over the points of ``pool``."""
    B, mu, Bot = crit.at(pool.q, pool.force)
    return B, mu, None if crit.ot is None else (crit.ot[0], Bot, crit.ot[2])


# --- power ----------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Power:
    """The F-test that rejects ``rival`` when ``truth`` holds, after the old data and a plan: delta [m^2] (the
    rival's lack of fit, the T-criterion), noncentrality delta / sigma^2, df_num, df_den, level (alpha / k)
    and power."""
    truth: tuple[str, ...]
    rival: tuple[str, ...]
    delta: float
    noncentrality: float
    df_num: int
    df_den: int
    level: float
    power: float


def f_power(noncentrality: float, df_num: int, df_den: int, level: float) -> float:
    """1 - F'(F_crit(level; df_num, df_den); df_num, df_den, noncentrality): the power of an F-test
    (Scheffe 1959, sec. 2.8); the level itself when there is nothing to detect."""
    if df_num <= 0 or df_den <= 0:
        return 0.0
    crit = stats.f.isf(level, df_num, df_den)
    if noncentrality <= 0:
        return float(level)
    return float(stats.ncf.sf(crit, df_num, df_den, noncentrality))


def plan_power(rm: RivalModels, q: np.ndarray, force: np.ndarray, repeats: int = 1, truth: int = 0,
               measurement=None) -> list[Power]:
    """The :class:`Power` of the separating F-test of every other model when ``rm.models[truth]`` (with its
    fitted parameters) is the truth, after the old data and the plan q (M, n) [rad], force (M, d) [N], each
    point measured ``repeats`` times, at the verdict's alpha and noise (module docstring)."""
    mm = measurement or PositionModel()
    robot = rm.robot
    T = rm.models[truth]
    sq = np.sqrt(repeats)
    mu = np.concatenate([rm.old_mean(T), sq * (mm.columns(robot, q, force, T.causes) @ T.beta).ravel()])
    X0 = np.vstack([rm.old_rows(T.causes), sq * D._stack(mm.columns(robot, q, force, T.causes))])
    df_den = noise_df(rm, q, force, repeats, mm)
    out = []
    for j, riv in enumerate(rm.models):
        if j == truth:
            continue
        Xj = np.vstack([rm.old_rows(riv.causes), sq * D._stack(mm.columns(robot, q, force, riv.causes))])
        fj = D.fit(Xj, mu)
        both = D.fit(np.hstack([Xj, X0]), mu).rank
        nu1 = both - fj.rank
        lam = fj.rss / rm.sigma**2 if nu1 > 0 else 0.0
        level = rm.alpha / riv.multiplicity
        out.append(Power(T.causes, riv.causes, fj.rss if nu1 > 0 else 0.0, lam, nu1, df_den, level,
                         f_power(lam, nu1, df_den, level)))
    return out


def noise_df(rm: RivalModels, q: np.ndarray, force: np.ndarray, repeats: int = 1, measurement=None) -> int:
    """Error degrees of freedom after the old data and the plan q (M, n) [rad], force (M, d), each point measured
    ``repeats`` times: pure error gains (count - 1) per row of each distinct point measured count times; a
    residual estimate (no replicates) is that of the union of every cause on old and new rows together."""
    mm = measurement or PositionModel()
    r = mm.rows(rm.robot)
    if rm.pure_error:  # every distinct point is one replicate group (a point of the plan may repeat)
        distinct = len({tuple(np.round(np.r_[a, f], 9)) for a, f in zip(q, force)})
        return rm.noise_df + r * (len(q) * repeats - distinct)
    Xo = rm.old_rows(D.CAUSES)
    Xn = np.sqrt(repeats) * D._stack(mm.columns(rm.robot, q, force, D.CAUSES))
    X = np.vstack([Xo, Xn])
    return len(Xo) + len(q) * r * repeats - D.fit(X, np.zeros(len(X))).rank


# --- which rivals a plan of positions can separate ------------------------------------------------------------

@dataclass(frozen=True)
class Separability:
    """Whether any plan measured by ``measurement`` can reject ``rival`` when ``truth`` holds: not when the
    truth's regressors lie in the rival's span at every candidate point (then the rival reproduces the
    truth's mean exactly, Delta = 0 for every plan). reason: why not; needs: the measurements that would."""
    truth: int
    rival: int
    separable: bool
    reason: str | None = None
    needs: tuple[str, ...] = ()


def separability(rm: RivalModels, pool: Pool, measurement=None, probe: int = 512, seed: int = 0) -> list[Separability]:
    """:class:`Separability` of every ordered pair of models over ``probe`` random points of the pool (the
    span of every point's rows stacked: the test of :func:`stiffcal.measured.discrepancy.separation_advice`)."""
    mm = measurement or PositionModel()
    pick = np.sort(np.random.default_rng(seed).choice(len(pool), min(probe, len(pool)), replace=False))
    q, F = pool.q[pick], pool.force[pick]
    X = {i: D._stack(mm.columns(rm.robot, q, F, m.causes)) for i, m in enumerate(rm.models)}
    out = []
    for t in range(len(rm.models)):
        for j in range(len(rm.models)):
            if t == j:
                continue
            if not D._spans_within(X[t], X[j]):
                out.append(Separability(t, j, True))
                continue
            a, b = rm.models[t].label, rm.models[j].label
            both = D._spans_within(X[j], X[t])
            why = (f"with the joint compliances, {a} and {b} span the same directions of the {mm.name} at every "
                   "pose and load" if both else
                   f"with the joint compliances, {b} spans every direction of the {mm.name} that {a} does (and "
                   "more) at every pose and load")
            out.append(Separability(t, j, False, f"{why}: if {a} holds, {b} fits any plan of these measurements "
                                    "exactly, so no plan can reject it", OTHER_MEASUREMENTS))
    return out


def false_alarm_possible(verdict: dict) -> bool:
    """Whether the verdict's rejection of "no cause is needed" may be one of the global test's false alarms:
    its adjusted p within a factor 100 of alpha. Far below that, the causes the data need are real but cannot
    be told apart on these data."""
    return verdict["p_value"] > verdict["alpha"] / 100


def unsupported_causes(verdict: dict) -> list[str]:
    """The verdict's cause and its indistinguishable alternatives when none of them is significant on its own
    (each one's closed-testing adjusted p above alpha), else []: the verdict then rests on the intersection
    "none of them is needed" alone (docs/measured-data.md, ``p_value_of``)."""
    named = [c for c in [*verdict["causes"], *verdict["indistinguishable_from"]] if c in verdict["tests"]]
    if not named or verdict["cause"] in ("none", "unexplained"):
        return []
    return [] if any(verdict["tests"][c]["significant"] for c in named) else named


def design_pairs(rm: RivalModels, seps: list[Separability], truth: str = "best") -> list[tuple[int, int]]:
    """The (truth, rival) pairs a plan is designed for: the verdict's combination against every rival it can
    separate (``truth="best"``, T-optimality), or every separable ordered pair (``truth="each"``: each model in
    turn as the truth, the maximin criterion of Atkinson & Fedorov 1975b)."""
    if truth not in ("best", "each"):
        raise InputError(f"expected 'best' or 'each', got {truth!r}", field="--truth")
    return [(s.truth, s.rival) for s in seps if s.separable and (truth == "each" or s.truth == 0)]


# --- certificates ------------------------------------------------------------------------------------------

def _continuum_max(fun, robot: Robot, pool: Pool, effort: Effort, extra_q=None, extra_load=None):
    """The local maxima over every pose within the joint limits and every load of ``pool`` of fun(q (k, n) [rad],
    loads (k, w) [N, N m] at those poses, :meth:`Pool.at`) -> (k,): per load, a grid over the joint space
    (:func:`stiffcal.planning.problem.joint_grids` at ``effort.search_step_deg``) whose best local maxima, and the
    ``extra_q`` (k, n) [rad] under that load (``extra_load`` (k,) load indices), are polished (L-BFGS-B, batched
    central differences); for 4+ joints :func:`stiffcal.planning.problem.sampled_minimise` with the extra points
    among its samples. Returns values (k,), poses (k, n) [rad] and load indices (k,), largest first."""
    from ..planning.problem import _is_full_turn, _polish_all, evaluate_grid, grid_local_minima

    step = effort.search_step_deg or SEARCH_STEP_DEG.get(robot.n_joints, 10.0)
    n = robot.n_joints
    extra_q = np.zeros((0, n)) if extra_q is None else np.atleast_2d(extra_q)
    extra_load = np.zeros(0, int) if extra_load is None else np.asarray(extra_load, int)
    vals, poses, which = [], [], []
    for i in range(len(pool.loads)):
        def neg(q, i=i):
            x = np.atleast_2d(q).reshape(-1, n)
            return -fun(x, pool.at(robot, x, np.full(len(x), i))).reshape(np.shape(q)[:-1])

        extra = extra_q[extra_load == i]
        if is_sampled(robot, step):
            xs, fs = sampled_minimise(neg, robot, 4, log2_count=effort.search_log2, extra_starts=extra, xatol=1e-9)
        else:
            grids = joint_grids(robot, step)
            values = evaluate_grid(neg, grids)
            mask = grid_local_minima(values, [_is_full_turn(lo, hi) for lo, hi in robot.joint_limits_rad])
            at = np.argwhere(mask)[np.argsort(values[mask], kind="stable")[:4]]
            starts = np.array([[g[k] for g, k in zip(grids, row)] for row in at]).reshape(-1, n)
            xs, fs = _polish_all(neg, robot, np.vstack([starts, extra]), 1e-9, smooth=True)
        vals += list(-fs)
        poses += list(xs)
        which += [i] * len(fs)
    order = np.argsort(-np.asarray(vals), kind="stable")
    return np.asarray(vals)[order], np.asarray(poses).reshape(-1, n)[order], np.asarray(which, int)[order]


@dataclass(frozen=True)
class TCertificate:
    """The equivalence-theorem bound on the T-criterion (module docstring): delta [m^2], the plan's smallest
    lack of fit over the design pairs; bound [m^2], no plan of the same size can exceed it; efficiency =
    delta / bound; pair: the (truth, rival) whose bound is smallest; power_bound: the power of that pair's
    F-test at the bound with the fewest numerator and most denominator degrees of freedom any plan of M points
    can have (:func:`_df_extremes`; no plan of M points does better); where_deg (k, n), where_load (k, w): the local
    maxima of psi over the joint space and the loads (the first is the maximum), where an optimal design puts
    its points (Atkinson & Fedorov 1975, Theorem 1)."""
    delta: float
    bound: float
    efficiency: float
    pair: tuple[int, int]
    power_bound: float
    where_deg: np.ndarray
    where_load: np.ndarray


def _minimax_theta(pair: Pair, B: np.ndarray, mu: np.ndarray, weight: float, theta0: np.ndarray) -> np.ndarray:
    """theta minimising old(theta) + weight max_k psi_k(theta) over the pool (psi_k = |mu_k - B_k theta|^2), by
    L-BFGS on the log-sum-exp smoothing of the maximum with a decreasing temperature (each smoothing is an
    upper bound of the maximum, and any theta gives a valid bound)."""
    old = pair.old

    def psi(th):
        e = mu - B @ th
        return np.einsum("kr,kr->k", e, e), e

    theta = theta0
    top = psi(theta)[0].max()
    if not top > 0:  # the plan's theta already fits every candidate: nothing to lower
        return theta
    for tau in top * np.array([1e-1, 1e-2, 1e-3, 1e-4]):
        def g(th, tau=tau):
            v, e = psi(th)
            r = old.z - old.R @ th
            w = np.exp((v - v.max()) / tau)
            lse = v.max() + tau * np.log(w.sum())
            grad_max = -2 * np.einsum("k,kr,krp->p", w / w.sum(), e, B)
            return float(r @ r + weight * lse), -2 * old.R.T @ r + weight * grad_max

        res = optimize.minimize(g, theta, jac=True, method="L-BFGS-B", options=dict(maxiter=500))
        theta = res.x
    return theta


def t_certificate(crit: Criterion, rm: RivalModels, pool: Pool, q: np.ndarray, force: np.ndarray, measurement=None,
                  effort: Effort = Effort()) -> TCertificate:
    """The :class:`TCertificate` of the plan q (M, n) [rad], force (M, d) [N] for ``crit``'s pairs: for every pair,
    bound = old(theta) + R M max_x psi(x, theta) at the minimax theta over the pool (started from the plan's),
    the maximum over x taken over the whole joint space and every load; the smallest over the pairs."""
    mm = measurement or PositionModel()
    m, R = len(q), crit.repeats
    robot = rm.robot
    local, every = crit.on(q, force), np.arange(m)
    deltas = local.deltas(every)
    plan_loads = _load_index(pool, force)
    best = None
    for pair in crit.pairs:
        B, mu = crit.B[pair.rival], crit.mu[pair.truth]
        _, theta_plan, _ = local.pair_fit(pair, every)
        theta = _minimax_theta(pair, B, mu, R * m, theta_plan)
        T, J = rm.models[pair.truth], rm.models[pair.rival]

        def psi(x, F):
            e = mm.columns(robot, x, F, T.causes) @ T.beta - (mm.columns(robot, x, F, J.causes) @ pair.old.T) @ theta
            return np.sum(e**2, axis=-1) * pool.admissible(robot, x, F)

        r = pair.old.z - pair.old.R @ theta
        on_pool = np.sum((mu - B @ theta) ** 2, axis=-1)
        vals, poses, li = _continuum_max(psi, robot, pool, effort, q, plan_loads)
        k = int(np.argmax(on_pool))  # the search cannot miss a pool point: keep the larger (the bound must hold)
        vals, poses, li = np.r_[vals, on_pool[k]], np.vstack([poses, pool.q[k]]), np.r_[li, pool.load[k]]
        order = np.argsort(-vals, kind="stable")
        bound = pair.old.rss_out + float(r @ r) + R * m * float(vals[order[0]])
        if best is None or bound < best[0]:
            best = (bound, (pair.truth, pair.rival), poses[order], li[order])
    bound, pr, pose, li = best
    delta = float(deltas.min())
    J = rm.models[pr[1]]
    test = [p for p in plan_power(rm, q, force, R, pr[0], mm) if p.rival == J.causes][0]
    df_num, df_den = _df_extremes(rm, rm.models[pr[0]], J, m, R, mm)
    power_bound = f_power(bound / rm.sigma**2, df_num, df_den, test.level)
    return TCertificate(delta, float(bound), float(delta / bound) if bound > 0 else 1.0, pr, power_bound,
                        np.degrees(pose), pool.at(robot, pose, li))


def _df_extremes(rm: RivalModels, truth: Rival, rival: Rival, m: int, repeats: int, mm) -> tuple[int, int]:
    """The fewest numerator and the most denominator degrees of freedom the separating F-test can have after
    the old data and ANY plan of m points, each measured ``repeats`` times (the power at a given noncentrality
    falls with the first and grows with the second, so the power bound uses these): new rows never lower
    rank([X_j, X_0]) - rank(X_j) (the null space of [X_j, X_0] only shrinks), so at least the old data's (and 1,
    for a test to exist); pure error gains at most r (m R - 1) (every point the same), a residual estimate at
    most the new rows (the union's rank never falls)."""
    Xj, X0 = rm.old_rows(rival.causes), rm.old_rows(truth.causes)
    nu1 = max(D.fit(np.hstack([Xj, X0]), np.zeros(len(Xj))).rank - D.fit(Xj, np.zeros(len(Xj))).rank, 1)
    r = mm.rows(rm.robot)
    if rm.pure_error:
        return nu1, rm.noise_df + r * (m * repeats - 1)
    Xo = rm.old_rows(D.CAUSES)
    return nu1, len(Xo) + m * r * repeats - D.fit(Xo, np.zeros(len(Xo))).rank


def ot_lower_bound(crit: Criterion, rm: RivalModels, pool: Pool, q: np.ndarray, force: np.ndarray, measurement=None,
                   effort: Effort = Effort()) -> float:
    """A lower bound [m^2] on O_t of ANY plan of len(q) points after the old data (q (M, n) [rad], force (M, d)
    [N] a good plan, e.g. the O_t-optimal one): O_t is convex in the
    information matrix N, so O_t(N') >= O_t(N) - sigma^2 R (sum_{plan'} phi - sum_{plan} phi) >= O_t(N) - sigma^2 R
    (M max_x phi(x) - sum_{plan} phi), phi(x) = |X(x) N^-1 X_t^T|_F^2 (tight at the optimum: equivalence theorem)."""
    mm = measurement or PositionModel()
    old, B, Xt = crit.ot
    local, every = crit.on(q, force), np.arange(len(q))
    N = local._ot_info(every)
    C = np.linalg.solve(N, Xt.T)  # (p, d_t)
    robot, ext = rm.robot, rm.extended

    def phi(q, F):
        return np.sum((mm.columns(robot, q, F, ext) @ old.T @ C) ** 2, axis=(-2, -1)) * pool.admissible(robot, q, F)

    on_plan = float(np.sum((local.ot[1] @ C) ** 2))
    top = max(float(_continuum_max(phi, robot, pool, effort, q, _load_index(pool, force))[0].max(initial=0.0)),
              float(np.max(np.sum((B @ C) ** 2, axis=(-2, -1)))))
    # the bound holds for any plan, but may fall below zero (where the plan's own phi is far from its maximum): O_t
    # is a mean square, so zero bounds it too (a fresh user's UR10 plan printed -5.7e-11 m^2)
    return max(float(local.o_t(every) - rm.sigma**2 * crit.repeats * (len(q) * top - on_plan)), 0.0)


# --- the next session -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Session:
    """A plan of M measurements: poses_deg (M, n), forces_N (M, d), each measured ``repeats`` times; deltas:
    Delta [m^2] of each design pair; powers: the :class:`Power` of every ordered pair of models (each model in
    turn as the truth); o_t [m^2]: the extended model's O_t after the old data and the plan (None without a
    test pose); value: the criterion it maximised."""
    poses_deg: np.ndarray
    forces_N: np.ndarray
    repeats: int
    deltas: np.ndarray
    powers: tuple[Power, ...]
    o_t: float | None
    value: float

    def power(self, pairs, models) -> float:
        """The smallest power over the (truth, rival) ``pairs`` (indices into ``models``)."""
        want = {(models[t].causes, models[j].causes) for t, j in pairs}
        got = [p.power for p in self.powers if (p.truth, p.rival) in want]
        return float(min(got)) if got else float("nan")


def _session(crit: Criterion, rm: RivalModels, q: np.ndarray, F: np.ndarray, measurement=None,
             ot_crit: Criterion | None = None) -> Session:
    """The plan q (M, n) [rad], force (M, d) [N] as a :class:`Session`: angles within the joint limits (a joint
    with a full turn of range wrapped into them), points closer than 1e-3 deg made one repeated point when that
    costs nothing (:func:`stiffcal.planning.plans.merge_repeats`), sorted; O_t from ``ot_crit`` when ``crit`` has
    none."""
    from ..planning.problem import into_limits
    from ..planning.plans import merge_repeats

    deg = into_limits(rm.robot, np.degrees(q))
    merged = merge_repeats(deg)
    every = np.arange(len(q))
    v0 = crit.on(np.radians(deg), F).value(every)
    if crit.on(np.radians(merged), F).value(every) >= v0 - 1e-9 * abs(v0):
        deg = merged
    order = np.lexsort(np.hstack([deg, F]).T[::-1])
    q, F = np.radians(deg[order]), F[order]
    local = crit.on(q, F)
    powers = tuple(p for t in range(len(rm.models)) for p in plan_power(rm, q, F, crit.repeats, t, measurement))
    ot_crit = crit if crit.ot is not None else ot_crit
    return Session(deg[order], F, crit.repeats, local.deltas(every) if crit.pairs else np.zeros(0), powers,
                   None if ot_crit is None else ot_crit.on(q, F).o_t(every), local.value(every))


@dataclass(frozen=True)
class Discrimination:
    """The next experiment for one data set (module docstring).

    rivals: the fitted rival models; loads; m: points in the plan; repeats; truth: 'best' or 'each';
    separability: every ordered pair; pairs: the (truth, rival) pairs the plan is designed for; plan: the
    discriminating (T-optimal) plan, None when no pair can be separated; certificate: its
    :class:`TCertificate`; weight: kappa of the compound criterion; compound: the compound plan (None without
    a test pose); ot_plan: the O_t-optimal plan (kappa = 0); ot_bound [m^2]: a lower bound on O_t of any M-point
    plan; power_against_m: (m, power of the best discriminating plan of m points); notes."""
    rivals: RivalModels
    loads: LoadSet
    m: int
    repeats: int
    truth: str
    separability: tuple[Separability, ...]
    pairs: tuple[tuple[int, int], ...]
    plan: Session | None
    certificate: TCertificate | None
    weight: float
    compound: Session | None
    ot_plan: Session | None
    ot_bound: float | None
    power_against_m: tuple[tuple[int, float], ...]
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def separable(self) -> bool | None:
        """Whether a plan can separate the rivals (None when there is no rival)."""
        return bool(self.pairs) if len(self.rivals.models) > 1 else None

    @property
    def power(self) -> float | None:
        """The smallest predicted power over the design pairs of the discriminating plan."""
        return None if self.plan is None else self.plan.power(self.pairs, self.rivals.models)


@single_threaded
def discriminate(robot: Robot, meas: Measurements, m: int, loads: LoadSet, verdict: dict | None = None,
                 repeats: int = 1, weight: float = COMPOUND_WEIGHT, truth: str = "best", test_pose=None,
                 test_force=None, alpha: float = 0.01, m_curve=None, measurement=None, effort: Effort = Effort(),
                 seed: int = 0) -> Discrimination:
    """The next experiment for the measurements ``meas`` (module docstring): the verdict (computed at ``alpha``
    unless given), its rival models, which pairs a plan of ``measurement`` can separate, the discriminating
    plan of m points (poses within the joint limits, loads from ``loads``, each measured ``repeats`` times)
    with its certificate and predicted power, and with a test pose (n,) [rad] and its force (d,) [N] the
    compound plan (``weight`` = kappa) and the O_t-optimal plan; the power of the best plan of every m of
    ``m_curve`` (default 1 .. max(m, 8); exchanged over the pool, not polished). ``effort``: how hard the
    searches work (:class:`Effort`); ``seed``: of the exchange's random starts. Raises :class:`InputError` for
    m < 1, repeats < 1, a weight outside [0, 1] or loads of the wrong dimension."""
    _check_request(robot, m, repeats, weight, loads)
    notes = []
    loads = _with_data_moments(robot, meas, loads, notes)
    pre = D.prepare(robot, meas, alpha if verdict is None else float(verdict["alpha"]))
    if verdict is None:
        verdict = D.verdict_of(robot, pre, alpha, gain=False)
    rm = rivals_from_verdict(robot, meas, verdict, prepared=pre)
    pool = make_pool(robot, pose_pool(robot, effort.pool_step_deg, effort.pool_log2), loads.forces,
                     {c for mdl in rm.models for c in mdl.causes}, loads.kind in ("hanging", "bar"), loads.arm)
    seps = separability(rm, pool, measurement)
    pairs = design_pairs(rm, seps, truth)
    notes += _rival_notes(verdict, rm, seps, pairs)
    crit0 = None
    if test_pose is not None and test_force is not None:
        crit0 = build_criterion(rm, pool, [], repeats, 0.0, test_pose, test_force, measurement)
    plan = cert = None
    curve: list[tuple[int, float]] = []
    if pairs:
        plan, cert, curve = _discriminating_plan(rm, pool, pairs, m, repeats, measurement, effort, seed, crit0,
                                                 m_curve)
        notes += _few_equations_note(robot, rm, m, repeats)
    compound = ot_plan = ot_bound = None
    if crit0 is not None:  # the O_t-optimal plan, then the compound plan started from both
        known = [] if plan is None else [(np.radians(plan.poses_deg), plan.forces_N)]
        q0, F0 = _optimise(crit0, robot, pool, m, effort.n_starts, seed, known)
        ot_plan = _session(crit0, rm, q0, F0, measurement)
        ot_bound = ot_lower_bound(crit0, rm, pool, q0, F0, measurement, effort)
        if pairs:
            critc = build_criterion(rm, pool, pairs, repeats, weight, test_pose, test_force, measurement)
            qc, Fc = _optimise(critc, robot, pool, m, effort.n_starts, seed, known + [(q0, F0)])
            compound = _session(critc, rm, qc, Fc, measurement)
    elif pairs:
        notes.append("no test pose: the compound plan (discrimination and O_t together) is left out")
    from ..model.workcell import cell_notes

    notes += [n if robot.cell is None else f"the cell ({robot.cell.describe()}): " + n for n in cell_notes(robot)]
    return Discrimination(rm, loads, m, repeats, truth, tuple(seps), tuple(pairs), plan, cert, float(weight),
                          compound, ot_plan, ot_bound, tuple(curve), tuple(notes))


def _check_request(robot: Robot, m: int, repeats: int, weight: float, loads: LoadSet) -> None:
    """:func:`discriminate`'s request checked: InputError naming the option."""
    if m < 1:
        raise InputError(f"expected a number of experiments >= 1, got {m}", field="--experiments")
    if repeats < 1:
        raise InputError(f"expected repeats >= 1, got {repeats}", field="--repeats")
    if not 0 <= weight <= 1:
        raise InputError(f"expected a weight in [0, 1], got {weight}", field="--weight")
    wrench_dim = robot.task_dim + D.moment_dim(robot)
    from ..model.observation import check_bar

    check_bar(robot, loads.arm, "--loads")
    if loads.forces.shape[1] not in (robot.task_dim, wrench_dim):
        raise InputError(f"expected loads of {robot.task_dim} components (forces) or {wrench_dim} (force and moment) "
                         f"for robot {robot.name}, got {loads.forces.shape[1]}", field="--loads")


def _bar_of_data(robot: Robot, meas: Measurements, loads: str | None) -> LoadSet | None:
    """The data's loads as the default, where they are masses on a loading bar (one lever in the tool frame gives
    every row's moment, :func:`stiffcal.measured.discrepancy.lab_loads`): the bar's masses, whose moment turns with
    the tool at every pose of the plan (a fresh user's bar log of 15 configurations was refused for its 45 distinct
    wrenches, each logged at one pose); else None."""
    if loads is not None or not meas.has_moment:
        return None
    lab = D.lab_loads(robot, meas)
    if lab is None or lab.arm is None:
        return None
    return LoadSet(np.asarray(lab.wrenches, float), "bar", "data", robot.task_dim, np.asarray(lab.arm, float))


def _with_data_moments(robot: Robot, meas: Measurements, loads: LoadSet, notes: list) -> LoadSet:
    """The loads to plan with: the data's own wrenches when the data's loads carry moments (a loading bar) and
    the loads are the data's; a note when pure forces are given for such data."""
    if meas.has_moment and loads.moments is None and loads.arm is None:
        if loads.kind == "data":  # the data's loads are wrenches (a loading bar): keep their moments
            return load_set("data", robot.task_dim, D.load_of(meas), meas.resolutions[1],
                            moment_resolution_Nm=meas.resolutions[2])
        notes.append(f"the data's loads carry moments (a loading bar) but the loads given ({loads.spec}) are "
                     "pure forces: the plan applies them without a moment")
    return loads


def _rival_notes(verdict: dict, rm: "RivalModels", seps, pairs) -> list[str]:
    """What the plan's user must know of the rivals: an unexplained verdict, causes needed only together, no
    rival or no separable pair, noise that varies with the position."""
    notes = []
    if verdict["cause"] == "unexplained":
        notes.append("the verdict is 'unexplained': something outside the catalogue is left, and the plan "
                     "separates the catalogue's combinations only")
    alone = unsupported_causes(verdict)
    if alone:
        why = ("a false alarm of the global test looks like this" if false_alarm_possible(verdict)
               else "the data cannot tell these causes apart")
        notes.append(f"no cause is needed on its own: the data need at least one of {{{', '.join(alone)}}} "
                     f"(adjusted p = {verdict['p_value']:.2g} of 'none of them is needed'), but none of them is "
                     f"significant on its own at alpha ({why}); the "
                     f"plan takes {rm.truth.label} as the truth with its fitted parameters, and its predicted power "
                     "holds only if that combination is real")
    if len(rm.models) == 1:
        what = rm.truth.label if rm.truth.causes else "no cause (the nominal model)"
        others = [c for c in verdict.get("indistinguishable_from") or [] if c not in rm.truth.causes]
        besides = (f" (the verdict's indistinguishable_from, {{{', '.join(others)}}}, are causes of which the data "
                   f"need at least one with {what}, not combinations that explain the data as well: "
                   "equivalent_combinations is empty, so no rival is fitted as well to plan against; the API's "
                   "rivals_from_verdict takes combinations= to plan against them)" if others else "")
        notes.append(f"no rival combination: the data single out {what}; nothing to discriminate{besides}")
    elif not pairs:
        notes.append("no plan of these measurements can separate the rivals; " + "; ".join(
            s.reason for s in seps if not s.separable and s.truth == 0))
    if verdict["nominal"]["noise_varies"]:
        notes.append("the noise varies with the position of the measured point; the new points are assumed to "
                     "have the noise of the median row")
    return notes


def _discriminating_plan(rm: "RivalModels", pool, pairs, m: int, repeats: int, measurement, effort: Effort,
                         seed: int, crit0, m_curve):
    """(plan, certificate, power against M) of the T-optimal discriminating plan: exchanged and polished, the
    maxima of psi brought into the pool while its certified efficiency is below 0.99 (vertex direction), then
    the best plan of every M of ``m_curve`` (exchanged over the pool, not polished)."""
    robot = rm.robot
    tpool = pool
    crit = build_criterion(rm, tpool, pairs, repeats, 1.0, measurement=measurement)
    q, F, val = polish(crit, robot, tpool, exchange(crit, m, effort.n_starts, seed).indices)
    cert = t_certificate(crit, rm, tpool, q, F, measurement, effort)
    for _ in range(effort.rounds):  # vertex direction: the maxima of psi join the pool
        if cert.efficiency >= 0.99:
            break
        bigger = tpool.joined(robot, np.vstack([q, np.radians(cert.where_deg)]),
                              np.concatenate([_load_index(tpool, F), _load_index(tpool, cert.where_load)]))
        crit2 = build_criterion(rm, bigger, pairs, repeats, 1.0, measurement=measurement)
        start = len(tpool) + np.arange(m)
        q2, F2, val2 = polish(crit2, robot, bigger, exchange(crit2, m, 0, seed, starts=[start]).indices)
        if not val2 > val + 1e-9 * abs(val):
            break
        tpool, crit, q, F, val = bigger, crit2, q2, F2, val2
        cert = t_certificate(crit, rm, tpool, q, F, measurement, effort)
    plan = _session(crit, rm, q, F, measurement, crit0)
    curve = []
    for mm_ in (m_curve or range(1, max(m, 8) + 1)):
        idx = None if mm_ == m else exchange(crit, int(mm_), 0, seed).indices
        qm, Fm = (q, F) if idx is None else (tpool.q[idx], tpool.force[idx])
        curve.append((int(mm_), _session(crit, rm, qm, Fm, measurement).power(pairs, rm.models)))
    return plan, cert, curve


def _few_equations_note(robot: Robot, rm: "RivalModels", m: int, repeats: int) -> list[str]:
    """A note when old and new data give at most twice the union model's parameters in equations."""
    total = len(rm.old.q) * robot.task_dim + m * repeats * PositionModel().rows(robot)
    p_union = rm.old_rows(D.CAUSES).shape[1]
    if total > 2 * p_union:
        return []
    return [f"old and new data give {total} equations, at most twice the {p_union} parameters of the union model: "
            "the analysis then screens blunders against the nominal model and may set aside the very points that "
            "separate the rivals; repeat the points (--repeats) or measure more"]


# --- results as JSON, the command and the figure ------------------------------------------------------------

def _tests(powers) -> list[dict]:
    return [{"truth": list(p.truth), "rival": list(p.rival), "t_criterion_m2": p.delta,
             "noncentrality": p.noncentrality,
             "df_num": p.df_num, "df_den": p.df_den, "level": p.level, "power": p.power} for p in powers]


def _split(load: np.ndarray, d: int):
    """Forces (k, d) [N] and moments (k, d_m) [N m] (None for pure forces) of loads (k, w), rounded for JSON."""
    load = np.round(np.atleast_2d(load), 4) + 0.0
    return load[:, :d].tolist(), (load[:, d:].tolist() if load.shape[1] > d else None)


def _session_json(s: Session, res: Discrimination) -> dict:
    from ..model.robot import round_within

    robot = res.rivals.robot
    forces, moments = _split(s.forces_N, robot.task_dim)
    out = {"poses_deg": round_within(s.poses_deg, robot.limits_deg, 4).tolist(), "forces_N": forces,
           "moments_Nm": moments,
           "repeats": s.repeats, "t_criterion_m2": float(s.deltas.min()) if len(s.deltas) else None,
           "power": s.power(res.pairs, res.rivals.models) if res.pairs else None, "tests": _tests(s.powers),
           "O_t_m2": s.o_t, "O_t_rms_m": None if s.o_t is None else float(np.sqrt(s.o_t))}
    points: dict = {}  # the distinct points in plan order, with how often each is measured
    for pose, f, mo in zip(out["poses_deg"], forces, moments or [None] * len(forces)):
        key = (tuple(pose), tuple(f), None if mo is None else tuple(mo))
        points[key] = points.get(key, 0) + s.repeats
    out["points"] = [{"pose_deg": list(p), "force_N": list(f), "moment_Nm": None if mo is None else list(mo),
                      "count": c} for (p, f, mo), c in points.items()]
    if robot.cell is not None:  # how far each pose keeps from the cell and from itself
        from ..model.workcell import clearance

        c, closest = clearance(robot, np.radians(s.poses_deg))
        out["clearance_m"] = [round(float(v), 6) for v in c]
        out["closest"] = list(closest)
    return out


def _parameters_json(rm: RivalModels, m: Rival, unknown: list[int]) -> dict:
    """A model's ``parameter_names`` and ``parameters`` [SI] (the joint compliances of the robot's parameters,
    then each cause's, as :func:`stiffcal.measured.discrepancy.parameter_names` names them), null for a
    compliance the data cannot identify (``unknown``) and for a parameter the old data do not determine (not
    estimable, :func:`stiffcal.measured.discrepancy.estimability`: its minimum-norm value is round-off)."""
    ob = rm.observed or D.Observed()
    names = [rm.robot.joint_columns("k")[int(j)] for j in ob.model_params(rm.robot)]
    names += [n for c in m.causes for n in D.parameter_names(c, rm.robot, ob)]
    ok = D.estimability(rm.old_rows(m.causes))[0]
    return {"parameter_names": names,
            "parameters": [None if i in unknown or not ok[i] else float(b) for i, b in enumerate(m.beta)]}


def to_json(res: Discrimination, data: str | None = None) -> dict:
    """The JSON-ready dict of a :class:`Discrimination` (fields in docs/measured-data.md); no NaN or inf."""
    rm = res.rivals
    models = rm.models
    names = {i: list(m.causes) for i, m in enumerate(models)}
    unknown = [i for i, j in enumerate(rm.robot.params) if j + 1 in rm.verdict["nominal"]["not_identifiable_joints"]]
    which = ", ".join(rm.robot.joint_names[rm.robot.params[i]] for i in unknown)
    absent = [rm.robot.joint_names[j - 1] for j in rm.verdict["nominal"]["not_identifiable_joints"]
              if j - 1 not in rm.robot.params]
    notes = list(res.notes) + ([f"the data cannot identify the compliance of joint(s) {which} (the verdict's "
                                "not_identifiable_joints): its parameter is null in models; every model keeps it as an "
                                "unknown, so its value does not change the discriminating plan or its power; ot_plan's "
                                "O_t leaves its error out where the test load turns it (the robot file's value stands "
                                "in)"] if unknown else [])
    notes += [f"joint(s) {', '.join(absent)} (the verdict's not_identifiable_joints) move no measured point: the "
              "models have no parameter of theirs (parameter_names)"] if absent else []
    out = {"robot": rm.robot.source, "data": data, "alpha": rm.alpha, "sigma_m": rm.sigma, "noise_df": rm.noise_df,
           "experiments": res.m, "repeats": res.repeats, "truth_mode": res.truth,
           "loads": {"kind": res.loads.kind, "spec": res.loads.spec, "description": res.loads.describe(),
                     "forces_N": _split(res.loads.forces, rm.robot.task_dim)[0],
                     "moments_Nm": _split(res.loads.forces, rm.robot.task_dim)[1],
                     "bar_end_m": None if res.loads.arm is None else [round(float(x), 6) + 0.0 for x in res.loads.arm]},
           "verdict": {"cause": rm.verdict["cause"], "causes": rm.verdict["causes"],
                       "equivalent_combinations": rm.verdict["equivalent_combinations"],
                       "p_value": rm.verdict["p_value"], "p_value_of": rm.verdict.get("p_value_of"),
                       "significant_on_its_own": [c for c, t in rm.verdict["tests"].items() if t["significant"]],
                       "false_alarm_possible": false_alarm_possible(rm.verdict)},
           "models": [{"causes": list(m.causes), "role": "truth" if i == 0 else "rival", "rss_m2": m.rss,
                       **_parameters_json(rm, m, unknown), "bonferroni_share": m.multiplicity}
                      for i, m in enumerate(models)],
           "separable": res.separable,
           "separability": [{"truth": names[s.truth], "rival": names[s.rival], "separable": s.separable,
                             "reason": s.reason, "needs": list(s.needs)} for s in res.separability],
           "design_pairs": [{"truth": names[t], "rival": names[j]} for t, j in res.pairs],
           "plan": None, "compound": None, "ot_plan": None,
           "power_against_m": [{"m": m, "power": p} for m, p in res.power_against_m],
           "cell": None if rm.robot.cell is None else rm.robot.cell.describe(),
           "notes": notes}
    if res.plan is not None:
        c = res.certificate
        out["plan"] = _session_json(res.plan, res) | {"certificate": {
            "bound_m2": c.bound, "efficiency": c.efficiency, "power_bound": c.power_bound,
            "pair": {"truth": names[c.pair[0]], "rival": names[c.pair[1]]},
            "psi_max_at_deg": np.round(c.where_deg[0], 4).tolist(),
            "psi_max_load_N": _split(c.where_load[0], rm.robot.task_dim)[0][0],
            "psi_max_moment_Nm": (_split(c.where_load[0], rm.robot.task_dim)[1] or [None])[0],
            "bound_over": ("every plan of the pool's points (exact) and, over the joint space, the largest psi the "
                           "search found" if rm.robot.cell is None else
                           "every plan of the feasible pool points (exact) and, over the poses the cell allows, the "
                           "largest psi the search found there (a search, not a guarantee, in a cell)")}}
    if res.ot_plan is not None:
        out["ot_plan"] = _session_json(res.ot_plan, res) | {"lower_bound_m2": res.ot_bound}
    if res.compound is not None:
        comp = _session_json(res.compound, res)
        t_eff = comp["t_criterion_m2"] / res.certificate.bound if res.certificate else None
        ot_eff = res.ot_bound / res.compound.o_t if res.ot_bound is not None and res.compound.o_t else None
        out["compound"] = comp | {"weight": res.weight, "t_efficiency": t_eff,
                                  "ot_efficiency": ot_eff if ot_eff is None or ot_eff > 0 else None}
    out["notes"] += _contact_notes(out) + _vacuous_bound_note(None if res.ot_plan is None else res.ot_bound)
    return json_safe(out, out["notes"])


def _vacuous_bound_note(bound: float | None) -> list[str]:
    """A note where the O_t plan's lower bound is 0: the equivalence theorem's bound came out at or below zero
    (:func:`ot_lower_bound` clips it) and certifies nothing (a fresh user's soft Panda read it as a bound)."""
    if bound != 0.0:
        return []
    return ["ot_plan.lower_bound_m2 is 0: the equivalence theorem's bound on O_t came out at or below zero (the "
            "approximate design far from its optimum, or the model's parameters barely determined), so it certifies "
            "nothing about the plan"]


def _contact_notes(out: dict) -> list[str]:
    """The notes of :func:`stiffcal.model.workcell.contact_note` for the plans of plan.json's dict ``out`` (their
    ``clearance_m``, in a cell)."""
    from ..model.workcell import contact_note

    notes = []
    for key, what in (("plan", "the discriminating plan"), ("compound", "the compound plan"),
                      ("ot_plan", "the O_t plan")):
        if out[key] and "clearance_m" in out[key]:
            notes += contact_note(out[key]["clearance_m"], out[key]["closest"], what)
    return notes


def planned(robot: Robot, data_path: str, experiments: int, loads: str | None = None, repeats: int = 1,
            weight: float = COMPOUND_WEIGHT, truth: str = "best", alpha: float = 0.01, test_pose=None,
            test_force=None, angle_resolution_deg: float | None = None, force_resolution_N: float | None = None,
            seed: int = 0, effort: Effort = Effort()) -> DiscriminationPlan:
    """Read the measured data, run the analysis and :func:`discriminate`: the
    :class:`~stiffcal.measured.results.DiscriminationPlan` (``plan.json``'s fields, JSON types), nothing written.
    loads: a :func:`load_set` spec (default: the loads of the data, with their moments for a loading bar); test_pose
    (n,) [rad] and test_force (d,) [N]: for the compound plan. Raises :class:`InputError` for bad input."""
    import json

    from . import measurements as M

    if not 0 < alpha < 1:
        raise InputError(f"expected 0 < alpha < 1, got {alpha}", field="--alpha")
    meas = M.read_measurements(data_path, robot,
                               M.ANGLE_RESOLUTION_DEG if angle_resolution_deg is None else angle_resolution_deg,
                               M.FORCE_RESOLUTION_N if force_resolution_N is None else force_resolution_N)
    ls = _bar_of_data(robot, meas, loads) or load_set(loads, robot.task_dim, D.load_of(meas), meas.resolutions[1],
                                                      moment_resolution_Nm=meas.resolutions[2], gravity=robot.gravity)
    res = discriminate(robot, meas, experiments, ls, repeats=repeats, weight=weight, truth=truth, test_pose=test_pose,
                       test_force=test_force, alpha=alpha, effort=effort, seed=seed)
    return DiscriminationPlan(**json.loads(json.dumps(to_json(res, str(data_path)), allow_nan=False)))


def run(robot: Robot, data_path: str, out_dir: str, experiments: int, loads: str | None = None, repeats: int = 1,
        weight: float = COMPOUND_WEIGHT, truth: str = "best", alpha: float = 0.01, test_pose=None, test_force=None,
        angle_resolution_deg: float | None = None, force_resolution_N: float | None = None, seed: int = 0,
        label: str | None = None, effort: Effort = Effort()) -> DiscriminationPlan:
    """:func:`planned`, and write ``out_dir/plan.json`` and ``out_dir/plan.{png,svg}`` (the Python API of
    ``stiffcal discriminate``). Everything is computed before anything is written."""
    import json
    from pathlib import Path

    from ..report import plots

    plan = planned(robot, data_path, experiments, loads, repeats, weight, truth, alpha, test_pose, test_force,
                   angle_resolution_deg, force_resolution_N, seed, effort)
    out = plan.to_dict()
    text = json.dumps(out, indent=2, allow_nan=False)
    fig = plots.fig_discrimination(robot, out, label or Path(data_path).name)
    d = Path(out_dir)
    d.mkdir(parents=True, exist_ok=True)
    plots.save(fig, d / "plan")
    (d / "plan.json").write_text(text + "\n", encoding="utf-8")
    return plan
