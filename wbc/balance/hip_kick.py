"""The push's hip kick: the stance hip roll's solved goal driven on toward the hip strategy's
roll, and braked before the torso tips past the tilt it may reach (issue 30).

After a push away from the swing foot, the hip strategy (:mod:`wbc.balance.stabilizer`) asks
the torso to roll toward the fall; the whole-body solve, its CoM task the heaviest, stops the
stance hip ~20° short of that roll. :class:`HipKick` moves that one joint's solved goal further
(``Gains.hip_kick``, benchmarks/pushes.md), so the servo spins the upper body at its stall
torque. Once out of stall the upper body carries on by its own angular momentum: the servo,
whose goal it has just passed, brakes it only by its position error, and the torso overshoots
(0.4 rad of kick at 0.85 N·s: the robot comes back, the torso 46° from its plan). The **brake**
(``kick_tilt`` > 0) reads the estimated torso's tilt toward the fall ``θ`` and its rate ``θ̇``
(the gyro's, about ``z × u``, ``u`` the roll's direction at the trigger) and takes
``kick_brake × (θ + kick_lead θ̇ − kick_tilt)⁺`` off the kick (below zero: the goal pulled
back behind the solved one), so the servo's full torque stops the spin before the tilt
passes ``kick_tilt``. Every goal's change per tick stays within the joint's speed limit.
**The hold** (``kick_hold`` > 0): while the pushed stance sole stays rolled onto its edge
toward the fall (:meth:`HipKick.rolled`: its normal, from the IMU and the encoders, tilted
beyond ``kick_hold``) in the double support after the pushed single support (the catch's
landing has not taken the robot off that sole), the limbs are not brought back: their
return would give back angular momentum while the DCM is still at the sole's edge (the
robot hangs there, then tips out). Not in the pushed single support itself (there the
limbs follow the roll) nor once the pushed sole lifts; after a hold the kick ramps out at
the joints' speeds when the roll is over (not dropped in one tick). **By the state**
(``kick_hold_edge`` > 0): held while the DCM, from the kinematics alone (the IMU's rotation
and the encoders: :meth:`HipKick.sole_dcm`), is beyond that sole's outer edge along the push
(:meth:`HipKick.beyond`, the sole's rectangle from the model), released when it is back
inside.
"""

from __future__ import annotations

import math

import numpy as np

from ..model import Robot
from .gains import Gains


class HipKick:
    """The kick's state for one walk (:meth:`offsets`, called by
    :meth:`Stabilizer.joint_offsets <wbc.balance.stabilizer.Stabilizer.joint_offsets>`)."""

    def __init__(self, robot: Robot) -> None:
        from .feedback import GyroFeedback

        self.robot = robot
        self._axes = GyroFeedback(robot, None, 0.0)  # (the joints' axes in the torso frame)
        #: the kicked joints: [joint index, sign, gain name, last goal (rad; None)], the stance
        #: hip roll first; empty: no kick
        self.joints: list[list] = []
        self.stance = ""  # the stance sole it kicks
        self.u = np.zeros(2)  # the roll's horizontal direction at the trigger (world)
        self.brake = 0.0  # rad: the brake's share of the last goal (a diagnostic)
        self.held = False  # the limbs' goals not brought back this tick (kick_hold)
        self.was_held = False  # held since the trigger: the kick ramps out after its roll
        self.holding = False  # the hold applied this tick (held, in the double support after)
        self.tilted = 0.0  # s: how long the sole has read rolled without a break (kick_hold_for)
        #: rad: the swing hip roll that brings that leg's CoM under the other hip (the
        #: ``counter_under`` cap on ``counter_leg``; π/2: never, within the leg's length)
        self.under = under_angle(robot)
        self._rel: np.ndarray | None = None
        self._vel = np.zeros(3)

    def _start(
        self,
        joints: np.ndarray,
        g: Gains,
        h: np.ndarray,
        m: float,
        stance: str,
        rotation: np.ndarray,
    ) -> None:
        """The trigger's first tick: the joints kicked (the stance hip roll first: a robot
        with one) and their signs."""
        side, other = ("left", "right") if stance == "l_sole" else ("right", "left")
        roles = self.robot.roles
        name = roles.joint(side, "hip_roll")
        v = rotation.T @ np.array([-h[1], h[0], 0.0]) / m  # the roll's axis (torso frame)
        axes = self._axes.axes(joints) @ v
        # with the sole held, turning the stance hip by dθ turns the torso by −a dθ; turning a
        # free limb's joint turns the limb by +a dθ (its spin toward the fall, the same way)
        picks = [(name, -1.0, "hip_kick"), (roles.get(other, "hip_roll"), 1.0, "counter_leg"),
                 (roles.get(other, "shoulder_roll"), 1.0, "counter_arm")]  # fmt: skip
        self.joints = []
        for n, s, gain in picks:
            if n is not None and (gain == "hip_kick" or getattr(g, gain) > 0):
                k = self.robot.joint_index(n)
                self.joints.append([k, s * float(np.sign(axes[k])), gain, None])
        self.stance, self.u = stance, np.array([h[0], h[1]]) / m
        self.held = self.was_held = False
        self.tilted = 0.0
        self._rel = None  # (sole_dcm: the CoM from the kicked sole, last tick)

    def debounced(self, rolled: bool, dt: float, after: float) -> bool:
        """``rolled`` read without a break for ``after`` s or more (``kick_hold_for``: a
        tilt read for one tick at a support switch does not hold the limbs; 0: at once)."""
        self.tilted = self.tilted + dt if rolled else 0.0
        return rolled and self.tilted >= after - 1e-9

    def offsets(
        self,
        joints: np.ndarray,
        d: np.ndarray | None,
        gains: Gains,
        h: np.ndarray,
        pushed: bool,
        active: bool,
        stance: str,
        rotation: np.ndarray,
        rate: np.ndarray,
        dt: float,
    ) -> np.ndarray | None:
        """``d`` with the kick added (``d`` None: no other offset): ``h`` the hip-strategy
        roll (2, world), ``pushed`` the push trigger fired in this single support, ``active``
        its roll not yet back to 0, ``stance`` the stance sole ("" in double support),
        ``rotation``, ``rate`` the estimated torso rotation (world) and gyro rate (torso
        frame). From the trigger until the roll is back to 0, the stance hip roll's goal is
        moved by ``hip_kick × min(|h| / max_hip, 1)`` toward the roll (its sign from the
        joint's axis ``a`` at the trigger: with the sole held, turning it by dθ turns the
        torso by ``−a dθ``) less the brake (module docstring); the other leg's hip roll and
        that side's shoulder roll by ``counter_leg``, ``counter_arm`` × the same share, their
        limbs spun toward the fall; each goal's change per tick within its joint's speed
        limit (``Robot.v_max``); once the kicked leg lifts, the kick ramps out at it. While
        :attr:`held` (``kick_hold``: the pushed sole still on its edge) in the double support
        (``stance`` "") the limbs' goals do not move back against their spin (the stance
        hip's goal keeps its brake); after a hold, the kick ramps out once the roll is over."""
        g = gains
        m = math.hypot(h[0], h[1])
        if m > 0 and stance and pushed:
            name = self.robot.roles.get("left" if stance == "l_sole" else "right", "hip_roll")
            if name is None:  # (a robot without a hip roll: no kick)
                return d
            if not self.joints or self.robot.joint_index(name) != self.joints[0][0]:
                self._start(joints, g, h, m, stance, rotation)
        if not self.joints or (not active and not self.was_held):  # (no push, or over)
            self.joints = []
            return d
        d = np.zeros(len(joints)) if d is None else d
        # its leg swings, or the roll is over after a hold: the kick ramped out at the servos'
        # speed (a held limb's goal is not dropped back in one tick)
        lifted = (bool(stance) and stance != self.stance) or not active
        share = 0.0 if lifted else min(m / max(g.max_hip, 1e-9), 1.0)
        self.brake = 0.0 if lifted else self._brake(g, rotation, rate)
        # (held only in the double support after the pushed single support: the catch's
        # landing did not take the robot off its rolled sole)
        hold = self.holding = self.held and not lifted and not stance
        self.was_held = self.was_held or hold
        over = lifted
        for j in self.joints:
            k, sign, gain, last = j
            solved = joints[k] + d[k]
            size = getattr(g, gain)
            if gain == "counter_leg" and g.counter_under > 0:  # (capped: the CoM under the hip)
                size = min(size, g.counter_under * self.under)
            amount = size * share - (self.brake if gain == "hip_kick" else 0.0)
            want = solved + sign * amount
            last = solved if last is None else last
            step = float(self.robot.v_max[k]) * dt  # (never a goal above the servo's speed)
            if hold and gain != "hip_kick" and sign * (want - last) < 0:
                want = last  # (kick_hold: a limb not brought back while the sole is rolled)
            j[3] = min(max(want, last - step), last + step)
            d[k] = j[3] - joints[k]
            over = over and j[3] == solved
        if over:
            self.joints = []  # (over)
        return d

    def rolled(self, estimator, present: np.ndarray, joints: np.ndarray, tilt: float) -> bool:
        """The kicked stance sole rolled onto its edge toward the fall: its normal, where the
        last estimate's rotation and the ``present`` joints (NaN: ``joints``) turn it,
        tilted along the roll's direction by more than ``tilt`` rad (``kick_hold``: the
        limbs are not brought back while it is, :attr:`held`; False without a kick)."""
        if not self.joints or estimator.last is None or not self.stance:
            return False
        from .estimator import SOLE_FRAMES

        n = estimator.sole_normals(present, joints)[SOLE_FRAMES.index(self.stance)]
        return float(n[0] * self.u[0] + n[1] * self.u[1]) > math.sin(tilt)

    def sole_dcm(self, estimator, present: np.ndarray, joints: np.ndarray, dt: float):
        """(the DCM, the kicked sole's placement), world, from the kinematics alone: the last
        estimate's rotation (the IMU's) and the ``present`` joints (NaN: ``joints``), the
        CoM's velocity relative to that sole differenced over the ticks (low-passed, 20 ms):
        not the estimate's anchored base, which a catch's sole still in the air at its
        planned landing throws off (``kick_hold_edge``). None without a kick or estimate."""
        if not self.joints or estimator.last is None or not self.stance:
            return None
        com, sole = estimator.com_and_placement(self.stance, present, joints)
        rel = com - sole.translation
        if self._rel is None:
            self._vel = np.zeros(3)
        else:
            a = dt / (dt + 0.02)
            self._vel = self._vel + a * ((rel - self._rel) / max(dt, 1e-9) - self._vel)
        self._rel = rel
        return com + self._vel / estimator.omega0, sole

    def beyond(self, dcm: np.ndarray, sole, share: float) -> bool:
        """The measured DCM ``dcm`` (world) beyond the kicked stance sole's outer edge along
        the roll's direction ``u``: its distance from the sole's centre (``sole``: the sole's
        placement, ``pin.SE3``) along ``u`` above ``share`` × the sole rectangle's half extent
        along ``u`` (:attr:`wbc.model.Robot.foot_size`; ``kick_hold_edge``: the limbs held
        while it is, released when it comes back inside; False without a kick)."""
        if not self.joints or not self.stance:
            return False
        u0, u1 = float(self.u[0]), float(self.u[1])
        r = sole.rotation
        length, width = self.robot.foot_size
        reach = 0.5 * length * abs(r[0, 0] * u0 + r[1, 0] * u1)
        reach += 0.5 * width * abs(r[0, 1] * u0 + r[1, 1] * u1)
        c = sole.translation
        return float((dcm[0] - c[0]) * u0 + (dcm[1] - c[1]) * u1) > share * reach

    def _brake(self, g: Gains, rotation: np.ndarray, rate: np.ndarray) -> float:
        """rad taken off the kick: ``kick_brake × (θ + kick_lead θ̇ − kick_tilt)⁺`` (0 with
        ``kick_tilt`` 0): ``θ`` the torso's top tilted along the roll's direction ``u``,
        ``θ̇`` the world-frame gyro rate about ``z × u`` (positive: the top toward ``u``)."""
        if g.kick_tilt <= 0:
            return 0.0
        u0, u1 = float(self.u[0]), float(self.u[1])
        top = rotation[:, 2]
        theta = math.asin(min(max(top[0] * u0 + top[1] * u1, -1.0), 1.0))
        w = rotation @ rate
        theta_dot = -u1 * float(w[0]) + u0 * float(w[1])
        return g.kick_brake * max(theta + g.kick_lead * theta_dot - g.kick_tilt, 0.0)


def under_angle(robot: Robot) -> float:
    """rad: the hip roll that swings one leg's CoM (the hip roll's subtree, the stand pose)
    across the hips' spacing ``w``: ``asin(min(w / l, 1))``, ``l`` the CoM's distance from
    its hip roll's axis point (π/2: a leg too short to reach; 0: no hip rolls)."""
    import pinocchio as pin

    names = [robot.roles.get(side, "hip_roll") for side in ("left", "right")]
    if None in names:
        return 0.0
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, robot.configuration(robot.stand_pose))
    ids = [model.getJointId(n) for n in names]
    w = float(np.linalg.norm(data.oMi[ids[0]].translation - data.oMi[ids[1]].translation))
    sub = [i for i in range(1, model.njoints) if ids[0] in model.supports[i]]
    mass = sum(model.inertias[i].mass for i in sub)
    if mass <= 0:
        return 0.0
    com = sum(model.inertias[i].mass * data.oMi[i].act(model.inertias[i].lever) for i in sub)
    lever = float(np.linalg.norm(com / mass - data.oMi[ids[0]].translation))
    return math.asin(min(w / lever, 1.0)) if lever > 0 else math.pi / 2
