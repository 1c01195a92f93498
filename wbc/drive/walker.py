"""Drive a robot: a :class:`Walker` turns velocity commands into servo goals, closed loop.

One walk tick: the :class:`~wbc.walking.engine.WalkEngine` gives the tick's targets (CoM,
soles, swing, torso) from the command in force → the
:class:`~wbc.balance.stabilizer.Stabilizer` reads the servos' present positions and the IMU
and adjusts them (state estimate, torso feedback; the closed loop of
:func:`wbc.balance.live.closed_loop`) → one solve of any
:class:`~wbc.walking.controller.Controller` (a task stack as a weighted or hierarchical QP, the
thesis's schemes, placo, pink) → the joint goals. A :class:`Walker` is a target source
(:class:`wbc.servos.sources.TargetSource`), so a :class:`~wbc.servos.playback.Deployment` on
any :class:`~wbc.servos.bus.ServoBus` plays it with every safety feature of ``wbc deploy``
(soft start, clamping to the joint limits, rate limit, watchdog, safe stop)::

    walker = Walker(robot, StackController(load_stack("walk", robot)), imu=my_imu)
    deployment = walker.deployment(my_bus)     # or walker.tick() in your own loop
    walker.start(); walker.command(0.05, 0.0, 0.2)   # m/s forward, m/s left, rad/s
    deployment.run()                           # in a thread; walker.stop(), walker.close()

(``docs/drive.md``; ``wbc drive`` on the command line.)
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from types import MappingProxyType
from typing import Any

import numpy as np
import pinocchio as pin

from ..balance.compliance import ComplianceCompensator
from ..balance.estimator import StateEstimator
from ..balance.stabilizer import Gains, Stabilizer
from ..exceptions import ConfigurationError, WbcError
from ..geometry import heading_free, rot_z, wrap_angle, yaw_of
from ..imu import Imu
from ..model import Robot
from ..recording import SUPPORT_DOUBLE
from ..roles import SOLE_FRAMES
from ..servos.config import DeployConfig
from ..servos.playback import Deployment
from ..walking.engine import EngineParams, EngineTick, VelocityLimits, WalkEngine
from ..walking.footsteps import Footstep, Side
from ..walking.geometry import Foot, rot2
from ..walking.legs import LegGeometry
from ..walking.loop import Controller, TickTargets
from ..walking.reference import StandingState
from ..walking.window import BalanceWindow
from .compensate import DRIVE_COMPENSATE as DRIVE_COMPENSATE  # (re-exported)
from .compensate import DRIVE_CORRECTION, LoadRamp
from .compensate import default_compensate as default_compensate  # (re-exported)
from .contacts import DRIVE_CONTACT_RATE as DRIVE_CONTACT_RATE  # (re-exported)
from .contacts import DRIVE_CONTACT_REACH as DRIVE_CONTACT_REACH  # (re-exported)
from .contacts import move_contacts
from .failures import failure_cause
from .failures import failure_lines as failure_lines  # (re-exported)
from .finish import DRIVE_FINISH_STEPS_AFTER, DRIVE_FINISH_TOLERANCE, FinishSteps
from .flatten import SoleFlatten
from .gyro_trim import stance_trim
from .liftoff import FlatLiftoff
from .odometry import (
    DRIVE_HEADING_GAIN,
    BaseHold,
    LandingMean,
    LiftGain,
    PlayInverse,
    PoseOdometry,
    StrideGain,
    base_over_soles,
)
from .slip import LastReading, SlipEstimate
from .stand import DRIVE_QUIET_STAND, QuietStand

#: the DCM feedback's gain of driven walks (:data:`DRIVE_GAINS`)
DRIVE_K_DCM = 0.1

#: the feedback gains of driven walks: the closed loop's defaults without the hip strategy
#: (``k_hip``: the torso rolled toward a DCM outward of the stance sole, for pushes). Walking
#: sideways the DCM runs outward by design: with it a randomised Bioloid fell at 3 cm/s
#: sideways (models 0 and 1 of benchmarks/drive.md at 3.1–3.8 s), without it both walked the
#: commanded 15 cm. Instead the CoM target moves against the estimated DCM's error
#: (``k_dcm`` 0.1: ``c − 0.1 (ξ − ξ_ref)``, at most 2 cm): the stiff, lightly damped,
#: late randomised Bioloids rocked sideways with a growing amplitude and fell at 3 cm/s
#: sideways (models 0 and 4 of 20), with it none, at 4.6 cm/s neither (0.15 and 0.3 threw
#: a model walking forward at the limit, 0.5 five; benchmarks/drive.md, "Contacts that
#: move"). Keyed by the outer loop
#: (``Walker(track=...)``): with it, no heading feedback on the torso either (``k_yaw``: the
#: torso held at the planned heading by the gyro; the outer loop turns the plan to steer the
#: real feet, so the torso would twist against them)
#: ``k_twist`` (with the outer loop): the torso's tilt command with no part about the leaned
#: torso's own vertical axis, so it turns no hip yaw: through their play and latency the
#: loaded soles stuck, slipped and turned (benchmarks/drive.md, 2026-12-06 fourteenth session)
DRIVE_K_TWIST = 0.0
DRIVE_GAINS = MappingProxyType(
    {
        True: Gains(k_hip=0.0, k_yaw=0.0, k_dcm=DRIVE_K_DCM, k_twist=DRIVE_K_TWIST),
        False: Gains(k_hip=0.0, k_dcm=DRIVE_K_DCM),
    }
)

#: the IMU's rest before a driven walk (s): shorter than the fixed walks'
#: :data:`wbc.balance.live.CALIBRATE_S` (1 s), measured side by side on the same code:
#: random sequences on the randomised Bioloids (``benchmarks/drive.py --random 10 --models 10
#: --calibrate S``) fell 1 of 100 with 0.3 s, 4 of 100 with 1 s (the displacement and heading
#: errors alike; why is not traced: the stiff, lightly damped models rock at rest, ±3° in
#: pitch on model 0, so what any rest samples depends on its length)
DRIVE_CALIBRATE_S = 0.3

#: a rest (s) after the IMU's calibration, before a driven walk with the outer loop, over
#: which :meth:`PoseOdometry.rest <wbc.drive.odometry.PoseOdometry.rest>` learns the gyro's
#: bias about the vertical, standing without torso feedback. 1.5 s learnt it within 6° of
#: heading over 30 s on ten randomised Bioloids (the calibration leaves up to 14°). On the
#: random sequences, side by side (benchmarks/drive.md, 2026-12-05 11:23 UTC, with the DCM
#: feedback): no fall and no failed solve in 100 either way, heading within 15 % on 64 of
#: 80 runs instead of 62 (median error 3.6° instead of 5.3°); the sideways envelope 20/20.
#: (Before the DCM feedback it threw model 0 once in 100: it was off then.) 0: none
DRIVE_YAW_REST_S = 1.5

#: a finishing stop (:meth:`Walker.stop` ``finish=True``) walks on
#: (command zero) at most this many steps while the steps make up the lag to the commanded
#: pose (a command takes effect at the next lift-off; the make-up is capped), then closes
#: (within :data:`~wbc.drive.finish.DRIVE_FINISH_TOLERANCE`)
DRIVE_FINISH_STEPS = 4

#: the largest gain on the planned stride (forward, sideways) for legs whose steps fall short
#: (:class:`~wbc.drive.odometry.StrideGain`, with the outer loop; the stride then within the
#: velocity limits); 1: the steps as commanded, the make-up alone (``EngineParams.catch_up``,
#: 25 % of the limits) closing the lag. Random sequences over ten randomised Bioloids, side by
#: side (benchmarks/drive.md, 2026-12-05 13:25 UTC): displacement within 15 % 48 -> 53 of 100
#: (the compliant model 7: a mean 107 -> 71 mm off), heading 64 -> 63 of 80, no fall and no
#: failed solve either way; the sideways envelope at 3 cm/s 20/20
DRIVE_STRIDE_GAIN = 1.5

#: the largest gain on the planned swing apex for legs whose swing sole stays low
#: (:class:`~wbc.drive.odometry.LiftGain`: the swing sole's highest point measured from the
#: encoders against 0.7 of the apex, per swing; closed loop); 1: the apex as planned. With
#: the heading on the calibrated gyro and the encoders' tilt (:meth:`Walker._heading_inputs`),
#: random sequences over ten randomised Bioloids side by side (benchmarks/drive.md,
#: 2026-12-05 16:10 UTC): displacement within 15 % 53 -> 56 of 100 (the compliant model 7:
#: a mean 71 -> 31 mm off), heading 63 -> 71 of 80, no fall and no failed solve either way;
#: forward 8 cm/s, sideways 3 cm/s, turning 30°/s 20/20 each
DRIVE_LIFT_GAIN = 2.0

#: the gain of the gyro's vertical bias learnt while walking (:class:`~wbc.drive.odometry.
#: PoseOdometry` ``walk_gain``: per landing, the stance sole's heading by the gyro against the
#: encoders'); 0: learnt at rest only (``yaw_rest_s``)
DRIVE_YAW_LEARN = 0.0

#: s a joint's encoder may stand still and its link still be taken at the play's edge the
#: reading last moved toward (:class:`~wbc.drive.odometry.PlayInverse`); longer, the middle
#: (on 20 random sequences × 10 randomised Bioloids, benchmarks/drive.md: held for ever the
#: heading was worse on 16 of 20 runs, at 0.1 s on 9); 0.03 s reads the landings unbiased (0.1
#: s: 0.2 mm behind): over 40 runs won 7 of 16 misses, lost none; envelope 20/20 (drive.md)
DRIVE_PLAY_HOLD = 0.03

#: the base's hold after a stop (``Walker(hold=DRIVE_HOLD["reach"])``; off by default;
#: :class:`~wbc.drive.odometry.BaseHold`, closed loop): the CoM target shifted at most this
#: far (m), at this rate (m/s), for at most this long (s) after the walk's end (a stop then
#: takes that much longer). On 2.5 s walks it took the base's error at the end from 7–22 to
#: 2–5 mm (four randomised Bioloids); on the 30 s random sequences the held base shows the
#: odometry's own error whole (the soles' unseen creep and slips, which the standing
#: posture's error had partly offset): displacement within 15 % 40 → 37 of 60, with the
#: simulator's creep stopped 25 → 22 of 30 (benchmarks/drive.md, 2026-12-06), hence off
DRIVE_HOLD = MappingProxyType({"reach": 0.02, "rate": 0.02, "seconds": 1.0})

#: the state estimate's settings for driven walks (:class:`~wbc.balance.estimator.
#: StateEstimator`)
DRIVE_ESTIMATOR = MappingProxyType({"bias_gain": 0.05})


class Walker:
    """Velocity-commanded walking on a robot (module docstring).

    ``controller``: any walking controller; ``imu``: the torso IMU (None: the estimate from
    the encoders alone); ``closed=False``: the open loop (the targets as planned).
    ``params``: the gait (:class:`EngineParams`). ``limits`` default to
    :meth:`VelocityLimits.from_robot` (measured on the model); ``window="auto"``: the
    whole-body balance window measured (:meth:`BalanceWindow.from_robot`) for a whole-body
    gait, None for the upright one; or give one. Both defaults
    are measured once per robot and gait and cached (:func:`wbc.drive.envelope.planning_envelope`).
    ``compensate`` > 0: the servo compliance feed-forward × gain in :meth:`deployment`
    (:func:`default_compensate` gives the measured gain); ``correct`` (with it, closed loop):
    the feed-forward rescaled per servo from the encoders' present positions
    (:class:`~wbc.balance.compliance.EncoderCorrection`: a servo stiffer or softer than its
    settings gets its own scale; on the randomised Bioloids it took the random sequences'
    falls from 29 to 2 of 100, benchmarks/drive.md).
    ``gains``: the feedback (default :data:`DRIVE_GAINS`). ``calibrate_s``: with an IMU and
    the closed loop, the first ``calibrate_s`` s stand at rest for the IMU's start-up
    calibration (gyro bias, levelling; as ``wbc deploy``'s closed loop), a :meth:`start`
    waiting for its end (0: none); ``settle_s`` > 0 (off): it rests up to this long more
    until the gyro is still, and takes its quietest window (Stabilizer ``settle_ticks``).
    ``track`` (with an IMU, closed loop): the outer loop —
    the steps aim the commanded pose from where :class:`~wbc.drive.odometry.PoseOdometry`
    (the gyro's heading, the encoders' landings) puts the body, heading included, instead of
    the legs' odometry alone (which cannot see a stance sole turning on the floor); the
    torso then gets no heading feedback (:data:`DRIVE_GAINS`). The command moves the base
    (:attr:`WalkEngine.origin <wbc.walking.engine.WalkEngine.origin>`: turning on the spot
    turns about the base, as ``commanded_xy_m`` counts it), not the soles' midpoint.
    ``contact_reach`` (m, default :data:`DRIVE_CONTACT_REACH` = 5 mm) and ``contact_rate``
    (m/s, default :data:`DRIVE_CONTACT_RATE` = 0.02): how far from its plan and how fast the
    controller's stance contact moves toward the measured landing in single support (0: the
    planned soles; :meth:`_contacts`); ``keep_clear`` (default True): never closer to the
    swing's planned landing than the engine's ``min_clearance`` (False: as before
    2026-12-06, the double support's solve failed where the move took the feet inside their
    self-collision margin).
    ``yaw_rest_s`` (with the outer loop; default :data:`DRIVE_YAW_REST_S`, 1.5 s) > 0: after
    the IMU's calibration the walker stands this long more, without torso feedback
    (:attr:`calibrating` stays True, a :meth:`start` waits), while the odometry learns the
    gyro's bias about the vertical. ``stride_gain`` (with the outer loop; default
    :data:`DRIVE_STRIDE_GAIN`, 1.5; 1: off): the steps planned up to this much longer, forward
    and sideways, where the odometry measures them falling short
    (:class:`~wbc.drive.odometry.StrideGain`). ``yaw_learn`` (default
    :data:`DRIVE_YAW_LEARN`, 0: off) > 0: the gyro's vertical bias learnt while walking too.
    ``lift_gain`` (closed loop; default :data:`DRIVE_LIFT_GAIN`; 1: off): the swing planned up
    to this much higher where the encoders measure the swing sole staying below the apex
    (:class:`~wbc.drive.odometry.LiftGain`). ``filter_heading``: the outer loop's heading
    integrates the attitude filter's rate (the calibrated gyro plus the filter's bias
    correction, :attr:`StateEstimator.gyro_correction <wbc.balance.estimator.StateEstimator.
    gyro_correction>`) instead of the calibrated gyro (the default; below).
    ``encoder_rest`` (default False: the torso taken not to turn at rest): True, the rest's
    bias about the vertical is the gyro's heading change less the torso's turn seen by the
    encoders (:class:`~wbc.drive.odometry.PoseOdometry`; measured not better on the random
    set, three falls in 200 runs against none: benchmarks/drive.md). ``rest_rotation``: the
    rest learns the gyro's whole bias less the torso's rotation seen by the encoders
    (PoseOdometry; off).
    ``play`` (rad, one or per joint, model order; default 0: none): the servos' gear play
    (backlash) between the encoder and the link, taken out of the present positions the
    walker's odometry uses — the leg odometry's landings and the heading's tilt over the
    stance sole (:class:`~wbc.drive.odometry.PlayInverse`; ``play_hold``: how long a still
    reading keeps its side, default :data:`DRIVE_PLAY_HOLD`; ``play_lift``: the swing's lift
    measured through it too — two falls in 100 random runs against none,
    benchmarks/drive.md; ``play_load``, ``"still"`` or ``"always"``: the loaded links' side
    from the static joint torques, ``""`` off); the feedback's state estimate keeps the raw
    readings. ``landing_share`` (closed loop; default 0: off): each landing's placement the
    mean over this last share of its double support (:class:`~wbc.drive.odometry.LandingMean`),
    for the outer loop's odometry and, with ``landing_contact`` (default True), the contact.
    :func:`wbc.drive.sim.drive_sim` gives the simulated servos' own play.
    ``hold`` (m, closed loop; default 0: off; :data:`DRIVE_HOLD`'s reach, 0.02, measured):
    after a stop, the CoM target shifted at most this far until the base, by the present
    joints over the planned soles, stands on the commanded pose
    (:class:`~wbc.drive.odometry.BaseHold`; :attr:`walking` stays True meanwhile, at most
    ``DRIVE_HOLD["seconds"]``).
    ``finish_steps`` (with the outer loop; default :data:`~wbc.drive.finish.
    DRIVE_FINISH_STEPS_AFTER`; 0: none): after a stop, the closing step's landing measured
    by the odometry and, off the commanded pose, at most this many finish steps aimed from
    the measured frame (:class:`~wbc.drive.finish.FinishSteps`, ``finish_xy``: the position
    corrected too; :attr:`walking` stays True meanwhile).
    ``heading_gain`` (outer loop; :data:`~wbc.drive.odometry.DRIVE_HEADING_GAIN`, 0.5; 1: the
    gyro's alone): the share of the gyro's stance-sole heading taken at each landing
    (PoseOdometry).
    ``quiet_stand`` (outer loop; :data:`~wbc.drive.stand.DRIVE_QUIET_STAND`): when standing
    still, no torso feedback (``"end"``, ``"standing"``, ``""``: :mod:`wbc.drive.stand`).
    ``slip_gain`` (outer loop, 0: off): the stance sole's slide by the IMU moved into the
    odometry, this share of it (:class:`~wbc.drive.slip.SlipEstimate`).
    ``load_ramp`` (with ``compensate``): the feed-forward's load moved from sole to sole over
    each walking double support, min-jerk (:class:`~wbc.drive.compensate.LoadRamp`; off).
    ``flat_liftoff`` (°, closed loop; 0: off): a lift-off waits while the soles' normals by
    the encoders differ by more (:class:`~wbc.drive.liftoff.FlatLiftoff`). ``flatten`` (1/s,
    closed loop; 0: off): a landed sole's target tilted against its tilt by the encoders
    (:class:`~wbc.drive.flatten.SoleFlatten`; ``flatten_band`` °, its tilt's dead band).
    ``gyro_trim`` (s, outer loop; 0: off): :class:`~wbc.drive.gyro_trim.StanceTrim`'s prior.
    ``rest_periods`` (off): the rest's bias over whole periods of the rocking (PoseOdometry).
    """

    def __init__(
        self,
        robot: Robot,
        controller: Controller,
        imu: Imu | None = None,
        params: EngineParams | None = None,
        limits: VelocityLimits | None = None,
        window: BalanceWindow | str | None = "auto",
        gains: Gains | None = None,
        closed: bool = True,
        compensate: float = 0.0,
        q0: np.ndarray | None = None,
        calibrate_s: float = DRIVE_CALIBRATE_S,
        settle_s: float = 0.0,
        correct: bool = True,
        track: bool = True,
        contact_reach: float = DRIVE_CONTACT_REACH,
        contact_rate: float = DRIVE_CONTACT_RATE,
        yaw_rest_s: float = DRIVE_YAW_REST_S,
        stride_gain: float = DRIVE_STRIDE_GAIN,
        yaw_learn: float = DRIVE_YAW_LEARN,
        lift_gain: float = DRIVE_LIFT_GAIN,
        filter_heading: bool = False,
        encoder_rest: bool = False,
        rest_rotation: bool = False,
        play: float | np.ndarray = 0.0,
        play_hold: float = DRIVE_PLAY_HOLD,
        play_lift: bool = False,
        play_load: str = "",
        landing_share: float = 0.0,
        landing_contact: bool = True,
        keep_clear: bool = True,
        hold: float = 0.0,
        finish_steps: int = DRIVE_FINISH_STEPS_AFTER,
        finish_xy: bool = False,
        heading_gain: float = DRIVE_HEADING_GAIN,
        quiet_stand: str = DRIVE_QUIET_STAND,
        slip_gain: float = 0.0,
        load_ramp: bool = False,
        flat_liftoff: float = 0.0,
        flatten: float = 0.0,
        flatten_band: float = 0.0,
        gyro_trim: float = 0.0,
        rest_periods: bool = False,
    ) -> None:
        if not (math.isfinite(compensate) and compensate >= 0):
            raise ConfigurationError(f"compensate must be a finite number >= 0, got {compensate}")
        if not contact_reach >= 0:  # (NaN too)
            raise ConfigurationError(
                f"contact_reach must be a number >= 0 (m; inf: up to the measured landings), "
                f"got {contact_reach}"
            )
        if not contact_rate >= 0:  # (NaN too)
            raise ConfigurationError(
                f"contact_rate must be a number >= 0 (m/s; inf: at once), got {contact_rate}"
            )
        self.contact_reach = float(contact_reach)
        self.contact_rate = float(contact_rate)
        self.keep_clear = bool(keep_clear)
        #: the controller's contact target per sole in contact (position) and the planned
        #: placement it started from (:meth:`_contacts`)
        self._held: dict[Side, tuple[Footstep, np.ndarray]] = {}
        for key, v in (("calibrate_s", calibrate_s), ("settle_s", settle_s)):
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"{key} must be a finite number >= 0, got {v}")
        if not (math.isfinite(yaw_rest_s) and yaw_rest_s >= 0):
            raise ConfigurationError(f"yaw_rest_s must be a finite number >= 0, got {yaw_rest_s}")
        if not (math.isfinite(stride_gain) and stride_gain >= 1):
            raise ConfigurationError(f"stride_gain must be a finite number >= 1, got {stride_gain}")
        if not (math.isfinite(lift_gain) and lift_gain >= 1):
            raise ConfigurationError(f"lift_gain must be a finite number >= 1, got {lift_gain}")
        if not (isinstance(finish_steps, int) and finish_steps >= 0):
            raise ConfigurationError(f"finish_steps must be an integer >= 0, got {finish_steps}")
        if not (math.isfinite(hold) and hold >= 0):
            raise ConfigurationError(f"hold must be a finite number >= 0 (m), got {hold}")
        if not (math.isfinite(yaw_learn) and 0 <= yaw_learn <= 1):
            raise ConfigurationError(f"yaw_learn must be a number in [0, 1], got {yaw_learn}")
        self.robot = robot
        self.controller = controller
        self.imu = imu
        stand = robot.configuration("stand")
        q0 = stand if q0 is None else robot.check_configuration(q0).copy()
        params = (params or EngineParams()).check()
        legs = LegGeometry.from_robot(robot, stand)
        foot = Foot(*robot.foot_size)
        if isinstance(window, str):
            if window != "auto":
                raise ConfigurationError(
                    f"window must be 'auto', None or a BalanceWindow, got {window!r}"
                )
            from .envelope import planning_envelope

            measured, window = planning_envelope(robot, params)  # (cached on disk)
            limits = limits or measured
        if limits is None:
            limits = VelocityLimits.from_robot(robot, params, window, legs, foot)
        self.engine = WalkEngine(StandingState.from_robot(robot, q0), params, limits, foot, legs,
                                 window)  # fmt: skip
        # the command moves the base (the issue's "base displacement"), not the soles' midpoint
        centre = self.engine.centre
        self.engine.origin[:] = rot2(centre[2]).T @ (q0[:2] - centre[:2])
        self.compensate = float(compensate)
        ramp_ticks = max(1, round(params.timing.double_support_time / self.engine.dt))
        self.load_ramp = LoadRamp(ramp_ticks) if load_ramp else None  #: the load's split
        flat = FlatLiftoff(robot, flat_liftoff)  # (checks it)
        self.flat_liftoff = flat if closed and flat_liftoff > 0 else None  #: lift-offs held
        level = SoleFlatten(robot, flatten, band_deg=flatten_band)  # (checks them)
        self.flatten = level if closed and flatten > 0 else None  #: landed soles flattened
        self._paused = 0.0  # s of walk ticks the engine waited (:attr:`flat_liftoff`)
        self.correct = bool(correct)
        self.q = q0.copy()
        self._lean = heading_free(robot.frame_placement(q0, "torso").rotation)
        controller.dt = self.engine.dt
        controller.start(robot, self.q, self.engine.standing_reference())
        #: the servos' present positions (rad, model order; NaN: unread) or None: set by
        #: :meth:`deployment` (or by a caller's own loop)
        self.present: Callable[[], np.ndarray | None] = lambda: None
        rest = round(calibrate_s / self.engine.dt) if closed and imu is not None else 0
        track = bool(track and closed and imu is not None)
        gains = (gains or DRIVE_GAINS[track]).check()
        #: the gains of the extra rest (``yaw_rest_s``) and of standing still (``quiet_stand``):
        #: no torso feedback (its integral restarts with the walk); with it the stiff, late
        #: randomised Bioloid 0 rang and spun on its soles, −56° in 1.5 s of rest (drive.md)
        self._gains = (gains, replace(gains, k_p=0.0, k_i=0.0, k_d=0.0) if track else gains)
        self.quiet = QuietStand(quiet_stand, on=track)
        slip = SlipEstimate(robot, slip_gain)  # (checks it)
        self.slip = slip if track and slip_gain > 0 else None  #: the stance sole's slide (IMU)
        imu = LastReading(imu) if self.slip is not None and imu is not None else imu
        estimator = StateEstimator(robot, self.engine.height, use_imu=imu is not None,
                                   gyro_heading=gains.k_yaw > 0, **DRIVE_ESTIMATOR)  # fmt: skip
        self.stabilizer = Stabilizer(robot, self.engine.height, lambda: self.present(), imu,
                                     gains, closed, estimator,
                                     calibration_ticks=rest,
                                     settle_ticks=round(settle_s / self.engine.dt))  # fmt: skip
        self._deferred_start = False  # start() asked during the calibration at rest
        self._finish_by: int | None = None  # a finishing stop: the last step it may take
        self.engine.on_landing = self._landed if closed else None
        #: the outer loop's pose (IMU heading + encoders), with an IMU and the closed loop
        odometry = PoseOdometry(robot, walk_gain=yaw_learn, encoder_rest=encoder_rest,
                                heading_gain=heading_gain, rest_rotation=rest_rotation,
                                rest_periods=rest_periods)  # fmt: skip
        self.odometry = odometry if track else None
        #: the steps' measured shortfall (with the outer loop and ``stride_gain`` > 1)
        self.stride = StrideGain(stride_gain) if track and stride_gain > 1 else None
        self.trim = stance_trim(robot, gyro_trim, track)  #: the gyro's bias trimmed walking
        self._yaw_rest_left = round(yaw_rest_s / self.engine.dt) if track else 0  # ticks
        #: the swing sole's measured lift (closed loop, ``lift_gain`` > 1): the apex wanted
        #: (m) and the highest point of the swing so far (m above the stance sole)
        self.lift = LiftGain(lift_gain) if closed and lift_gain > 1 else None
        self.filter_heading = bool(filter_heading)
        #: the encoders' gear play taken out of the present positions the odometry uses
        #: (closed loop, any play > 0)
        inverse = PlayInverse(play, robot.n_joints, play_hold, play_load)  # (checks them)
        self.play = inverse if closed and np.any(inverse.half > 0) else None
        self.play_lift = bool(play_lift)  # the swing's lift measured through it too
        #: the static joint torques: each loaded link's side of the play (``play_load``)
        self._loads = ComplianceCompensator(robot) if self.play is not None and play_load else None
        mean = LandingMean(robot, landing_share)  # (checks it)
        self.landing = mean if closed and landing_share > 0 else None  #: landings averaged
        self.landing_contact = bool(landing_contact)  # the engine's measured contact too
        #: after a stop, the base held onto its commanded place (closed loop, ``hold`` > 0)
        rate, seconds = DRIVE_HOLD["rate"], DRIVE_HOLD["seconds"]
        self.hold = BaseHold(hold, rate, seconds) if closed and hold > 0 else None
        self._walked = False  # the engine walked at the last tick (the hold begins at its end)
        #: finish steps after a stop (with the outer loop)
        self.finish = FinishSteps(finish_steps if track else 0, finish_xy)
        self._engine_walked = False  # the engine walked at the last tick
        self._links: np.ndarray | None = None  # this tick's present positions, play out
        self._apex = params.swing.apex
        self._peak = -math.inf
        self._offset: np.ndarray | None = None  # measured − planned frame at the last landing
        self.last: EngineTick | None = None
        self._previous: tuple[str, str, str] | None = None
        self._t = 0.0  # engine time of the last solve
        self.closed_at: float | None = None
        self._play_t: float | None = None  # playback time of the last target asked for
        #: called with the playback time before each tick as a target source (a command
        #: script, a keyboard): it may command, start, stop or close the walker
        self.before_tick: Callable[[float], None] | None = None
        #: solves the controller failed (the robot then holds its last goals: counted and
        #: reported by the run's record and ``wbc drive``, never silent), and per cause
        #: (:func:`failure_cause`)
        self.failed_solves = 0
        self.failure_causes: Counter[str] = Counter()
        self.joint_names = robot.joint_names
        self.tick_time: list[float] = []  # s per walk tick (engine + feedback + solve)

    # ------------------------------------------------------------------ commands
    @property
    def limits(self) -> VelocityLimits:
        return self.engine.limits

    def command(self, vx: float, vy: float, wz: float) -> tuple[float, float, float]:
        """Walk at ``vx`` (m/s forward), ``vy`` (m/s left), ``wz`` (rad/s counter-clockwise);
        returns the command clipped to :attr:`limits`. Taken at the next lift-off."""
        return self.engine.command(vx, vy, wz)

    @property
    def calibrating(self) -> bool:
        """True while the IMU's start-up calibration at rest (gyro bias, levelling:
        :meth:`Stabilizer._calibrate <wbc.balance.stabilizer.Stabilizer>`) runs, and the
        rest after it that learns the gyro's bias about the vertical (``yaw_rest_s``); a
        :meth:`start` then waits for their end."""
        return self.stabilizer.calibrating or self._yaw_rest_left > 0

    def start(self) -> None:
        """Start walking (with the command in force; zero: on the spot) — after the
        start-up calibration at rest, if it is still running. (During a finishing
        :meth:`stop`: walk on.)"""
        self._finish_by = None
        self.quiet.start()
        if self.hold is not None:
            self.hold.end()
        if self.calibrating:
            self._deferred_start = True
        else:
            self.engine.start()

    def stop(self, finish: bool = False) -> None:
        """Finish with a closing step and stand. ``finish``: first walk on with the command
        zero while the steps make up the lag to the commanded pose — until the planned
        frame, with the odometry's offset, is within :data:`DRIVE_FINISH_TOLERANCE` of it, at
        most :data:`DRIVE_FINISH_STEPS` steps — so that the plan ends where the commands put
        it, not a step's latency short (a command takes effect at the next lift-off; on the
        random sequences of benchmarks/drive.md the base's error did not shrink with it: the
        odometry's own)."""
        self._deferred_start = False
        engine = self.engine
        self.finish.stop()
        if finish and engine.walking:
            engine.command(0.0, 0.0, 0.0)
            self._finish_by = engine.steps_taken + DRIVE_FINISH_STEPS
        else:
            self._finish_by = None
            engine.stop()

    def lag(self) -> tuple[float, float]:
        """The commanded pose against the walking frame's commanded point where the plan and
        the odometry put it after the committed steps: (m, rad)."""
        engine = self.engine
        c = engine.centre + engine.odometry_offset
        p = c[:2] + rot2(c[2]) @ engine.origin
        target = engine.pose_cmd
        return float(np.hypot(*(target[:2] - p))), abs(wrap_angle(target[2] - c[2]))

    def close(self) -> None:
        """End the motion: as a target source, the walker answers None from now on (the
        deployment then holds or turns torque off as configured)."""
        self.closed_at = self._t

    @property
    def walking(self) -> bool:
        """Walking, a start waiting for the calibration, or the base's hold after a stop."""
        held = self.hold is not None and self.hold.active
        engine = self.engine
        return engine.walking or engine.starting or self._deferred_start or held

    def _landed(self, step: Footstep) -> Footstep | None:
        """Leg odometry at a landing: the swing sole's placement relative to the stance sole
        from the servos' present positions (forward kinematics; flat: x, y, heading), put
        beside the stance sole where the walk has it. None if a position is unread."""
        feet = self.engine.feet
        stance = feet["right" if step.side == "left" else "left"]
        q = self._present_configuration()
        if self.flat_liftoff is not None:
            self.flat_liftoff.landed(q)
        if q is None:
            return None
        placed = None if self.landing is None else self.landing.placed(step.side)
        if placed is None or not self.landing_contact:
            (rel,) = self.robot.placements_in(q, SOLE_FRAMES[stance.side], [SOLE_FRAMES[step.side]])
            xy, dyaw = rel.translation[:2], yaw_of(rel.rotation)
        else:
            xy, dyaw = placed[:2], float(placed[2])
        xy = stance.xy + rot_z(stance.yaw)[:2, :2] @ xy
        odo = self.odometry
        if odo is not None and odo.started:
            if self.slip is not None:
                odo.soles[stance.side][:2] += self.slip.landed(step.side)
            measured = odo.landed(step.side, q, placed)
            if self.stride is not None:
                self.engine.stride_gain[:] = self.stride.landed(self.engine.centre, measured)
            off = measured - self.engine.centre
            off[2] = wrap_angle(off[2])
            self._offset = off
            # the soles' midpoint measured less planned: where a closing step aims from
            error = measured - self.engine.mid_frame()
            error[2] = wrap_angle(error[2])
            self.engine.frame_error = error
        return Footstep(step.side, float(xy[0]), float(xy[1]), stance.yaw + dyaw, step.z)

    # ------------------------------------------------------------------ ticks
    def targets(self, e: EngineTick) -> TickTargets:
        """The controller's targets for one engine tick."""
        rl = pin.SE3(rot_z(e.l_yaw), e.l_sole)
        rr = pin.SE3(rot_z(e.r_yaw), e.r_sole)
        phase = "double" if e.support == SUPPORT_DOUBLE else "single"
        cr, sr = math.cos(e.torso_roll), math.sin(e.torso_roll)
        roll = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
        torso = rot_z(e.torso_yaw) @ roll @ self._lean
        swing = rl if e.swing_frame == "l_sole" else rr
        return TickTargets(
            self.engine.k - 1, e.t, phase, e.support_frame, e.swing_frame, e.com, rl, rr,
            e.torso_yaw, torso, swing.translation.copy(), swing.rotation.copy(),
        )  # fmt: skip

    def tick(self, dt: float | None = None) -> np.ndarray:
        """One walk tick ``dt`` seconds after the last (default: the engine's ``dt``): the
        engine advances (by whole ticks), the feedback adjusts its targets, the controller
        solves; returns the configuration (the goals are its joints ``q[7:]``)."""
        start = time.perf_counter()
        if self.play is not None:
            present = self.present()
            step = self.engine.dt if dt is None else dt
            load, links = None, self._links
            if self._loads is not None and self.last is not None and links is not None:
                load = -np.sign(self._loads.torques(links, self.last.support))  # (NaN: unread)
            self._links = None if present is None else self.play.update(present, step, load)
        if self.landing is not None:  # (the last tick a walking double support: the mean goes on)
            e = self.last
            double = e is not None and e.support == SUPPORT_DOUBLE and e.state != "standing"
            self.landing.sample(self._present_configuration(), double)
        engine = self.engine
        if self._deferred_start and not self.calibrating:
            self._deferred_start = False
            engine.start()
        if self._finish_by is not None:
            xy, yaw = self.lag()
            tol_xy, tol_yaw = DRIVE_FINISH_TOLERANCE
            if engine.steps_taken >= self._finish_by or (xy <= tol_xy and yaw <= tol_yaw):
                self._finish_by = None
                engine.stop()
        dt = engine.dt if dt is None else float(dt)
        target_t = self._t + dt
        e = self.last
        flat = self.flat_liftoff  # (the present configuration read only while one is armed)
        if flat is not None and flat.armed and flat.hold(self._present_configuration()):
            self._paused += dt  # (the lift-off waits; the command's pose moves on)
            engine.advance_command(dt)
        while e is None or engine.k * engine.dt + self._paused < target_t - 1e-9:
            e = engine.tick()
            if self._offset is not None:  # the measured pose replaces the engine's own sum
                engine.odometry_offset[:] = self._offset
                self._offset = None
        self.last = e
        self._t = target_t
        if self._engine_walked and not engine.walking:
            self._walk_ended()
        self._engine_walked = engine.walking
        targets = self.targets(e)
        key = (targets.phase, targets.support, targets.swing)
        changed = key != self._previous
        self._previous = key
        stab = self.stabilizer
        if self.hold is not None and stab.enabled:
            targets = self._held_base(targets, dt)
        if stab.enabled:
            resting = self._yaw_rest_left > 0 and not stab.calibrating
            quiet = resting or self.quiet(e, engine.starting or self._deferred_start, engine.ending)
            stab.gains = self._gains[1 if quiet else 0]
            if quiet:
                stab.integral[:] = 0.0  # (the walk starts from an unwound integral)
            targets = stab.adjust(targets, e.com_vel, self.q, dt)
            odo = self.odometry
            if odo is not None and stab.last is not None and not stab.calibrating:
                est = stab.last
                if engine.walking and not odo.started:
                    odo.start(engine.feet, yaw_of(est.rotation))
                    if self.stride is not None:
                        self.stride.restart()
                    if self.slip is not None:
                        self.slip.restart()
                elif not (engine.walking or engine.starting) and odo.started:
                    odo.stop()  # (kept through a finish step)
                rotation, rate = self._heading_inputs(targets, est)
                if resting:
                    odo.rest(rotation, rate, dt)
                    self._yaw_rest_left -= 1
                else:
                    if self.trim is not None:  # (the gyro's bias trimmed in double supports)
                        rate = rate - self.trim.walker_tick(self, e, rotation, rate, dt)
                    odo.turn(rotation, rate, dt)
                    if self.slip is not None and odo.started:
                        self.slip.walker_tick(self, dt)
        if self.lift is not None:
            self._lift(targets)
        self._contacts(targets, dt)
        if self.flatten is not None:
            self.flatten.update(targets, self._present_configuration(), engine.walking, dt)
        try:
            self.q = self.controller.track(self.q, targets, dt, changed)
        except WbcError as exc:
            self.failed_solves += 1  # the robot holds its last goals
            self.failure_causes[failure_cause(exc, targets.phase)] += 1
        self.tick_time.append(time.perf_counter() - start)
        return self.q

    def _walk_ended(self) -> None:
        """The walk has ended: finish steps (:meth:`FinishSteps.after_walk
        <wbc.drive.finish.FinishSteps.after_walk>`), with the outer loop's odometry."""
        odo, q = self.odometry, self._present_configuration()
        if odo is not None and odo.started and self.engine.planned and q is not None:
            self.finish.after_walk(self.engine, odo, q)

    def _present_configuration(self, links: bool = True) -> np.ndarray | None:
        """The configuration of the servos' present positions (the base at the origin), or
        None if a position is unread; ``links`` (with :attr:`play`): the play taken out."""
        present = self._links if self.play is not None and links else self.present()
        if present is None or not np.all(np.isfinite(present)):
            return None
        return self.robot.with_joints(np.asarray(present, dtype=float))

    def _heading_inputs(self, targets: TickTargets, est: Any) -> tuple[np.ndarray, np.ndarray]:
        """The torso's rotation (its tilt used, and at rest its turn) and rate for the outer
        loop's heading (:class:`~wbc.drive.odometry.PoseOdometry`): the calibrated gyro
        (without the attitude filter's bias correction: about a leaning torso's vertical it
        is not observable, and it drifted the heading ~10° over 30 s on the randomised
        Bioloid 8) on the torso's tilt over the stance sole by the present joints (the sole
        flat: within 1° of the simulator's, where the filter's tilt was 10° off on the
        rocking model 0); with ``filter_heading`` the filter's rate and rotation."""
        q = None if self.filter_heading else self._present_configuration()
        if q is None:
            return est.rotation, est.angular_velocity
        (torso,) = self.robot.placements_in(q, targets.support, ["torso"])
        return torso.rotation, est.angular_velocity - self.stabilizer.estimator.gyro_correction

    def _held_base(self, targets: TickTargets, dt: float) -> TickTargets:
        """The CoM target shifted by the base's hold (:class:`~wbc.drive.odometry.BaseHold`):
        when the walk ends, against the error of the measured base (:meth:`_measured_base`)
        from the commanded pose (the engine's, less the odometry's frame error, as the
        closing step aims it)."""
        engine, hold = self.engine, self.hold
        assert hold is not None
        if engine.walking:
            self._walked = True
        elif self._walked:
            self._walked = False
            hold.begin()
        error = None
        base = self._measured_base() if hold.active else None
        if base is not None:
            error = engine.pose_cmd[:2] - engine.frame_offset[:2] - base
        offset = hold.update(error, dt, engine.walking)
        if not offset.any():
            return targets
        return targets.retarget(targets.com + np.r_[offset, 0.0], targets.torso_rotation)

    def _measured_base(self) -> np.ndarray | None:
        """The base over the planned soles by the present joints (:func:`~wbc.drive.odometry.
        base_over_soles`), or None if a position is unread."""
        return base_over_soles(self.robot, self.engine.feet, self._present_configuration())

    def _lift(self, targets: TickTargets) -> None:
        """The swing sole's lift (:class:`~wbc.drive.odometry.LiftGain`): in single support
        its height above the stance sole from the present joints (forward kinematics), the
        highest kept; at the swing's end the gain on the apex of the swings planned next
        (:attr:`WalkEngine.params <wbc.walking.engine.WalkEngine.params>`)."""
        if targets.phase == "single":
            q = self._present_configuration(links=self.play_lift)
            if q is not None:
                (swing,) = self.robot.placements_in(q, targets.support, [targets.swing])
                self._peak = max(self._peak, float(swing.translation[2]))
        elif self._peak > -math.inf:  # a swing has ended
            gain = self.lift.landed(self._apex, self._peak)  # type: ignore[union-attr]
            self._peak = -math.inf
            p = self.engine.params
            self.engine.params = replace(p, swing=replace(p.swing, apex=self._apex * gain))

    def _contacts(self, targets: TickTargets, dt: float) -> None:
        """The controller's soles in contact (:func:`~wbc.drive.contacts.move_contacts`)."""
        if self.engine.on_landing is not None:
            move_contacts(self.engine, self._held, targets, dt, self.contact_reach,
                          self.contact_rate, self.keep_clear)  # fmt: skip

    def _load_share(self, t: float) -> float | None:
        """The feed-forward's left share of the load (:attr:`load_ramp`) at this walk tick."""
        e, ramp = self.last, self.load_ramp
        return None if e is None or ramp is None else ramp.update(e.support, e.support_frame)

    # ------------------------------------------------------------------ target source
    def first(self) -> np.ndarray:
        return self.q[7:].copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        """The goals of playback time ``t`` (a deployment's target source): one walk tick
        of the time since the last call."""
        if self.before_tick is not None:
            self.before_tick(t)
        if self.closed_at is not None:
            return None
        dt = self.engine.dt if self._play_t is None else t - self._play_t
        self._play_t = t
        return self.tick(max(dt, 1e-9))[7:].copy()

    def deployment(
        self, bus: Any, config: DeployConfig | None = None, out: Callable[[str], None] = print
    ) -> Deployment:
        """A :class:`~wbc.servos.playback.Deployment` of this walker on ``bus`` (``config``
        defaults to the engine's rate with the present positions read, as the closed loop
        needs); its :meth:`~Deployment.run` plays until :meth:`close`."""
        config = config or DeployConfig(rate=min(100.0, 1.0 / self.engine.dt), read=True)
        if self.stabilizer.enabled and not (config.read and bus.can_read):
            raise ConfigurationError(
                "the closed loop reads the servos' present positions: a bus that can read, "
                "with read on (or closed=False)"
            )
        holder: list[Deployment] = []
        self.present = lambda: holder[0].last_present if holder else None
        source: Any = self
        if self.compensate > 0:
            from ..balance.compliance import CompensatedSource, ComplianceCompensator

            comp = ComplianceCompensator(self.robot, gain=self.compensate)
            fix = None
            if self.correct and self.stabilizer.enabled:
                from ..balance.compliance import EncoderCorrection

                fix = EncoderCorrection(self.robot.n_joints, **DRIVE_CORRECTION)
            source = CompensatedSource(
                self, comp, lambda t: self.last.support if self.last else SUPPORT_DOUBLE,
                self.present if fix is not None else None, fix,
            )  # fmt: skip
            if self.load_ramp is not None:  # (one update a goal: the walk tick just taken)
                source.share = self._load_share
        dep = Deployment(bus, source, self.robot, config, out=out)
        holder.append(dep)
        return dep
