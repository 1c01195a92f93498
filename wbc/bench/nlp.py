"""The accuracy reference of the converged mode: each pose solved as one nonlinear program.

With x = (p_b, r, q_j) — base position, base rotation R_b = R_ref · cay(r) (Cayley map of r
around a reference rotation R_ref, the warm start's: no unit-quaternion constraint and no
singularity near the start) and the joints — :class:`PoseNLP` solves, with IPOPT,

    min  w_c ‖c − c*‖² + [single] w_s (‖p_sw − p_sw*‖² + ½‖R_sw − R_sw*‖_F²)
         + w_t ½‖R_t − R_t*‖_F² + w_p ‖q_j − q_j*‖²
    s.t. p_st = p_st*,  vee(R_st*ᵀ R_st − R_stᵀ R_st*) / 2 = 0      (support sole; both in
                                                                   double support)
         A c_xy ≤ b                      (support polygon shrunk by a margin, optional)
         z of the swing sole's corners ≥ 0                          (single support, optional)
         q_min ≤ q_j ≤ q_max,

the tasks and weights of the peers' stack (:func:`wbc.bench.peers.peer_stack`; by default
``tasks/walk.toml``'s).
½‖R − R*‖_F² = 2(1 − cos θ) = θ² − θ⁴/12 + … is the smooth stand-in for the QP tasks'
‖log(R* Rᵀ)‖² = θ². ``hard_com_and_swing=True`` turns the CoM and the swing sole's position
into equalities: the thesis's tasks met exactly, and the residual says whether the pose is
reachable (with the torso free to tilt; ``hard_torso=True`` also holds the torso's orientation).

Each structure (double support; single support on the left or the right sole) is built once as
a casadi ``nlpsol`` with the targets as parameters, and re-solved warm-started from the
previous solution (primal and multipliers).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, InfeasibleError, SolverError, TaskError
from ..geometry import sole_corners
from ..model import Robot
from ..walking.loop import Controller, TickTargets
from ..walking.reference import WalkingReference
from .casadi_kinematics import CasadiKinematics
from .peers import PeerTasks

PHASES = ("double", "single")
SOLES = ("l_sole", "r_sole")
MAX_POLYGON_SIDES = 12
#: the CoM support-polygon margin of tasks/walk.toml (m)
WALK_COM_MARGIN = 0.01
#: IPOPT statuses counted as solved
SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class NlpWeights:
    """Weights of the soft tasks (by default ``tasks/walk.toml``'s on the Bioloid; a stack's:
    :meth:`of`)."""

    com: float = 1000.0
    swing: float = 100.0
    torso: float = 1.0
    posture: float = 0.01
    #: the stack they were read from (None: these defaults)
    stack: str | None = None

    @classmethod
    def of(cls, tasks: PeerTasks) -> NlpWeights:
        """The weights of a stack read for the peers (the swing sole's: its position rows')."""
        return cls(tasks.com, tasks.swing_position, tasks.torso, tasks.posture, tasks.stack)


@dataclass
class PoseTargets:
    """Targets of one pose (world frame).

    ``support`` is the sole held in single support (in double support both are held);
    ``com_polygon`` is an optional ``(A, b)`` with ``A c_xy <= b`` (at most
    :data:`MAX_POLYGON_SIDES` rows).
    """

    com: np.ndarray
    l_sole: pin.SE3
    r_sole: pin.SE3
    torso: np.ndarray
    posture: np.ndarray
    phase: str = "double"
    support: str = "l_sole"
    com_polygon: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def swing(self) -> str:
        return "r_sole" if self.support == "l_sole" else "l_sole"

    def sole(self, name: str) -> pin.SE3:
        return self.l_sole if name == "l_sole" else self.r_sole


@dataclass
class PoseSolution:
    """One solved pose, its residuals evaluated at the returned ``q``.

    ``residuals``: g(q) per constraint group (equalities: = 0; inequalities: <= 0);
    ``violation``: the largest |equality| or inequality excess (m, rad).
    """

    q: np.ndarray
    iterations: int
    status: str
    objective: float
    violation: float
    solve_time: float
    residuals: dict[str, np.ndarray] = field(default_factory=dict)
    violations: dict[str, float] = field(default_factory=dict)  # per constraint group

    @property
    def success(self) -> bool:
        return self.status in SOLVED


def cayley(r: Any) -> Any:
    """Cayley map: R = I + 2 / (1 + rᵀr) ([r]× + [r]×²), a rotation by 2 atan(‖r‖) about r."""
    K = ca.skew(r)
    return ca.DM.eye(3) + 2.0 / (1.0 + ca.dot(r, r)) * (K + ca.mtimes(K, K))


def _rotation_residual(R: Any, R_target: Any) -> Any:
    """vee(R*ᵀR − RᵀR*)/2 = sin θ · axis: zero iff R = R* (for θ < π)."""
    A = ca.mtimes(R_target.T, R)
    return 0.5 * ca.vertcat(A[2, 1] - A[1, 2], A[0, 2] - A[2, 0], A[1, 0] - A[0, 1])


def _chordal(R: Any, R_target: Any) -> Any:
    """½‖R − R*‖_F² = 2 (1 − cos θ)."""
    D = R - R_target
    return 0.5 * ca.sumsqr(D)


class PoseNLP:
    """One pose as an NLP solved by IPOPT (see the module docstring).

    ``hard_com_and_swing``: CoM and swing-sole position as equalities; ``hard_torso``: the
    torso orientation as an equality; ``ground_clearance``: the swing sole's corners stay above
    z = 0 (single support); ``foot``: (length, width) of the sole rectangle (m; default the
    robot's, :attr:`wbc.model.Robot.foot_size`); ``tol``:
    IPOPT's optimality and constraint-violation tolerance; ``feasibility_tol``: the largest
    hard-constraint residual (m / rad) of an accepted solution; ``warm_start``: reuse the
    previous solve's multipliers.
    """

    def __init__(
        self,
        robot: Robot,
        hard_com_and_swing: bool = False,
        weights: NlpWeights | None = None,
        hard_torso: bool = False,
        ground_clearance: bool = True,
        foot: tuple[float, float] | None = None,
        tol: float = 1e-10,
        feasibility_tol: float = 1e-8,
        max_iterations: int = 300,
        warm_start: bool = True,
        torso: str = "torso",
    ) -> None:
        self.robot = robot
        self.kin = CasadiKinematics(robot)
        self.hard_com_and_swing = bool(hard_com_and_swing)
        self.hard_torso = bool(hard_torso)
        self.weights = weights or NlpWeights()
        self.ground_clearance = bool(ground_clearance)
        self.corners = sole_corners(*(robot.foot_size if foot is None else foot))
        self.tol = float(tol)
        self.feasibility_tol = float(feasibility_tol)
        self.max_iterations = int(max_iterations)
        self.warm_start = bool(warm_start)
        self.torso = torso
        self.kin.link_of(torso)
        for s in SOLES:
            self.kin.link_of(s)
        n = robot.n_joints
        self.nx = 6 + n
        self.lbx = np.concatenate([np.full(6, -np.inf), robot.q_min])
        self.ubx = np.concatenate([np.full(6, np.inf), robot.q_max])
        self._problems: dict[tuple[str, str], _Problem] = {}
        self._warm: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}

    # ------------------------------------------------------------------ parameters
    def _param_size(self) -> int:
        n = self.robot.n_joints
        return 3 + 12 + 12 + 9 + n + 9 + 3 * MAX_POLYGON_SIDES

    def _pack(self, targets: PoseTargets, R_ref: np.ndarray) -> np.ndarray:
        n = self.robot.n_joints
        com = _vector(targets.com, 3, "com target")
        posture = np.asarray(targets.posture, dtype=float)
        if posture.shape == (self.robot.nq,):
            posture = posture[7:]
        posture = _vector(posture, n, "posture target")
        torso = _rotation(targets.torso, "torso target")
        A = np.zeros((MAX_POLYGON_SIDES, 2))
        b = np.ones(MAX_POLYGON_SIDES)
        if targets.com_polygon is not None:
            A_in, b_in = (np.asarray(v, dtype=float) for v in targets.com_polygon)
            m = len(b_in)
            if A_in.shape != (m, 2) or m > MAX_POLYGON_SIDES or m == 0:
                raise TaskError(
                    f"com_polygon: expected A (m, 2) and b (m,) with 1 <= m <= "
                    f"{MAX_POLYGON_SIDES}, got {A_in.shape} and {b_in.shape}"
                )
            if not (np.all(np.isfinite(A_in)) and np.all(np.isfinite(b_in))):
                raise TaskError("com_polygon: non-finite values")
            A[:m], b[:m] = A_in, b_in
        parts = [com]
        for s in SOLES:
            M = targets.sole(s)
            parts += [
                _vector(M.translation, 3, f"{s} target"),
                _rotation(M.rotation, f"{s} target").ravel(order="F"),
            ]
        parts += [torso.ravel(order="F"), posture, R_ref.ravel(order="F"), A.ravel(order="F"), b]
        return np.concatenate(parts)

    def _symbols(self) -> dict[str, Any]:
        n = self.robot.n_joints
        p = ca.SX.sym("p", self._param_size())
        out: dict[str, Any] = {"p": p}
        k = 0

        def take(name: str, rows: int, cols: int = 1) -> None:
            nonlocal k
            out[name] = ca.reshape(p[k : k + rows * cols], rows, cols)
            k += rows * cols

        take("com", 3)
        for s in SOLES:
            take(f"{s}_p", 3)
            take(f"{s}_R", 3, 3)
        take("torso", 3, 3)
        take("posture", n)
        take("R_ref", 3, 3)
        take("A", MAX_POLYGON_SIDES, 2)
        take("b", MAX_POLYGON_SIDES)
        assert k == p.numel()
        return out

    # ------------------------------------------------------------------ building
    def _problem(self, phase: str, support: str) -> _Problem:
        key = (phase, support if phase == "single" else "both")
        prob = self._problems.get(key)
        if prob is None:
            prob = self._build(phase, support)
            self._problems[key] = prob
        return prob

    def _build(self, phase: str, support: str) -> _Problem:
        w = self.weights
        x = ca.SX.sym("x", self.nx)
        s = self._symbols()
        R_base = ca.mtimes(s["R_ref"], cayley(x[3:6]))
        joints = x[6:]
        links = self.kin.forward(x[0:3], R_base, joints)
        com = self.kin.com(links)
        held = list(SOLES) if phase == "double" else [support]
        swing = None if phase == "double" else ("r_sole" if support == "l_sole" else "l_sole")
        eq: list[tuple[str, Any]] = []
        for sole in held:
            p, R = self.kin.placement(sole, links)
            eq.append((f"{sole}_position", p - s[f"{sole}_p"]))
            eq.append((f"{sole}_rotation", _rotation_residual(R, s[f"{sole}_R"])))
        f: Any = 0
        com_err = com - s["com"]
        if self.hard_com_and_swing:
            eq.append(("com", com_err))
        else:
            f += w.com * ca.sumsqr(com_err)
        ineq: list[tuple[str, Any]] = []
        if swing is not None:
            p, R = self.kin.placement(swing, links)
            pos_err = p - s[f"{swing}_p"]
            if self.hard_com_and_swing:
                eq.append((f"{swing}_position", pos_err))
            else:
                f += w.swing * ca.sumsqr(pos_err)
            f += w.swing * _chordal(R, s[f"{swing}_R"])
            if self.ground_clearance:  # -z <= 0 for every corner
                z = ca.vertcat(*[-(p[2] + ca.mtimes(R[2, :], ca.DM(c))) for c in self.corners])
                ineq.append(("ground_clearance", z))
        ineq.append(("com_polygon", ca.mtimes(s["A"], com[0:2]) - s["b"]))
        _, R_torso = self.kin.placement(self.torso, links)
        if self.hard_torso:
            eq.append(("torso_rotation", _rotation_residual(R_torso, s["torso"])))
        else:
            f += w.torso * _chordal(R_torso, s["torso"])
        f += w.posture * ca.sumsqr(joints - s["posture"])
        g = ca.vertcat(*[e for _, e in eq], *[e for _, e in ineq])
        n_eq = sum(e.numel() for _, e in eq)
        lbg = np.concatenate([np.zeros(n_eq), np.full(g.numel() - n_eq, -np.inf)])
        ubg = np.zeros(g.numel())
        opts = {
            "print_time": False,
            "error_on_fail": False,
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "tol": self.tol,
                "constr_viol_tol": self.tol,
                "acceptable_tol": 1e-8,
                "acceptable_constr_viol_tol": self.feasibility_tol * 1e-2,
                "max_iter": self.max_iterations,
                "bound_relax_factor": 0.0,
                "honor_original_bounds": "yes",
                "mu_strategy": "adaptive",
            },
        }
        if self.warm_start:
            opts["ipopt"].update(
                {
                    "warm_start_init_point": "yes",
                    "warm_start_bound_push": 1e-9,
                    "warm_start_bound_frac": 1e-9,
                    "warm_start_slack_bound_push": 1e-9,
                    "warm_start_slack_bound_frac": 1e-9,
                    "warm_start_mult_bound_push": 1e-9,
                }
            )
        name = f"pose_{phase}" + ("" if swing is None else f"_{support}")
        solver = ca.nlpsol(name, "ipopt", {"x": x, "p": s["p"], "f": f, "g": g}, opts)
        names = [nm for nm, _ in eq] + [nm for nm, _ in ineq]
        sizes = [e.numel() for _, e in eq] + [e.numel() for _, e in ineq]
        evaluate = ca.Function(f"{name}_eval", [x, s["p"]], [f, g, com])
        return _Problem(solver, evaluate, lbg, ubg, n_eq, names, sizes)

    # ------------------------------------------------------------------ solving
    def _check(self, targets: PoseTargets) -> None:
        if targets.phase not in PHASES:
            raise TaskError(f"phase must be one of {PHASES}, got {targets.phase!r}")
        if targets.support not in SOLES:
            raise TaskError(f"support must be one of {SOLES}, got {targets.support!r}")

    def to_variables(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x, R_ref)``: the NLP variables of q, with the base rotation as R_ref (r = 0)."""
        q = self.robot.check_configuration(q)
        M = pin.XYZQUATToSE3(q[:7])
        x = np.concatenate([q[:3], np.zeros(3), q[7:]])
        return x, np.array(M.rotation)

    def to_configuration(self, x: np.ndarray, R_ref: np.ndarray) -> np.ndarray:
        """The pinocchio configuration of NLP variables x (joints clipped into the bounds)."""
        x = np.asarray(x, dtype=float).ravel()
        R = R_ref @ np.array(cayley(ca.DM(x[3:6])))
        q = np.empty(self.robot.nq)
        q[:3] = x[:3]
        quat = pin.Quaternion(R)
        quat.normalize()
        q[3:7] = quat.coeffs()
        q[7:] = np.clip(x[6:], self.robot.q_min, self.robot.q_max)
        return q

    def evaluate(self, q: np.ndarray, targets: PoseTargets) -> PoseSolution:
        """Objective and constraint residuals of a configuration (no solve)."""
        self._check(targets)
        prob = self._problem(targets.phase, targets.support)
        x, R_ref = self.to_variables(q)
        p = self._pack(targets, R_ref)
        f, g, _ = prob.evaluate(x, p)
        return self._solution(prob, q, np.array(g).ravel(), float(f), 0, "evaluated", 0.0)

    def objective(self, q: np.ndarray, targets: PoseTargets) -> float:
        """The NLP's objective at q (comparable across solvers at the same targets)."""
        return self.evaluate(q, targets).objective

    def solve(self, q0: np.ndarray, targets: PoseTargets) -> PoseSolution:
        """Solve the pose from the initial guess ``q0`` (joints clipped into their limits)."""
        self._check(targets)
        start = time.perf_counter()
        key = (targets.phase, targets.support if targets.phase == "single" else "both")
        prob = self._problem(targets.phase, targets.support)
        x0, R_ref = self.to_variables(self.robot.clip_to_limits(q0))
        p = self._pack(targets, R_ref)
        args: dict[str, Any] = {"x0": x0, "p": p, "lbx": self.lbx, "ubx": self.ubx}
        args.update(lbg=prob.lbg, ubg=prob.ubg)
        warm = self._warm.get(key)
        if self.warm_start and warm is not None:
            args.update(lam_x0=warm[0], lam_g0=warm[1])
        try:
            out = prob.solver(**args)
        except RuntimeError as exc:
            raise SolverError(f"IPOPT failed on the pose NLP: {exc}") from exc
        stats = prob.solver.stats()
        status = str(stats.get("return_status", "unknown"))
        x = np.array(out["x"]).ravel()
        if status in SOLVED:
            self._warm[key] = (np.array(out["lam_x"]).ravel(), np.array(out["lam_g"]).ravel())
        else:
            self._warm.pop(key, None)
        q = self.to_configuration(x, R_ref)
        # residuals from the returned configuration (not IPOPT's): the same x up to clipping
        x_q, R_q = self.to_variables(q)
        f, g, _ = prob.evaluate(x_q, self._pack(targets, R_q))
        return self._solution(
            prob,
            q,
            np.array(g).ravel(),
            float(f),
            int(stats.get("iter_count", 0)),
            status,
            time.perf_counter() - start,
        )

    def reset(self) -> None:
        """Forget the warm-start multipliers."""
        self._warm.clear()

    def build(self) -> None:
        """Build every structure now (double support, single support on either sole)."""
        self._problem("double", "l_sole")
        for sole in SOLES:
            self._problem("single", sole)

    def _solution(self, prob, q, g, f, iterations, status, elapsed) -> PoseSolution:
        residuals, violations = {}, {}
        k = 0
        for name, size in zip(prob.names, prob.sizes, strict=True):
            r = g[k : k + size]
            residuals[name] = r
            equality = k < prob.n_eq
            excess = np.abs(r) if equality else np.maximum(r, 0.0)
            violations[name] = float(np.max(excess, initial=0.0))
            k += size
        violation = max(violations.values(), default=0.0)
        return PoseSolution(q, iterations, status, f, violation, elapsed, residuals, violations)


@dataclass
class _Problem:
    solver: ca.Function
    evaluate: ca.Function
    lbg: np.ndarray
    ubg: np.ndarray
    n_eq: int
    names: list[str]
    sizes: list[int]


def _vector(v: Any, size: int, what: str) -> np.ndarray:
    a = np.asarray(v, dtype=float).ravel()
    if a.shape != (size,) or not np.all(np.isfinite(a)):
        raise TaskError(f"{what}: expected {size} finite values, got {np.asarray(v).shape}")
    return a


def _rotation(R: Any, what: str) -> np.ndarray:
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise TaskError(f"{what}: expected a finite 3x3 rotation matrix, got shape {R.shape}")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise TaskError(f"{what}: not a rotation matrix (RᵀR ≠ I or det < 0)")
    return R


class NlpController(Controller):
    """:class:`PoseNLP` behind the benchmark loop's :class:`Controller` interface.

    Every tick is solved to optimality (``track`` = ``converge``): an accuracy reference, not a
    real-time solver. The loop's ``tol`` / ``max_iterations`` are those of the iterative
    solvers; the NLP uses its own (``PoseNLP``'s ``tol``, ``max_iterations``). A pose whose
    solve fails or leaves a hard constraint violated by more than ``feasibility_tol`` raises
    (:class:`InfeasibleError` / :class:`SolverError`), which the loop counts as a failure.
    ``com_margin``: margin (m) of the CoM support-polygon constraint (the reference's support
    polygon at the tick); ``None`` leaves the CoM unconstrained. By default 0.01 (as in
    ``tasks/walk.toml``) for the weighted reference, and ``None`` with
    ``hard_com_and_swing`` (the thesis's tasks alone: with the polygon, a CoM reference closer
    than the margin to the polygon's edge would be reported unreachable).
    """

    name = "nlp-ipopt"
    family = "nlp"

    def __init__(
        self,
        hard_com_and_swing: bool = False,
        com_margin: float | str | None = "default",
        name: str | None = None,
        **nlp_options: Any,
    ) -> None:
        self.hard_com_and_swing = hard_com_and_swing
        if com_margin == "default":
            com_margin = None if hard_com_and_swing else WALK_COM_MARGIN
        if com_margin is not None and not (
            isinstance(com_margin, (int, float)) and np.isfinite(com_margin) and com_margin >= 0
        ):
            raise ConfigurationError(f"com_margin must be None or >= 0 (m), got {com_margin!r}")
        self.com_margin = com_margin
        self.nlp_options = nlp_options
        weights = nlp_options.get("weights")
        #: the stack its weights come from (recorded; None: the defaults, or the hard tasks)
        self.stack: str | None = getattr(weights, "stack", None)
        if name is not None:
            self.name = name
        elif hard_com_and_swing:
            self.name = "nlp-ipopt-hard"
        self.nlp: PoseNLP | None = None
        self.last: PoseSolution | None = None
        self._ref: WalkingReference | None = None
        self._posture = np.zeros(0)

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        if self.nlp is None or self.nlp.robot is not robot:
            self.nlp = PoseNLP(robot, self.hard_com_and_swing, **self.nlp_options)
        self.nlp.build()  # setup, not per-tick cost
        self.nlp.reset()
        q0 = robot.check_configuration(q0)
        self._posture = q0[7:].copy()
        self._ref = ref
        self.last = None

    def pose_targets(self, targets: TickTargets) -> PoseTargets:
        """The NLP targets of a tick (the torso's: Rz(yaw) · start torso, heading-free)."""
        polygon = None
        if self.com_margin is not None and self._ref is not None:
            polygon = self._ref.support_halfplanes(targets.i, self.com_margin)
        return PoseTargets(
            com=np.asarray(targets.com, dtype=float),
            l_sole=targets.l_sole,
            r_sole=targets.r_sole,
            torso=targets.torso_rotation,
            posture=self._posture,
            phase=targets.phase,
            support=targets.support,
            com_polygon=polygon,
        )

    def converge(self, q, targets, tol, max_iterations, phase_changed):
        if self.nlp is None:
            raise ConfigurationError(f"{self.name}: call start() before converge()")
        sol = self.nlp.solve(q, self.pose_targets(targets))
        self.last = sol
        if sol.violation > self.nlp.feasibility_tol:
            worst = max(sol.violations, key=sol.violations.__getitem__)
            raise InfeasibleError(
                f"{self.name}: tick {targets.i}: hard constraints violated by "
                f"{sol.violation:.3g} (worst: {worst}; IPOPT status {sol.status})"
            )
        if not sol.success:
            raise SolverError(f"{self.name}: tick {targets.i}: IPOPT status {sol.status}")
        return sol.q, sol.iterations

    def track(self, q, targets, dt, phase_changed):
        return self.converge(q, targets, 0.0, 0, phase_changed)[0]

    def task_errors(self) -> dict[str, np.ndarray]:
        if self.last is None:
            return {}
        return {
            "nlp_objective": np.array([self.last.objective]),
            "nlp_violation": np.array([self.last.violation]),
        }
