"""Choosing measurement poses: the optimal single pose for every criterion (Tables 2-3, Figs. 3-5).

Global search for one pose
--------------------------
Every criterion is a continuous function of the joint angles on a compact domain (the torus of full
turns, or the box of the joint limits), so the search is exhaustive rather than started from a guess:

1. evaluate the criterion at every node of a regular grid covering the whole domain (vectorised);
2. take every grid node that is no worse than its 2n axis neighbours (a grid local minimum: every basin
   wider than one grid step contains one), keep the best ``n_refine`` of them;
3. polish each with Nelder-Mead (derivative-free, so the max() kinks of MDC and G are no obstacle);
4. the optimum is the best polished value; the *optimal set* is every polished pose within a relative
   ``set_rtol`` of it, duplicates merged.

No starting point is involved, so the result does not depend on one; the test-suite checks it against
an independent brute force on a finer grid and against shifted grids.

Symmetries and the representative pose
--------------------------------------
For a fixed force, a planar arm's information matrix is unchanged by turning the arm half a turn
(``q1 + 180``: J -> -J, so each column ``J_j (J_j^T F)`` is unchanged) and by mirroring it about the
force line through the base (``q1 -> 2 phi - q1``, ``q_i -> -q_i``); every criterion, O_t included,
depends on the measurement pose only through that matrix, so optima come in sets of (usually) four.
The representative reported is chosen by one documented rule (:func:`representative`): the copy
with positive "elbow" (first nonzero of q2..qn) and ``q1`` in (-90, 90], ties to the largest q1, q2, ...
For the paper's arm this rule selects every pose printed in Table 2.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..model import criteria
from ..errors import InputError
from ..model.observation import (Loads, Sensing, as_wrench, loaded_rows, observation_rows, sensed_params,
                          target_offsets, test_rows)
from ..model.robot import TOOL_TARGET, Robot
from ..model.stiffness import functional_variance, information_matrix, observation_matrix, spectral
from ..threads import single_threaded

TWO_PI = 2.0 * np.pi


#: a joint whose torque under every measurement load is at most this fraction of the load times the reach is not
#: turned (its information at most ~1e-12 of the others': no plan identifies it; :attr:`Problem.unturned`)
UNTURNED_RTOL = 1e-6


@dataclass(frozen=True)
class Problem:
    """A pose-selection problem.

    robot; force: (d,) [N] applied at the tool point in every measurement; criterion: key of
    :data:`criteria.CRITERIA_KEYS`; m: number of measurement poses; test_pose: (n,) [rad] (needed for 'ot');
    test_force: (d,) [N] (default: ``force`` and ``moment``); sigma: position noise standard deviation [m];
    moment: (d_m,) [N m] about the tool point in every measurement (default none; d_m = 1 planar, 3 spatial);
    test_moment: (d_m,) [N m] with ``test_force``; sensing: what is measured at every pose
    (:class:`stiffcal.model.observation.Sensing`; default the tool point's position); test_target: the target whose
    position error O_t measures; length_m: the length scale [m] that adds the tool's rotation to that error
    (0: position only); loads: the loads every pose is measured under (:class:`stiffcal.model.observation.Loads`,
    ``--loads``; default the force and moment above, which are then the test pose's load only); candidates:
    the only poses a plan may use (N, n) [rad] (a candidate file: plans are chosen among them, not polished
    in the continuum), None for the whole joint space. The module :mod:`stiffcal.model.observation` gives the
    equations; the robot's cell (:mod:`stiffcal.model.workcell`) which poses can be taken.
    """

    robot: Robot
    force: np.ndarray
    criterion: str = "ot"
    m: int = 1
    test_pose: np.ndarray | None = None
    test_force: np.ndarray | None = None
    sigma: float = 1.0
    moment: np.ndarray | None = None
    test_moment: np.ndarray | None = None
    sensing: Sensing | None = None
    test_target: str = TOOL_TARGET
    length_m: float = 0.0
    loads: Loads | None = None
    candidates: np.ndarray | None = None

    @property
    def hang_offset(self) -> np.ndarray | None:
        """Where the cable of hanging masses starts (tip frame, from the tool point), or None without them."""
        return None if self.loads is None else self.loads.hang_offset

    def feasible(self, q: np.ndarray) -> np.ndarray:
        """(...,) bool: the poses q (..., n) [rad] the robot can take in its cell, with the cable of hanging
        masses free (:func:`stiffcal.model.workcell.feasible`); all True without a cell."""
        from ..model.workcell import feasible

        return feasible(self.robot, q, self.hang_offset)

    @property
    def continuous(self) -> bool:
        """Plans move in the continuum of poses (False: only the candidate poses)."""
        return self.candidates is None

    @cached_property
    def _sensing(self) -> Sensing:
        s = self.sensing or Sensing()
        return Sensing(s.targets, s.orientation, self.sigma, s.sigma_rad)

    @cached_property
    def is_default(self) -> bool:
        """The paper's problem: a force, the tool point's position measured, its error at the test pose."""
        no_moment = all(v is None or not np.any(v) for v in (self.moment, self.test_moment))
        return (no_moment and self._sensing.is_default and self.test_target == TOOL_TARGET and self.length_m == 0
                and self.loads is None and not self.unturned)

    @property
    def load(self) -> np.ndarray:
        """The wrench (w,) [N, N m] of every measurement (:func:`stiffcal.model.observation.as_wrench`)."""
        return as_wrench(self.robot, self.force if self.moment is None else np.r_[self.force, self.moment])

    @property
    def test_load(self) -> np.ndarray:
        """The wrench (w,) at the test pose."""
        if self.test_force is None:
            return self.load
        f = self.test_force if self.test_moment is None else np.r_[self.test_force, self.test_moment]
        return as_wrench(self.robot, f)

    @cached_property
    def params(self) -> np.ndarray:
        """Joints whose compliances the measurements see (:func:`stiffcal.model.observation.sensed_params`) and the
        loads turn: a force at the tool point on a joint's axis (:attr:`stiffcal.model.robot.Robot.inert_joints`) has
        no torque about it, so without a moment that joint never deflects, whatever is measured; nor does a joint
        that no measurement load turns at any pose (:attr:`unturned`: a vertical axis under hanging masses)."""
        if self.is_default:
            return self.robot.params
        base = np.intersect1d(self.sensed, self.robot.params) if self.unloaded_inert else self.sensed
        return np.setdiff1d(base, self.unturned)

    @cached_property
    def unturned(self) -> tuple[int, ...]:
        """Joints that no measurement load turns at any pose (a torque at most :data:`UNTURNED_RTOL` of the load
        times the reach at 512 random poses within the limits): a vertical axis 1 under hanging masses, also where
        a URDF's rounded angles tilt it by 1e-10 rad (a Bravo 7's base, rpy 3.141592654: refused as
        unidentifiable before, while the same arm with an exact axis was planned with a note). Their compliance
        cannot be identified and is left out of the model, as the measured-data analysis does; the test load
        must not turn them either (:meth:`check_test_load`)."""
        from ..model.observation import torques

        lo, hi = self.robot.joint_limits_rad.T
        q = np.random.default_rng(5).uniform(lo, hi, (512, self.robot.n_joints))
        if self.loads is None:
            W = np.asarray(self.load)[None]
            tau = np.abs(torques(self.robot, q, W[0]))[None]
        else:
            W = self.loads.at(self.robot, q)  # (N, L, w)
            tau = np.abs(np.stack([torques(self.robot, q, W[:, k]) for k in range(W.shape[1])]))
        scale = np.abs(W).max() * max(self.robot.reach_m, 1.0)
        dead = np.all(tau <= UNTURNED_RTOL * scale, axis=(0, 1))
        return tuple(int(j) for j in np.flatnonzero(dead) if j in self.robot.params)

    def check_test_load(self, field: str = "force_N", source: str | None = None) -> None:
        """Refuse a test load that turns a joint no measurement load turns (:attr:`unturned`): its compliance
        deflects the test pose but cannot be identified, so O_t is infinite for every plan."""
        if not self.unturned or self.test_pose is None:
            return
        from ..model.observation import torques

        tau = np.abs(torques(self.robot, self.test_pose, self.test_load))
        scale = np.abs(self.test_load).max() * max(self.robot.reach_m, 1.0)
        bad = [j for j in self.unturned if tau[j] > UNTURNED_RTOL * scale]
        if bad:
            names = ", ".join(self.robot.joint_names[j] for j in bad)
            raise InputError(f"the measurement loads never turn joint {names}, but the test load does "
                             f"({tau[bad[0]]:.3g} N m): its compliance deflects the test pose and cannot be "
                             "identified, so O_t is infinite for every plan; add a measurement load that turns it (a "
                             "push sideways, a moment, a loading bar)", source=source, field=field)

    @cached_property
    def sensed(self) -> np.ndarray:
        """Joints whose rotation changes some measured quantity (:func:`stiffcal.model.observation.sensed_params`),
        whether or not the loads turn them."""
        return sensed_params(self.robot, self._sensing)

    @property
    def unloaded_inert(self) -> bool:
        """No moment in the measurements' loads: the joints whose axis passes through the tool point carry no
        torque."""
        return self.moment is None or not np.any(self.moment)

    @property
    def n_params(self) -> int:
        return len(self.params)

    @property
    def rows_per_pose(self) -> int:
        per = self._sensing.rows_per_pose(self.robot)
        return per if self.loads is None else per * len(self.loads.wrenches)

    @property
    def min_poses(self) -> int:
        """Fewest poses that give as many equations as compliances."""
        return -(-self.n_params // self.rows_per_pose)

    @cached_property
    def symmetric(self) -> bool:
        """Whether a pose's half-turn and mirror copies (planar arms, :func:`stiffcal.planning.plans.symmetric_copies`)
        carry the same information: no moment (a moment about z does not turn with the arm) and every measured
        target on the last link's line (the mirror copy of a target beside it is another point)."""
        if self.moment is not None and np.any(self.moment) or self.loads is not None or self.robot.cell is not None:
            return False
        off = target_offsets(self.robot, self._sensing.targets)
        return bool(np.all(np.abs(off[:, 1:]) <= 1e-12))

    def rows(self, q: np.ndarray) -> np.ndarray:
        """Observation matrices (..., r, p) of poses q (..., n) [rad]: eq. 4 for the paper's problem, else
        :func:`stiffcal.model.observation.observation_rows` (orientation rows weighted by sigma / sigma_rad)."""
        if self.is_default:
            return observation_matrix(self.robot.model_jacobian(q), self.force)
        if self.loads is not None:
            return loaded_rows(self.robot, q, self.loads, self._sensing, self.params)
        return observation_rows(self.robot, q, self.load, self._sensing, self.params)

    @cached_property
    def At(self) -> np.ndarray | None:
        """Observation matrix at the test pose, (d, n) (with the rotation rows times ``length_m``), or None.
        Computed once per problem (every loss of O_t reads it) and read-only."""
        if self.test_pose is None:
            return None
        if self.is_default:
            F = self.force if self.test_force is None else self.test_force
            At = observation_matrix(self.robot.model_jacobian(self.test_pose), F)
        else:
            At = test_rows(self.robot, self.test_pose, self.test_load, self.test_target, self.length_m, self.params)
        At = np.array(At, float)
        At.flags.writeable = False
        return At

    def ot_star(self, m: int) -> float:
        """O_t* of eq. 17: O_t when all m measurements are taken at the test pose (``n sigma^2 / m`` for the
        paper's problem, n the number of parameters those measurements identify at a generic test pose: the
        number of compliances, or the number of measured coordinates d for an arm with more joints than d,
        where A_t has rank d; in general ``sigma^2 trace(A_t (m A_1^T A_1)^+ A_t^T)`` with A_1 the rows
        measured at the test pose (from the rows: :func:`stiffcal.model.criteria.o_t_of_rows`), inf when they cannot
        give the error at the test pose)."""
        if self.is_default:
            return criteria.o_t_star(min(self.n_params, self.robot.task_dim), m, self.sigma)
        return criteria.o_t_of_rows(self.rows(self.test_pose).reshape(-1, self.n_params), self.At, self.sigma) / m


def plan_observations(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Stacked observation matrices of plans. q: (..., m, n) [rad]. Returns (..., m r, p)."""
    A = problem.rows(q)
    return A.reshape(A.shape[:-3] + (A.shape[-3] * A.shape[-2], A.shape[-1]))


def plan_loss(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Criterion to minimise for plans q: (..., m, n) [rad]. Returns (...,); +inf where singular, and where a
    pose cannot be taken in the robot's cell (:meth:`Problem.feasible`)."""
    loss = criteria.loss(problem.criterion, plan_observations(problem, q), problem.m, problem.At, problem.sigma)
    if problem.robot.cell is None:
        return loss
    ok = problem.feasible(q).all(axis=-1)
    return np.where(ok, loss, np.inf)


def plan_value(problem: Problem, q: np.ndarray) -> np.ndarray:
    """Natural (Table 1 / eq. 16) value of the criterion for plans q: (..., m, n) [rad]."""
    return criteria.evaluate(problem.criterion, plan_observations(problem, q), problem.m, problem.At,
                             problem.sigma)


# ---------------------------------------------------------------------------------------------------
# grid search helpers

def joint_grids(robot: Robot, step_deg: float) -> list[np.ndarray]:
    """Per-joint grid [rad]: full-turn joints get ``[-180, 180)`` (periodic), limited joints their
    closed interval, each at (at most) ``step_deg`` spacing. A limited joint whose range spans a full turn
    or more (e.g. +-350 deg) gets one turn centred in its range: further angles repeat the same poses."""
    grids = []
    for lo, hi in robot.joint_limits_rad:
        if _is_full_turn(lo, hi):
            count = int(np.ceil(360.0 / step_deg - 1e-9))
            grids.append(_turn_start(lo, hi) + TWO_PI * np.arange(count) / count)
        else:
            count = int(np.ceil(np.degrees(hi - lo) / step_deg - 1e-9)) + 1
            grids.append(np.linspace(lo, hi, count))
    return grids


def _is_full_turn(lo: float, hi: float) -> bool:
    return hi - lo >= TWO_PI - 1e-12


def _turn_start(lo, hi):
    """Start [rad] of the one turn that represents a joint whose range spans a full turn: -pi without limits,
    else the turn centred in the range (further angles repeat the same poses). Works elementwise."""
    return np.where(hi - lo <= TWO_PI + 1e-12, -np.pi, 0.5 * (lo + hi) - np.pi)


def _periodic(robot: Robot) -> list[bool]:
    """Joints whose grid wraps around (exactly one full turn: no limits)."""
    return [abs(hi - lo - TWO_PI) <= 1e-12 for lo, hi in robot.joint_limits_rad]


def _bounds(robot: Robot) -> list[tuple[float, float] | None]:
    """Bounds for local polishing: None for a free full-turn joint, the limits otherwise."""
    return [None if p else (lo, hi) for p, (lo, hi) in zip(_periodic(robot), robot.joint_limits_rad)]


def grid_size(robot: Robot, step_deg: float) -> int:
    """Number of nodes of :func:`joint_grids` (without building them)."""
    return int(np.prod([len(g) for g in joint_grids(robot, step_deg)], dtype=float))


#: largest grid searched exhaustively; beyond it (typically 4+ joints) the search samples the joint space
MAX_GRID_NODES = 400_000
#: quasi-random (scrambled Sobol) samples of the joint space when the grid would be too large
SAMPLES_LOG2 = 15


def sample_joint_space(robot: Robot, log2_count: int = SAMPLES_LOG2, seed: int = 0) -> np.ndarray:
    """``2**log2_count`` scrambled-Sobol poses (k, n) [rad] filling the joint-limit box (one turn for
    joints with a full turn or more). Deterministic for a seed."""
    from scipy.stats import qmc

    lo, hi = robot.joint_limits_rad.T
    span = np.minimum(hi - lo, TWO_PI)
    start = np.where(hi - lo > TWO_PI + 1e-12, _turn_start(lo, hi), lo)
    u = qmc.Sobol(robot.n_joints, scramble=True, seed=seed).random_base2(log2_count)
    return start + u * span


def joint_space_pool(robot: Robot, step_deg: float, log2_count: int, max_grid: int | None = None) -> np.ndarray:
    """The project's one builder of candidate poses (K, n) [rad] over the joint space: the grid of
    :func:`joint_grids` at ``step_deg`` or, when :func:`is_sampled` (or the grid exceeds ``max_grid`` nodes),
    ``2**log2_count`` scrambled-Sobol poses (:func:`sample_joint_space`, seed 0). Neither symmetry nor a cell is
    applied here: the planner's pool (:func:`stiffcal.planning.certificate.candidate_pool`), the discrimination
    pool and the measured-data plan's poses filter it for what they need."""
    if is_sampled(robot, step_deg) or (max_grid is not None and grid_size(robot, step_deg) > max_grid):
        return sample_joint_space(robot, log2_count, seed=0)
    grids = joint_grids(robot, step_deg)
    return np.stack(np.meshgrid(*grids, indexing="ij"), -1).reshape(-1, robot.n_joints)


def grid_local_minima(values: np.ndarray, periodic: list[bool]) -> np.ndarray:
    """Boolean mask of grid nodes no worse than their 2n axis neighbours (finite values only).

    values: (N1, ..., Nn); periodic: per axis, whether the grid wraps around.
    """
    mask = np.isfinite(values)
    for ax, wrap in enumerate(periodic):
        for shift in (1, -1):
            nb = np.roll(values, shift, axis=ax)
            if not wrap:
                edge = [slice(None)] * values.ndim
                edge[ax] = 0 if shift == 1 else -1
                nb[tuple(edge)] = np.inf
            mask &= values <= nb
    return mask


def evaluate_grid(fun, grids: list[np.ndarray], chunk: int = 1 << 16) -> np.ndarray:
    """``fun`` (q (k, n) [rad] -> (k,)) at every node of the product grid, in chunks to bound memory.

    Returns an array of shape ``tuple(len(g) for g in grids)``.
    """
    shape = tuple(len(g) for g in grids)
    total = int(np.prod(shape))
    out = np.empty(total)
    for start in range(0, total, chunk):
        idx = np.unravel_index(np.arange(start, min(start + chunk, total)), shape)
        q = np.stack([g[i] for g, i in zip(grids, idx)], axis=-1)
        out[start:start + q.shape[0]] = fun(q)
    return out.reshape(shape)


def wrap_deg(q_deg: np.ndarray) -> np.ndarray:
    """Wrap angles to [-180, 180) degrees (values within 1e-9 deg of +180 become -180)."""
    w = (np.asarray(q_deg, float) + 180.0) % 360.0 - 180.0
    return np.where(np.isclose(w, 180.0, rtol=0.0, atol=1e-9), -180.0, w) + 0.0  # + 0.0 turns -0.0 into 0.0


#: angles within this of a joint limit [deg] count as on it (round-off of the degree-radian conversions)
LIMIT_TOL_DEG = 1e-9


def into_limits(robot: Robot, q_deg: np.ndarray) -> np.ndarray:
    """Angles (..., n) [deg] written in their joints' limits: each angle is moved by whole turns to the copy
    that lies within the limits as the robot file writes them (a range [-230, 50] prints 130 deg as -230 + 0.49
    = -229.51; a range [190, 260] prints -170 as 190), preferring the copy in [-180, 180) and then the fewest
    turns. An angle with no copy within its limits gets the copy nearest to them. Angles within
    :data:`LIMIT_TOL_DEG` of a limit are put on it. Joints without limits: [-180, 180)."""
    q = wrap_deg(q_deg)
    lo, hi = np.degrees(robot.joint_limits_rad.T)
    turns = np.array([0.0, 1.0, -1.0, 2.0, -2.0, 3.0, -3.0])  # limits lie within +-720 deg
    copies = q[..., None] + 360.0 * turns  # (..., n, 7), in order of preference
    outside = np.maximum(lo[:, None] - copies, copies - hi[:, None])  # > 0: that far outside the limits
    best = np.argmin(np.where(outside <= LIMIT_TOL_DEG, -1.0, outside), axis=-1)  # first copy within, else nearest
    out = np.take_along_axis(copies, best[..., None], axis=-1)[..., 0]
    within = np.take_along_axis(outside, best[..., None], axis=-1)[..., 0] <= LIMIT_TOL_DEG
    return np.where(within, np.clip(out, lo, hi), out) + 0.0


def representative(poses_deg: np.ndarray, tie_deg: float = 1e-3) -> np.ndarray:
    """Pick one pose from a set of equally optimal ones by the documented rule.

    The rule first picks the symmetry copy in a fixed fundamental domain, then breaks accidental ties:

    1. the first nonzero angle among ``q2 .. qn`` is positive ("elbow" sign; removes the mirror copy);
    2. ``q1`` lies in ``(-90, 90]`` (removes the half-turn copy);
    3. the largest ``q1``, then the largest ``q2``, ``q3``, ... .

    Each step keeps the candidates within ``tie_deg`` of the best. For the paper's arm this selects
    every pose printed in Table 2. poses_deg: (k, n), the candidates as they are printed: only copies within
    the joint limits, written in the limits' range (:func:`into_limits`; [-180, 180) without limits), so the
    pose chosen lies within the limits. Returns (n,).
    """
    cand = np.asarray(poses_deg, float)

    def elbow_sign(c):
        rest = np.where(np.abs(c[:, 1:]) > tie_deg, c[:, 1:], 0.0)
        if rest.shape[1] == 0:
            return np.zeros(len(c))
        first = rest[np.arange(len(c)), np.argmax(rest != 0, axis=1)]  # 0 when all are zero
        return (first < 0).astype(float)

    keys = [elbow_sign, lambda c: ((c[:, 0] <= -90 + tie_deg) | (c[:, 0] > 90 + tie_deg)).astype(float)]
    keys += [lambda c, j=j: -c[:, j] for j in range(cand.shape[1])]
    for key_fn in keys:
        key = key_fn(cand)
        cand = cand[key <= key.min() + tie_deg]
    return cand[0]


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a - b wrapped to (-pi, pi] [rad], elementwise."""
    return np.pi - np.mod(np.pi - (np.asarray(a) - b), 2 * np.pi)


def dedupe(poses_rad: np.ndarray, tol_rad: float = 1e-4) -> np.ndarray:
    """Drop poses (rows) that repeat an earlier one within ``tol_rad`` on every joint, modulo 2 pi."""
    kept: list[np.ndarray] = []
    for p in poses_rad:
        if not any(np.all(np.abs(angle_diff(p, k)) < tol_rad) for k in kept):
            kept.append(p)
    return np.array(kept)


# ---------------------------------------------------------------------------------------------------
# single pose

@dataclass
class SinglePoseResult:
    """Result of :func:`optimal_single_pose`.

    pose_deg: (n,) the representative; optimal_set_deg: (k, n) all equally optimal poses found;
    loss: minimised value; value: the criterion's natural value; degenerate: True when the criterion
    is constant over all nonsingular poses (no pose is better than another).
    """

    pose_deg: np.ndarray
    optimal_set_deg: np.ndarray
    loss: float
    value: float
    degenerate: bool = False
    notes: list[str] = field(default_factory=list)


def grid_minimise(fun, robot: Robot, step_deg: float = 1.0, n_refine: int = 24, xatol: float = 1e-10):
    """Exhaustive global minimisation of ``fun`` over one pose of ``robot`` (module docstring, steps 1-3).

    fun: q (..., n) [rad] -> (...,) values (+inf allowed). Returns ``(grids, values, xs, fs)``: the grid,
    the values on it, and the polished grid local minima (k, n) [rad] with their values, best first.
    """
    grids = joint_grids(robot, step_deg)
    values = evaluate_grid(fun, grids)
    xs, fs = polish_grid_minima(fun, robot, grids, values, n_refine, xatol)
    return grids, values, xs, fs


def polish_grid_minima(fun, robot: Robot, grids, values, n_refine: int = 24, xatol: float = 1e-10,
                       smooth: bool = False):
    """Polish the ``n_refine`` best grid local minima of ``values`` (module docstring, steps 2-3).

    Returns (xs (k, n) [rad], fs (k,)), best first. In a cell (``robot.cell``), minima a few grid steps from a
    better one are not polished apart (:func:`_spread_minima`), and a ``smooth`` function is polished by
    L-BFGS-B (:func:`polish_smooth`: a step out of the cell is refused) rather than Nelder-Mead, whose simplex
    creeps along the boundary of the feasible set for thousands of evaluations.
    """
    mask = grid_local_minima(values, [_is_full_turn(lo, hi) for lo, hi in robot.joint_limits_rad])
    idx = np.argwhere(mask)
    if robot.cell is not None:
        return _polish_all(fun, robot, _spread_minima(grids, values, idx, n_refine), xatol, smooth)
    order = np.argsort(values[mask], kind="stable")[:n_refine]
    starts = np.array([[g[i] for g, i in zip(grids, idx[o])] for o in order]).reshape(-1, robot.n_joints)
    return _polish_all(fun, robot, starts, xatol)


#: in a cell, grid local minima closer than this many grid steps (every joint) to a better one are not polished
#: apart: the boundary of the feasible set makes a row of grid minima along it, which polish to one point
CELL_MINIMA_STEPS = 4


def _spread_minima(grids, values, idx, n_refine: int) -> np.ndarray:
    """The ``n_refine`` best grid local minima (indices ``idx``) at least :data:`CELL_MINIMA_STEPS` grid steps
    from every better one chosen (on some joint, with the grid's wrap-around): the starts of the polish in a
    cell. Returns (k, n) [rad]."""
    order = np.argsort(values[tuple(idx.T)], kind="stable")
    sizes = np.array([len(g) for g in grids])
    chosen: list[np.ndarray] = []
    for o in order:
        if len(chosen) == n_refine:
            break
        i = idx[o]
        if all(np.any(np.minimum(np.abs(i - c), sizes - np.abs(i - c)) > CELL_MINIMA_STEPS) for c in chosen):
            chosen.append(i)
    return np.array([[g[k] for g, k in zip(grids, i)] for i in chosen]).reshape(-1, len(grids))


def _polish_all(fun, robot: Robot, starts: np.ndarray, xatol: float = 1e-10, smooth: bool = False):
    """Polish every start (k, n) [rad]: Nelder-Mead, or for a ``smooth`` function L-BFGS-B with batched
    central-difference gradients (:func:`polish_smooth`; one-sided next to the poses a cell does not allow).
    Returns (xs, fs) best first."""
    if smooth:
        def one(f, x0, bounds, xatol):
            return polish_smooth(f, x0, bounds, xatol, one_sided=robot.cell is not None)
    elif robot.cell is not None:
        def one(f, x0, bounds, xatol):
            return _polish(f, x0, bounds, xatol, CELL_MAXFEV * len(x0))
    else:
        one = _polish
    polished = [one(fun, x0, _bounds(robot), xatol) for x0 in starts]
    xs = np.array([p[0] for p in polished]).reshape(-1, robot.n_joints)
    fs = np.array([p[1] for p in polished])
    order = np.argsort(fs, kind="stable")
    return xs[order], fs[order]


def sampled_minimise(fun, robot: Robot, n_refine: int = 16, log2_count: int = SAMPLES_LOG2, seed: int = 1,
                     extra_starts: np.ndarray | None = None, min_separation_deg: float = 10.0,
                     xatol: float = 1e-10):
    """Global minimisation of ``fun`` over one pose when a grid is too large (4+ joints).

    ``fun`` is evaluated at ``2**log2_count`` scrambled-Sobol poses (plus ``extra_starts`` (k, n) [rad]);
    the ``n_refine`` best that are at least ``min_separation_deg`` apart on some joint are polished
    (L-BFGS-B within the limits: ``fun`` must be smooth). Unlike the grid search this finds the global optimum
    only with high
    probability; the tests compare it with an independent brute-force random search.
    Returns ``(xs (k, n) [rad], fs (k,))``, best first.
    """
    q = sample_joint_space(robot, log2_count, seed)
    if extra_starts is not None and len(extra_starts):
        q = np.vstack([np.atleast_2d(extra_starts), q])
    v = np.concatenate([fun(q[i:i + 8192]) for i in range(0, len(q), 8192)])
    starts: list[np.ndarray] = []
    sep = np.radians(min_separation_deg)
    for i in np.argsort(v, kind="stable"):
        if not np.isfinite(v[i]) or len(starts) == n_refine:
            break
        if all(np.any(np.abs(angle_diff(q[i], s)) > sep) for s in starts):
            starts.append(q[i])
    if not starts:
        return q[:0], v[:0]
    return _polish_all(fun, robot, np.array(starts), xatol, smooth=True)


def is_sampled(robot: Robot, step_deg: float) -> bool:
    """Whether searches over one pose sample the joint space instead of gridding it: for 4+ joints (a grid
    fine enough to resolve the optimum would be too large) or a grid above :data:`MAX_GRID_NODES`."""
    return robot.n_joints >= 4 or grid_size(robot, step_deg) > MAX_GRID_NODES


def global_minimise(fun, robot: Robot, step_deg: float, n_refine: int = 8):
    """:func:`grid_minimise` at ``step_deg`` or, when :func:`is_sampled`, :func:`sampled_minimise`.
    Returns ``(xs (k, n) [rad], fs (k,))``, best first."""
    if not is_sampled(robot, step_deg):
        return grid_minimise(fun, robot, step_deg, n_refine)[2:]
    return sampled_minimise(fun, robot, n_refine)


#: criteria with kinks (a max over poses or eigenvalues): polished by Nelder-Mead even in a cell
NONSMOOTH = tuple(k for k, c in criteria.CRITERIA.items() if c.nonsmooth)  # registered as such


@single_threaded
def optimal_single_pose(problem: Problem, step_deg: float = 1.0, n_refine: int = 24,
                        set_rtol: float = 1e-7, xatol: float = 1e-10) -> SinglePoseResult:
    """Global optimum of the criterion over one measurement pose (see the module docstring).

    step_deg: grid spacing; n_refine: grid local minima polished; set_rtol: relative tolerance that
    defines "equally optimal". Deterministic: no random numbers are used.
    """
    assert problem.m == 1, "optimal_single_pose is for one measurement pose"
    robot = problem.robot
    d, n = problem.rows_per_pose, problem.n_params
    few = f"one pose gives {d} equations for {n} compliances; use at least {-(-n // d)} poses"
    if d < n and problem.criterion in criteria.NEEDS_INVERSE:
        raise InputError(f"criterion {criteria.label(problem.criterion)} is infinite at every pose: {few}")

    def fun(q):
        return plan_loss(problem, q[..., None, :])

    if not problem.continuous:  # a candidate file: the best of its poses the cell allows
        return _best_candidate(problem, fun, set_rtol)
    if is_sampled(robot, step_deg):
        if d < n and problem.criterion != "t":
            raise InputError(f"criterion {criteria.label(problem.criterion)} is zero at every pose: {few}")
        xs, fs = sampled_minimise(fun, robot, n_refine)
    else:
        grids = joint_grids(robot, step_deg)
        values = evaluate_grid(fun, grids)
        finite = values[np.isfinite(values)]
        if finite.size == 0:
            raise InputError(f"criterion {criteria.label(problem.criterion)} is infinite at every pose: no pose of "
                             "the joint space identifies every compliance with this force")
        if finite.max() - finite.min() <= 1e-9 * max(1.0, abs(finite.min())):
            return _degenerate_result(problem, grids, values)
        smooth = robot.cell is not None and problem.criterion not in NONSMOOTH
        xs, fs = polish_grid_minima(fun, robot, grids, values, n_refine, xatol, smooth)
    best = fs[0]
    near = fs <= best + set_rtol * max(abs(best), 1e-300)
    opt_deg = into_limits(robot, np.degrees(dedupe(xs[near])))
    rep = representative(opt_deg)
    value = float(plan_value(problem, np.radians(rep)[None, None, :])[0])
    return SinglePoseResult(rep, opt_deg, float(best), value)


def polish_smooth(fun, x0: np.ndarray, bounds, xatol: float = 1e-10, h: float = 1e-6, one_sided: bool = False):
    """L-BFGS-B from x0 on a smooth batched ``fun`` (q (k, n) -> (k,)): the value and the central-difference
    gradient come from one call on 2n + 1 poses. Returns (x, f), never worse than x0. ``one_sided`` (a cell,
    where ``fun`` is +inf at the poses the robot cannot take): next to such a pose the gradient is a one-sided
    difference, and a step onto one is refused (a finite value far above the start's, so the line search
    backtracks)."""
    n = len(x0)
    steps = np.vstack([np.zeros(n), h * np.eye(n), -h * np.eye(n)])
    big = [None]

    def fg(x):
        v = fun(x + steps)
        if not np.all(np.isfinite(v)):
            if not one_sided or big[0] is None:
                return float(v[0]), np.zeros(n)
            if not np.isfinite(v[0]):
                return big[0], np.zeros(n)
            up, down = v[1:n + 1], v[n + 1:]
            with np.errstate(invalid="ignore"):
                g = np.where(np.isfinite(up) & np.isfinite(down), (up - down) / (2 * h),
                             np.where(np.isfinite(up), (up - v[0]) / h,
                                      np.where(np.isfinite(down), (v[0] - down) / h, 0.0)))
            return float(v[0]), g
        return float(v[0]), (v[1:n + 1] - v[n + 1:]) / (2 * h)

    f0 = fg(x0)[0]
    big[0] = 1e3 * (abs(f0) + 1.0) if np.isfinite(f0) else None
    bnds = [b if b is not None else (None, None) for b in bounds]
    from scipy.optimize import minimize

    res = minimize(fg, x0, jac=True, method="L-BFGS-B", bounds=bnds,
                   options=dict(maxiter=500, ftol=1e-15, gtol=max(xatol, 1e-12)))
    if np.isfinite(res.fun) and res.fun <= f0:
        return res.x, float(res.fun)
    return x0, f0


#: Nelder-Mead's evaluations per joint in a cell (its simplex creeps along the boundary of the feasible set)
CELL_MAXFEV = 300


def _polish(fun, x0: np.ndarray, bounds, xatol: float, maxfev: int | None = None):
    """Nelder-Mead from x0 on ``fun`` (one pose), at most ``maxfev`` evaluations (default 8000 per joint);
    returns (x, f), never worse than x0."""
    def f(x):
        return float(fun(x))

    f0 = f(x0)
    has_bounds = any(b is not None for b in bounds)
    bnds = [b if b is not None else (None, None) for b in bounds] if has_bounds else None
    simplex = x0 + np.vstack([np.zeros(len(x0)), np.eye(len(x0)) * np.radians(0.5)])
    if has_bounds:
        lo = np.array([b[0] if b else -np.inf for b in bounds])
        hi = np.array([b[1] if b else np.inf for b in bounds])
        simplex = np.clip(simplex, lo, hi)
    from scipy.optimize import minimize

    res = minimize(f, x0, method="Nelder-Mead", bounds=bnds,
                   options=dict(xatol=xatol, fatol=1e-15 * max(1.0, abs(f0)), maxiter=4000 * len(x0),
                                maxfev=maxfev or 8000 * len(x0), initial_simplex=simplex))
    if res.fun <= f0:
        return res.x, float(res.fun)
    return x0, f0


def _best_candidate(problem: Problem, fun, set_rtol: float) -> SinglePoseResult:
    """The single pose of a candidate file (``problem.candidates``) with the best criterion among those the cell
    allows, and every candidate within ``set_rtol`` of it (the optimal set)."""
    q = problem.candidates[problem.feasible(problem.candidates)]
    if not len(q):
        raise InputError("none of the candidate poses can be taken in the cell", source=problem.robot.source,
                         field="candidates")
    v = np.asarray(fun(q), float)
    if not np.isfinite(v).any():
        raise InputError(f"criterion {criteria.label(problem.criterion)} is infinite at every candidate pose",
                         field="candidates")
    best = float(np.nanmin(v))
    near = v <= best + set_rtol * max(abs(best), 1e-300)
    opt_deg = into_limits(problem.robot, np.degrees(q[near]))
    pose = opt_deg[0]
    value = float(plan_value(problem, np.radians(pose)[None, None, :])[0])
    return SinglePoseResult(pose, opt_deg, best, value)


def _degenerate_result(problem: Problem, grids, values) -> SinglePoseResult:
    """Every nonsingular pose is optimal: report the rule's pick among all finite grid nodes."""
    idx = np.argwhere(np.isfinite(values))
    poses = into_limits(problem.robot, np.degrees(np.array([[g[i] for g, i in zip(grids, row)] for row in idx])))
    rep = representative(poses, tie_deg=0.0)
    value = float(plan_value(problem, np.radians(rep)[None, None, :])[0])
    note = (f"{criteria.label(problem.criterion)} is constant ({value:.6g}) over every nonsingular pose: "
            "one pose gives as many equations as parameters, so no pose is better than another")
    return SinglePoseResult(rep, poses[:0], float(values[np.isfinite(values)].min()), value, True, [note])


def plan_summary(study, plan_deg: np.ndarray) -> dict:
    """O_t, chi, E[dk_i^2] and dk_i = sqrt(E[dk_i^2]) of plans of a :class:`stiffcal.planning.study.Study`, vectorised.

    plan_deg: (..., m, n) [deg]. Returns a dict of arrays of shape (...,): 'O_t' (eq. 16; inf when a
    compliance is not identifiable), 'chi' (eq. 27), 'E_dk1'.. (eq. 11), 'dk1'.. (per joint, named by
    ``robot.joint_columns``: 'E_dk_a1' for a joint named a1).
    """
    plan = np.radians(np.asarray(plan_deg, float))
    m, n = plan.shape[-2:]
    prob = study.problem("ot", m)
    M = information_matrix(prob.rows(plan))
    spec = spectral(M)  # one eigen-decomposition for both
    cov_p = functional_variance(M, np.eye(M.shape[-1]), study.sigma, spec)  # covariance_diagonal
    ot = np.where(np.all(np.isfinite(cov_p), axis=-1), criteria.o_t(M, prob.At, study.sigma, spec), np.inf)
    with np.errstate(invalid="ignore"):  # inf / inf (no plan identifies the test pose's parameters): chi undefined
        out = {"O_t": ot, "chi": prob.ot_star(m) / np.asarray(ot, float)}
    cov = np.full(cov_p.shape[:-1] + (n,), np.inf)  # a joint the measurements never see: not identifiable
    cov[..., prob.params] = cov_p
    for i, (e, dk) in enumerate(zip(study.robot.joint_columns("E_dk"), study.robot.joint_columns("dk"))):
        out[e] = cov[..., i]
        out[dk] = np.sqrt(cov[..., i])
    return out


def load_words(problem: "Problem") -> str:
    """The measurement loads of ``problem`` in words: its load set's spec, or its force."""
    return problem.loads.spec if problem.loads is not None else f"the force {problem.force.tolist()} N"


def unidentified_notes(robot: Robot, base: "Problem") -> list[str]:
    """A note for each joint whose compliance the plan cannot identify (not among ``base.params``), saying why and
    what would: its axis through every measured point, never turned by the measurement loads, or through the tool
    point without a moment (the design's notes and the report's design study say the same)."""
    params_note = base.sensed
    return [f"joint {robot.joint_names[j]}'s axis passes through every measured point at every pose: its "
            "compliance never deflects them, cannot be identified from their positions and is left out of the "
            "model (cov_diag 'inf'); measure a point off that axis (tool_m, targets) or the orientation to "
            "identify it" if j not in params_note else
            f"joint {robot.joint_names[j]} is never turned by the measurement loads ({load_words(base)}) at any "
            "pose, nor by the test load: its compliance cannot be identified and is left out of the model "
            "(cov_diag 'inf'), as the measured-data analysis does; a load that turns it (a push sideways, a "
            "moment) identifies it" if j in base.unturned else
            f"joint {robot.joint_names[j]}'s axis passes through the tool point, where the force is applied: "
            "without a moment the load never turns that joint, whose compliance cannot be identified and is "
            "left out of the model (cov_diag 'inf'); apply a moment (--wrench) to identify it"
            for j in range(robot.n_joints) if j not in base.params]


def weak_compliance_notes(robot, cov_diag: np.ndarray) -> list[str]:
    """A note naming the compliances a plan determines far worse than the others, relative to their nominal values (the
    robot file's ``compliances_rad_per_Nm``; none without them): r_j = sqrt(cov_diag_j) / k_j (cov_diag (n,), eq.
    11) above 1 and above :data:`WEAK_COMPLIANCE_FACTOR` times the median r over the joints (so the note does not
    depend on the sigma unit); where the median r is itself above 1 (below :data:`WEAK_MEDIAN_UNITS`) the note says
    so. O_t needs only what the test pose's deflection depends on, so its plan may leave a joint the test load
    barely turns nearly free; the analysis of the data fits it all the same, and a fresh user's iiwa plan (sd 22
    times the nominal k5) gave k5 = -3.5e-5 and predictions 88 um off at other poses."""
    k = getattr(robot, "compliances", None)
    if k is None:
        return []
    r = np.sqrt(np.asarray(cov_diag, float)) / np.where(np.asarray(k) > 0, k, np.nan)
    known = np.isfinite(r)
    if not known.any():
        return []
    median = float(np.median(r[known]))
    weak = [j for j in np.flatnonzero(known) if r[j] > max(1.0, WEAK_COMPLIANCE_FACTOR * median)]
    if not weak:
        return []
    listed = ", ".join(f"{robot.joint_names[j]} ({r[j]:.2g} times its nominal)" for j in weak)
    whole = (f"; the median joint's sd is itself {median:.2g} times its nominal: a model identified from this plan "
             "predicts the test pose (what O_t asks for), and at other poses it can be worse than the robot file's"
             if 1.0 <= median < WEAK_MEDIAN_UNITS else "")
    return [f"this plan determines the compliance of joint(s) {listed} far worse than the others (sd over the robot "
            f"file's compliance; the median joint {median:.2g}): O_t does not need it (the test load barely turns "
            "it), but the analysis of the data fits every compliance, and one this free can come out far off (below "
            f"zero) and bias the model at other poses{whole}; to calibrate the whole arm add poses or plan with "
            "--criterion a"]


#: a compliance whose sd over its nominal value is this many times the median joint's is named (weak_compliance_notes;
#: at 10 a fresh user's Panda plan named k7 at 37 times its nominal but not k1 and k5 at 4.9 and 4.3, the median 1.3,
#: and the model identified from it predicted other poses 4.5 times worse than the robot file's flat guess)
WEAK_COMPLIANCE_FACTOR = 3.0
#: ... and the median joint's ratio is said to be undetermined too when it is at least 1 and below this (beyond, the
#: sigma is no tracker's noise in metres under these loads: the paper's sigma = 1 and F = 1 N give ratios of 1e3-1e7)
WEAK_MEDIAN_UNITS = 100.0
