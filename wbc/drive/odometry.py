"""Where a driven robot really is: the body's pose from the torso IMU's heading and the
encoders, for the walk engine's outer loop (:attr:`wbc.walking.engine.WalkEngine.odometry_offset`).

The encoders alone (the engine's own leg odometry) see where each swing sole lands relative
to the stance sole, but not a stance sole turning on the floor: a rotational slip of a few
tenths of a degree per step turns the whole path, and the feet's heading with it. The torso
IMU's gyro sees it. :class:`PoseOdometry` keeps each sole's pose in the walk's world frame:

* the torso's heading ``ψ`` integrates the calibrated gyro ``ω`` (torso frame) on the
  estimated tilt (:meth:`PoseOdometry.turn`; the estimate's own heading is the encoders',
  planned soles assumed), from the estimate's heading when the walk starts;
* at each landing (the end of the double support that follows it) the stance sole's heading
  is the torso's plus the torso-to-sole yaw of the present joints (forward kinematics), its
  position where it landed (a sole standing on the floor is taken not to slide: the encoders
  cannot see a slide, the gyro only a turn); the landed sole is placed from the stance sole
  by the present joints;
* the walking frame measured is the soles' midpoint, heading their mean.

**The stance sole's heading, blended** (``heading_gain`` k, the Walker's
:data:`DRIVE_HEADING_GAIN`): at each landing the stance sole's heading
moves the share k from the encoders' chain (where the last landing placed it, from the other
sole) to the gyro's (the torso's heading plus the stance leg's torso-to-sole turn). The
gyro's goes through one leg's joints, whose play and ticks read that leg's turn a few
tenths of a degree off, differently for the two legs; the landed sole 6–7 cm beside it is
then placed forward or back by that error, alternately, and the walk's position drifts. The
blend damps the alternation (to k / (2 − k) of it) and follows a turn the gyro keeps seeing
within (1 − k)^n after n landings (k = 1: the gyro's alone); where the two disagree by more
than ``heading_band`` (:data:`DRIVE_HEADING_BAND`, 1°: a sole turned on the floor) the gyro's
is followed at once, within (1 − k) × the band.

**The gyro's bias about the vertical**, learnt at rest (:meth:`PoseOdometry.rest`): what
the start-up calibration leaves about the vertical integrates into the heading unseen (the
accelerometer levels only roll and pitch). Its 0.15 s of samples take any twist of a robot
settling or rocking at rest for bias (on the randomised Bioloids of benchmarks/drive.md up
to 14° of heading over 30 s). Standing still, the torso does not turn on average (it may
rock, or twist back and forth a little in the servos' backlash), so the heading's mean rate
over a rest, ``b = Σ δψ / Σ dt`` (``δψ`` each tick's heading change,
:meth:`PoseOdometry.turn`, from the calibrated gyro), is the bias left, and the heading
integrates ``δψ − b dt`` (1.5 s of rest: within 6° over 30 s on the same models; the
Walker's rest for it, ``yaw_rest_s``, 1.5 s by default). Not the vertical rate's mean,
``Σ (u · ω) dt / Σ dt`` with ``u`` the world's up: a torso rocking in roll and pitch out of
phase has one (the rocking's enclosed area per cycle) while its heading stays.

The error left is the gyro's bias (with a rest: the noise and the robot's slow creep over
it) and the soles' sliding. On the stiff, rocking randomised Bioloid 0 the torso twists
±0.25° over the 1.5 s rest inside the servos' play (the encoders read 0.03–0.1° of it), a
bias error of ±0.17°/s, and walking the gyro reads the heading's rate 0.12–0.16°/s lower
than at rest (its bias about the torso's pitch axis, 3°/s after the start-up calibration,
at the walk's lean and roll, and what 100 Hz samples miss): 5° and 4–5° over 30 s, which
add or cancel with the rest's twist (benchmarks/drive.md, 2026-12-07, i33t).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..balance.estimator import exp3
from ..exceptions import ConfigurationError
from ..geometry import clip_norm, mean_angle, relative_pose, rot_z, wrap_angle, yaw_of
from ..model import Robot
from ..roles import SOLE_FRAMES
from ..walking.footsteps import Footstep, Side, other_side
from ..walking.geometry import rot2
from .gyro_trim import RestPeriods

#: the soles' relative heading (rad) at which the bias learnt while walking
#: (:meth:`PoseOdometry.landed`) takes half the weight: a stance sole turns on the floor
#: mostly while the feet turn (on the compliant randomised Bioloids its slip was learnt as
#: bias at full weight)
WALK_TURN = 0.03

#: the share of the gyro's stance-sole heading the outer loop's odometry takes at each
#: landing (:class:`PoseOdometry` ``heading_gain``), the rest the
#: encoders' chain (the heading the last landing placed the sole at); 1: the gyro's alone.
#: The gyro's heading of a stance sole goes through the stance leg's joints, whose play and
#: ticks read each leg's turn a few tenths of a degree off, differently for the two legs: at
#: every landing the landed sole, 6–7 cm beside the stance sole, is then placed forward or
#: back by that error, alternately, and the walk's position drifts. 0.5 damps it. With the
#: robot standing still after its walk (``Walker(quiet_stand="end")``: model 0 no longer
#: turns on its soles, which had made it 14–22° off on three runs blended), random sequences
#: 0, 1, 3, 6, 8 × randomised Bioloids 0–9 beside 1 (45 runs, benchmarks/drive.md,
#: thirteenth session): displacement within 15 % 31 -> 37, mean error 23.3 -> 19.6 mm;
#: heading 33 -> 34 of 35, mean 2.18 -> 2.19°, median 1.60 -> 1.80°; no fall. (Before it,
#: on 73 runs: displacement 44 -> 48, heading 58 of 63 both.) The scripted walks on the
#: nominal model (no play) are the same to the digit
DRIVE_HEADING_GAIN = 0.5

#: ... within this disagreement of the two (rad): beyond it the gyro's is followed (within
#: (1 − gain) × it), a stance sole turned on the floor being taken at once (without it the
#: randomised Bioloid with the most play ended a 30 s walk 41° off, benchmarks/drive.md)
DRIVE_HEADING_BAND = math.radians(1.0)

#: the share of the planned swing apex the swing sole should reach, measured
#: (:class:`LiftGain`): below it the swing is planned higher
LIFT_WANT = 0.7


class PoseOdometry:
    """Pose odometry of a walking robot from the torso heading and the encoders (module
    docstring). :meth:`start` at the walk's start, :meth:`turn` every tick, :meth:`landed`
    at each landing."""

    def __init__(
        self,
        robot: Robot,
        gyro: bool = True,
        walk_gain: float = 0.0,
        encoder_rest: bool = False,
        heading_gain: float = 1.0,
        heading_band: float = DRIVE_HEADING_BAND,
        rest_rotation: bool = False,
        rest_periods: bool = False,
    ) -> None:
        if not 0.0 < heading_gain <= 1.0:  # (NaN too)
            raise ConfigurationError(f"heading_gain must be in (0, 1], got {heading_gain}")
        if not heading_band >= 0.0:  # (NaN too)
            raise ConfigurationError(f"heading_band must be >= 0 (rad), got {heading_band}")
        #: the largest disagreement of the gyro's and the chain's stance heading blended (rad;
        #: beyond it the gyro's is followed within (1 − heading_gain) × the band)
        self.heading_band = float(heading_band)
        self.robot = robot
        #: the share of the gyro's stance-sole heading taken at each landing (1: all of it;
        #: below, the rest is the encoders' chain: :meth:`landed`)
        self.heading_gain = float(heading_gain)
        #: at rest, the torso's turn seen by the encoders is not bias (:meth:`rest`)
        self.encoder_rest = bool(encoder_rest)
        #: at rest, the gyro's whole bias (3, torso frame) is learnt less the torso's rotation
        #: seen by the encoders, and taken out of the rate before the heading's increment
        #: (:meth:`rest`; ``encoder_rest``'s turn included)
        self.rest_rotation = bool(rest_rotation)
        #: the rest's bias over whole periods of its rocking (:class:`RestPeriods`), or None
        self.periods = RestPeriods() if rest_periods else None
        #: the gyro's bias learnt at rest with ``rest_rotation`` (rad/s, torso frame)
        self.rate_bias = np.zeros(3)
        self._rest_rate = np.zeros(3)  # Σ ω dt over the rests, less the encoders' rotation
        self._rest_rotation: np.ndarray | None = None  # the torso's last rotation at rest
        #: > 0: the bias about the vertical learnt while walking too (:meth:`landed`)
        self.walk_gain = float(walk_gain)
        self.time = 0.0  # s of :meth:`turn` and :meth:`rest` ticks
        self._placed: dict[Side, float] = {}  # when each sole's heading was last set
        self._turn: dict[Side, float] = {}  # |the soles' relative heading| at its landing
        self.gyro = gyro  # False: the stance sole keeps its landed heading (encoders alone)
        self.heading = 0.0  # the torso's heading (rad, world), gyro-integrated
        self.start_heading = 0.0
        self.soles: dict[Side, np.ndarray] = {}  # side -> (x, y, heading), world
        self.started = False
        #: the gyro's bias about the vertical learnt at rest (rad/s; module docstring)
        self.yaw_bias = 0.0
        self.rest_time = 0.0  # s of rest it was learnt over
        self._rest_angle = 0.0  # rad, Σ δψ over them
        #: the torso's heading by the encoders over the rests: (last, Σ change) (rad)
        self._rest_turn: tuple[float, float] | None = None

    def start(self, feet: dict[Side, Footstep], torso_heading: float) -> None:
        """Start from the soles' planned placements and the torso's estimated heading."""
        self.soles = {side: np.array([f.x, f.y, f.yaw]) for side, f in feet.items()}
        self.heading = float(torso_heading)
        self.start_heading = self.heading  #: the torso's heading at :meth:`start` (rad)
        self.started = True
        self._placed, self._turn = {}, {}

    def stop(self) -> None:
        self.started = False

    def turn(self, rotation: np.ndarray, rate: np.ndarray, dt: float) -> None:
        """One tick of the heading: ``rotation`` the torso's estimated (3, 3) rotation (its
        tilt used, its heading not), ``rate`` the calibrated gyro (rad/s, torso frame): the
        heading of ``Rz(ψ) · T · Exp(ω dt)`` with ``T`` the tilt (not ``ψ += (R ω)_z dt``: a
        torso leaning forward while it rocks sideways changes its heading by more than the
        vertical rate's integral, ~20° over 30 s of walking, benchmarks/drive.md), less the
        vertical bias learnt at rest (:attr:`yaw_bias`)."""
        rate = np.asarray(rate, dtype=float) - self.rate_bias
        self.heading += self._increment(rotation, rate, dt) - self.yaw_bias * dt
        self.time += dt

    def unbiased(self, rotation: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """``rate`` (torso frame) less the biases :meth:`turn` takes out: :attr:`rate_bias`
        and the vertical bias :attr:`yaw_bias` about the world's up in the torso's frame
        (``rotation``'s tilt)."""
        up = np.asarray(rotation, dtype=float)[2]  # (Rᵀ e_z)
        return np.asarray(rate, dtype=float) - self.rate_bias - self.yaw_bias * up

    def rest(self, rotation: np.ndarray, rate: np.ndarray, dt: float) -> None:
        """One tick standing still (both soles on the floor, the robot not walking), as
        :meth:`turn`; the heading's mean rate over the rests so far is the gyro's bias about
        the vertical (:attr:`yaw_bias`, module docstring), taken out of the heading from
        then on. With ``rest_rotation``: the bias is the whole rate's, in the torso's frame,
        ``b = (Σ ω dt − Σ log(R_{k−1}ᵀ R_k)) / Σ dt`` with ``R`` the torso's rotation over
        the soles by the encoders (``rotation``), taken out of the rate (:attr:`rate_bias`):
        a torso that settles or twists over its soles at rest is not bias, and the bias about
        the torso's other axes is not projected onto the vertical at the rest's lean alone
        (the walk leans further: benchmarks/drive.md, 2026-12-07)."""
        if self.rest_rotation:
            last, self._rest_rotation = self._rest_rotation, np.array(rotation, dtype=float)
            seen = np.zeros(3) if last is None else pin.log3(last.T @ self._rest_rotation)
            self._rest_rate += np.asarray(rate, dtype=float) * dt - seen
            self.rest_time += dt
            self.rate_bias = self._rest_rate / self.rest_time
            self.heading += self._increment(rotation, np.asarray(rate) - self.rate_bias, dt)
            self.time += dt
            return
        d = self._increment(rotation, rate, dt)
        self._rest_angle += d
        self.rest_time += dt
        turned = 0.0
        if self.encoder_rest:
            yaw = yaw_of(rotation)
            last, turned = self._rest_turn or (yaw, 0.0)
            turned += wrap_angle(yaw - last)
            self._rest_turn = (yaw, turned)
        if self.rest_time > 0:
            self.yaw_bias = (self._rest_angle - turned) / self.rest_time
        if self.periods is not None:  # (over whole periods of the rocking)
            self.yaw_bias = self.periods.add(rate, d, dt, self.yaw_bias)
        self.heading += d - self.yaw_bias * dt
        self.time += dt

    @staticmethod
    def _increment(rotation: np.ndarray, rate: np.ndarray, dt: float) -> float:
        """The heading's change over one tick of the rate (:meth:`turn`)."""
        yaw = yaw_of(rotation)
        c, s = math.cos(yaw), math.sin(yaw)
        tilt = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ rotation
        return yaw_of(tilt @ exp3(np.asarray(rate, dtype=float) * dt))

    def landed(self, side: Side, q: np.ndarray, placed: np.ndarray | None = None) -> np.ndarray:
        """``side`` has landed (``q``: the configuration of the present joints): the soles'
        poses updated; returns the walking frame measured (x, y, heading; world). ``placed``
        (x, y, heading): the landed sole in the stance sole's frame, if not ``q``'s
        (:class:`LandingMean`)."""
        robot = self.robot
        stance = other_side(side)
        M_t = robot.frame_placement(q, "torso")
        M_st = robot.frame_placement(q, SOLE_FRAMES[stance])
        M_sw = robot.frame_placement(q, SOLE_FRAMES[side])
        st = self.soles[stance]
        if self.gyro:
            gyro = self.heading + yaw_of(M_t.actInv(M_st).rotation)
            since = self._placed.get(stance)
            turn = max(abs(yaw_of(M_st.actInv(M_sw).rotation)), self._turn.get(stance, 0.0))
            if self.walk_gain > 0 and since is not None and self.time > since:
                # the stance sole's heading by the gyro against the encoders' (placed at its
                # landing, from the other sole): the bias, if the sole did not turn on the
                # floor — less likely the less the feet turn (WALK_TURN, rad)
                weight = self.walk_gain / (1.0 + (turn / WALK_TURN) ** 2)
                self.yaw_bias += weight * wrap_angle(gyro - st[2]) / (self.time - since)
            k, band = self.heading_gain, self.heading_band
            if k >= 1.0:
                st[2] = gyro
            else:  # (beyond the band the gyro's turn is taken: a sole turned on the floor)
                st[2] = gyro - (1.0 - k) * min(max(wrap_angle(gyro - st[2]), -band), band)
        if placed is None:
            rel = M_st.actInv(M_sw)
            placed = np.r_[rel.translation[:2], yaw_of(rel.rotation)]
        xy = st[:2] + rot2(st[2]) @ placed[:2]
        self.soles[side] = np.array([xy[0], xy[1], wrap_angle(st[2] + placed[2])])
        self._placed[side] = self.time
        self._turn[side] = abs(float(placed[2]))
        sw = self.soles[side]
        return np.array([0.5 * (st[0] + sw[0]), 0.5 * (st[1] + sw[1]), mean_angle(st[2], sw[2])])


class LandingMean:
    """A landed sole's placement from the stance sole averaged over the double support that
    ends with its landing's measurement (the engine measures a landing at the double
    support's last tick, :attr:`wbc.walking.engine.WalkEngine.on_landing`): both soles stand,
    their relative placement is fixed while the readings through the servos' play and dither
    move. :meth:`sample` every tick with the present joints, :meth:`placed` at the landing:
    the mean over the last ``share`` of the double support's ticks so far (at least the
    present one; 0: the present tick alone, as without it)."""

    def __init__(self, robot: Robot, share: float) -> None:
        if not 0.0 <= share <= 1.0:  # (NaN too)
            raise ConfigurationError(f"landing share must be in [0, 1], got {share}")
        self.robot = robot
        self.share = float(share)
        #: per tick of the double support so far: the right sole from the left (x, y, yaw)
        #: and the left from the right
        self._rows: list[np.ndarray] = []

    def sample(self, q: np.ndarray | None, double: bool) -> None:
        """One tick: ``double`` False (the last tick not a walking double support) restarts
        the mean; ``q`` the present joints' configuration (None: unread, not sampled)."""
        if not double:
            self._rows.clear()
        if q is not None:
            (rel,) = self.robot.placements_in(q, SOLE_FRAMES["left"], [SOLE_FRAMES["right"]])
            inv = rel.inverse()
            self._rows.append(np.r_[rel.translation[:2], yaw_of(rel.rotation),
                                    inv.translation[:2], yaw_of(inv.rotation)])  # fmt: skip

    def placed(self, side: Side) -> np.ndarray | None:
        """The landed ``side``'s mean placement in the other sole's frame (x, y, heading), or
        None if no tick was sampled."""
        if not self._rows:
            return None
        n = max(1, math.ceil(self.share * len(self._rows)))
        mean = np.mean(self._rows[-n:], axis=0)
        return mean[:3] if side == "right" else mean[3:]


#: :class:`PlayInverse`'s ``load`` modes: the load's side of the play unused, for the still
#: readings, everywhere it is known
PLAY_LOAD_MODES = ("", "still", "always")


class PlayInverse:
    """The links' positions from encoders that read through a gear play (backlash): per joint
    the encoder reads the motor side, which follows the link only once the play ``p`` is
    taken up, so while a joint moves the encoder lags the link by ``p / 2`` against the
    motion (and stands still while the link crosses the play after a reversal). The inverse
    of that play: the link is the encoder's reading plus ``p / 2`` in the direction of the
    reading's last change (``0`` before any: the middle of the play).

    On the randomised Bioloids of benchmarks/drive.md (0–1° of play) the leg odometry read
    the steps long by the play (a leg moving forward reads behind its links at the stance
    sole and at the landed sole alike). ``play`` (rad, one or per joint, model order) is the
    servo's: measured per servo on the hardware, the servo model's in the simulator.

    ``hold`` (s): a reading standing still longer than this is taken at the middle of the
    play (the link may have turned back inside it: a joint rocking by less than the play
    never moves its reading, and its last side goes stale). The inverse is of the
    simulator's play, where the reading follows the link's motion.

    ``load`` (the side of a loaded link, from :meth:`update`'s ``load``: the direction the
    static load pushes each link, the negated torque its servo holds): ``""`` unused (the
    default); ``"still"``: a reading standing still longer than ``hold`` is taken at the
    load's flank instead of the middle (a link that sagged under its load dragged its
    reading along and rocks inside the play without moving it); ``"always"``: the load's
    flank wherever the load is known (a gearbox whose link is held against one flank by
    its load)."""

    def __init__(
        self, play: float | np.ndarray, n: int, hold: float = math.inf, load: str = ""
    ) -> None:
        given = np.asarray(play, dtype=float)
        if given.shape not in ((), (n,)):
            raise ConfigurationError(f"play must be one number or {n} (one per joint), got {play}")
        half = 0.5 * np.broadcast_to(given, (n,))
        if not (np.all(np.isfinite(half)) and np.all(half >= 0)):
            raise ConfigurationError(f"play must be finite numbers >= 0 (rad), got {play}")
        if not hold > 0:
            raise ConfigurationError(f"hold must be a number > 0 (s), got {hold}")
        if load not in PLAY_LOAD_MODES:
            raise ConfigurationError(f"load must be one of {PLAY_LOAD_MODES}, got {load!r}")
        self.load = load
        self.half = half.copy()
        self.hold = float(hold)
        self.side = np.zeros(n)  # the direction of each reading's last change (−1, 0, 1)
        self.still = np.full(n, math.inf)  # s since each reading last changed
        self._last: np.ndarray | None = None

    def update(
        self, sensed: np.ndarray, dt: float = 0.0, load: np.ndarray | None = None
    ) -> np.ndarray:
        """One reading of the encoders (rad, NaN: unread) ``dt`` s after the last; returns
        the links' positions. ``load`` (per joint −1, 0, 1, or None: unknown): the direction
        the load pushes each link, used by the ``load`` mode."""
        sensed = np.asarray(sensed, dtype=float)
        if self._last is not None:
            d = sensed - self._last
            read = np.isfinite(d)
            moved = read & (d != 0)
            self.side = np.where(read & (d > 0), 1.0, np.where(read & (d < 0), -1.0, self.side))
            self.still = np.where(moved, 0.0, self.still + dt)
            sensed_or_last = np.where(read, sensed, self._last)
            self._last = np.where(np.isfinite(sensed), sensed, sensed_or_last)
        else:
            self._last = sensed.copy()
        moving = self.still <= self.hold
        side = np.where(moving, self.side, 0.0)
        if load is not None and self.load:
            pushed = np.sign(np.asarray(load, dtype=float))
            known = np.isfinite(pushed) & (pushed != 0)
            side = np.where(known & (~moving if self.load == "still" else True), pushed, side)
        return sensed + self.half * side


class StrideGain:
    """How much longer to plan the steps of legs whose steps fall short (compliant servos):
    per axis (forward, left, heading), the walking frame's measured move between landings
    ``m`` against its planned move ``p`` (each in its own previous frame), the efficiency a
    least-squares fit through the origin with forgetting ``λ`` per step,
    ``e = (Σ λ^k m p + w) / (Σ λ^k p² + w)`` (``w``: a prior of ``e = 1``, worth one step of
    ``prior`` per axis), and the gain ``1 / e`` within ``[1, most]`` (never shorter: a step
    measured long is the odometry's error more likely than the legs'), forward and sideways
    only: the turn measured carries the gyro's bias (with the heading's gain too, the random
    sequences' heading within 15 % dropped from 64 to 59 of 80, benchmarks/drive.md). The
    engine plans the stride × the gain, within its velocity limits
    (:attr:`wbc.walking.engine.WalkEngine.stride_gain`)."""

    def __init__(
        self,
        most: float,
        forget: float = 0.9,
        prior: tuple[float, float, float] = (0.01, 0.01, 0.02),
    ) -> None:
        self.most = float(most)
        self.forget = float(forget)
        self.prior = np.square(prior)
        self.mp = np.zeros(3)
        self.pp = np.zeros(3)
        self.gain = np.ones(3)
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def restart(self) -> None:
        """A new walk: the next landing's frames are the first pair (the fit is kept)."""
        self._last = None

    def landed(self, planned: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """The walking frame planned and measured (x, y, heading; world) after a landing;
        returns the gain (3,)."""
        if self._last is not None:
            p = relative_pose(self._last[0], planned)
            m = relative_pose(self._last[1], measured)
            self.mp = self.forget * self.mp + m * p
            self.pp = self.forget * self.pp + p * p
            efficiency = (self.mp + self.prior) / (self.pp + self.prior)
            self.gain[:2] = np.clip(1.0 / np.maximum(efficiency[:2], 1e-3), 1.0, self.most)
        self._last = (np.array(planned, dtype=float), np.array(measured, dtype=float))
        return self.gain


class LiftGain:
    """How much higher to plan the swing of legs whose swing sole stays low (compliant or
    lagging servos; the stance leg's sag): per swing, the swing sole's highest point above
    the stance sole measured from the encoders (forward kinematics of the present joints),
    ``h``, against the height wanted, ``a`` = ``want`` × the planned apex; the gain on the
    planned apex moves by ``(a / h)^rate`` per swing, within ``[1, most]`` (an integral on
    the measured apex's log: the swing planned higher until the real sole reaches ``a``). On
    the randomised Bioloids of benchmarks/drive.md the swing sole planned 10 mm high reached
    7 mm on the stiff models and 2 mm on the most compliant (the servos lag the swing's
    0.2 s rise): it touched the floor for the last quarter of almost every swing, and for
    most of it on the compliant one, dragging, the steps short. ``want``
    (:data:`LIFT_WANT`): only the swing staying low is raised: wanting the full apex raised
    the stiff models' too, and their errors grew as much as the compliant one's shrank."""

    def __init__(self, most: float, rate: float = 0.5, want: float = LIFT_WANT) -> None:
        self.most = float(most)
        self.rate = float(rate)
        self.want = float(want)
        self.gain = 1.0

    def landed(self, apex: float, peak: float) -> float:
        """A swing ended: ``apex`` the apex planned without the gain (m), ``peak`` the swing
        sole's highest point measured above the stance sole (m); returns the gain on the
        planned apex."""
        if math.isfinite(peak) and apex > 0:
            want = self.want * apex
            ratio = want / max(peak, want / self.most)
            self.gain = min(max(self.gain * ratio**self.rate, 1.0), self.most)
        return self.gain


class BaseHold:
    """After a stop, the base brought onto its commanded place: the walk's last steps land
    where the commands put the soles, but the robot then stands with its base off its
    standing pose over them (compliant joints sag, the feedback's integral, the CoM's
    rest target at the soles' midpoint: on the randomised Bioloids of
    benchmarks/drive.md 5–25 mm, a steady error of the whole walk). For ``seconds`` after
    the walk ends (:meth:`begin`) the CoM target is shifted (:attr:`offset`, world xy)
    against the measured base's error (the state estimate: encoders and IMU) at most
    ``rate`` m/s, at most ``reach`` m from the plan, until the error is within
    ``tolerance``; standing, the shift is kept; walking, it returns to none at ``rate``."""

    def __init__(self, reach: float, rate: float, seconds: float, tolerance: float = 5e-4) -> None:
        for name, value in (("reach", reach), ("rate", rate), ("seconds", seconds)):
            if not (math.isfinite(value) and value >= 0):
                raise ConfigurationError(
                    f"base hold: {name} must be a finite number >= 0, got {value}"
                )
        self.reach, self.rate, self.seconds = float(reach), float(rate), float(seconds)
        self.tolerance = float(tolerance)
        self.offset = np.zeros(2)  #: the CoM target's shift (m, world xy)
        self.left = 0.0  #: s of holding left

    @property
    def active(self) -> bool:
        return self.left > 0

    def begin(self) -> None:
        """The walk has ended: hold for ``seconds``."""
        self.left = self.seconds

    def end(self) -> None:
        """A new walk starts: stop holding (the shift then returns to none)."""
        self.left = 0.0

    def update(self, error: np.ndarray | None, dt: float, walking: bool) -> np.ndarray:
        """One tick: ``error`` the base's commanded less measured position (m, world xy;
        None: unknown); returns :attr:`offset`."""
        step = self.rate * dt
        if walking:
            self.offset = self.offset - clip_norm(self.offset, step)
        elif self.left > 0 and error is not None:
            self.left = 0.0 if float(np.hypot(*error)) <= self.tolerance else self.left - dt
            self.offset = clip_norm(self.offset + clip_norm(np.asarray(error, float), step),
                                     self.reach)  # fmt: skip
        return self.offset


def base_over_soles(
    robot: Robot, feet: dict[Side, Footstep], q: np.ndarray | None
) -> np.ndarray | None:
    """Standing on both soles: the base's position (x, y) over the planned soles ``feet`` by
    the configuration ``q`` (forward kinematics, the soles flat; the mean of the two), or
    None if ``q`` is (a position unread)."""
    if q is None:
        return None
    xy = np.zeros(2)
    for side, step in feet.items():
        sole = robot.frame_placement(q, SOLE_FRAMES[side])  # (the base at the origin)
        base = pin.SE3(rot_z(step.yaw), step.position) * sole.inverse()
        xy += 0.5 * base.translation[:2]
    return xy
