"""A support switch without a joint-speed spike: the legs' posture targets and a landing
contact carried continuously across it (a stack file's ``[support_switch]`` table,
:class:`wbc.stack_tables.SupportSwitch`; benchmarks/balance.md, "Joint speed at a support switch").

A walk stack's weighted level holds an equilibrium between its tasks: in double support the
hard contacts hold the legs up to 0.4 rad from the posture's target, and that pull biases the
CoM by ~0.2 mm; in single support the swing leg's pull holds the swing sole 1-3 mm off its
target. A support switch changes which rows the pull meets (a leg freed, a sole anchored),
so the equilibrium jumps, and a task at gain 1 asks the jump back in one tick: the freed knee,
the landing knee or the arms (the cheapest joints) at the servo's full speed. Two changes make
every switch continuous, whatever the solver path (they write the tasks' target arrays):

* **The legs' posture targets are filtered**: each leg's target q*_leg follows its set point
  with the time constant τ (``posture_lag``), ``q*_leg += (1 − e^(−dt/τ)) (s − q*_leg)``, the
  set point ``s`` Walk Ready (the posture's start target) while the leg swings and the
  configuration it holds while its sole is in contact (a leg in contact is placed by the
  contact, the CoM and the torso; its pull there only biases them). A switch changes the set
  point, never the target: the error asked per tick changes by at most ``dt/τ`` of the set
  points' gap. With ``carry_contact_targets`` a leg in contact carries its target with its
  joints instead, ``q*_leg = q_leg + e^(−dt/τ) (q*_leg − q_leg)_last tick``: the offset it
  had at the touch-down decays and nothing resists the held legs' motion (the lag's pull,
  ~weight·τ·q̇, held the OP3's double-support CoM 0.6–0.7 mm low: the freed knee took it
  back at the servo's full speed at each lift-off).
* **A landing contact is settled**: at a touch-down the new contact is anchored where the sole
  is (the swing task's residual, 1-3 mm), not where the reference puts it, and walked there
  in ``landing_time`` (s; position and rotation the same share of the way each tick), instead
  of asked in one tick by the hard row. A miss beyond ``landing_band`` (m; a catch step's
  centimetres after a push) is asked at once as before, only the band's part settled. Targets
  whose contacts move (:attr:`~wbc.walking.loop.TickTargets.contacts_move`: a driven walk,
  whose walker anchors its landed soles itself) are left to their caller. With
  ``landing_fallback``, a tick whose hard level cannot be met while a landing is under way
  (a catch's miss beyond the band, more than the servos move in one tick: the solve failed
  and the controller held its last configuration through the whole double support, issue 30)
  is solved again with the landing re-anchored where the sole is (:meth:`SwitchHandover.solve`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numba import njit

from ..compiled.checks import entry
from ..exceptions import InfeasibleError, TaskError
from ..model import Robot
from ..roles import SOLE_FRAMES as SOLES
from ..stacks import ControlStack
from ..tasks import ComTask, ContactTask, FrameOrientationTask
from ..tasks.posture import PostureTask
from .sizing import SPEED_FRACTION


@njit(
    "void(float64[:], float64[:], float64[:], float64[:], float64[:], int64[:], int64[:], int64, "
    "float64, float64, boolean, boolean)",
    cache=True,
)
def follow_set_points(
    target, walk_ready, q, held, mid, joints, sides, swing, a, a_swing, carry, second
) -> None:
    """For each leg joint ``j = joints[k]`` of side ``sides[k]``: on the ``swing`` side (−1:
    none) ``target[j] += a_swing (walk_ready[j] − target[j])``, or with ``second`` through a
    middle stage, ``mid[k] += a_swing (walk_ready[j] − mid[k]); target[j] += a_swing (mid[k] −
    target[j])``
    (``mid[k]`` starts at the target at the lift-off; NaN: not swinging); on a side in contact,
    with ``carry``, ``target[j] = q_j + (1 − a) (target[j] − held[k])`` (the target moves with
    the joint, its offset decaying; ``held[k]``: the joint at the last call, NaN: none yet),
    else ``target[j] += a (q_j − target[j])`` (the target lags the joint). ``held[k] = q_j``
    after."""
    off = q.shape[0] - target.shape[0]
    for k in range(joints.shape[0]):
        j = joints[k]
        qj = q[off + j]
        if sides[k] == swing and second:
            if mid[k] != mid[k]:
                mid[k] = target[j]
            mid[k] += a_swing * (walk_ready[j] - mid[k])
            target[j] += a_swing * (mid[k] - target[j])
            held[k] = qj
            continue
        mid[k] = np.nan
        if sides[k] == swing:
            target[j] += a_swing * (walk_ready[j] - target[j])
        elif carry:
            before = held[k] if held[k] == held[k] else qj
            target[j] = qj + (1.0 - a) * (target[j] - before)
        else:
            target[j] += a * (qj - target[j])
        held[k] = qj


@njit(
    "float64(float64[:], float64[:], int64[:], int64[:], float64[:], int64)",
    cache=True,
)
def swing_gap(target, walk_ready, joints, sides, speed, side) -> float:
    """max over the leg joints ``j = joints[k]`` of side ``sides[k] == side`` of
    ``|walk_ready[j] − target[j]| / speed[k]`` (s at full speed; 0 with none; NaN if any is):
    :meth:`SwitchHandover.swing_share`'s gap, one compiled call (its numpy form took 25–30 µs
    at a running walk's lift-off, the tail of the ``walk`` stack's tick times)."""
    gap = 0.0
    for k in range(joints.shape[0]):
        if sides[k] != side:
            continue
        j = joints[k]
        share = abs(walk_ready[j] - target[j]) / speed[k]
        if share != share:
            return share
        if share > gap:
            gap = share
    return gap


def _toward(start: pin.SE3, end: pin.SE3, share: float) -> pin.SE3:
    """The placement ``share`` of the way from ``start`` to ``end``: the translation along
    the segment, the rotation along the geodesic (the same share of each)."""
    turn = pin.log3(start.rotation.T @ end.rotation)
    return pin.SE3(
        start.rotation @ pin.exp3(share * turn),
        start.translation + share * (end.translation - start.translation),
    )


class _Prepared(NamedTuple):
    """A tick's landing made ahead (:meth:`SwitchHandover.prepare`): what it was made from
    and what it made."""

    start: object  # the touch-down's q, or the landing under way (frame, anchor, elapsed)
    values: bytes | None  # the touch-down's q's bytes (None: a landing under way)
    left: object  # the tick's reference soles (identity-compared)
    right: object
    dt: float
    swing: str | None  # the swing sole's frame then (None: a landing under way)
    made: tuple  # (the anchor of the tick, the landing after it, the anchor packed)


class SwitchHandover:
    """The per-walk state of a stack's :class:`~wbc.stack_tables.SupportSwitch` (a
    :class:`~wbc.walking.controller.StackController` keeps one): :meth:`start` at the walk's start
    pose, then :meth:`update` after each tick's targets are set, before its solve."""

    def __init__(
        self,
        control: ControlStack,
        com: Sequence[ComTask] = (),
        torso: Sequence[FrameOrientationTask] = (),
    ) -> None:
        """``com``, ``torso``: the controller's CoM and torso tasks, whose targets a brace
        freezes (``brace``: :meth:`solve`)."""
        settings = control.support_switch
        if settings is None:
            raise TaskError(f"stack {control.name!r} has no [support_switch] table to hand over")
        self.lag = settings.posture_lag
        self.landing_time = settings.landing_time
        self.landing_band = settings.landing_band
        self.carry = settings.carry_contact_targets
        self.second = settings.second_order_swing
        self.fit_speed = settings.fit_speed
        self.fallback = settings.landing_fallback
        self.fallback_hold = settings.fallback_hold
        #: ticks the fallback solved again (:meth:`solve`), since :meth:`start`
        self.fallbacks = 0
        self.brace = settings.brace
        self.brace_speed = settings.brace_speed
        self._com_tasks, self._torso_tasks = tuple(com), tuple(torso)
        #: ticks braced (:meth:`_braced`: a landing's failed tick solved holding the pose),
        #: since :meth:`start`
        self.braced = 0
        #: the sole that landed at this double support's start (None in single support)
        self._landed: str | None = None
        robot: Robot = control.robot
        tasks = list(control.stack.tasks())
        #: the posture tasks: their targets a braced tick sets to the pose at q (:meth:`_braced`)
        self._posed = [t for t in tasks if isinstance(t, PostureTask)]
        #: the posture tasks whose targets follow the legs (:meth:`update`; with a lag only)
        self._postures = self._posed if self.lag else []
        self._contacts = [t for t in tasks if isinstance(t, ContactTask)]
        legs = [
            (frame, robot.joint_index(j))
            for side, frame in SOLES.items()
            if robot.has_frame(frame)
            for j in robot.roles.leg(side)
        ]
        #: the legs' joints and the sole frame each moves (index in :data:`SOLES`' frames)
        self._frames = tuple(SOLES.values())
        self._joints = np.array([j for _, j in legs], dtype=np.int64)
        self._sides = np.array([self._frames.index(f) for f, _ in legs], dtype=np.int64)
        self._a = (0.0, 0.0)  # (dt, 1 − e^(−dt/τ)) last used
        #: the swinging leg's share per tick, set at its lift-off (:meth:`swing_share`)
        self._a_swing = 0.0
        #: the legs' joints' no-load speeds (rad/s; the robot's [servo] table, its URDF limits)
        self._speed = np.asarray(robot.v_max, dtype=float)[self._joints]
        self._robot = robot
        self._set_points: list[np.ndarray] = []
        #: (posture target array, its Walk Ready copy, the legs' joints at the last update (NaN:
        #: none yet)): the tasks own the target arrays, never re-bound
        self._pairs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._side = {frame: k for k, frame in enumerate(self._frames)}
        self._follow = entry(follow_set_points)  # (its compiled entry: no dispatch per tick)
        self._gap = entry(swing_gap)
        self._landing: tuple[str, pin.SE3, float] | None = None
        self._swing: str | None = None
        #: a touch-down's landing made ahead (:meth:`prepare`): what it was made from, then
        #: the anchor to set and the landing after the tick
        self._prepared: _Prepared | None = None

    def start(self) -> None:
        """The posture targets as they are now (Walk Ready, set from the start pose) are the
        swing set points; no landing under way."""
        self._set_points = [p.target.copy() for p in self._postures]
        n = len(self._joints)
        self._pairs = [
            (p.target, w, np.full(n, np.nan), np.full(n, np.nan))
            for p, w in zip(self._postures, self._set_points, strict=True)
        ]
        self._landing, self._swing, self._prepared = None, None, None
        self._landed, self.fallbacks, self.braced = None, 0, 0

    def reset(self) -> None:
        """Back to the state of :meth:`start` (after a rehearsed tick)."""
        for task, set_point in zip(self._postures, self._set_points, strict=True):
            task.target[:] = set_point
        for _, _, held, mid in self._pairs:
            held[:] = np.nan
            mid[:] = np.nan
        self._landing, self._swing, self._prepared = None, None, None
        self._landed, self.fallbacks, self.braced = None, 0, 0

    def prepare(self, q: np.ndarray, targets, dt: float) -> None:
        """The landing's work of the tick of ``targets`` made ahead (a loop's idle part before
        it: :meth:`wbc.walking.controller.StackController.prepare_phase` and ``prepare_tick``): at a
        touch-down where the landing sole is at ``q`` (a forward kinematics pass) and the
        landing's first share of the way, on a landing under way its next share (an SE(3)
        log and exp); kept for that tick's :meth:`update`, which takes it if it is the tick
        prepared (the same inputs: at a touch-down the same ``q`` object, its values
        unchanged, on the way the same landing; the same reference soles, ``dt`` and swing
        sole: so the same answers) and else makes it itself. A touch-down tick then only
        sets the anchor (~14 µs less, 40–80 µs in a running walk: the tail of the ``walk``
        stack's tick times), and so do the landing's next ticks (~6 µs less, 10–15).
        Nothing else is made ahead (the posture targets follow ``q``: the tick's)."""
        self._prepared = None
        if targets.contacts_move or not self.landing_time or targets.phase == "single":
            return
        if self._swing is not None:  # (the last tick in single support: a touch-down next)
            anchor, landing = self._land(q, targets, dt)
            inputs: tuple = (q, q.tobytes())
        elif self._landing is not None:
            anchor, landing = self._step(self._landing, targets, dt)
            inputs = (self._landing, None)
        else:
            return
        packed = self._contacts[0].pack_target(anchor) if self._contacts else None
        made = (anchor, landing, packed)
        self._prepared = _Prepared(*inputs, targets.l_sole, targets.r_sole, dt, self._swing, made)

    def place_ahead(self) -> None:
        """The landing's anchor :meth:`prepare` made written into its contact now (the loop's
        idle part, after the support switch made ahead: the contact of the landing sole
        active in the tick's phase), so that the idle part's rehearsals of the tick
        (:func:`wbc.solvers.rehearsal.rehearse`: the switch's, the warm-up's) solve it with
        the tick's own contact target. The tick writes its anchor itself all the same
        (:meth:`update`: the same numbers if it is the tick prepared, else its own); a switch
        made ahead and taken back puts back the targets from before it; a contact of that
        sole not active in the tick's phase is anchored afresh when it becomes active."""
        prepared = self._prepared
        if prepared is None:
            return
        frame = prepared.swing if prepared.swing is not None else prepared.start[0]
        anchor, _, packed = prepared.made
        for task in self._contacts:
            if task.active and task.frame == frame:
                task.set_target(anchor, packed)

    def _land(self, q: np.ndarray, targets, dt: float) -> tuple:
        """A touch-down at ``q``: (the anchor of its tick, the landing after it)."""
        return self._step((self._swing, self._touch_down(q, targets), 0.0), targets, dt)

    def _step(self, landing: tuple, targets, dt: float) -> tuple:
        """One tick of ``landing`` (frame, anchor, elapsed): (the tick's anchor, the landing
        after it: None once at the reference sole)."""
        frame, anchor, elapsed = landing
        goal = targets.sole(frame)
        left = self.landing_time - elapsed
        if left <= dt:
            return goal, None
        anchor = _toward(anchor, goal, dt / left)
        return anchor, (frame, anchor, elapsed + dt)

    def _made_ahead(self, start, targets, dt: float) -> tuple | None:
        """What :meth:`prepare` made for this tick if made from its inputs (``start``: the
        touch-down's q, or the landing under way), else None."""
        made, self._prepared = self._prepared, None
        if made is None:
            return None
        start0, values, left, right, dt0, swing, out = made
        if (
            start is start0
            and targets.l_sole is left
            and targets.r_sole is right
            and dt == dt0
            and swing == self._swing
            and (values is None or start.tobytes() == values)
        ):
            return out
        return None

    def update(self, q: np.ndarray, targets, phase_changed: bool, dt: float) -> None:
        """Filter the legs' posture targets one step of ``dt`` and settle a landing contact,
        for the tick of ``targets`` (a :class:`~wbc.walking.loop.TickTargets`) at ``q``."""
        single = targets.phase == "single"
        if self._pairs:
            if self._a[0] != dt:
                self._a = (dt, 1.0 - math.exp(-dt / self.lag))
            swing = self._side[targets.swing] if single else -1
            a, joints, sides, follow = self._a[1], self._joints, self._sides, self._follow
            if single and self._swing != targets.swing:  # a lift-off: the freed leg's share
                self._a_swing = self.swing_share(swing, a, dt)
            for target, walk_ready, held, mid in self._pairs:
                follow(target, walk_ready, q, held, mid, joints, sides, swing, a,
                       self._a_swing, self.carry, self.second)  # fmt: skip
        if targets.contacts_move:  # the caller moves the contacts (a driven walk): not here
            self._landing = self._landed = None
        elif self.landing_time and not (single and self._landing is None):
            self._settle(q, targets, phase_changed, dt)
        self._swing = targets.swing if single else None
        self._prepared = None  # (made for this tick only)

    def _braced(self, solver, q: np.ndarray, frame: str, dt: float) -> np.ndarray | None:
        """A landing's tick whose solve failed, solved braced (``brace``, issue 30): the
        landed sole ``frame``'s contact anchored where the sole is at ``q`` (with
        ``brace_speed``, m/s, one step of ``brace_speed·dt`` from there toward its anchor),
        the other contacts where their soles are,
        the CoM, torso and posture targets where they are at ``q`` (the feedback's targets
        frozen): the pose held by a solve, as the failed tick held it by accident (the
        survivors of main's pushes stand on those held poses, benchmarks/pushes.md); the
        tasks' targets are put back after it (the next tick tries the landing again). None
        if that fails too."""
        robot = self._robot
        sole = robot.frame_placement(q, frame)
        anchor = sole
        if self.brace_speed > 0:
            goal = self.anchor_of(frame)
            gap = float(np.linalg.norm(goal.translation - sole.translation))
            share = 1.0 if gap <= self.brace_speed * dt else self.brace_speed * dt / gap
            anchor = _toward(sole, goal, share)
        contacts = [t for t in self._contacts if t.active]
        saved = [(t.target_position.copy(), t.target_rotation.copy()) for t in contacts]
        posed = (*self._com_tasks, *self._torso_tasks, *self._posed)
        held = [(t, t.target.copy()) for t in posed]
        for task in contacts:  # (the other sole's too: where it is at q)
            task.set_target(anchor if task.frame == frame else robot.frame_placement(q, task.frame))
        com = robot.com(q)
        for task in self._com_tasks:
            task.set_target(com)
        for task in self._torso_tasks:
            task.set_target(robot.frame_placement(q, task.frame).rotation)
        for task in self._posed:
            task.set_target(q)
        try:
            q_next = solver.step(q, dt)
            self.braced += 1
            return q_next
        except InfeasibleError:
            return None
        finally:
            for task, (position, rotation) in zip(contacts, saved, strict=True):
                task.target_position[:] = position
                task.target_rotation[:] = rotation
            for task, target in held:
                task.target[:] = target

    def anchor_of(self, frame: str) -> pin.SE3:
        """The active contact's anchor on ``frame`` (the landing's, this tick)."""
        task = next(t for t in self._contacts if t.active and t.frame == frame)
        return pin.SE3(task.target_rotation.copy(), task.target_position.copy())

    def swing_share(self, side: int, a: float, dt: float) -> float:
        """The share per tick ``a_s`` with which the leg of ``side`` (index in the sole frames),
        freed now, walks its posture targets to Walk Ready: the table's ``a`` (its
        ``posture_lag``), or less if that would ask a joint for more than
        :data:`~wbc.walking.sizing.SPEED_FRACTION` of its no-load speed ``v``: the first step
        ``a·gap`` in ``dt`` (the target's fastest; with ``second_order_swing`` the two lags'
        fastest, ~``a·gap/e`` per tick) within ``SPEED_FRACTION·v·dt``. The lag then is the
        time the freed joints need, at that share of their servos' speed, to absorb the pull
        toward the standing pose that lift-off releases (slower than the table, never faster).
        The table's ``fit_speed = false``: ``a`` as stated."""
        if not self.fit_speed:
            return a
        gap = 0.0
        for target, walk_ready, _, _ in self._pairs:
            gap = max(
                gap, self._gap(target, walk_ready, self._joints, self._sides, self._speed, side)
            )
        peak = math.e if self.second else 1.0
        room = peak * SPEED_FRACTION * dt
        return a if gap * a <= room else room / gap

    def _touch_down(self, q: np.ndarray, targets) -> pin.SE3:
        """Where the landing sole is, or, if it missed its reference placement by more than
        ``landing_band``, the point of the band on the way there (the miss beyond the band is
        asked at once, as a catch step needs)."""
        sole = self._robot.frame_placement(q, self._swing)
        goal = targets.sole(self._swing)
        miss = sole.translation - goal.translation
        distance = float(np.linalg.norm(miss))
        if distance <= self.landing_band:
            return sole
        return _toward(goal, sole, self.landing_band / distance)

    def _settle(self, q: np.ndarray, targets, phase_changed: bool, dt: float) -> None:
        """The landing contact's anchor: where the sole touched down (:meth:`_touch_down`),
        then each tick the share ``dt / (T − elapsed)`` of the way to the reference sole: there
        after ``T = landing_time``."""
        if targets.phase == "single":
            self._landing = self._landed = None
            return
        if phase_changed and self._swing is not None:  # a touch-down: anchor where it is
            frame = self._landed = self._swing
            made = self._made_ahead(q, targets, dt) or (*self._land(q, targets, dt), None)
        elif self._landing is None:
            return
        else:
            frame, landing = self._landing[0], self._landing
            made = self._made_ahead(landing, targets, dt) or (
                *self._step(landing, targets, dt),
                None,
            )
        anchor, self._landing, packed = made
        for task in self._contacts:
            if task.active and task.frame == frame:
                task.set_target(anchor, packed)  # (packed: checked ahead, copied)

    def solve(self, solver, q: np.ndarray, targets, dt: float) -> np.ndarray:
        """``solver.step(q, dt)`` (a :class:`~wbc.solvers.base.StackSolver`), after
        :meth:`update`. With ``landing_fallback``, where that raises
        :class:`~wbc.exceptions.InfeasibleError` in the double support of a landing (its miss
        beyond ``landing_band`` asked of the hard contact row in one tick, more than the
        servos move in it): the landing re-anchored where the sole is at ``q`` and walked
        from there to the reference sole in a new ``landing_time`` (this tick its first
        share), solved again; if that fails too, the anchor at the sole itself (the landed
        contact met as it stands). ``fallback_hold``: the anchor at the sole, held there
        through the double support (not walked to the reference). Each tick solved so counts
        in :attr:`fallbacks`; a tick neither solves raises the first error (the controller
        then holds its last configuration, as without). With ``brace`` (before the fallback),
        that tick is solved braced (:meth:`_braced`), counted in :attr:`braced`."""
        if not (self.fallback or self.brace) or targets.phase == "single" or not self._landed:
            return solver.step(q, dt)
        try:
            return solver.step(q, dt)
        except InfeasibleError as exc:
            frame, failure = self._landed, exc
        if self.brace:
            q_next = self._braced(solver, q, frame, dt)
            if q_next is not None:
                return q_next
        if not self.fallback:
            raise failure
        sole = self._robot.frame_placement(q, frame)
        shares = (0.0,) if self.fallback_hold else (dt / self.landing_time, 0.0)
        for share in shares:
            anchor = _toward(sole, targets.sole(frame), min(share, 1.0))
            self._landing = None if self.fallback_hold else (frame, anchor, dt if share else 0.0)
            for task in self._contacts:
                if task.active and task.frame == frame:
                    task.set_target(anchor)
            try:
                q_next = solver.step(q, dt)
            except InfeasibleError:
                continue
            self.fallbacks += 1
            return q_next
        raise failure
