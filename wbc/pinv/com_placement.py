"""Static CoM placement of the thesis (com-control-thesis ch. 3): MCMT, DE, MS, DEAV, MSAV.

Every method iterates ``Δq = α J_wλ† Δx`` with the weighted-damped pseudo-inverse (1.43),
the fixed joint weights W of Annex B and one (λ, α) setting of Table 3.3.1 (sec. 3.3), in
the support-sole-rooted coordinates of :class:`~wbc.pinv.rooted.SoleRooted` (the thesis
keeps one sole fixed on the ground as the reference, sec. 3.2.1):

* **MCMT** (sec. 3.2.3): on the total CoM, J = J_T (3 x 18), Δx = x* − x (the shared
  :class:`~wbc.tasks.ComTask`).
* **DE** (sec. 3.2.1): principal-mass targets x_k* (3.8-3.11), then the support leg alone
  with [J_1; J_5] on its 6 joints (3.13-3.15) until masses 1 and 5 reach their targets, then
  each other limb alone on its own joints; repeat (targets recomputed from the new pose)
  until the CoM error is small.
* **MS** (sec. 3.2.2): the same outer loop, but all five masses at once, J_s 15 x 18 (3.17-3.18).
* **DEAV / MSAV** (sec. 3.3): DE / MS with the adaptive λ (halve on progress, double and
  discard the iteration otherwise), λ starting at the setting's value in every inner loop.

Nothing keeps the joints within their limits or the swing foot above the ground (the thesis
does not either); :class:`PlacementResult` reports both.

Units: the thesis measures lengths in millimetres (sec. 1.5.1, prismatic joints in mm;
every error in mm), so its λ is relative to Jacobians in mm/rad. λ is not scale-free in
(1.43), so we apply it to the residuals and Jacobians expressed in mm (``length_scale``
= 1000); in metres the same λ would weigh 10⁶ times more against J W⁻¹ Jᵀ.

Choices the thesis leaves open (documented, not tuned): the stopping tolerance on ‖x* − x‖ is
:data:`THESIS_COM_TOLERANCE` = 0.0005 mm, the smallest error Table 3.3.2 reports (MCMT,
sim1/sim6), which is what a converged run of the thesis produced; inner loops of DE/MS
("varias iteraciones") run until their masses are within the same tolerance or
``inner_iterations``; every run is capped at ``max_iterations`` pseudo-inverse updates
(rejected adaptive iterations count), after which it stops unconverged (the thesis's large
MCMT errors for α >= 0.5 were presumably such runs).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigurationError, SolverError
from ..model import Robot
from ..tasks import ComTask
from .principal_masses import PrincipalMasses, principal_mass_targets
from .pseudoinverse import AdaptiveDamping, weighted_damped_pinv
from .rooted import SoleRooted
from .thesis_data import TABLE_3_3_1, annex_b_weights

__all__ = [
    "METHODS",
    "THESIS_COM_TOLERANCE",
    "ComPlacement",
    "PlacementResult",
    "default_com_target",
    "place_com",
]

METHODS = ("DE", "DEAV", "MS", "MSAV", "MCMT")
#: smallest CoM error of Table 3.3.2 (m): the stopping tolerance of the placement methods
THESIS_COM_TOLERANCE = 0.0005e-3

Residual = Callable[[], tuple[np.ndarray, np.ndarray]]


@dataclass
class PlacementResult:
    """Outcome of one CoM placement run."""

    method: str
    damping: float
    gain: float
    q: np.ndarray
    com: np.ndarray
    com_error: float  #: ‖x* − x‖ at the end (m)
    converged: bool
    iterations: int  #: pseudo-inverse updates, rejected adaptive ones included
    outer_iterations: int  #: target recomputations (DE/MS family; 0 for MCMT)
    time: float  #: wall time of the whole run (s)
    joint_limit_excess: float  #: largest excursion beyond a joint limit (rad, 0 if none)
    swing_sole_height: float  #: swing sole z minus support sole z at the end (m)
    #: per inner loop (one for MCMT), the residual norm after each accepted iteration (in
    #: metres; the loop's own residual: CoM, masses 1 and 5, one limb's mass, or all masses)
    trace: list[list[float]] = field(default_factory=list)


def default_com_target(robot: Robot, q: np.ndarray, support: str = "l_sole") -> np.ndarray:
    """The CoM moved horizontally over the support sole's origin, height unchanged.

    The first move of the thesis's step (torso shifted over the support foot); it is what
    the benchmark asks the five methods to reach from the Annex A start pose (walk_ready).
    """
    sole = robot.frame_placement(q, support).translation
    return np.array([sole[0], sole[1], robot.com(q)[2]])


class ComPlacement:
    """The five static CoM placement methods of ch. 3 on one robot.

    Args:
        robot: the model.
        support, swing: sole frames; the support sole is the fixed root.
        weights: diagonal W on the joints, model order (default Annex B for ``support``).
        tol: stopping tolerance on ‖x* − x‖ (m).
        length_scale: lengths are multiplied by this before the pseudo-inverse (1000: mm, the
            thesis's unit, so that its λ means what it meant there; 1: metres).
        max_iterations: cap on pseudo-inverse updates per run.
        inner_iterations: cap per inner loop of DE/MS.
    """

    def __init__(
        self,
        robot: Robot,
        support: str = "l_sole",
        swing: str = "r_sole",
        weights: np.ndarray | None = None,
        tol: float = THESIS_COM_TOLERANCE,
        max_iterations: int = 2000,
        inner_iterations: int = 100,
        length_scale: float = 1000.0,
    ) -> None:
        if not (tol > 0 and max_iterations >= 1 and inner_iterations >= 1):
            raise ConfigurationError("tol must be > 0 and iteration caps >= 1")
        self.robot = robot
        self.support, self.swing = support, swing
        self.root = SoleRooted(robot, support)
        self.masses = PrincipalMasses(robot, support, swing)
        self.com_task = ComTask(robot, name="thesis_com")
        self.weights = (
            annex_b_weights(robot, support) if weights is None else np.asarray(weights, dtype=float)
        )
        if self.weights.shape != (robot.n_joints,):
            raise ConfigurationError(
                f"weights must have {robot.n_joints} entries (model joint order)"
            )
        self.tol = float(tol)
        self.max_iterations = int(max_iterations)
        self.inner_iterations = int(inner_iterations)
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ConfigurationError(f"length_scale must be > 0, got {length_scale}")
        self.length_scale = float(length_scale)
        self._all = np.arange(robot.n_joints)
        self._swing_fid = robot.frame_id(swing)
        self._support_fid = robot.frame_id(support)

    # ------------------------------------------------------------------ public
    def solve(
        self,
        q0: np.ndarray,
        com_target: np.ndarray,
        method: str = "MCMT",
        damping: float = 0.1,
        gain: float = 0.1,
    ) -> PlacementResult:
        """Place the CoM at ``com_target`` from ``q0`` with one method and one (λ, α)."""
        method = method.upper()
        if method not in METHODS:
            raise ConfigurationError(
                f"unknown CoM placement method {method!r}; use one of {METHODS}"
            )
        if not (np.isfinite(gain) and gain > 0):
            raise ConfigurationError(f"gain α must be > 0, got {gain}")
        q0 = self.robot.check_configuration(q0).copy()
        self.com_task.set_target(com_target)
        self._budget = self.max_iterations
        self._trace: list[list[float]] = []
        start = time.perf_counter()
        self.root.anchor(q0)
        if method == "MCMT":
            q, _ = self._iterate(
                q0, self._com_residual, self._all, damping, gain, False, self.max_iterations
            )
            outer = 0
        else:
            q, outer = self._outer(q0, method, damping, gain)
        elapsed = time.perf_counter() - start
        return self._result(method, damping, gain, q, outer, elapsed)

    # ------------------------------------------------------------------ residuals
    def _com_residual(self) -> tuple[np.ndarray, np.ndarray]:
        J, e = self.com_task.compute(self.root.kin)
        return self.root.reduce(J, e)

    def _mass_residual(self, rows: tuple[int, ...], targets: np.ndarray) -> Residual:
        def residual() -> tuple[np.ndarray, np.ndarray]:
            x, J = self.masses.compute(self.root.kin)
            e = np.concatenate([targets[k] - x[k] for k in rows])
            Jk = np.vstack([J[k] for k in rows])
            return self.root.reduce(Jk, e)

        return residual

    # ------------------------------------------------------------------ loops
    def _iterate(
        self,
        q: np.ndarray,
        residual: Residual,
        cols: np.ndarray,
        damping: float,
        gain: float,
        adaptive: bool,
        max_iterations: int,
    ) -> tuple[np.ndarray, float]:
        """Iterate Δq_cols = α J_wλ† e on ``residual`` until ‖e‖ <= tol; return (q, ‖e‖)."""
        root = self.root
        root.update(q)
        J, e = residual()
        err = float(np.linalg.norm(e))
        lam = AdaptiveDamping(damping) if adaptive else None
        W = self.weights[cols]
        dq = np.zeros(self.robot.n_joints)
        trace = [err]
        self._trace.append(trace)
        n = 0
        while n < max_iterations and self._budget > 0 and err > self.tol:
            n += 1
            self._budget -= 1
            s = self.length_scale  # the thesis's λ is for lengths in mm (see module docstring)
            Jp = weighted_damped_pinv(s * J[:, cols], W, lam.value if lam else damping)
            dq[cols] = gain * (Jp @ (s * e))
            q_new = root.integrate(dq)
            root.update(q_new)
            J_new, e_new = residual()
            err_new = float(np.linalg.norm(e_new))
            if not np.isfinite(err_new):
                raise SolverError("CoM placement diverged (non-finite error)")
            if lam is not None and not lam.accept(err_new, err):
                root.update(q)  # discard the iteration
                if lam.exhausted:
                    break
                continue
            q, J, e, err = q_new, J_new, e_new, err_new
            trace.append(err)
        return q, err

    def _outer(self, q: np.ndarray, method: str, damping: float, gain: float):
        """DE / MS outer loop: targets from the current pose, inner loops, CoM check."""
        adaptive = method.endswith("AV")
        simultaneous = method.startswith("MS")
        chains = self.masses.chains
        outer = 0
        while self._budget > 0:
            self.root.update(q)
            if np.linalg.norm(self.com_task.compute(self.root.kin)[1]) <= self.tol:
                break
            outer += 1
            budget = self._budget
            x, _ = self.masses.compute(self.root.kin)
            targets, _ = principal_mass_targets(self.masses.masses, x, self.com_task.target)
            if simultaneous:
                q, _ = self._iterate(
                    q,
                    self._mass_residual((0, 1, 2, 3, 4), targets),
                    self._all,
                    damping,
                    gain,
                    adaptive,
                    self.inner_iterations,
                )
            else:
                # support leg moves the support-leg and torso masses (3.13-3.15)
                q, _ = self._iterate(
                    q,
                    self._mass_residual((0, 4), targets),
                    chains[0].joints,
                    damping,
                    gain,
                    adaptive,
                    self.inner_iterations,
                )
                for k in (1, 2, 3):  # then each remaining limb on its own joints
                    q, _ = self._iterate(
                        q,
                        self._mass_residual((k,), targets),
                        chains[k].joints,
                        damping,
                        gain,
                        adaptive,
                        self.inner_iterations,
                    )
            if self._budget == budget:  # every mass at its target, CoM still off: stalled
                break
        return q, outer

    def _result(self, method, damping, gain, q, outer, elapsed) -> PlacementResult:
        self.root.update(q)
        kin = self.root.kin
        com = kin.com.copy()
        err = float(np.linalg.norm(self.com_task.target - com))
        j = q[7:]
        excess = float(max(0.0, np.max(self.robot.q_min - j), np.max(j - self.robot.q_max)))
        height = float(
            kin.placement(self._swing_fid).translation[2]
            - kin.placement(self._support_fid).translation[2]
        )
        return PlacementResult(
            method=method, damping=damping, gain=gain, q=q, com=com, com_error=err,
            converged=err <= self.tol, iterations=self.max_iterations - self._budget,
            outer_iterations=outer, time=elapsed, joint_limit_excess=excess,
            swing_sole_height=height,
            trace=self._trace,
        )  # fmt: skip


def place_com(
    robot: Robot,
    q0: np.ndarray,
    com_target: np.ndarray,
    method: str = "MCMT",
    setting: str | None = None,
    damping: float = 0.1,
    gain: float = 0.1,
    **options,
) -> PlacementResult:
    """One-shot :class:`ComPlacement` run; ``setting`` ("sim1".."sim6") overrides (λ, α)."""
    if setting is not None:
        try:
            damping, gain = TABLE_3_3_1[setting]
        except KeyError:
            raise ConfigurationError(
                f"unknown setting {setting!r}; use one of {list(TABLE_3_3_1)}"
            ) from None
    return ComPlacement(robot, **options).solve(q0, com_target, method, damping, gain)
