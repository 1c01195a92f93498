"""Is a reference kinematically feasible? Track it with a small bounded IK and measure.

The pre-motion checks (:mod:`.checks`) use a simplified leg model. This module is the
independent judge: at every tick it iterates a weighted least-squares IK step with the
joint limits as hard bounds (quadprog via qpsolvers),

    min_dq  sum_k w_k |J_k dq - e_k|^2 + eps |dq|^2    s.t.  q_min <= q + dq <= q_max,

on both sole poses (6 + 6), the CoM (3) and the torso orientation (3: the start pitch/roll,
the reference's heading and planned roll), from Walk Ready placed at the reference's start,
and reports the worst task errors and the smallest joint-limit margin. A feasible reference
is tracked to numerical precision; an infeasible one leaves millimetre errors with joints on
their limits. It is a check, not a controller: the control loop (:mod:`.loop`) runs the real stacks.

    python -m wbc.walking.feasibility            # the standard references
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import SolverError
from ..geometry import heading_free
from ..model import Kinematics
from ..tasks import ComTask, LocalFramePoseTask
from .reference import WalkingReference

#: the share of a servo's no-load speed (the model's velocity limit) a reference may ask for.
#: The AX-12A's speed falls linearly with torque, ``w = w0 (1 - tau / tau_stall)``; a swing
#: leg's joints carry ~0.1 N.m (7 % of the 1.5 N.m stall), the recommended 11.1 V supply
#: gives ~0.93 w0, and the compliance slope adds lag: 0.75 w0 leaves the servo a margin
#: (a plan at the no-load speed, walk10's swing knee, lags up to 24 deg in the simulator).
PLANNING_SPEED_FRACTION = 0.75


@dataclass(frozen=True)
class FeasibilityReport:
    """Worst errors over the reference (m, rad) and the smallest joint-limit margin (rad)."""

    max_com_error: float
    max_sole_error: float
    max_torso_error: float
    min_limit_margin: float
    ticks: int
    #: the largest joint speed (rad/s) of the tracked motion (finite differences per tick)
    #: and its joint: what the reference asks of the servos, whatever the controller
    max_joint_speed: float = float("nan")
    speed_joint: str = ""
    #: the largest joint speed as a share of that joint's no-load speed (its velocity limit),
    #: and its joint
    speed_fraction: float = float("nan")
    fraction_joint: str = ""
    #: the largest joint torque of the tracked motion as a share of that joint's stall torque
    #: (the model's effort limit), and its joint (:func:`joint_torques`)
    torque_fraction: float = float("nan")
    torque_joint: str = ""

    @property
    def feasible(self) -> bool:
        return max(self.max_com_error, self.max_sole_error, self.max_torso_error) < 1e-6


def kinematic_feasibility(
    robot: Any,
    ref: WalkingReference,
    q0: np.ndarray | None = None,
    hold_arms: bool = True,
    iterations: int = 8,
    weights: tuple[float, float, float] = (1e4, 1e2, 1e3),
    torques: bool = True,
) -> FeasibilityReport:
    """Track ``ref`` with the bounded IK (soles, CoM, torso weights ``weights``); the arms
    (and any other joint not a leg's, :attr:`wbc.model.Robot.roles`) are held at their start
    angles if ``hold_arms``. ``torques``: the peak torque share (:func:`joint_torques`, ~11 %
    of the call on the Bioloid's walk) computed; False leaves ``torque_fraction`` NaN (the
    speed fit and the velocity limits, which do not read it)."""
    from qpsolvers import solve_qp

    model = robot.model
    if q0 is None:
        q0 = robot.place_on_ground(
            robot.configuration("stand"), "l_sole", ref.sole_placement(0, "left")
        )
    q = robot.check_configuration(q0).copy()
    R0 = robot.frame_placement(q, "torso").rotation
    pitch_roll = heading_free(R0)
    torsos = ref.torso_rotations(pitch_roll)  # with the reference's planned lean, if any
    w_sole, w_com, w_torso = weights
    W = np.array([w_sole] * 12 + [w_com] * 3 + [w_torso] * 3)
    legs = {robot.v_index(j) for s in ("left", "right") for j in robot.roles.leg(s)}
    # held: the arms and every other joint that is not a leg's (a head)
    held = sorted(set(range(6, model.nv)) - legs) if hold_arms else []
    free = np.setdiff1d(np.arange(model.nv), held)
    worst = np.zeros(3)
    min_margin = np.inf
    speed = np.zeros(model.nv - 6)
    q_prev = None
    path = np.empty((ref.n, model.nq))
    rows = _Rows(robot, q)
    for i in range(ref.n):
        rows.set_targets(ref.sole_placement(i, "left"), ref.sole_placement(i, "right"),
                         ref.com[i], torsos[i])  # fmt: skip
        for _ in range(iterations):
            J, e = rows(q)
            H = J.T @ (W[:, None] * J) + 1e-4 * np.eye(model.nv)
            g = -J.T @ (W * e)
            lb = np.full(model.nv, -1e3)
            ub = np.full(model.nv, 1e3)
            lb[6:] = robot.q_min - q[7:]
            ub[6:] = robot.q_max - q[7:]
            sol = solve_qp(
                H[np.ix_(free, free)],
                g[free],
                lb=np.minimum(lb[free], 0.0),
                ub=np.maximum(ub[free], 0.0),
                solver="quadprog",
            )
            if sol is None:
                raise SolverError(f"feasibility IK: quadprog failed at tick {i}")
            dq = np.zeros(model.nv)
            dq[free] = sol
            q = pin.integrate(model, q, dq)
        _, e = rows(q)
        worst = np.maximum(
            worst,
            [
                np.linalg.norm(e[12:15]),
                max(np.linalg.norm(e[:6]), np.linalg.norm(e[6:12])),
                np.linalg.norm(e[15:]),
            ],
        )
        j = q[7:]
        min_margin = min(min_margin, float(np.min(np.minimum(j - robot.q_min, robot.q_max - j))))
        if q_prev is not None:
            speed = np.maximum(speed, np.abs(j - q_prev) / ref.dt)
        q_prev = j.copy()
        path[i] = q
    k = int(np.argmax(speed))
    share = speed / robot.v_max
    f = int(np.argmax(share))
    if torques:
        torque = np.abs(joint_torques(robot, ref, path)).max(axis=0)
        torque /= np.asarray(robot.model.effortLimit[6:])
        t = int(np.argmax(torque))
        peak, peak_joint = float(torque[t]), robot.joint_names[t]
    else:
        peak, peak_joint = float("nan"), ""
    return FeasibilityReport(
        float(worst[0]),
        float(worst[1]),
        float(worst[2]),
        min_margin,
        ref.n,
        float(speed[k]),
        robot.joint_names[k],
        float(share[f]),
        robot.joint_names[f],
        peak,
        peak_joint,
    )


def joint_torques(robot: Any, ref: WalkingReference, path: np.ndarray) -> np.ndarray:
    """(N, n_joints) the joint torques (N·m) of the motion ``path`` ((N, nq), one
    configuration per tick of ``ref``): inverse dynamics (``pin.rnea``, velocities and
    accelerations by finite differences on the configuration space) with the floating base's
    wrench carried by the soles in contact — all of it by the stance sole in single support;
    in double support split between the two by where the reference's ZMP lies along the
    segment between the soles (:func:`contact_forces`; the static torques of
    :meth:`wbc.balance.compliance.ComplianceCompensator.torques` split by the CoM)."""
    model = robot.model
    data = model.createData()
    n, dt = ref.n, ref.dt
    diff = np.array([pin.difference(model, path[i], path[i + 1]) / dt for i in range(n - 1)])
    vel = np.vstack([diff[:1], 0.5 * (diff[1:] + diff[:-1]), diff[-1:]])
    acc = np.vstack([np.zeros((1, model.nv)), np.diff(diff, axis=0) / dt, np.zeros((1, model.nv))])
    ids = {s: robot.frame_id(f"{s[0]}_sole") for s in ("left", "right")}
    zmp = ref.zmp
    out = np.empty((n, model.nv - 6))
    for i in range(n):
        tau = pin.rnea(model, data, path[i], vel[i], acc[i])
        pin.computeJointJacobians(model, data, path[i])
        pin.updateFramePlacements(model, data)
        sides = ref.contact_sides(i)
        jc = np.vstack(
            [pin.getFrameJacobian(model, data, ids[s], pin.LOCAL_WORLD_ALIGNED) for s in sides]
        )
        share = 1.0
        if len(sides) == 2:
            pl, pr = (data.oMf[ids[s]].translation[:2] for s in sides)
            seg = pl - pr
            share = float((zmp[i] - pr) @ seg / max(seg @ seg, 1e-12))
        out[i] = tau[6:] - jc[:, 6:].T @ contact_forces(jc[:, :6].T, tau[:6], share)
    return out


def contact_forces(a: np.ndarray, wrench: np.ndarray, share: float = 1.0) -> np.ndarray:
    """The soles' contact wrenches ``f`` (6 a sole) that carry the floating base's ``wrench``,
    ``a f = wrench`` (``a``: the base rows of the soles' Jacobians, transposed, (6, 6k)): one
    sole carries all of it; two split it as the weighted least-norm
    ``f = W aᵀ (a W aᵀ)⁻¹ wrench``, the first sole weighted ``share`` (clipped to 0.02–0.98:
    where the load point lies from the second sole to the first), the second ``1 − share``."""
    if a.shape[1] == 6:
        return np.linalg.solve(a, wrench)
    share = float(np.clip(share, 0.02, 0.98))
    w = np.repeat([share, 1.0 - share], 6)
    return w * (a.T @ np.linalg.solve((a * w) @ a.T, wrench))


class _Rows:
    """The IK's rows (:mod:`wbc.tasks`), ``J dq = e``: both soles at their placements
    (:class:`~wbc.tasks.LocalFramePoseTask`: ``log6(M⁻¹ M*)``, local Jacobian), the CoM
    (:class:`~wbc.tasks.ComTask`) and the torso's orientation (the local pose task's rotation
    rows: ``log3(Rᵀ R*)``, local angular Jacobian); 6 + 6 + 3 + 3 rows."""

    def __init__(self, robot: Any, q: np.ndarray) -> None:
        self.kin = Kinematics(robot, q)
        self.soles = [LocalFramePoseTask(robot, f) for f in ("l_sole", "r_sole")]
        self.com = ComTask(robot)
        self.torso = LocalFramePoseTask(robot, "torso", mask=[False] * 3 + [True] * 3)
        self.tasks = [*self.soles, self.com, self.torso]
        self.J = np.zeros((18, robot.model.nv))
        self.e = np.zeros(18)

    def set_targets(
        self, left: pin.SE3, right: pin.SE3, com: np.ndarray, torso: np.ndarray
    ) -> None:
        """The soles' placements, the CoM (world) and the torso's rotation."""
        self.soles[0].set_target(left)
        self.soles[1].set_target(right)
        self.com.set_target(com)
        self.torso.set_rotation_target(torso)

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J, e) at ``q`` (this object's arrays, overwritten by the next call)."""
        self.kin.update(q)
        r = 0
        for task in self.tasks:
            task.fill(self.kin, self.J[r : r + task.rows], self.e[r : r + task.rows])
            r += task.rows
        return self.J, self.e


def main(argv: list[str] | None = None) -> int:
    from ..model import load_robot
    from .gait import forward_walk, lateral_walk, turning_walk
    from .reference import StandingState
    from .thesis_step import thesis_lipm_step, thesis_step

    robot = load_robot("bioloid")
    start = StandingState.from_robot(robot)
    refs = [thesis_step(start), thesis_lipm_step(start)]
    for gen in ("preview", "mpc", "lipm"):
        refs += [
            forward_walk(start, 10, generator=gen, name=f"forward-10-{gen}"),
            turning_walk(start, 8, generator=gen, name=f"turning-8-{gen}"),
            lateral_walk(start, 6, 0.015, generator=gen, name=f"lateral-6-{gen}"),
        ]
    for ref in refs:
        for hold in (True, False):
            rep = kinematic_feasibility(robot, ref, hold_arms=hold)
            print(
                f"{ref.name:22s} arms {'held' if hold else 'free':4s}  CoM err "
                f"{rep.max_com_error * 1e3:7.4f} mm  sole err {rep.max_sole_error:.1e}  torso "
                f"err {rep.max_torso_error:.1e}  min joint-limit margin "
                f"{rep.min_limit_margin:.4f} rad  {'feasible' if rep.feasible else 'INFEASIBLE'}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
