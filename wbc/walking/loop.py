"""The control loop: drive a controller along a walking reference, tick by tick, and record.

Every solver family (QP stacks, the thesis's pseudo-inverse schemes, placo, pink) plugs in
through :class:`Controller`; the loop gives each the same targets, switches contacts at
support changes, times everything a user's tick costs (targets, kinematics, assembly, solve,
integration) with the same clock, and measures errors from forward kinematics of the returned
configurations, never from a solver's own residuals.
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, InfeasibleError, TrajectoryError, WbcError
from ..geometry import heading_free, sole_corners
from ..model import Kinematics, Robot
from ..recording import SUPPORT_DOUBLE, Recording, assess
from .clock import tick_clock
from .controller import Controller as Controller
from .controller import StackController as StackController
from .reference import WalkingReference
from .tick_targets import SOLES as SOLES  # (the targets' names, imported from here too)
from .tick_targets import TickTargets, sole_pack, support_roles
from .tick_targets import torso_target as torso_target

MODES = ("tick", "converge")
#: a sole in contact at the start (both in double support, the stance sole in single support)
#: more than START_CONTACT_TOL (m) from its contact placement must be brought there within
#: START_CONTACT_TICKS solved ticks in a row, else :class:`InfeasibleError` naming the frame
#: and the distance (a hard level not met: the robot started with a sole off the floor, out
#: of the legs' reach or speed); checked only until every contact is first met
START_CONTACT_TOL = 1e-3
START_CONTACT_TICKS = 25


@dataclass
class RunOptions:
    """How to run a reference: one QP per tick in real time, or converged per pose."""

    mode: str = "tick"
    tol: float = 1e-6
    max_iterations: int = 100
    stop_on_failure: bool = False
    record_task_errors: bool = True
    meta: dict[str, Any] = field(default_factory=dict)
    clock: str = "wall"  # the ticks' timings: "wall" or "cpu" (thread CPU time: wbc.walking.clock)


class Session:
    """A controller stepping along a reference one tick at a time (live use, and :func:`run`).

    ``tick(i)`` computes the configuration for reference tick ``i`` (ticks may be skipped, as
    a live loop running slower than the reference does); a solve raising a
    :class:`~wbc.WbcError` is a failure: the robot holds its last configuration.

    ``stabilizer`` (a :class:`wbc.balance.stabilizer.Stabilizer`, or None): closed loop, it
    reads the sensors and adjusts each tick's targets before the solve (its time is
    :attr:`feedback_time`, the solve's :attr:`solve_time`, the closed loop's whole with the
    step adjustment :attr:`loop_time`: :func:`wbc.balance.live.loop_share`);
    ``stabilizer.enabled = False`` (or None) is the open loop. ``stepping`` (a
    :class:`wbc.balance.stepping.StepAdjuster`, or None; closed loop only): each tick it may
    re-plan the footsteps from the stabilizer's last DCM estimate; the re-planned reference
    replaces :attr:`ref` (:meth:`set_reference`).
    ``hold`` (a :class:`wbc.balance.retime.PhaseHold`, or None; closed loop only): in
    :meth:`at_time`, a lift-off whose DCM is not ready waits — the last double-support tick
    is replayed and the rest of the walk runs later by :attr:`delay` seconds.
    """

    def __init__(
        self,
        controller: Controller,
        robot: Robot,
        ref: WalkingReference,
        q0: np.ndarray | None = None,
        options: RunOptions | None = None,
        stabilizer: Any = None,
        stepping: Any = None,
        hold: Any = None,
    ) -> None:
        self.options = options or RunOptions()
        self.stabilizer = stabilizer
        self.stepping = stepping
        self.hold = hold
        self.delay = 0.0  # s the walk runs behind its reference's clock (lift-offs held)
        self._last_time: float | None = None  # session time of the last at_time call
        self._elapsed: float | None = None  # s since that call, for the tick it calls
        #: s, the last tick's step adjustment: the step timing and lift-off hold checks of
        #: :meth:`at_time`, the re-plan check (and re-plan)
        self.stepping_time = 0.0
        self._clock_time = 0.0  # s, :meth:`at_time`'s checks before the tick it calls
        if self.options.mode not in MODES:
            raise ConfigurationError(f"mode must be one of {MODES}, got {self.options.mode!r}")
        self._now = tick_clock(self.options.clock)  # every timing of the session
        self.controller, self.robot, self.ref = controller, robot, ref
        self.q = (
            start_configuration(robot, ref) if q0 is None else robot.check_configuration(q0).copy()
        )
        self.support, self.swing = support_roles(ref)
        # the targets of every tick, built once (not part of any controller's tick time)
        self._soles: list[tuple[pin.SE3, pin.SE3]] = []
        self._swing: list[tuple[np.ndarray, np.ndarray]] = []
        self._packs: list[tuple] = []  # (left, right, sole_pack) per tick
        self._sole_targets(0)
        start = robot.frame_placement(self.q, "torso").rotation
        pitch_roll = heading_free(start)
        self._torso = list(ref.torso_rotations(pitch_roll))
        controller.dt = ref.dt
        controller.start(robot, self.q, ref)
        self._previous: tuple[str, str, str] | None = None
        #: reference ticks from the solve before the last one to it (1 before two): a loop
        #: slower than the reference plays every ``gap``-th tick, the idle part prepares it
        self._gap = 1
        self.prepare_time = 0.0
        self.warm_time = 0.0
        if self.options.mode == "tick":
            controller.rehearse(self.q, self.targets(0), ref.dt)
            self._prepare(0)  # (the first tick's switch: its contacts anchored afresh)
        self._last_index: int | None = None  # reference tick of the last solve
        self.failed = False
        self.failure: WbcError | None = None  # why the last tick failed
        self.iterations = 0
        self.solve_time = 0.0
        self.feedback_time = 0.0
        self._landing = 0  # ticks solved with a start contact off its placement (-1: met)

    def _sole_targets(self, first: int) -> None:
        """Both soles' and the swing sole's targets of ticks ``first, …`` from :attr:`ref`."""
        ref = self.ref
        soles = [(ref.sole_placement(i, "left"), ref.sole_placement(i, "right"))
                 for i in range(first, ref.n)]  # fmt: skip
        swing = [
            (sole.translation.copy(), sole.rotation.copy())
            for i, (left, right) in enumerate(soles, start=first)
            for sole in [left if self.swing[i] == "l_sole" else right]
        ]
        self._soles[first:] = soles
        self._swing[first:] = swing
        self._packs[first:] = [(left, right, sole_pack(left, right)) for left, right in soles]

    def set_reference(self, ref: WalkingReference, first: int) -> None:
        """Follow ``ref`` from tick ``first`` on (a re-planned walk: the same time grid,
        support schedule and torso headings, other footsteps and CoM)."""
        if ref.n != self.ref.n or np.any(ref.support != self.ref.support):
            msg = "a re-planned reference must keep the time grid and support schedule"
            raise TrajectoryError(msg)
        self.ref = ref
        self._sole_targets(first)

    def targets(self, i: int) -> TickTargets:
        ref = self.ref
        phase = "double" if ref.support[i] == SUPPORT_DOUBLE else "single"
        left, right = self._soles[i]
        return TickTargets(
            i,
            float(ref.t[i]),
            phase,
            self.support[i],
            self.swing[i],
            ref.com[i],
            left,
            right,
            float(ref.torso_yaw[i]),
            self._torso[i],
            *self._swing[i],
            sole_pack=self._packs[i],
        )

    def tick(self, i: int) -> np.ndarray:
        """The configuration for reference tick ``i`` (timed in :attr:`solve_time`).

        The step's time is the reference time since the last solved tick: a caller that skips
        ticks (a live deployment at a lower rate than the reference) gets the velocity bounds
        of the whole interval, not of one reference tick.
        """
        stab = self.stabilizer
        self.stepping_time, self._clock_time = self._clock_time, 0.0
        if (
            self.stepping is not None
            and stab is not None
            and stab.enabled
            and stab.last is not None
        ):
            start = self._now()  # the last tick's DCM estimate: re-plan the steps?
            new = self.stepping.update(self.ref, i, stab.last.dcm)
            if new is not None:
                self.set_reference(new, i)
            self.stepping_time += self._now() - start
        targets = self.targets(i)
        gap = 1 if self._last_index is None else max(1, i - self._last_index)
        self._last_index, self._gap = i, gap
        key = (targets.phase, targets.support, targets.swing)
        changed = key != self._previous
        self._previous = key
        opts = self.options
        if stab is not None and stab.enabled:
            start, stepping = self._now(), self.stepping
            if stepping is not None:  # (back_anchor: the estimator's band this tick)
                targets = stepping.banded(targets)
            targets = stab.adjust(targets, self.ref.com_vel[i], self.q, self._step(stab, gap))
            if stepping is not None and stepping.lands and stab.last is not None:
                targets = stepping.land(targets, stab.last, self.q)  # the swing, measured
            self.feedback_time = self._now() - start
        start = self._now()
        self.failed, self.failure = False, None
        try:
            if opts.mode == "tick":
                self.q = self.controller.track(self.q, targets, gap * self.ref.dt, changed)
                self.iterations = 1
            else:
                self.q, self.iterations = self.controller.converge(
                    self.q, targets, opts.tol, opts.max_iterations, changed
                )
        except WbcError as exc:
            self.failed = True
            self.failure = exc
            if opts.stop_on_failure:
                raise
        self.solve_time = self._now() - start
        if self._landing >= 0:
            self._check_start_contacts(targets)
        return self.q

    def prepare_next(self) -> None:
        """The idle part after a tick (its configuration used: recorded, or sent to the
        servos): if the next reference tick starts a support phase, its switch is made now
        (:meth:`Controller.prepare_phase`: the contacts anchored on its reference soles), so
        that the tick itself does not pay it (a support phase's first tick, issue 34's
        tail); that tick checks the switch was the one it needs, else takes it back (a
        re-planned reference, a held lift-off, a skipped tick: the same answers as without);
        else the work of the next tick that needs no solve (:meth:`Controller.prepare_tick`:
        a landing's next share of the way), checked the same way. Its time is
        :attr:`prepare_time` (s; not in :attr:`solve_time`). Ticks mode only (the first
        tick's switch is made so before the loop, after the rehearsal). The next reference
        tick is the last one plus the last gap between solves (a live loop at 50 Hz on a
        100 Hz reference plays every other one: its switches were made in the tick, cold)."""
        i = self._last_index
        self.prepare_time = 0.0
        if i is not None and self.options.mode == "tick":
            self._prepare(i + self._gap)

    def warm_next(self) -> None:
        """The end of the idle part, just before the next tick's deadline (a paced loop):
        :meth:`Controller.warm` (the tick's code and arrays brought back into the caches that
        the wait left cold; the same answers). Its time is :attr:`warm_time` (s). Ticks mode
        only."""
        self.warm_time = 0.0
        if self._last_index is not None and self.options.mode == "tick":
            start = self._now()
            self.controller.warm(self._gap * self.ref.dt)  # (the next tick's step, as last)
            self.warm_time = self._now() - start

    def _prepare(self, j: int) -> None:
        """:meth:`prepare_next` for reference tick ``j``."""
        if j >= self.ref.n:
            return
        phase = "double" if self.ref.support[j] == SUPPORT_DOUBLE else "single"
        switch = (phase, self.support[j], self.swing[j]) != self._previous
        start = self._now()
        dt = self._gap * self.ref.dt  # (the step of that tick, as the tick computes it)
        try:
            if switch:
                self.controller.prepare_phase(self.q, self.targets(j), dt)
            else:
                self.controller.prepare_tick(self.q, self.targets(j), dt)
        except WbcError:
            pass  # (nothing made ahead: the tick raises it again, as a failed tick)
        self.prepare_time = self._now() - start

    def _check_start_contacts(self, targets: TickTargets) -> None:
        """Until every sole in contact first sits within :data:`START_CONTACT_TOL` of its
        contact placement: count the solved ticks; past :data:`START_CONTACT_TICKS`, raise
        :class:`InfeasibleError` naming the sole frame and its distance."""
        frames = ["l_sole", "r_sole"] if targets.phase == "double" else [targets.support]
        off = []
        for frame in frames:
            d = (
                self.robot.frame_placement(self.q, frame).translation
                - targets.sole(frame).translation
            )
            if float(np.linalg.norm(d)) > START_CONTACT_TOL:
                off.append((frame, d))
        if not off:
            self._landing = -1
            return
        self._landing += 1
        if self._landing > START_CONTACT_TICKS:
            names = ", ".join(
                f"{frame} ({np.linalg.norm(d) * 1e3:.1f} mm from its contact placement, "
                f"{d[2] * 1e3:+.1f} mm in height)"
                for frame, d in off
            )
            raise InfeasibleError(
                f"{self.controller.name}: the contact(s) {names} not brought to the floor "
                f"within {START_CONTACT_TICKS} ticks of the start: the hard contact level "
                "cannot be met (start the robot with its soles on the floor, within the legs' "
                "reach)"
            )

    @property
    def index(self) -> int | None:
        """The reference tick of the last solve (None before the first)."""
        return self._last_index

    def at_time(self, t: float) -> np.ndarray | None:
        """The configuration for time ``t`` (s) from the start, None past the end (the
        reference's time ``t − delay``: :attr:`delay` grows while ``hold`` holds a lift-off,
        and changes with the clock's rate: the step timing's, the stabilizer's ``clock``)."""
        ref = self.ref
        last, stab = self._last_index, self.stabilizer
        closed = last is not None and stab is not None and stab.enabled and stab.last is not None
        clock = 0.0  # s in the step timing and hold checks (stepping_time)
        hurries = self.stepping is not None and self.stepping.hurries  # (else its rate is 1)
        slow = getattr(stab, "clock", 1.0) if closed else 1.0  # the stabilizer's (lag_clock)
        if closed and self._last_time is not None and (hurries or slow != 1.0):
            start = self._now()  # the step timing's rate while it asks one, else the clock's
            rate = self.stepping.rate(ref, last, stab.last.dcm) if hurries else 1.0
            self.delay -= ((slow if rate == 1.0 else rate) - 1.0) * (t - self._last_time)
            clock = self._now() - start
        s = t - self.delay
        if s > ref.t[-1] - ref.t[0] + 1e-9:
            return None
        i = ref.index_at(ref.t[0] + s)
        if self.hold is not None and closed and i > last and self._last_time is not None:
            start = self._now()
            if self.hold.wait(ref, last, i, stab.last.dcm, t - self._last_time):
                self.delay = t - float(ref.t[last] - ref.t[0])
                i = last
            clock += self._now() - start
        self._elapsed = None if self._last_time is None else t - self._last_time
        self._last_time = t
        self._clock_time = clock
        return self.tick(i)

    def _step(self, stab: Any, gap: int) -> float:
        """The stabilizer's step (s): the reference's time since the last solved tick, or with
        ``Gains.real_step`` the real time since the last :meth:`at_time` where the two differ
        by more than half a reference tick (the walk's clock skipped reference ticks: the step
        timing's rate; a paced loop's jitter keeps the reference's own number)."""
        dt = gap * self.ref.dt
        real, self._elapsed = self._elapsed, None
        if real is None or stab.gains.real_step <= 0:
            return dt
        return real if real > 0 and abs(real - dt) > 0.5 * self.ref.dt else dt

    @property
    def loop_time(self) -> float:
        """s, the last tick's closed loop: step adjustment (:attr:`stepping_time`), sensor
        reads, estimator and feedback (:attr:`feedback_time`)."""
        return self.feedback_time + self.stepping_time


def run(
    controller: Controller,
    robot: Robot,
    ref: WalkingReference,
    q0: np.ndarray | None = None,
    options: RunOptions | None = None,
    on_tick: Callable[[int, np.ndarray, TickTargets], None] | None = None,
) -> Recording:
    """Drive ``controller`` along ``ref`` and return the recording of the run.

    ``q0`` defaults to Walk Ready placed so that its soles sit where the reference starts.
    A tick whose solve raises a :class:`~wbc.WbcError` is counted as a failure: the robot holds
    its last configuration (or the run stops with ``stop_on_failure``).
    """
    ticks = run_stepwise(controller, robot, ref, q0, options, on_tick)
    while True:
        try:
            next(ticks)
        except StopIteration as end:
            return end.value


def run_stepwise(
    controller: Controller,
    robot: Robot,
    ref: WalkingReference,
    q0: np.ndarray | None = None,
    options: RunOptions | None = None,
    on_tick: Callable[[int, np.ndarray, TickTargets], None] | None = None,
) -> Generator[int, None, Recording]:
    """:func:`run` one tick at a time: a generator that yields each tick's index once the tick
    is done and recorded, and returns the recording (``StopIteration.value``). Several
    controllers' runs can so be interleaved in blocks of ticks (benchmarks/qp_tick.py: the
    machine's noise hits them alike), each doing exactly what :func:`run` does."""
    session = Session(controller, robot, ref, q0, options)
    options = session.options
    kin = Kinematics(robot, session.q)
    n, dt = ref.n, ref.dt
    l_id, r_id = robot.frame_id("l_sole"), robot.frame_id("r_sole")
    Q = np.zeros((n, robot.nq))
    com = np.zeros((n, 3))
    soles = {"l_sole": np.zeros((n, 7)), "r_sole": np.zeros((n, 7))}
    lowest = {"l_sole": np.zeros(n), "r_sole": np.zeros(n)}  # lowest sole corner height
    corners = sole_corners(ref.foot.length, ref.foot.width)
    solve_time = np.zeros(n)
    iterations = np.zeros(n, dtype=int)
    failed = np.zeros(n, dtype=bool)
    hard_failed = np.zeros(n, dtype=bool)  # a hard level could not be met (InfeasibleError)
    first_failure = ""
    errors: dict[str, np.ndarray] = {}
    for i in range(n):
        q = session.tick(i)
        failed[i], iterations[i], solve_time[i] = (
            session.failed,
            session.iterations,
            session.solve_time,
        )
        if session.failure is not None:
            hard_failed[i] = isinstance(session.failure, InfeasibleError)
            first_failure = first_failure or f"tick {i}: {session.failure}"
        Q[i] = q
        kin.update(q)
        com[i] = kin.com
        for name, fid in (("l_sole", l_id), ("r_sole", r_id)):
            soles[name][i] = pin.SE3ToXYZQUAT(kin.placement(fid))
            lowest[name][i] = kin.translation(fid)[2] + (corners @ kin.rotation(fid)[2]).min()
        if options.record_task_errors:
            for name, e in controller.task_errors().items():
                if name not in errors:
                    errors[name] = np.full((n, e.size), np.nan)
                if errors[name].shape[1] == e.size:
                    errors[name][i] = e
        if on_tick is not None:
            on_tick(i, q, session.targets(i))
        session.prepare_next()  # (the idle part: the next support switch, if any)
        yield i
    channels = _channels(robot, ref, Q, com, soles, lowest, session.swing)
    channels.update(solve_time=solve_time, iterations=iterations, failed=failed)
    for name, e in errors.items():
        channels[f"err/{name}"] = e
    meta = {
        "controller": controller.name,
        "family": controller.family,
        "trajectory": ref.name,
        "mode": options.mode,
        "robot": robot.name,
        "dt": dt,
        **options.meta,
    }
    rec = Recording(ref.t.copy(), Q, robot.joint_names, channels, meta)
    rec.meta["validity"] = assess(rec, int(hard_failed.sum()), first_failure)
    return rec


def start_configuration(robot: Robot, ref: WalkingReference) -> np.ndarray:
    """Walk Ready with the left sole placed where the reference's left sole starts."""
    q = robot.configuration("stand")
    return robot.place_on_ground(q, "l_sole", ref.sole_placement(0, "left"))


def _channels(
    robot: Robot,
    ref: WalkingReference,
    Q: np.ndarray,
    com: np.ndarray,
    soles: dict[str, np.ndarray],
    lowest: dict[str, np.ndarray],
    swing: list[str],
) -> dict[str, np.ndarray]:
    """Everything measured from forward kinematics, next to the references."""
    n = ref.n
    swing_idx = np.array([s == "l_sole" for s in swing])
    swing_pos = np.where(swing_idx[:, None], soles["l_sole"][:, :3], soles["r_sole"][:, :3])
    swing_ref = np.where(swing_idx[:, None], ref.l_sole, ref.r_sole)
    j = Q[:, 7:]
    limit_margin = np.minimum(j - robot.q_min, robot.q_max - j)
    com_margin = np.array([ref.signed_distance(i, com[i, :2]) for i in range(n)])
    # ZMP of the achieved CoM motion (cart-table model), from its finite-difference acceleration
    acc = np.gradient(np.gradient(com, ref.t, axis=0), ref.t, axis=0)
    zmp = com[:, :2] - com[:, 2:3] * acc[:, :2] / (ref.g + acc[:, 2:3])
    zmp_margin = np.array([ref.signed_distance(i, zmp[i]) for i in range(n)])
    return {
        "com": com,
        "com_ref": ref.com.copy(),
        "swing": swing_pos,
        "swing_ref": swing_ref,
        "swing_is_left": swing_idx,
        "support": ref.support.copy(),
        "l_sole": soles["l_sole"],
        "r_sole": soles["r_sole"],
        "l_sole_ref": ref.sole_xyzquat("left"),
        "r_sole_ref": ref.sole_xyzquat("right"),
        "com_margin": com_margin,
        "zmp": zmp,
        "zmp_margin": zmp_margin,
        "zmp_ref": ref.zmp.copy(),
        "limit_margin": limit_margin,
        # the swing sole's lowest corner (penetration below the ground is negative)
        "swing_lowest": np.where(swing_idx, lowest["l_sole"], lowest["r_sole"]),
    }
