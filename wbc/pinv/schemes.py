"""The thesis's walking schemes (com-control-thesis ch. 4): VAT, CJ, VATL, CJL.

Tasks (sec. 4.2), the shared task objects of :mod:`wbc.tasks`, all relative to the support
sole (see :mod:`wbc.pinv.rooted`):

* CoM position Δx = x* − x (4.1), :class:`~wbc.tasks.ComTask` (3 rows);
* swing-foot position Δx_f (4.2), :class:`~wbc.tasks.FramePositionTask` (3);
* swing-foot orientation Δx_of = [1 − k·k_f, 1 − i·i_f] (4.3),
  :class:`~wbc.tasks.SwingFootOrientationTask` (2), target axes = the support sole's;
* torso orientation Δx_ot = 1 − k·k_t (4.4), :class:`~wbc.tasks.TorsoOrientationTask` (1),
  axis = the support sole's z.

Schemes (``kind``):

* ``"vat"`` (4.5-4.7): one augmented task [CoM; foot pos; foot ori; torso] (9 x 18),
  Δq = J_A^†w Δx_A.
* ``"cj_foot"`` (4.8-4.11): primary [foot pos; foot ori; torso] (6 x 18), secondary the CoM,
  Δq_s = J† Δx, projected: Δq = J_A^†w Δx_A + (I − J_A^†w J_A) Δq_s.
* ``"cj_com"`` (4.12-4.14): primary [CoM; foot ori; torso], secondary the foot position.
* ``"vatl"``, ``"cjl_foot"``, ``"cjl_com"`` (sec. 4.4): the same with the Chan–Dubey joint-limit
  weights (1.52-1.54) multiplying W, updated every iteration.

Parameters — the thesis's, where it gives them (documented choices where it does not):

* J_A^†w is the weighted-damped pseudo-inverse (1.43). Ch. 4 writes only "†w"; the
  undamped weighted inverse (1.40) cannot work with these tasks: the orientation Jacobians
  of (4.3)/(4.4) vanish when the axes are aligned (the swing foot starts flat), so
  J W⁻¹ Jᵀ is singular. The damping and gain default to the setting ch. 3 found best and
  ch. 4 builds on (MCMT, sim1: λ = 0.1, α = 0.1), with lengths in mm as the thesis (so λ
  means what it meant there, ``length_scale`` = 1000; orientation rows are dimensionless).
* W = I for VAT and CJ, and W = diag(w_CD), the Chan–Dubey weights, for VATL and CJL: the
  thesis gives Annex B's W for the ch. 3 algorithms only (it lists them), and sec. 4.4
  introduces W in the walking schemes as the joint-limit device ("VATL incorpora a la
  metodología VAT el uso de la matriz de pesos W"). With Annex B's anisotropic weights
  (0.1 vs 10) the CJ schemes diverge on our model: the W-oblique projector and the
  unweighted J† of Δq_s (4.11) no longer agree: J_s (I − J_A^†w J_A) J_s† can have
  negative eigenvalues, and the projected secondary step then moves away from its target
  (``benchmarks/thesis_tables.py --weights annex_b`` shows it). ``weights="annex_b"`` (or
  any vector) sets another base W; the "L" schemes multiply it by the Chan–Dubey weights.
* Δq_s uses the plain Moore–Penrose inverse (4.11, 4.14: "J†").
* Eq. 4.8 prints ``− (I − J_A^†w J_A) Δq_s``. Taken literally (the minus of the
  gradient-descent form 1.25, where ż is a cost gradient) it drives the secondary task away
  from its target, which contradicts the thesis's results (CJ1 CoM error at most 5.3 mm), so
  the default ``secondary_sign`` is +1; ``secondary_sign=-1`` gives the literal equation.
* α multiplies every task error (the task objects' ``gain``), i.e. the whole Δq as in ch. 3.
* Joints are not clipped (neither does the thesis); :class:`SchemeInfo` reports any
  excursion. ``clip_to_limits=True`` clips (an improvement, not the thesis's method); a
  control loop that sends the result to servos must clip.
* Optional ``limit_cost`` (one of :data:`~wbc.limits.joint_costs.COSTS`) adds the gradient
  projection term of (1.44), −k ∇G, to the null-space vector — the alternatives the thesis
  tried before adopting the weighting.

The damped projector is not an exact null-space projector (J (I − J⁺J) ≠ 0 when λ > 0):
the secondary task leaks into the primary. That is the thesis's scheme; we keep it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigurationError
from ..limits.joint_costs import COSTS, ChanDubeyWeights
from ..model import Robot
from ..tasks import ComTask, FramePositionTask, SwingFootOrientationTask, TorsoOrientationTask
from ..tasks.task import Task
from .pseudoinverse import moore_penrose, weighted_damped_pinv
from .rooted import SoleRooted
from .thesis_data import annex_b_weights

__all__ = ["SCHEME_NAMES", "SchemeInfo", "ThesisScheme"]

#: kind -> (primary tasks, secondary task or None, Chan–Dubey limits)
_LAYOUT: dict[str, tuple[tuple[str, ...], str | None, bool]] = {
    "vat": (("com", "foot", "foot_ori", "torso"), None, False),
    "vatl": (("com", "foot", "foot_ori", "torso"), None, True),
    "cj_foot": (("foot", "foot_ori", "torso"), "com", False),
    "cj_com": (("com", "foot_ori", "torso"), "foot", False),
    "cjl_foot": (("foot", "foot_ori", "torso"), "com", True),
    "cjl_com": (("com", "foot_ori", "torso"), "foot", True),
}
SCHEME_NAMES: tuple[str, ...] = tuple(_LAYOUT)
_POSITION_TASKS = ("com", "foot")


@dataclass
class SchemeInfo:
    """Outcome of :meth:`ThesisScheme.solve_pose` (errors at the returned configuration)."""

    iterations: int
    converged: bool
    time: float  #: wall time (s)
    com_error: float  #: ‖x* − x‖ (m)
    foot_error: float  #: ‖x_f* − x_f‖ (m)
    #: every task's error, by key: "com", "foot" (m), "foot_ori", "torso" (1 − cos)
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    joint_limit_excess: float = 0.0  #: largest excursion beyond a joint limit (rad)

    def max_error(self) -> float:
        return max(float(np.max(np.abs(e))) for e in self.errors.values())


class ThesisScheme:
    """One of the six walking schemes of ch. 4 (see the module docstring).

    Args:
        robot: the model.
        kind: one of :data:`SCHEME_NAMES`.
        support, swing: sole frames (support = the fixed root).
        torso: frame whose z axis the torso task keeps vertical.
        damping: λ of (1.43) (with ``length_scale``).
        gain: α, applied to every task error.
        weights: base joint weights W (model order); default identity; "annex_b" for
            Annex B (mirrored for a right support foot).
        length_scale: position rows are expressed in metres x this before the inverse.
        secondary_sign: +1 (default) or −1 (eq. 4.8 literally), for the CJ schemes.
        limit_cost, limit_cost_gain: optional gradient-projection cost (1.44) and its gain k.
        clip_to_limits: clip joints into their limits after each iteration (not the thesis).
    """

    def __init__(
        self,
        robot: Robot,
        kind: str = "vat",
        support: str = "l_sole",
        swing: str = "r_sole",
        torso: str = "torso",
        damping: float = 0.1,
        gain: float = 0.1,
        weights: np.ndarray | str | None = None,
        length_scale: float = 1000.0,
        secondary_sign: float = 1.0,
        limit_cost: str | None = None,
        limit_cost_gain: float = 1.0,
        clip_to_limits: bool = False,
    ) -> None:
        if kind not in _LAYOUT:
            raise ConfigurationError(f"unknown scheme {kind!r}; use one of {SCHEME_NAMES}")
        if support == swing:
            raise ConfigurationError(f"support and swing must differ, both are {support!r}")
        if not (np.isfinite(damping) and damping >= 0):
            raise ConfigurationError(f"damping λ must be >= 0, got {damping}")
        if not (np.isfinite(gain) and gain > 0):
            raise ConfigurationError(f"gain α must be > 0, got {gain}")
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ConfigurationError(f"length_scale must be > 0, got {length_scale}")
        if secondary_sign not in (1.0, -1.0):
            raise ConfigurationError(f"secondary_sign must be +1 or -1, got {secondary_sign}")
        if limit_cost is not None and limit_cost not in COSTS:
            raise ConfigurationError(
                f"unknown limit cost {limit_cost!r}; use one of {sorted(COSTS)}"
            )
        self.robot = robot
        self.kind = kind
        self.support, self.swing = support, swing
        self.damping = float(damping)
        self.gain = float(gain)
        self.length_scale = float(length_scale)
        self.secondary_sign = float(secondary_sign)
        self.limit_cost = limit_cost
        self.limit_cost_gain = float(limit_cost_gain)
        self.clip_to_limits = clip_to_limits
        self.root = SoleRooted(robot, support)
        self.tasks: dict[str, Task] = {
            "com": ComTask(robot, name="com"),
            "foot": FramePositionTask(robot, swing, name="swing_position"),
            "foot_ori": SwingFootOrientationTask(robot, swing, name="swing_orientation"),
            "torso": TorsoOrientationTask(robot, torso, name="torso_orientation"),
        }
        for task in self.tasks.values():
            task.gain = self.gain
        self.primary, self.secondary, limits = _LAYOUT[kind]
        if weights is None:
            self.weights = np.ones(robot.n_joints)
        elif isinstance(weights, str):
            if weights != "annex_b":
                raise ConfigurationError(
                    f"weights: unknown name {weights!r}; use 'annex_b' or a vector"
                )
            self.weights = annex_b_weights(robot, support)
        else:
            self.weights = np.asarray(weights, dtype=float)
        if self.weights.shape != (robot.n_joints,) or np.any(self.weights <= 0):
            raise ConfigurationError(
                f"weights must be {robot.n_joints} positive values (model order)"
            )
        self.chan_dubey = ChanDubeyWeights(robot.q_min, robot.q_max) if limits else None
        self._J: dict[str, np.ndarray] = {}
        self._e: dict[str, np.ndarray] = {}
        self.last_time = 0.0
        self.last_errors: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------ factories
    @classmethod
    def make(cls, name: str, robot: Robot, **options) -> ThesisScheme:
        """Factory by name: "vat", "vatl", "cj_foot", "cj_com", "cjl_foot", "cjl_com"."""
        return cls(robot, name, **options)

    @classmethod
    def vat(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "vat", **options)

    @classmethod
    def vatl(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "vatl", **options)

    @classmethod
    def cj_foot(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "cj_foot", **options)

    @classmethod
    def cj_com(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "cj_com", **options)

    @classmethod
    def cjl_foot(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "cjl_foot", **options)

    @classmethod
    def cjl_com(cls, robot: Robot, **options) -> ThesisScheme:
        return cls(robot, "cjl_com", **options)

    @property
    def hierarchical(self) -> bool:
        return self.secondary is not None

    # ------------------------------------------------------------------ targets
    def reset(self, q: np.ndarray) -> None:
        """Anchor the support sole at q, aim every task at q's values, reset Chan–Dubey.

        The swing-foot orientation target is the support sole's rotation and the torso axis
        the support sole's z axis (the thesis's k, i of the fixed sole).
        """
        self.root.anchor(q)
        kin = self.root.kin
        for name in ("com", "foot"):
            self.tasks[name].set_target_from(kin)
        sole = self.root.contact.target_rotation
        self.tasks["foot_ori"].set_target(sole)
        self.tasks["torso"].set_axis(sole[:, 2])
        if self.chan_dubey is not None:
            self.chan_dubey.reset()

    def set_targets(
        self,
        com: np.ndarray,
        swing_position: np.ndarray,
        swing_rotation: np.ndarray | None = None,
    ) -> None:
        """CoM and swing-sole targets (world frame, m); rotation default: the support sole's."""
        self.tasks["com"].set_target(com)
        self.tasks["foot"].set_target(swing_position)
        if swing_rotation is not None:
            self.tasks["foot_ori"].set_target(swing_rotation)

    # ------------------------------------------------------------------ iterations
    def _evaluate(self) -> None:
        """Sole-rooted (J, α e) of every task at the root's configuration, mm-scaled."""
        kin = self.root.kin
        for name, task in self.tasks.items():
            J, e = task.compute(kin)
            Jr, er = self.root.reduce(J, task.gain * e)
            if name in _POSITION_TASKS:
                Jr *= self.length_scale
                er *= self.length_scale
            self._J[name], self._e[name] = Jr, er

    def _joint_weights(self) -> np.ndarray:
        if self.chan_dubey is None:
            return self.weights
        return self.weights * self.chan_dubey.update(self.root.q[7:])

    def _increment(self) -> np.ndarray:
        """Δq_j (joints) at the evaluated configuration."""
        JA = np.vstack([self._J[n] for n in self.primary])
        eA = np.concatenate([self._e[n] for n in self.primary])
        JA_pinv = weighted_damped_pinv(JA, self._joint_weights(), self.damping)
        dq = JA_pinv @ eA
        z = None
        if self.secondary is not None:
            z = self.secondary_sign * (
                moore_penrose(self._J[self.secondary]) @ self._e[self.secondary]
            )
        if self.limit_cost is not None:
            _, grad = COSTS[self.limit_cost]
            g = -self.limit_cost_gain * grad(self.root.q[7:], self.robot.q_min, self.robot.q_max)
            z = g if z is None else z + g
        if z is not None:
            dq += z - JA_pinv @ (JA @ z)  # (I − J_A⁺ J_A) z
        return dq

    def _advance(self, dq_joints: np.ndarray) -> np.ndarray:
        q = self.root.integrate(dq_joints)
        if self.clip_to_limits:
            np.clip(q[7:], self.robot.q_min, self.robot.q_max, out=q[7:])
            q = self.root.reanchor(q)  # the clipped joints moved the support sole
        return q

    def _converged(self, tol: float, orientation_tol: float | None) -> bool:
        """‖Δx‖ of the scheme's tasks, stacked in the thesis's units, <= tol·length_scale."""
        names = self.primary + ((self.secondary,) if self.secondary else ())
        total = 0.0
        for name in names:
            e = self._e[name] / self.tasks[name].gain  # undo α: the errors themselves
            total += float(e @ e)
            if (
                orientation_tol is not None
                and name not in _POSITION_TASKS
                and np.max(np.abs(e)) > orientation_tol
            ):
                return False
        return np.sqrt(total) <= tol * self.length_scale

    def step(self, q: np.ndarray) -> np.ndarray:
        """One iteration (per-tick mode): q ⊕ Δq. Anchors the support sole on first use.

        :attr:`last_errors` holds the task errors at ``q`` (before the step) and
        :attr:`last_time` the wall time of the step (s).
        """
        start = time.perf_counter()
        if not self.root.anchored:
            self.reset(q)
        self.root.update(q)
        self._evaluate()
        self.last_errors = {name: task.last_error.copy() for name, task in self.tasks.items()}
        q_next = self._advance(self._increment())
        self.last_time = time.perf_counter() - start
        return q_next

    def solve_pose(
        self,
        q: np.ndarray,
        tol: float = 1e-5,
        max_iterations: int = 200,
        orientation_tol: float | None = None,
    ) -> tuple[np.ndarray, SchemeInfo]:
        """Iterate on one pose until the errors are small, as the thesis does per pose.

        Stops when the magnitude of the stacked task error ("hasta que la magnitud de Δx
        sea lo suficientemente pequeña", sec. 1.5.2) in the thesis's units — positions in
        mm (``length_scale``), orientations 1 − cos, dimensionless — is at most
        ``tol`` x ``length_scale`` (tol = 1e-5 m: 0.01, "hundredths of a millimetre"), or after
        ``max_iterations``. In those units the orientation errors weigh little (1 − cos =
        0.01 is 8°): that is the thesis's criterion; ``orientation_tol`` additionally bounds
        every orientation error.
        """
        start = time.perf_counter()
        q = self.robot.check_configuration(q)
        if not self.root.anchored:
            self.reset(q)
        converged = False
        it = 0
        while True:
            self.root.update(q)
            self._evaluate()
            if self._converged(tol, orientation_tol):
                converged = True
                break
            if it >= max_iterations:
                break
            q = self._advance(self._increment())
            it += 1
        elapsed = time.perf_counter() - start
        self.last_time = elapsed
        return q, self._info(q, it, converged, elapsed)

    def _info(self, q, iterations, converged, elapsed) -> SchemeInfo:
        errors = {name: task.last_error.copy() for name, task in self.tasks.items()}
        j = q[7:]
        excess = float(max(0.0, np.max(self.robot.q_min - j), np.max(j - self.robot.q_max)))
        return SchemeInfo(
            iterations=iterations, converged=converged, time=elapsed,
            com_error=float(np.linalg.norm(errors["com"])),
            foot_error=float(np.linalg.norm(errors["foot"])),
            errors=errors, joint_limit_excess=excess,
        )  # fmt: skip

    def __repr__(self) -> str:
        return (
            f"ThesisScheme({self.kind!r}, support={self.support!r}, λ={self.damping:g}, "
            f"α={self.gain:g})"
        )
