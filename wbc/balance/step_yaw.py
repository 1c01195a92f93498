"""The heading corrected by the footsteps (``Gains.step_yaw``, issue 30).

A plant whose hip yaw servos follow late (soft, or with latency) under-turns every step of
a turning walk: each landing sole is a few degrees short of its planned yaw, the next one
is placed from it, and the whole robot's heading falls behind the plan step after step
(``turn_wb``, benchmarks/physics.md: the soles 20–27° behind after 4 s). The torso term can
only twist the torso against the stance sole, up to the clip it shares with the tilt, and
nothing turns the soles back: the controller places the swing sole relative to *its*
stance sole, which it holds where the plan put it.

Here the footsteps take the heading error the measurement shows. At each lift-off, once,
the stance sole's heading is measured (the state estimate's torso rotation and the
encoders' kinematics from the torso to the sole) and compared with where the controller
holds it: the robot stands turned by that ``δ`` about the stance sole against the
controller's model, so a swing sole asked for the rotation ``R`` lands near ``Rz(δ) R``.
Beyond a dead band (``step_yaw_band``: small errors stay the torso term's), the swing
target's rotation turns toward ``Rz(−a) R``, ``a`` → ``k δ`` (``k``: ``step_yaw``), so the
sole lands nearer the plan's yaw and the next steps are placed from it. Only the sole's
rotation: its position stays the plan's, where the walk's CoM reference expects it.
``a`` is clipped to ``max_step_yaw``, moves at most :data:`RATE` rad/s, and is cut (halved,
else 0) where the turned sole would come within :data:`CLEARANCE` of the stance sole (the
footstep plans' no-crossing; the controller's joint limits and speed bounds stay hard).
At the touch-down the landed sole keeps the yaw the controller landed it at (``off``: its
contact targets turned so, ``contacts_move``, until it lifts; the torso target turned with
the stance sole's): else the double support turns it back and the correction is lost.
``step_yaw_turn`` limits it to a turning walk's steps; ``step_yaw_cap`` keeps the swing's
angle within that many times the step's planned turn of the stance sole's kept yaw
(:meth:`StepYaw.plan`: the walk's closing step lands parallel to the stance sole).
Feedback only: no model of the servos. Measured (issue 30, benchmarks/physics.md, i30p's
tenth and twelfth rounds; no feed-forward, plant-randomised): ``step_yaw`` 1, band 0.15
rad keeps the two soft ``turn_wb`` plants the torso term could not and brings the nominal
turn 19.2 → 15.3°, but loses five other soft ``turn_wb`` plants and, without
``step_yaw_turn``, nine ``walk10_wb`` ones; ``step_yaw_cap`` does not keep those: off.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import polygon_distance, rot_z, wrap_angle, yaw_of
from ..walking.geometry import Foot

#: rad/s: the largest rate of the swing target's yaw correction
RATE = 2.0
#: m: the gap the turned swing sole keeps from the stance sole (on the floor plane; the
#: footstep plans' ``min_clearance``), or the plan's own gap when that is less
CLEARANCE = 0.005


def stance_heading_error(
    robot, joints: np.ndarray, R_est: np.ndarray, stance: str, planned: np.ndarray
) -> float:
    """rad: the stance sole's measured heading (the estimated torso's rotation and the
    encoders' kinematics from the torso to it; ``joints`` in model order) less its planned
    one (``planned``, the rotation the controller holds it at), wrapped to (−π, π]."""
    q = np.zeros(robot.model.nq)
    q[6] = 1.0
    q[7:] = joints
    M = robot.placements_in(q, "torso", [stance])[0]
    return wrap_angle(yaw_of(R_est @ M.rotation) - yaw_of(planned))


def ramp(
    applied: float,
    want: float,
    share: float,
    limit: float,
    dt: float,
    window: tuple[float, float] = (-math.inf, math.inf),
) -> float:
    """The swing's next angle (rad): toward ``clip(share · want, ±limit)``, within
    ``window`` (lowest, highest), by at most :data:`RATE` · ``dt``."""
    goal = min(max(share * want, -limit, window[0]), limit, window[1])
    step = RATE * dt
    return applied + min(max(goal - applied, -step), step)


class StepYaw:
    """The footsteps' heading correction along one walk (module docstring): the swing's
    angle and each landed sole's ``off`` (the yaw the controller landed it at less the
    plan's, kept on its contact target while it is down, so the controller's double support
    does not turn it back; the torso target turned with the stance sole's)."""

    def __init__(self, robot) -> None:
        self.robot = robot
        self.foot: Foot | None = None  # (the robot's, when first needed: _clear)
        self.angle = 0.0  # rad: the swing sole's correction now
        self.want = 0.0  # rad: the stance sole's heading error at the lift-off (beyond band)
        self.off = {"l_sole": 0.0, "r_sole": 0.0}  # rad: the landed soles'
        self._swing = ""  # the swing sole of the last tick ("" in double support)
        self._turn = (0.0, 0.0)  # (t, the reference's heading) at the last lift-off
        #: rad per reference tick: the planned turn of the step under way (its swing sole's
        #: landing yaw less its stance sole's; 0 in double support), None: unknown (:meth:`plan`)
        self.turns: np.ndarray | None = None
        #: rad: the swing's angle's (lowest, highest) this step (Gains.step_yaw_cap)
        self.window = (-math.inf, math.inf)

    def plan(self, ref) -> None:
        """Read the walk's planned step turns (:attr:`turns`) from the reference ``ref``
        (a :class:`~wbc.walking.reference.WalkingReference`): for each single support, its
        swing sole's yaw at the touch-down less its stance sole's."""
        turns = np.zeros(ref.n)
        for a, b, _ in ref.phases():
            swing, stance = ref.swing_side(a), ref.stance_side(a)
            if swing is None or stance is None:
                continue
            end = min(b, ref.n - 1)
            turns[a:b] = wrap_angle(float(ref.sole(swing)[1][end] - ref.sole(stance)[1][end]))
        self.turns = turns

    def apply(self, targets, out, R_est: np.ndarray, joints: np.ndarray, q: np.ndarray,
              share: float, limit: float, band: float, turn: float, dt: float,
              cap: float = 0.0):  # fmt: skip
        """``out`` (the feedback's targets for ``targets``) with the correction. At a
        lift-off, once: the stance sole's measured heading (``R_est``, the encoders
        ``joints``) less the controller's (its planned placement turned by its ``off``),
        beyond ``band`` (``want``); in the single support the swing's angle moves toward
        ``share · want`` (clipped to ``limit``, :func:`ramp`), less where the turned sole
        would come near the stance sole (:meth:`_clear`); at the touch-down the landed sole
        keeps the yaw the controller (its configuration ``q``) landed it at. The soles'
        contact targets (``contacts_move``), the swing's and the torso's (by the stance
        sole's ``off``) turned about the vertical. With ``turn`` > 0 (rad/s) only on a step
        whose reference heading turned at least that fast since the last lift-off (a turning
        walk's; else ``want`` 0). With ``cap`` > 0 and the walk's :attr:`turns` known,
        the swing's angle stays within ``cap`` × the step's planned turn of the stance
        sole's kept yaw (``off``): a straight walk's steps and a walk's closing step land
        parallel to the stance sole as the controller holds it (:attr:`window`)."""
        single = targets.phase != "double"
        swing = targets.swing if single else ""
        if swing != self._swing:
            if self._swing and self.angle != 0.0:  # a touch-down: where the controller put
                # it (the angle asked may be beyond what its joints reached)
                landed = self.robot.frame_placement(q, self._swing).rotation
                d = yaw_of(targets.sole(self._swing).rotation) - yaw_of(landed)
                self.off[self._swing] = wrap_angle(d)
            if swing:  # a lift-off: the freed sole starts from the plan
                self.off[swing] = 0.0
                stance = targets.support
                planned = rot_z(-self.off[stance]) @ targets.support_placement.rotation
                w = stance_heading_error(self.robot, joints, R_est, stance, planned)
                self.want = math.copysign(max(abs(w) - band, 0.0), w)
                t0, yaw0 = self._turn  # (the reference's heading at the last lift-off)
                if turn > 0 and abs(targets.torso_yaw - yaw0) < turn * (targets.t - t0):
                    self.want = 0.0  # (not a turning step)
                self._turn = (targets.t, targets.torso_yaw)
                self.window = (-math.inf, math.inf)
                if cap > 0 and self.turns is not None and 0 <= targets.i < len(self.turns):
                    most, kept = cap * abs(float(self.turns[targets.i])), self.off[stance]
                    self.window = (kept - most, kept + most)
            self.angle = 0.0
            self._swing = swing
        if single:
            self.angle = self._clear(
                targets, ramp(self.angle, self.want, share, limit, dt, self.window)
            )
        off = self.off
        if self.angle == 0.0 and off["l_sole"] == 0.0 and off["r_sole"] == 0.0:
            return out
        changes: dict = {}
        for frame in ("l_sole", "r_sole"):
            if off[frame] != 0.0 and frame != swing:
                M = targets.sole(frame)
                changes[frame] = type(M)(rot_z(-off[frame]) @ M.rotation, M.translation)
        if changes:  # (the controller sets its contacts' targets to these every tick)
            changes["sole_pack"] = None
            changes["contacts_move"] = True
        if single and self.angle != 0.0:
            changes["swing_rotation"] = rot_z(-self.angle) @ targets.swing_rotation
        turn = off[targets.support]
        if turn != 0.0:
            changes["torso_rotation"] = rot_z(-turn) @ out.torso_rotation
        return out.replace(**changes)

    def _clear(self, targets, angle: float) -> float:
        """``angle``, or less (halved, up to three times, else 0) where the swing sole's
        target turned by it would come nearer the stance sole than :data:`CLEARANCE` (or
        than the plan's own gap, when that is less): the turned feet do not cross."""
        if angle == 0.0:
            return angle
        if self.foot is None:
            self.foot = Foot(*self.robot.foot_size)
        stance = targets.sole(targets.support)
        yaw_s = yaw_of(stance.rotation) - self.off[targets.support]
        rect_s = self.foot.rectangle(stance.translation[:2], yaw_s)
        xy = np.asarray(targets.swing_position[:2], dtype=float)
        yaw = yaw_of(targets.swing_rotation)
        need = min(CLEARANCE, polygon_distance(self.foot.rectangle(xy, yaw), rect_s))
        for _ in range(4):
            if polygon_distance(self.foot.rectangle(xy, yaw - angle), rect_s) >= need:
                return angle
            angle *= 0.5
        return 0.0
