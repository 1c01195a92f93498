"""The closed loop on any robot: a controller solved live inside the deployment's tick.

:func:`closed_loop` wires a walking :class:`~wbc.walking.loop.Session` (one solve per tick)
and a :class:`~wbc.balance.stabilizer.Stabilizer` (estimator + feedback on the targets) to a
:class:`~wbc.servos.playback.Deployment` on any :class:`~wbc.servos.bus.ServoBus`, reading
any :class:`~wbc.imu.Imu` (or none: encoders only). On a bus that reads no positions
(``can_read`` False: hobby PWM servos behind an SSC-32) the loop closes through the IMU and
the *commanded* joint positions (the controller's last solve, in place of the encoders: see
:mod:`wbc.balance.estimator`), said with one line. Per tick, inside the deployment's loop: the
previous tick's present positions (``Deployment.last_present``, read right after the
goals) and a fresh IMU sample → state estimate → adjusted targets → one solve → (optional
compliance feed-forward) → the deployment's clamping, rate limit and watchdog → the servos.

    from wbc.balance.live import closed_loop
    loop = closed_loop(my_bus, robot, controller, ref, imu=my_imu)
    result = loop.deployment.run()

(``docs/examples/closed_loop_own_robot.py``: a user's own simulator driving it.)
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numba
import numpy as np

from ..exceptions import ConfigurationError
from ..imu import Imu
from ..model import Robot
from ..servos.bus import ServoBus
from ..servos.config import DeployConfig
from ..servos.playback import Deployment
from ..servos.sources import CallableSource
from ..sim.actuator import HobbyServoParams, ServoParams
from ..sim.xm430 import XServoParams
from ..types import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from ..walking.gait import narrow_sway
from ..walking.loop import Controller, Session
from ..walking.reference import WalkingReference
from .fall import FallDetector, FallParams
from .goal_probe import GoalProbe, ProbeResult, probe_joints
from .margin import default_sized_gains
from .retime import HoldParams, PhaseHold
from .stabilizer import Gains, Stabilizer, default_gains
from .stance_lift import LiftedStabilizer, final_double_start, identified_soft
from .stepping import StepAdjuster, SteppingParams, can_step
from .stiff_twist import stiff_class

#: s: the longest single support whose sway the closed loop narrows. Measured (wqp-daqp,
#: nominal, benchmarks/pushes.md): on the 0.4 s single supports of ``fast_wb`` and
#: ``lateral_wb`` the narrowed sway costs distance (0.907 → 0.884, 0.902 → 0.877 of the plan)
#: and the transfer alone tips ``lateral_wb`` to 31.5°
NARROW_LONGEST = 0.3
#: s at rest before the walk: the IMU's start-up calibration (gyro bias, levelling; the second
#: half's mean rate). Issue 30: 0.3 s took the compliant body's settling (below the encoders'
#: steps) for ~0.01 rad/s of gyro bias, a false 3° tilt through the filter, and the feedback
#: tipped the robot by it (nominal turn_wb 3.35°, 2.76° at 1 s; benchmarks/physics.md)
CALIBRATE_S = 1.0
#: the servo laws a feed-forward model can be given as (``closed_loop(servo=...)``)
SERVO_LAWS = (ServoParams, HobbyServoParams, XServoParams)


@numba.njit(cache=True)
def _envelope(j: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """``lo``, ``hi`` (in place): the running minimum and maximum of ``j`` (NaN not counted)."""
    for k in range(j.size):
        v = j[k]
        if v < lo[k]:
            lo[k] = v
        if v > hi[k]:
            hi[k] = v


class SessionSource(CallableSource):
    """A target source solving ``session`` live: target of time t = the session's solve for
    the reference tick at t (None past the end). Keeps the largest excursion of its targets
    beyond the joint limits (rad, before the deployment's clamp) in :attr:`limit_excess`."""

    def __init__(self, session: Session) -> None:
        self.session = session
        robot = session.robot
        #: the targets' running minimum and maximum per joint (:attr:`limit_excess`)
        self._low = np.full(robot.n_joints, np.inf)
        self._high = np.full(robot.n_joints, -np.inf)
        #: per walking tick (the start-up calibration's ticks at rest not counted), s: the
        #: closed loop's own work (step adjustment, estimator, feedback: :func:`loop_share`),
        #: the sensor reads it did (the drivers'), the controller's tick (solve + integration)
        self.feedback_time: list[float] = []
        self.read_time: list[float] = []
        self.solve_time: list[float] = []
        self.start_offset = 0.0  # s the walk starts late: the start-up calibration at rest
        #: per walking tick: the walk's time (s since its start) and the reference time it
        #: played (its clock: held lift-offs, the stabilizer's ``clock``); see :meth:`played`
        self._played: list[tuple[float, float]] = []
        self._slowed = False  # the stabilizer's clock (Gains.lag_clock) left 1 at some tick
        self._last: tuple[float, np.ndarray] | None = None  # (t, joints): Gains.goal_lead
        #: walking ticks whose solve failed (the last configuration held: a failed hard
        #: level) and whose hard level the solver relaxed (its least-squares best kept)
        self.failed_ticks = 0
        self.relaxed_ticks = 0

        self.rest_hook: Callable[[bool], None] | None = None  # called each tick: at rest?
        #: the start-up goal probe (``Gains.probe_step``; :mod:`wbc.balance.goal_probe`), the
        #: encoders it reads and what is told its fit after the rest
        self.probe: GoalProbe | None = None
        self.probe_present: Callable[[], np.ndarray | None] = lambda: None
        self.probe_done: Callable[[GoalProbe], None] = lambda probe: None

        def target(tick: int, t: float) -> np.ndarray | None:
            stab = session.stabilizer
            resting = stab is not None and stab.calibrating
            if resting:
                self.start_offset = t
            if self.rest_hook is not None:
                self.rest_hook(resting)
            probe = self.probe
            if probe is not None and resting:
                probe.sample(t, self.probe_present())
            elif probe is not None:
                self.probe = None
                self.probe_done(probe)
            g = stab.gains if stab is not None and stab.enabled and not resting else None
            lead = g.ref_lead if g is not None else 0.0  # (Gains.ref_lead: the plan ahead)
            q = session.at_time(t - self.start_offset + lead)
            if q is None:
                return None
            if not resting:
                self.failed_ticks += session.failed
                self.relaxed_ticks += session.controller.relaxed
                walk = t - self.start_offset
                self._played.append((walk, walk - session.delay))
                self._slowed |= stab is not None and stab.clock != 1.0
            j = q[7:].copy()
            if probe is not None and resting and (step := probe.offset(t)) is not None:
                j[probe.joints] = np.clip(j[probe.joints] + step, robot.q_min[probe.joints],
                                          robot.q_max[probe.joints])  # fmt: skip
            start = time.perf_counter()
            offsets = session.stabilizer.joint_offsets(j) if session.stabilizer else None
            if offsets is not None:  # joint-level feedback (counted with the feedback)
                j = np.clip(j + offsets, robot.q_min, robot.q_max)
            if g is not None and g.goal_lead > 0:  # the goals led by the joints' velocity
                j = self._led(j, t, g.goal_lead, g.goal_lead_stance > 0)
            extra = time.perf_counter() - start if offsets is not None else 0.0
            _envelope(j, self._low, self._high)  # (the excess when read: limit_excess)
            if not resting:
                read = stab.read_time if stab is not None else 0.0
                self.feedback_time.append(session.loop_time - read + extra)
                self.read_time.append(read)
                self.solve_time.append(session.solve_time)
            return j

        super().__init__(target, session.q[7:].copy(), robot.joint_names)
        self.duration = float(session.ref.duration)

    def _led(self, j: np.ndarray, t: float, lead: float, stance: bool = False) -> np.ndarray:
        """``j`` led by ``lead`` s of its velocity since the last tick (``Gains.goal_lead``),
        within the joint limits (the first tick: ``j``); ``stance``: only the pitch joints
        of the legs on the floor in the tick's planned support (``goal_lead_stance``)."""
        last, self._last = self._last, (t, j.copy())
        if last is None or t <= last[0]:
            return j
        session = self.session
        robot = session.robot
        step = (lead / (t - last[0])) * (j - last[1])
        if stance:
            i = session.index
            support = int(session.ref.support[i]) if i is not None else SUPPORT_DOUBLE
            keep = np.zeros(robot.n_joints, dtype=bool)
            for side, code in (("left", SUPPORT_LEFT), ("right", SUPPORT_RIGHT)):
                if support in (SUPPORT_DOUBLE, code):
                    keep |= sagittal_scale(robot, 0.0, (side,)) == 0.0
            step = np.where(keep, step, 0.0)
        return np.clip(j + step, robot.q_min, robot.q_max)

    @property
    def limit_excess(self) -> float:
        """rad: the targets' largest excursion beyond a joint limit so far (0 if none): the
        per-tick maximum of ``max(q_min − j, j − q_max)`` over the joints, taken from the
        targets' running extremes per joint when read (the same number: a rounded
        difference keeps its operands' order)."""
        q_min, q_max = self.session.robot.q_min, self.session.robot.q_max  # (none yet: ±inf)
        return max(0.0, float(np.max(np.maximum(q_min - self._low, self._high - q_max))))

    def idle(self) -> None:
        """After a tick's goals are sent: the next support switch made now
        (:meth:`Session.prepare_next`), not in the next tick's solve."""
        self.session.prepare_next()

    def warm(self) -> None:
        """Just before the next tick's deadline: :meth:`Session.warm_next` (the tick's code
        and arrays back in the caches; nothing unless the solver's ``warm_ahead``)."""
        self.session.warm_next()

    def played(self) -> np.ndarray | None:
        """(2, n): the walk's time and the reference time it played per walking tick (s),
        what a physics record compares the run with (:attr:`wbc.sim.log.PlayResult.played`);
        None unless the stabilizer's clock slowed the walk (``Gains.lag_clock``): a run
        whose only delay is held lift-offs is compared at the wall time, as before (the
        lift-off hold's records unchanged; issue 30, i30p's eighth round)."""
        return np.array(self._played).T if self._slowed and self._played else None

    def solve_counts(self) -> dict[str, int]:
        """The walking ticks so far (``walking_ticks``), those whose solve failed (the last
        configuration held: ``failed_solves``) and those whose hard level the solver relaxed
        (``relaxed_solves``): what ``wbc sim`` and ``wbc deploy --live`` report."""
        return {"walking_ticks": len(self.solve_time), "failed_solves": self.failed_ticks,
                "relaxed_solves": self.relaxed_ticks}  # fmt: skip

    def solve_line(self) -> str:
        """One line of :meth:`solve_counts`: ``live solves: F of N walking ticks failed (the
        last pose held), R relaxed``."""
        c = self.solve_counts()
        return (f"live solves: {c['failed_solves']} of {c['walking_ticks']} walking ticks "
                f"failed (the last pose held), {c['relaxed_solves']} relaxed")  # fmt: skip

    def cost_share(self, skip: int = 0) -> float | None:
        """The closed loop's share of the tick (:func:`loop_share`) over the walking ticks
        so far, the first ``skip`` left out (None before any)."""
        if len(self.solve_time) <= skip:
            return None
        return loop_share(self.feedback_time[skip:], self.solve_time[skip:])


def loop_share(loop: Sequence[float] | np.ndarray, solve: Sequence[float] | np.ndarray) -> float:
    """The closed loop's share of a control tick (issue 30's target: ≤ 30 %), the one
    definition the physics benchmark and ``benchmarks/closed_loop_cost.py`` report: per
    walking tick, ``loop / (loop + solve)`` with ``loop`` the step adjustment (step timing,
    lift-off hold, re-plan check), the estimator and the feedback (fall detection, joint-level
    offsets included; the drivers' sensor reads not: a deployment's own I/O, as the servos'
    positions are) and ``solve`` the controller's tick (solve + integration); the median over
    the ticks."""
    fb, sv = np.asarray(loop, dtype=float), np.asarray(solve, dtype=float)
    return float(np.median(fb / np.maximum(fb + sv, 1e-12)))


def loop_rate(ref: WalkingReference) -> float:
    """The closed loop's deployment rate (Hz) on ``ref``: its tick's, at most 100 Hz."""
    return min(100.0, 1.0 / ref.dt)


@dataclass
class ClosedLoop:
    """What :func:`closed_loop` built: ``deployment.run()`` runs it."""

    deployment: Deployment
    session: Session
    source: SessionSource  # per-tick costs, limit excursions
    stabilizer: Stabilizer
    stepping: StepAdjuster | None = None  # its ``events``: the re-plans
    hold: PhaseHold | None = None  # its ``holds``, ``held``: the lift-offs held
    #: which servo model the feed-forward uses (servos.toml, the user's, or identified)
    servo_model: str = "servos.toml (nominal)"
    #: the identified stiffness / servos.toml's (``servo="identify"``, after the rest)
    stiffness_scale: float | None = None
    #: the start-up goal probe's fit (``Gains.probe_step``, after the rest; None: not run)
    goal_probe: ProbeResult | None = None


def closed_loop(
    bus: ServoBus,
    robot: Robot,
    controller: Controller,
    ref: WalkingReference,
    imu: Imu | None = None,
    gains: Gains | None = None,
    enabled: bool = True,
    compensate: float | None = None,
    correct: bool = False,
    config: DeployConfig | None = None,
    q0: np.ndarray | None = None,
    out: Callable[[str], None] = print,
    duration: float | None = None,
    stepping: SteppingParams | None = SteppingParams(),  # noqa: B008 (frozen)
    hold: HoldParams | None = HoldParams(),  # noqa: B008 (frozen)
    fall: FallParams | None = FallParams(),  # noqa: B008 (frozen)
    calibrate_s: float = CALIBRATE_S,
    servo: ServoParams | HobbyServoParams | XServoParams | str | None = None,
    step_on_commands: bool = False,
) -> ClosedLoop:
    """A deployment of ``controller`` along ``ref`` on ``bus``, closed through ``imu`` and
    the servos' present positions (``enabled=False``: the same run, open loop).

    The defaults are the measured best configuration (issue 30, benchmarks/physics.md):
    ``compensate`` None = :func:`wbc.balance.best_compensate` (×0.5 on AX-12A servos, ×1 on
    hobby PWM servos, 0 when open loop or on servos without a compliance model); ``gains``
    None = :func:`~wbc.balance.stabilizer.default_gains` for that ``compensate``, its torso
    term and hip strategy scaled to the servos' gain margin
    (:func:`wbc.balance.margin.torso_gains`; without the feed-forward ``joint_lag`` and
    ``k_d`` 0.03; gains given are used as they are); step
    adjustment on, the lift-off hold, fall detection and the start-up calibration on.
    ``compensate`` > 0 adds the servo compliance feed-forward (×gain) to the goals
    (:mod:`wbc.balance.compliance`; ``correct``: rescaled per joint from the encoders,
    :class:`~wbc.balance.compliance.EncoderCorrection`); ``config`` defaults to the
    reference's rate with ``read`` on if the bus can read (the estimator needs the encoders);
    a config without ``read`` is refused when the loop is closed. On a bus that reads nothing
    the closed loop runs on ``imu`` and the commanded joints (module docstring; refused
    without an IMU, with ``correct`` or with ``servo="identify"``). ``duration`` (s) ends
    the run early (None: the whole reference).
    ``stepping`` (closed loop only; on by default, None: off): re-plan the footsteps from
    the measured DCM (:class:`~wbc.balance.stepping.StepAdjuster` with these parameters).
    Off on a robot with no dead bands of its own (:meth:`SteppingParams.measured`).
    ``hold`` (closed loop only; on by default, None: off): a lift-off waits while the
    measured DCM is not ready for it (:class:`~wbc.balance.retime.PhaseHold` with these
    parameters). The closed loop walks ``ref`` with its sway narrowed by the walk's
    generator (``gains.transfer``, :func:`wbc.walking.gait.narrow_sway`, single supports of
    at most :data:`NARROW_LONGEST`; ``Gains(transfer=0)``: as planned). ``fall`` (closed loop only;
    on by default, None: off): a state beyond recovery stops the walk within a tick and the
    deployment falls safely (:mod:`wbc.balance.fall`). ``calibrate_s`` (with an IMU; 0: off):
    the walk starts after that long at rest in its first pose, the IMU's gyro bias and
    levelling estimated (:func:`wbc.imu.calibrate`; a mount error stops the run, named).
    On a bus that reads nothing, step adjustment is off unless ``step_on_commands`` (it
    re-planned Kokone's steps from a DCM the servos' sag falsifies: walk10 on the 6 randomised
    models open loop stands on, 1 up with it, 6 without; benchmarks/kokone_sim.md 0000).
    ``servo``: the servo model of the feed-forward — None: the robot's ``servos.toml``; a
    :class:`~wbc.sim.actuator.ServoParams`, :class:`~wbc.sim.actuator.HobbyServoParams` or
    :class:`~wbc.sim.xm430.XServoParams`: the user's; ``"identify"``: servos.toml's with
    the stiffness identified at rest from the encoders' sag under the known gravity torques
    (:func:`wbc.balance.compliance.identify_stiffness`; needs ``calibrate_s`` > 0). Which
    one is used is said through ``out`` and kept in :attr:`ClosedLoop.servo_model`.
    """
    if compensate is None:
        from . import best_compensate

        compensate = best_compensate(robot) if enabled else 0.0
    rate = loop_rate(ref)
    commanded = enabled and not bus.can_read  # IMU + commanded joints (module docstring)
    if commanded:
        if imu is None:
            raise ConfigurationError(
                f"the closed loop needs servo positions or an IMU; the {bus.name} bus cannot "
                "read and no IMU was given"
            )
        if correct or servo == "identify":
            raise ConfigurationError(
                f"closed_loop: {'correct' if correct else 'servo=identify'} needs the servos' "
                f"present positions; the {bus.name} bus cannot read"
            )
        if config is not None and config.read:
            raise ConfigurationError(f"the {bus.name} bus cannot read: a config without read")
        out(f"closed loop: the {bus.name} bus reports no positions: the estimator uses the IMU "
            "and the commanded joint positions")  # fmt: skip
        if stepping is not None and not step_on_commands:
            stepping = None
            out("closed loop: no step adjustment (its DCM would come from the commanded joints, "
                "blind to the servos' sag: benchmarks/kokone_sim.md section 0000)")  # fmt: skip
    if stepping is not None and not stepping.measured(robot):
        stepping = None
        out(
            f"closed loop: no step adjustment ({robot.name} states no dead bands: robot.toml "
            "[balance.stepping] band_x, band_y, the DCM error its unpushed walks show)"
        )
    config = config or DeployConfig(rate=rate, read=bus.can_read)
    if enabled and not commanded and not config.read:
        raise ConfigurationError("the closed loop reads the servos' present positions: use --read")
    if gains is None and enabled:  # the defaults, sized to the servos' margin (explicit win)
        gains, scale = default_sized_gains(
            robot, compensate, 1.0 / (config.rate if config is not None else rate)
        )
        if scale < 1.0:
            out(f"closed loop: torso gains and hip strategy x{scale:.3f} (the servos leave "
                f"{scale:.3f} of the design's gain margin: wbc.balance.margin)")  # fmt: skip
    gains = (gains or default_gains(compensate)).check()
    if commanded and gains.kin_tilt > 0:  # the commanded joints hold no sag: no kinematic tilt
        gains = replace(gains, kin_tilt=0.0)
    if enabled and gains.transfer > 0:  # the sway narrowed within the walk's margin
        ref = narrow_sway(ref, gains.transfer, longest=NARROW_LONGEST)
    holder: list[Deployment] = []
    detector = None
    if fall is not None and enabled:
        detector = FallDetector(fall, (ref.foot.length, ref.foot.width))
    identify = isinstance(servo, str)
    if (identify and servo != "identify") or not (
        servo is None or identify or isinstance(servo, SERVO_LAWS)
    ):
        raise ConfigurationError(
            f"closed_loop: servo = {servo!r}: None, 'identify' or one of "
            + ", ".join(law.__name__ for law in SERVO_LAWS)
        )
    if not (math.isfinite(calibrate_s) and calibrate_s >= 0):
        raise ConfigurationError(f"closed_loop: calibrate_s must be >= 0 s, got {calibrate_s}")
    rest = round(calibrate_s * config.rate) if enabled and (imu is not None or identify) else 0
    if identify and rest < 2:
        raise ConfigurationError("closed_loop: servo='identify' measures at rest: calibrate_s > 0")
    gate = enabled and gains.j_i > 0 and gains.j_i_stiff > 0  # (j_i_stiff: identified at rest)
    lift = enabled and (
        gains.lift != 0 or gains.end_clock != 1 or gains.end_leak > 0 or gains.soft_hip > 0
    )  # (soft)
    stiff = enabled and gains.stiff_twist != 1  # (stiff plants: the twist scaled)
    if (gate or lift or stiff) and (commanded or rest < 2):
        what = " and ".join(n for n, on in (("joint integral (j_i_stiff)", gate),
                                            ("CoM lift, walk's end or hip hold (lift, "
                                             "end_clock, end_leak, soft_hip)", lift),
                                            ("twist on stiff servos (stiff_twist)", stiff))
                            if on)  # fmt: skip
        gate = lift = stiff = False
        out(f"closed loop: no {what}: the servos' stiffness is identified from their "
            "encoders during the start-up rest: an IMU or servo='identify', calibrate_s > 0, "
            "a bus that reads")  # fmt: skip
    kind = LiftedStabilizer if lift else Stabilizer
    stabilizer = (stiff_class(kind) if stiff else kind)(
        robot, ref.com_height, lambda: holder[0].last_present if holder else None, imu, gains,
        enabled, fall=detector, calibration_ticks=rest,
    )  # fmt: skip
    stabilizer.steps_yaw.plan(ref)  # (the steps' planned turns: Gains.step_yaw_cap)
    if lift:  # (Gains.end_clock: the walk's end re-timed from its final double support)
        stabilizer.end_start = final_double_start(ref)
    if stepping is not None and enabled and not can_step(ref):
        out("closed loop: no step adjustment on this walk (it re-plans dynamic walks made by "
            "wbc.walking.gait.walk)")  # fmt: skip
        stepping = None
    adjuster = StepAdjuster(robot, ref, stepping) if stepping is not None and enabled else None
    if adjuster is not None:  # (its touch-down reads the estimator's contact detection)
        adjuster.contact = stabilizer.estimator
        adjuster.present = stabilizer.present  # (landing_tilt: the stance sole's roll)
    phase_hold = PhaseHold(hold) if hold is not None and enabled else None
    if phase_hold is not None:  # (a late landing: the estimator's contact detection)
        phase_hold.contact = stabilizer.estimator
    session = Session(controller, robot, ref, q0, stabilizer=stabilizer, stepping=adjuster,
                      hold=phase_hold)  # fmt: skip
    source = SessionSource(session)
    target = source
    params = servo if isinstance(servo, SERVO_LAWS) else None
    model = "the user's servo model" if params is not None else "servos.toml (nominal)"
    comp = None
    if compensate > 0:
        from .compliance import CompensatedSource, ComplianceCompensator, EncoderCorrection

        def support(t: float) -> int:  # the phase of the tick just solved (holds delay it)
            i = session.index
            return int(session.ref.support[ref.index_at(ref.t[0] + t) if i is None else i])

        present = (lambda: holder[0].last_present) if correct else None
        fix = EncoderCorrection(robot.n_joints) if correct else None
        comp = ComplianceCompensator(robot, params, gain=compensate)
        if gains is not None and gains.ff_sagittal != 1.0:  # (Gains.ff_sagittal)
            comp.scale = sagittal_scale(robot, gains.ff_sagittal)
        target = CompensatedSource(source, comp, support, present, fix)
        if gains is not None and gains.ff_inertial > 0:  # the plan's CoM acceleration
            target.accel = _inertial_field(session, gains)
    if duration is not None:
        from ..servos.sources import CallableSource

        whole = target
        target = CallableSource(
            lambda tick, t: None if t > duration else whole(tick, t),
            whole.first(),
            whole.joint_names,
        )
        target.idle = whole.idle  # type: ignore[attr-defined]  # (the session's, forwarded)
    deployment = Deployment(bus, target, robot, config, out=out)
    holder.append(deployment)
    loop = ClosedLoop(deployment, session, source, stabilizer, adjuster, phase_hold, model)
    if enabled and gains.probe_step > 0:
        _probe(loop, robot, gains.probe_step, rest, commanded, out, holder)
    if identify:
        model = "servos.toml with the stiffness identified at rest"
        loop.servo_model = model
    if identify or gate or lift or stiff:
        source.rest_hook = _identifier(loop, comp if identify else None, rest, out, identify)
    if compensate > 0:
        out(f"closed loop: compliance feed-forward x{compensate:g} on {model}")
    return loop


def _probe(loop: ClosedLoop, robot: Robot, step: float, rest: int, commanded: bool,
           out: Callable[[str], None], holder: list[Deployment]) -> None:  # fmt: skip
    """The start-up goal probe (``Gains.probe_step``, :mod:`wbc.balance.goal_probe`) on
    ``loop``'s rest: its fit said through ``out`` and kept in :attr:`ClosedLoop.goal_probe`
    and the stabilizer's ``goal_probe``; a rest too short or a bus that reads nothing: said,
    no probe."""
    if commanded or rest < 2:
        out("closed loop: no goal probe (probe_step): it steps the goals during the start-up "
            "rest and reads the encoders: calibrate_s > 0, a bus that reads")  # fmt: skip
        return
    source = loop.source
    source.probe = GoalProbe(probe_joints(robot), step)
    source.probe_present = lambda: holder[0].last_present if holder else None

    def done(probe: GoalProbe) -> None:
        try:
            fit = probe.result()
        except ConfigurationError as err:
            out(f"closed loop: no goal probe: {err}")
            return
        loop.goal_probe = loop.stabilizer.goal_probe = fit
        out(f"closed loop: goal probe at rest: {fit.line()}")

    source.probe_done = done


def _inertial_field(session: Session, gains: Gains) -> Callable[[float], np.ndarray | None]:
    """The feed-forward's field at the tick just solved (``Gains.ff_inertial``): ``k ×`` the
    plan's CoM acceleration (the re-planned plan's: ``session.ref``; with
    ``ff_inertial_first`` the first plan's), gated by
    ``ff_inertial_back`` and ``ff_inertial_band`` (:func:`~wbc.balance.inertial_ff.gated_field`;
    the DCM error: the stabilizer's last estimate against the plan's)."""
    from .inertial_ff import gated_field

    k, back, band = gains.ff_inertial, gains.ff_inertial_back > 0, gains.ff_inertial_band
    first = session.ref if gains.ff_inertial_first > 0 else None  # (the unpushed walk's c̈)
    start = gains.ff_inertial_from

    def accel(t: float) -> np.ndarray | None:
        i = session.index
        if i is None:
            return None
        ref = session.ref
        acc = k * (ref if first is None else first).com_acc[i]
        if not back and band <= 0:
            return acc
        est = session.stabilizer.last if session.stabilizer is not None else None
        err = None if est is None else np.asarray(est.dcm)[:2] - ref.dcm_at(i)
        return gated_field(acc, float(ref.torso_yaw[i]), err, back, band, start)

    return accel


def sagittal_scale(
    robot: Robot, factor: float, sides: Sequence[str] = ("left", "right")
) -> np.ndarray:
    """Per joint: ``factor`` on the pitch joints (their roles hip pitch, knee, ankle pitch)
    of the legs of ``sides``, 1 elsewhere (``Gains.ff_sagittal``, ``goal_lead_stance``)."""
    scale = np.ones(robot.n_joints)
    for side in sides:
        for role in ("hip_pitch", "knee", "ankle_pitch"):
            name = robot.roles.get(side, role)
            if name is not None:
                scale[robot.joint_index(name)] = factor
    return scale


def _identifier(loop: ClosedLoop, comp, rest: int, out: Callable[[str], None],
                strict: bool = True):  # fmt: skip
    """The rest hook of ``servo='identify'`` and of ``Gains.j_i_stiff``: averages the goals
    written and the encoders' positions over the second half of the rest, then identifies
    the stiffness (:func:`wbc.balance.compliance.identify_stiffness`), gives the feed-forward
    (``comp``, if any) the identified model and the stabilizer the scale (``j_i_stiff``'s
    gate). ``strict`` False: a failed identification is said, not raised (the gate stays
    shut: no joint integral)."""
    from .compliance import identify_stiffness

    goals: list[np.ndarray] = []
    present: list[np.ndarray] = []
    seen = [0]

    def hook(resting: bool) -> None:
        dep = loop.deployment
        if resting:
            seen[0] += 1
            ready = dep.limiter.prev is not None and dep.last_present is not None
            if seen[0] > rest // 2 and ready:
                goals.append(dep.bus.codec.decode(dep.limiter.prev))
                present.append(np.asarray(dep.last_present, dtype=float))
            return
        if loop.stiffness_scale is not None or not goals:
            return
        try:
            k, used = identify_stiffness(loop.session.robot, loop.session.q[7:],
                                         np.mean(goals, axis=0), np.nanmean(present, axis=0),
                                         None if comp is None else comp.params)  # fmt: skip
        except ConfigurationError as err:
            if strict:
                raise
            goals.clear()  # (said once)
            g = loop.stabilizer.gains
            what = [n for n, on in (("joint integral (j_i_stiff)", g.j_i > 0 and g.j_i_stiff > 0),
                                    ("CoM lift (lift)", g.lift != 0),
                                    ("walk's end (end_clock, end_leak)",
                                     g.end_clock != 1 or g.end_leak > 0),
                                    ("single support's hip hold (soft_hip)", g.soft_hip > 0),
                                    ("twist on stiff servos (stiff_twist)", g.stiff_twist != 1))
                    if on]  # fmt: skip
            out(f"closed loop: no {' nor '.join(what) or 'identified stiffness'}: {err}")
            return
        loop.stiffness_scale = loop.stabilizer.stiffness_scale = k
        if comp is not None:
            comp.params = comp.params.scaled(stiffness=k)
        out(f"closed loop: servo stiffness identified at rest: {k:.2f} x servos.toml's "
            f"({used} loaded joints)")  # fmt: skip
        g = loop.stabilizer.gains
        if g.j_i > 0 and g.j_i_stiff > 0:
            on = "on" if loop.stabilizer.sag_integrated else "off"
            out(f"closed loop: joint integral {on} (j_i_stiff {g.j_i_stiff:g})")
        soft = identified_soft(g.lift_stiff, k)  # (what lift and the walk's end act on)
        for on, what, value, key in (
            (g.lift != 0, "CoM target lift", f"{g.lift * 1000:+.1f} mm", ""),
            (g.end_clock != 1, "walk-end clock", f"x{g.end_clock:g}", "end_clock, "),
            (g.end_leak > 0, "walk-end DCM integral leak", f"{g.end_leak:g} /s", "end_leak, "),
            (
                g.soft_hip > 0,
                "hip strategy held from each single support's start",
                f"{g.soft_hip:g} s",
                "soft_hip, ",
            ),
        ):
            if on and loop.stabilizer.enabled:
                out(f"closed loop: {what} {value if soft else 'none'} "
                    f"({key}lift_stiff {g.lift_stiff:g})")  # fmt: skip
        if g.stiff_twist != 1 and loop.stabilizer.enabled:  # (stiff plants: the complement)
            out(f"closed loop: torso command's twist {'none' if soft else f'x{g.stiff_twist:g}'}"
                f" (stiff_twist, lift_stiff {g.lift_stiff:g})")  # fmt: skip

    return hook
