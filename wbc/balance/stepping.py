"""Step placement from the measured DCM: re-plan the footsteps when a push moves the DCM.

Inside the closed loop (:class:`~wbc.walking.loop.Session`'s ``stepping``), in single support
(after its first ``settle`` s, not in its last ``min_remaining`` s), each tick compares the
estimated divergent component of motion (DCM, ``ξ = c + ċ/ω``, :mod:`.estimator`) with the
reference's. The error beyond a dead band (what the unpushed walk shows on the compliant body),
``e = dz(ξ_meas − ξ_ref)``, grows as ``e^{ω t}`` until the landing (LIPM: both DCMs diverge
from the same CoP); the classic DCM step adjustment (Englsberger et al. 2015; placo's
``update_supports`` adjusts from the measured DCM too) moves the landing — and every later
footstep — so that the DCM keeps its planned offset to the new supports. The shift is
``δ = e / s`` with ``s = ∂ξ_ref(t)/∂δ`` the sensitivity of the re-planned reference's DCM now
to the shift (:meth:`StepAdjuster.sensitivity`, ≈ ``e^{−ω (t_land − t)}`` times the share of
the ZMP path that moves), so that, unclipped, the re-planned reference's DCM is the measured
one (less the dead band). The shift is clipped to the landings the robot can make
(:func:`feasible_shift`): the feet never cross and keep ``min_clearance``
(:meth:`~wbc.walking.footsteps.FootstepPlan.validate`), both ankles within the leg reach
(:func:`~wbc.walking.footsteps.check_stance`) and both hip rolls within their limits
(:meth:`~wbc.walking.legs.LegGeometry.leg_rolls`). A re-plan rebuilds the rest of the walk
with wbc.walking's own generators (:func:`~wbc.walking.schedule.sole_tracks`,
:func:`~wbc.walking.schedule.zmp_knots` and the LIPM generator
:func:`~wbc.walking.lipm.lipm_com_for_zmp`: the CoM from the current CoM target whose ZMP
follows the new path exactly and whose DCM comes to rest over the final feet — with the
footsteps moved by ``δ`` its DCM now is the measured one); the swing already under way is
bent smoothly toward its new landing (no jump in any position target). Every controller
family benefits: they all track the re-planned targets. (The preview controller, the walks'
own generator, is not used to re-plan: started off its plan it swings the ZMP far outside
the soles to catch up, 0.4 m on ``walk10`` for a 3 cm DCM error.)

**Planned recovery steps** (``steps_ahead`` > 1; off by default, measured below): one re-plan
places the landing under way *and* the steps after it, each taking what the steps before it
could not (:meth:`StepAdjuster.place`): step ``k + j`` and the later ones move by an increment
``Δ_j``, chosen in turn as ``Δ_j + r / s_j`` clipped to the landings the legs can make, with
``s_j`` the sensitivity of the reference's DCM now to it and ``r ← r − s_j ΔΔ_j`` what is left;
with ``double_support``, once a catch has begun, the next landing is re-planned in the double
support too (its swing not yet started, so the whole swing's reach). The LIPM says how little
a later step buys on these walks: each is ``e^{−ω T}`` less effective than the one before (``T``
the step's period; 1/20 on ``walk10_wb``: 0.4 s at ω = 7.5 /s), so 80 mm of second step is
worth 4 mm of DCM now.

**The band's centre** (``baseline_tau`` > 0): the compliant body lags its plan the same way
step after step, differently on either foot (``lateral_wb``: +24 mm sideways on one stance,
−10 mm on the other); the dead band is centred on the running mean of the error per stance
side (fed only by errors inside the band, so a push does not move it) rather than on zero.

**The swing landed in the measured frame** (``landing``; off by default, measured below):
the controller places the swing sole relative to its own base; a pushed robot's base is
pitched about the stance sole (the compliant stance hip yielding), and the sole lands where
the same relative pose puts it from the *measured* base — short and high. :meth:`StepAdjuster.
land` moves the swing target so that the measured base carries it to the planned place.
**Step timing** (``hurry``; off): in a double support pushed along the walk, the walk's
clock runs faster (:meth:`StepAdjuster.rate`, read by the session's ``at_time``).

What no step can do: a push *away from the swing foot* (the physics benchmark's lateral push)
sends the DCM toward the stance sole's outer edge; a step of the swing foot cannot land beyond
that edge (the legs would cross), so once the DCM is past it the robot falls whatever the
steps (LIPM, :func:`capture_bounds`: 0.934 N·s on ``walk10``, benchmarks/pushes.md).

**Multi-step recovery** (``until_inside``; off): the catch goes on step after step while
each next single support still finds the DCM error beyond the band, then rests. **The
landing time** (``hurry_single``; off): in a single support being caught, the clock runs
faster when the swing lacks the room for the shift the error asks (:meth:`rate`). With
``catch_band`` a catch under way takes the whole error, not the dead band's less.

**Early touch-down** (``touchdown``; off; needs the estimator's contact detection,
``Gains.contact_band``): a push forward pitches the body about the stance toe and the swing
sole's toe meets the floor early, short of its landing (issue 30: 20 mm short at 0.6 N·s).
During a catch, a swing sole found down that many ticks running lands where it is: that step
and every later one move by its shortfall (the rest of the plan re-based on the landed
foothold, the CoM re-planned from it) and the walk's clock jumps to the landing
(:meth:`StepAdjuster.rate`), so the next step takes the catch. Measured: one bisection step
forward, costs the walk without the feed-forward (the next swing's toe meets the floor too:
steps of a few mm; benchmarks/pushes.md, seventh pass).

**The push caught in its own step** (``trigger_jump``, ``lift``; issue 30; on by default):
the dead band swallows a push's first 40 ms and the re-plan came a step later. A jump of the
DCM error along the walk in one tick (a push: 25 mm at 0.6 N·s; unpushed: 14 mm at most,
past the support switch's tick, ``trigger_skip``) starts the catch at once: that swing's band
drops to ``trigger_band``, the landing correction (``landing``, latched by ``landing_catch``)
starts, and the swing target is raised by ``lift`` (:meth:`StepAdjuster.lifted`; lift first,
then reach: the pitched body puts the swing toe on the floor 20 ms after the push). Measured
(benchmarks/pushes.md): forward 0.547 → 0.711, backward 0.461 → 0.602 N·s; the same
randomised plants up. Off: ``{"trigger_jump": 0, "landing": 0, "lift": 0}``. Every other
term here is off by default (sideways on ``walk10`` 0.797 → 0.844 N·s; the bound 0.934).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, TrajectoryError
from ..model import Robot
from ..recording import SUPPORT_DOUBLE
from ..walking.footsteps import FootstepPlan
from ..walking.legs import LegGeometry
from ..walking.lipm import lipm_com_for_zmp
from ..walking.reference import WalkingReference
from ..walking.schedule import (
    GaitTiming,
    Phase,
    SwingParams,
    build_phases,
    sample_knots,
    sole_tracks,
    zmp_knots,
)
from ..walking.spline import smooth
from .footholds import bend, bend_rate, dead_zone, feasible_shift, shifted_plan

#: m: the DCM error an unpushed walk shows on the Bioloid (stance heading frame), along the
#: walk and sideways (hqp-daqp: 16 mm, its torso rolls at lift-off): the dead bands of a
#: robot that states none (robot.toml ``[balance.stepping]``; the OP3's: 60 mm,
#: benchmarks/op3.md)
BAND_X = 0.025
BAND_Y = 0.018
#: the push trigger's DCM jump per tick of a robot that states none, as a share of its dead
#: band along the walk (the Bioloid: 18 mm; its unpushed ``walk10_wb``'s largest jump 6–8
#: mm, 14 mm on 50 randomised plants past the support switch; a 0.6 N·s push's 25 mm)
TRIGGER_SHARE = 0.72


@dataclass(frozen=True)
class SteppingParams:
    """When and how far the footsteps move (module docstring)."""

    threshold: float = 0.005  # m: the smallest footstep shift worth a re-plan
    #: m: DCM error along the walk (heading frame) a walk shows unpushed; None: the robot's
    #: (robot.toml ``[balance.stepping]``, measured on it), else :data:`BAND_X`
    band_x: float | None = None
    band_y: float | None = None  # m: ... sideways; None: the robot's, else :data:`BAND_Y`
    settle: float = 0.04  # s: no re-plan in the first 40 ms of a single support (lift-off)
    gain: float = 1.0  # footstep shift per m of predicted DCM error
    min_remaining: float = 0.05  # s: no re-plan in the swing's last 50 ms (it is landing)
    min_clearance: float = 0.005  # m between the feet (as the footstep plans)
    max_shift: float = 0.08  # m: largest shift of a step from the plan before its re-plans
    max_foot_speed: float = 0.6  # m/s: peak speed the bend adds to the swing sole (≈ 0.75 of
    # the AX-12A's no-load speed at the ~0.13 m hip-to-ankle lever)
    hold_ticks: int = 3  # ticks between two re-plans
    #: a catch re-plans the step it starts in and episode_steps − 1 after it (0: every later
    #: step, which keeps the walk rocking sideways after a push), then rests rest_steps steps
    episode_steps: int = 2
    rest_steps: int = 2
    #: multi-step recovery: the catch goes on, step after step (at most this many more than
    #: episode_steps), while each next single support still finds the DCM error beyond the
    #: dead band — until the DCM is back within it; then the rest (0: episode_steps only)
    until_inside: int = 0
    #: steps one re-plan places: the landing under way (or, in double support, the next) and
    #: the ones after it, each taking what the previous could not (1: one step)
    #: (3 measured: no push survived further, the away push 0.680 against 0.750 N·s;
    #: benchmarks/pushes.md)
    steps_ahead: int = 1
    #: during a catch, re-plan the next landing in double support too (its swing not started)
    double_support: bool = False
    #: s: time constant of the DCM error's running mean per stance side (heading frame), the
    #: centre of the dead band: the compliant body's steady lag of its plan (0: the band
    #: centred on zero; 0.3 s measured best without the feed-forward, 8 plants of 150 fewer
    #: with it: benchmarks/physics.md)
    baseline_tau: float = 0.0
    #: the swing sole's target in the measured frame (:meth:`StepAdjuster.land`): the share
    #: of the base's measured pose error (rotation and position, the estimate against the
    #: controller's own) the swing target takes, from a tilt error of ``landing_band`` rad on,
    #: fully from twice it (0: off)
    landing: float = 1.0
    landing_band: float = 0.0
    #: the share of the sideways parts (roll, the lateral position) the swing target takes
    landing_lateral: float = 1.0
    #: share of the swing over which the correction blends in from lift-off (smoothstep)
    landing_blend: float = 0.0
    #: s: > 0: the correction only in a single support whose DCM error has left the dead
    #: band (with ``trigger_jump``: whose DCM jumped) (a push being caught; latched to the
    #: landing), blended in over this time
    landing_catch: float = 0.02
    #: s: > 0: the correction less its running mean per stance side (this time constant):
    #: a plant's steady lag of its plan left alone, a push's departure from it corrected
    landing_tau: float = 0.0
    #: step timing: in double support, while the DCM error along the walk (heading frame) is
    #: beyond ``hurry_band``, the walk's clock runs ``hurry`` times as fast (the next lift-off
    #: and landing come earlier; :meth:`StepAdjuster.rate`; 1: off)
    hurry: float = 1.0
    hurry_band: float = 0.03
    #: step timing in single support too: during a catch (the DCM error ``e`` beyond the dead
    #: band), the landing comes sooner when that leaves the swing more room beyond the shift
    #: it needs (LIPM: the shift needed grows as ``e e^{ω T}``, the room as ``v T``): the clock
    #: runs ``T / T*``, ``T* = ln(v / (ω e)) / ω``, at most ``hurry``× (:meth:`rate`)
    hurry_single: bool = False
    #: m: once a catch has re-planned a step, the dead band of its later re-plans (None: the
    #: band): the band decides whether to catch, the catch then takes the whole error
    catch_band: float | None = None
    #: early touch-down (needs the estimator's contact detection, ``Gains.contact_band``):
    #: during a catch, a swing sole found down on the floor for this many ticks running lands
    #: where it is: that step and every later one re-based on it (moved by its shortfall),
    #: the CoM reference re-planned, the walk's clock jumps to the landing (0: off)
    touchdown: int = 0
    #: > 0: the dead bands at least this share of the walk's largest DCM travel in a single
    #: support (:meth:`StepAdjuster.planned_travel`; benchmarks/physics.md, tenth pass)
    band_travel: float = 0.0
    #: m: a push caught in the step it comes in: in single support, the DCM error along the
    #: walk jumping by more than this in one tick (a 0.6 N·s push: 25 mm) starts the catch at
    #: once: that swing's dead bands drop to ``trigger_band`` (the re-plan in the pushed
    #: step), the landing correction (``landing_catch``) starts, the swing lifts (0: off)
    trigger_jump: float | None = None  # (None: the robot's, else TRIGGER_SHARE × band_x)
    trigger_band: float = 0.0
    #: ticks of a single support whose jump is not read (the first: the estimator's support
    #: switch makes the DCM estimate jump there, up to 40 mm on the randomised plants; 14 mm
    #: at any later tick); and the jump must pass ``trigger_sigma`` × the RMS of the per-tick
    #: change before it (running, ``trigger_tau`` s): a jittery plant (22 mm on ``turn_wb``,
    #: RMS 5.5 mm) is no push (benchmarks/pushes.md)
    trigger_skip: int = 1
    trigger_sigma: float = 5.0
    trigger_tau: float = 0.3
    #: m: once triggered, the swing sole's target raised by this much (blended in over
    #: ``lift_time`` s, out over the swing's last ``lift_land`` share so that it lands on
    #: time): the push pitches the body about the stance toe and the swing toe meets the
    #: floor 20 ms later, short of any re-planned landing (lift first, then reach; 0: off)
    lift: float = 0.015
    lift_time: float = 0.03
    lift_land: float = 0.3

    def for_robot(self, robot: Robot) -> SteppingParams:
        """These parameters with the dead bands left None taken from ``robot``'s
        ``robot.toml`` ``[balance.stepping]`` (what its unpushed walks show), else the
        defaults :data:`BAND_X`, :data:`BAND_Y` (measured on the Bioloid)."""
        data = getattr(robot, "robot_data", None)
        stated = data.balance.get("stepping", {}) if data is not None else {}
        bands = {"band_x": BAND_X, "band_y": BAND_Y}
        out = {k: stated.get(k, d) for k, d in bands.items() if getattr(self, k) is None}
        if self.trigger_jump is None:  # the robot's, else a share of its band along the walk
            band_x = float(out.get("band_x", self.band_x) or BAND_X)
            out["trigger_jump"] = stated.get("trigger_jump", TRIGGER_SHARE * band_x)
        return replace(self, **out) if out else self

    def check(self) -> SteppingParams:
        for name in (
            "threshold", "gain", "min_remaining", "min_clearance", "max_shift", "max_foot_speed",
            "band_x", "band_y", "settle", "baseline_tau", "landing", "landing_band",
            "landing_lateral", "landing_blend", "landing_catch", "landing_tau", "hurry",
            "hurry_band", "catch_band", "band_travel", "trigger_jump", "trigger_band", "lift",
            "lift_time", "lift_land", "trigger_sigma", "trigger_tau",
        ):  # fmt: skip
            v = getattr(self, name)
            if v is None and name in ("band_x", "band_y", "catch_band", "trigger_jump"):
                continue  # (the robot's: for_robot)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"stepping: {name} must be a finite number >= 0, got {v}")
        if not self.hurry >= 1.0:
            raise ConfigurationError(
                f"stepping: hurry must be >= 1 (a clock speed), got {self.hurry}"
            )
        if int(self.steps_ahead) != self.steps_ahead or self.steps_ahead < 1:
            raise ConfigurationError(
                f"stepping: steps_ahead must be an integer >= 1, got {self.steps_ahead}"
            )
        for name in ("episode_steps", "rest_steps", "until_inside", "touchdown", "trigger_skip"):
            v = getattr(self, name)
            if int(v) != v or v < 0:
                raise ConfigurationError(f"stepping: {name} must be an integer >= 0, got {v}")
        if int(self.hold_ticks) != self.hold_ticks or self.hold_ticks < 1:
            raise ConfigurationError(
                f"stepping: hold_ticks must be an integer >= 1, got {self.hold_ticks}"
            )
        return self


# ---------------------------------------------------------------------- the re-planner
def can_step(ref: WalkingReference) -> bool:
    """True when :class:`StepAdjuster` can re-plan ``ref`` (a dynamic walk made by
    :func:`wbc.walking.gait.walk`: its timing and generator are known)."""
    meta = ref.meta
    return ref.gait == "dynamic" and "timing" in meta and "generator" in meta


class StepAdjuster:
    """Re-plans the footsteps of a dynamic walk (:func:`wbc.walking.gait.walk`, any
    generator) from the measured DCM (module docstring). ``enabled=False``: never re-plans.

    :meth:`update` is called by the :class:`~wbc.walking.loop.Session` once per tick with
    the state estimate; it returns a new reference when it re-plans (None otherwise).
    ``events`` lists the re-plans: (time, step, wanted shift, applied shift).
    """

    def __init__(
        self,
        robot: Robot,
        ref: WalkingReference,
        params: SteppingParams | None = None,
        legs: LegGeometry | None = None,
        enabled: bool = True,
    ) -> None:
        self.params = (params or SteppingParams()).for_robot(robot).check()
        self.enabled = enabled
        meta = ref.meta
        if not can_step(ref):
            raise TrajectoryError(
                f"stepping re-plans dynamic walks made by wbc.walking.gait.walk; reference "
                f"{ref.name!r} is not one"
            )
        self.timing = GaitTiming(**meta["timing"])
        self.swing = SwingParams(**meta.get("swing", {}))
        self.zmp_offset = tuple(meta.get("zmp_offset", (0.0, 0.0)))
        self.transfer = float(meta.get("transfer", 1.0))  # (gait.narrow_sway)
        self.base = ref
        self.phases = build_phases(ref.plan, self.timing)
        if self.phases[-1].i1 != ref.n:
            raise TrajectoryError(f"stepping: reference {ref.name!r} does not match its own timing")
        self.legs = legs or LegGeometry.from_robot(robot, robot.configuration("stand"))
        torso = robot.model.frames[robot.frame_id("torso")]
        self._torso_b = torso.placement.rotation.copy()  # the torso in the base frame
        self.omega = ref.omega
        self.tc = 1.0 / self.omega
        self.phase_of = np.zeros(ref.n, dtype=int)
        for j, ph in enumerate(self.phases):
            self.phase_of[ph.i0 : ph.i1] = j
        self.shift = np.zeros(2)  # current shift of the step `first` (and those after it)
        self.first: int | None = None
        self.before = ref.plan  # the plan before the re-plans of step `first`
        #: the increments Δ_j of steps first + j, … since `before` (:meth:`place`)
        self.increments = np.zeros((self.params.steps_ahead, 2))
        #: the DCM error's running mean per stance side (left, right; heading frame,
        #: :meth:`_track_baseline`)
        self.baseline = np.zeros((2, 2))
        self.episode: int | None = None  # the step the current catch started in
        self.end = 0  # the first step after the catch (until_inside extends it)
        self.caught_step = -1  # the last step a re-plan moved
        self._caught: int | None = None  # tick the DCM error left the band (landing_catch)
        self._trigger: int | None = None  # tick a DCM jump started a catch (trigger_jump)
        #: (tick, reference, raw DCM error) of the last single-support tick (trigger_jump)
        self._last_err: tuple[int, Any, np.ndarray] | None = None
        self._jitter = 0.0  # the running mean square of its per-tick change (trigger_sigma)
        #: the landing correction's running mean per stance side (landing_tau): v, p_r − p_m
        self._landing_mean = np.zeros((2, 6))
        self._dcm: tuple = (None, None)  # (a reference, its DCM per tick: _dcm_ref)
        self.plan = ref.plan
        #: the state estimator whose contact detection (``contact_band``) the touch-down reads
        #: (set by wbc.balance.live.closed_loop; None: no touch-down)
        self.contact: Any = None
        self._down = 0  # ticks the swing sole has been found down (touchdown)
        self._jump: int | None = None  # the landing tick the clock jumps to (touchdown)
        self.last_tick = -(10**9)
        self.events: list[tuple[float, int, np.ndarray, np.ndarray]] = []
        most = self.params.band_travel * self.planned_travel(ref).max(axis=0)  # (band_travel)
        self.bands = (max(self.params.band_x, most[0]), max(self.params.band_y, most[1]))

    def _heading(self, ref: WalkingReference, i: int) -> tuple[float, float]:
        """cos, sin of the stance sole's heading at tick ``i`` (the left sole's in double
        support)."""
        side = ref.stance_side(i) or "left"
        yaw = float(ref.sole(side)[1][i])
        return math.cos(yaw), math.sin(yaw)

    def _centre(self, ref: WalkingReference, i: int) -> np.ndarray:
        """The dead band's centre at tick ``i``: the running mean of the stance side's error
        (zero in double support)."""
        side = ref.stance_side(i)
        return self.baseline[0 if side == "left" else 1] if side is not None else np.zeros(2)

    def planned_travel(self, ref: WalkingReference) -> np.ndarray:
        """Per phase, how far the reference's DCM travels (max − min) in a single support
        from the stance sole, its heading frame at lift-off (along, sideways; else zero)."""
        out, dcm = np.zeros((len(self.phases), 2)), ref.com[:, :2] + ref.com_vel[:, :2] / ref.omega
        for j, ph in enumerate(self.phases):
            side = ref.stance_side(ph.i0) if ph.kind == "single" and ph.i1 > ph.i0 else None
            if side is not None:
                pos, yaw = ref.sole(side)
                c, s = math.cos(float(yaw[ph.i0])), math.sin(float(yaw[ph.i0]))
                e = (dcm[ph.i0 : ph.i1] - pos[ph.i0 : ph.i1, :2]) @ np.array([[c, -s], [s, c]])
                out[j] = np.ptp(e, axis=0)
        return out

    def _catch_end(self) -> int:
        """The first step after the catch under way (``until_inside`` extends it; 0: none)."""
        if self.episode is None:
            return 0
        return max(self.episode + self.params.episode_steps, self.end)

    def _dcm_ref(self, ref: WalkingReference, i: int) -> np.ndarray:
        """``ref.dcm_at(i)``, from the whole walk's array (built once per reference)."""
        if self._dcm[0] is not ref:
            self._dcm = (ref, ref.com[:, :2] + ref.com_vel[:, :2] / ref.omega)
        return self._dcm[1][i]

    def error(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> tuple[Phase, np.ndarray]:
        """The current phase and the DCM error beyond the dead band, ``dz(ξ_meas − ξ_ref − b)``
        (``band_x``, ``band_y`` in the stance sole's heading frame around ``b``, the stance
        side's running mean of the error, :attr:`baseline`: what an unpushed walk shows)."""
        ph = self.phases[self.phase_of[i]]
        d = self._dcm_ref(ref, i)
        e0, e1 = float(dcm[0]) - float(d[0]), float(dcm[1]) - float(d[1])
        c, s = self._heading(ref, i)
        b0, b1 = self._centre(ref, i)
        x, y = c * e0 + s * e1 - b0, -s * e0 + c * e1 - b1
        p = self.params
        band_x, band_y = self.bands
        end = self._catch_end()
        if p.catch_band is not None and ph.kind == "single" and self.caught_step <= ph.step < end:
            band_x, band_y = min(band_x, p.catch_band), min(band_y, p.catch_band)  # a catch
        if self.triggered(i):  # a push caught in this swing: its whole error
            band_x, band_y = min(band_x, p.trigger_band), min(band_y, p.trigger_band)
        x = dead_zone(x, band_x)
        y = dead_zone(y, band_y)
        return ph, np.array([c * x - s * y, s * x + c * y])

    def _track_baseline(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> None:
        """In single support, the running mean (time constant ``baseline_tau``) of the
        heading-frame DCM error on this stance side (a walk lags its plan differently on
        either foot: sideways, toward the side it walks to), fed only by errors inside the
        band around it (a push does not move it)."""
        tau = self.params.baseline_tau
        if tau <= 0:
            return
        side = ref.stance_side(i)
        if side is None:
            return
        e = np.asarray(dcm[:2], float) - self._dcm_ref(ref, i)
        c, s = self._heading(ref, i)
        local = np.array([c * e[0] + s * e[1], -s * e[0] + c * e[1]])
        band = np.array(self.bands, dtype=float)
        b = self.baseline[0 if side == "left" else 1]
        if np.all(np.abs(local - b) <= band):
            b += (local - b) * min(ref.dt / tau, 1.0)

    def sensitivity(self, ref: WalkingReference, plan: FootstepPlan, k: int, i: int) -> float:
        """``∂ξ_ref(t_i) / ∂δ``: how far the re-planned reference's DCM at tick ``i`` moves per
        metre of shift of the footsteps ``k, …`` (the LIPM of :meth:`regenerate`; about
        ``e^{−ω (t_land − t)}`` times the share of the ZMP path that moves)."""
        t = ref.t - ref.t[0]
        xi = []
        for d in (0.0, 1e-2):
            kt, kp = zmp_knots(shifted_plan(plan, k, np.array([d, 0.0])), self.phases,
                               self.base.com[0, :2], self.zmp_offset,
                               transfer=self.transfer)  # fmt: skip
            later = kt > t[i] + 1e-12
            T = np.concatenate([[t[i]], kt[later]])
            P = np.vstack([sample_knots(kt, kp, t[i : i + 1]), kp[later]])
            pos, vel, _ = lipm_com_for_zmp(T, P, ref.com[i, :2], self.tc, t[i : i + 1])
            xi.append(pos[0, 0] + vel[0, 0] / self.omega)
        return max((xi[1] - xi[0]) / 1e-2, 1e-3)

    def land(self, targets: Any, est: Any, q: np.ndarray) -> Any:
        """``targets`` with the swing sole's target moved into the measured frame (single
        support, ``landing`` > 0; else ``targets`` itself). The controller places the swing
        sole relative to *its* base (``p_r``, ``R_r``: ``q``); the robot's base is where the
        estimate puts it (``p_m``, ``R_m``: a push pitches the body about the stance sole and
        the compliant stance hip yields), and the sole lands where the same relative pose puts
        it from there, ``p_m + R_m R_rᵀ (p − p_r)``: short and high. The target
        ``p' = p_r + E (p − p_m)``, ``R' = E R`` with ``E = R_r R_mᵀ`` lands it at ``p``
        (blended by ``w``: ``landing`` × a ramp from ``landing_band`` to twice it on the
        angle of ``E``)."""
        p = self.params
        if targets.phase != "single":
            return targets
        targets = self.lifted(targets)
        if p.landing <= 0:
            return targets
        since = self._caught
        if p.landing_catch > 0 and p.landing_tau <= 0:  # no catch in this swing: at once
            if since is None or self.phase_of[since] != self.phase_of[targets.i]:
                return targets
        R_r = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix() @ self._torso_b
        E = R_r @ np.asarray(est.rotation).T
        v = pin.log3(E)
        st = targets.support_placement.rotation[:2, 0]
        h = np.array([st[0], st[1], 0.0]) / max(math.hypot(st[0], st[1]), 1e-9)  # heading
        lat = p.landing_lateral
        if lat != 1.0:  # the roll part (about the heading) scaled
            v = v - (1.0 - lat) * (v @ h) * h
        base_m = np.asarray(est.base, dtype=float)
        if p.landing_tau > 0:  # less the running mean (per stance side) of v and p_r − p_m
            mean = self._landing_mean[0 if targets.support == "l_sole" else 1]
            mean += (np.concatenate([v, q[:3] - base_m]) - mean) * min(
                self.base.dt / p.landing_tau, 1.0
            )
            v = v - mean[:3]
            base_m = base_m + mean[3:]
        angle = float(np.linalg.norm(v))
        band = p.landing_band
        w = p.landing * (min(max((angle - band) / band, 0.0), 1.0) if band > 0 else 1.0)
        if p.landing_catch > 0:  # only while a push is caught: since the error left the band
            since = self._caught
            if since is None or self.phase_of[since] != self.phase_of[targets.i]:
                return targets
            w *= smooth((targets.i - since + 1) * self.base.dt / p.landing_catch)
        if p.landing_blend > 0:  # blended in from lift-off
            ph = self.phases[self.phase_of[targets.i]]
            w *= smooth((targets.i - ph.i0) / max(ph.i1 - ph.i0, 1) / p.landing_blend)
        if w <= 0:
            return targets
        E = pin.exp3(w * v)
        pos = np.asarray(targets.swing_position, dtype=float)
        moved = q[:3] + E @ (pos - base_m)
        if lat != 1.0:  # the lateral part of the move scaled
            side = np.array([-h[1], h[0], 0.0])
            moved = moved - (1.0 - lat) * ((moved - pos) @ side) * side
        return targets.replace(
            swing_position=pos + w * (moved - pos), swing_rotation=E @ targets.swing_rotation
        )

    def triggered(self, i: int) -> bool:
        """True when a DCM jump (``trigger_jump``) started a catch in tick ``i``'s phase."""
        t = self._trigger
        return t is not None and self.phase_of[t] == self.phase_of[i]

    def _watch(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> None:
        """The push trigger (``trigger_jump``): in single support, the DCM error along the walk
        (the stance sole's heading; against the same reference) jumping by more than
        ``trigger_jump`` since the last tick (sideways pushes: the default catch, measured
        better toward the swing foot; benchmarks/pushes.md)."""
        ph = self.phases[self.phase_of[i]]
        if ref.support[i] == SUPPORT_DOUBLE or i - ph.i0 < self.params.trigger_skip:
            self._last_err = None  # (the support switch: trigger_skip)
            return
        e = np.asarray(dcm[:2], dtype=float) - self._dcm_ref(ref, i)
        last, self._last_err = self._last_err, (i, ref, e)
        if last is None or last[0] != i - 1 or last[1] is not ref or self.triggered(i):
            return
        c, s = self._heading(ref, i)
        p, d = self.params, (c * (e[0] - last[2][0]) + s * (e[1] - last[2][1]))  # along
        if abs(d) > max(p.trigger_jump or 0.0, p.trigger_sigma * math.sqrt(self._jitter)):
            self._trigger = i
        self._jitter += (d * d - self._jitter) * min(ref.dt / max(p.trigger_tau, 1e-9), 1.0)

    def lifted(self, targets: Any) -> Any:
        """``targets`` with the swing sole's target raised by ``lift`` in a triggered catch
        (:meth:`triggered`): blended in over ``lift_time``, out over the swing's last
        ``lift_land`` share (smoothstep both), so that it lands where and when planned."""
        p, i = self.params, targets.i
        if p.lift <= 0 or not self.triggered(i):
            return targets
        ph = self.phases[self.phase_of[i]]
        w = smooth((i - self._trigger + 1) * self.base.dt / max(p.lift_time, 1e-9)) * smooth(
            (ph.i1 - i) / max(ph.i1 - ph.i0, 1) / max(p.lift_land, 1e-9)
        )
        pos = np.array(targets.swing_position, dtype=float)
        pos[2] += p.lift * w
        return targets.replace(swing_position=pos)

    @property
    def hurries(self) -> bool:
        """False when :meth:`rate` is 1 at every tick (``hurry`` 1 and no ``touchdown``, or
        off): not called."""
        return self.enabled and (self.params.hurry != 1.0 or self.params.touchdown > 0)

    @property
    def lands(self) -> bool:
        """False when :meth:`land` returns its targets at every tick (``landing`` and
        ``lift`` 0)."""
        return self.params.landing > 0 or (self.params.lift > 0 and self.enabled)

    def rate(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> float:
        """The walk's clock speed after tick ``i``: ``hurry`` in a double support whose DCM
        error along the walk (the stance sole's heading frame) is beyond ``hurry_band`` (a
        push along the walk: the next step should start, and land, sooner), else 1."""
        p = self.params
        if self._jump is not None:  # a touch-down: the clock to the landing at once (the
            # deployment ticks at the reference's rate: closed_loop)
            jump, self._jump = self._jump, None
            if jump > i:
                return 1.0 + (jump - i)
        if p.hurry == 1.0 or not self.enabled:
            return 1.0
        if ref.support[i] != SUPPORT_DOUBLE:  # single support: while a catch is on
            if not p.hurry_single or self.episode is None:
                return 1.0
            ph = self.phases[self.phase_of[i]]
            if ph.step >= self._catch_end():
                return 1.0  # (the catch is over)
            left = (ph.i1 - i) * ref.dt
            if left < p.min_remaining:  # (landing: its clock as planned)
                return 1.0
            e = float(np.linalg.norm(self.error(ref, i, dcm)[1]))
            if e <= 0:
                return 1.0
            # the landing time T' that leaves the swing the most room beyond the shift it
            # needs: room v T' (v the swing's added reach per second left), need e e^{ω T'}
            # (LIPM): T* = ln(v / (ω e)) / ω; the clock runs T / T* (1 … hurry)
            v = p.max_foot_speed / bend_rate(ph, i, ref.dt, self.swing) / left
            best = math.log(v / (self.omega * e)) / self.omega if v > self.omega * e else 0.0
            return min(max(left / max(best, p.min_remaining), 1.0), p.hurry)
        e = np.asarray(dcm[:2], float) - self._dcm_ref(ref, i)
        c, s = self._heading(ref, i)
        return p.hurry if abs(c * e[0] + s * e[1]) > p.hurry_band else 1.0

    def _swing_phase(self, k: int) -> Phase:
        """The single support in which step ``k`` swings."""
        return next(ph for ph in self.phases if ph.kind == "single" and ph.step == k)

    def update(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> WalkingReference | None:
        """A re-planned reference if the DCM error beyond the dead band asks for a footstep
        shift above ``threshold`` and a feasible shift changes the plan (None otherwise): in
        single support the landing under way (after ``settle``, not in the last
        ``min_remaining``), in double support (``double_support``) the next landing; each
        re-plan places ``steps_ahead`` steps, each taking the share of the error the steps
        before it could not (:meth:`place`)."""
        p = self.params
        if not self.enabled:
            return None
        if p.baseline_tau > 0:
            self._track_baseline(ref, i, dcm)
        if (p.trigger_jump or 0.0) > 0:
            self._watch(ref, i, dcm)
        if p.landing_catch > 0 and ref.support[i] != SUPPORT_DOUBLE:
            caught = self._caught is not None and self.phase_of[self._caught] == self.phase_of[i]
            # the tick the DCM error left the band in this swing (with trigger_jump: the
            # tick of the jump; an unpushed walk leaving the band is no push)
            jumps = (p.trigger_jump or 0.0) > 0
            pushed = self.triggered(i) if jumps else self.error(ref, i, dcm)[1].any()
            if not caught and pushed:
                self._caught = i
        if p.touchdown > 0 and self.contact is not None:
            new = self._touchdown(ref, i)
            if new is not None:
                return new
        if i - self.last_tick < p.hold_ticks:
            return None
        ph = self.phases[self.phase_of[i]]
        if ph.kind == "single":
            dt = ref.dt
            if (ph.i1 - i) * dt < p.min_remaining or (i - ph.i0) * dt < p.settle - 1e-9:
                return None
            k = int(ph.step)
        elif ph.kind == "double" and p.double_support and self.episode is not None:
            # during a catch, the next landing (its swing has not started): the DCM error of
            # an unpushed double support (the sway crossing over) is no reason to re-plan
            k = int(ph.step) + 1
        else:
            return None
        if k >= len(self.plan.steps):
            return None
        err = self.error(ref, i, dcm)[1]  # (only where a re-plan may follow: the tick's cost)
        if not err.any():
            return None
        if self.episode is not None and p.episode_steps > 0:
            end = self._catch_end()
            if (  # multi-step recovery: the DCM still outside the band on the next step
                k == end
                and self.caught_step == k - 1
                and k < self.episode + p.episode_steps + p.until_inside
            ):
                end = self.end = k + 1
            if end <= k < end + p.rest_steps:
                return None  # the catch is over: let the walk settle
            if k >= end + p.rest_steps:
                self.episode = None
        if self.first != k:  # a new step: its shifts are relative to the plan now
            self.before, self.first = self.plan, k
            self.increments = np.zeros((p.steps_ahead, 2))
        placed = self.place(ref, i, k, ph, err)
        if placed is None:
            return None
        plan, increments, wanted = placed
        new = self.regenerate(ref, plan, i, ph)
        self.plan, self.increments, self.last_tick = plan, increments, i
        self.shift = increments[0].copy()
        self.episode = k if self.episode is None else self.episode
        self.caught_step = k
        self.events.append((float(ref.t[i]), k, wanted, increments[0].copy()))
        return new

    def _touchdown(self, ref: WalkingReference, i: int) -> WalkingReference | None:
        """The walk re-based on an early touch-down (``touchdown``; module docstring), or
        None: in a single support (after ``settle``, before its last ``min_remaining``)
        of a catch (a step the DCM's re-plans moved, or the next), the swing sole found down
        (``contact.down``) ``touchdown`` ticks running: step ``k`` and every later one move
        by where it touched less where the plan lands it, the rest re-planned
        (:meth:`regenerate`) and the clock jumps to the landing (:meth:`rate`)."""
        p = self.params
        ph = self.phases[self.phase_of[i]]
        dt = ref.dt
        if ph.kind != "single" or ph.step >= len(self.plan.steps):
            self._down = 0
            return None
        k = int(ph.step)
        s = 0 if self.plan.steps[k].side == "left" else 1
        if not self.contact.down[s] or (i - ph.i0) * dt < p.settle - 1e-9:
            self._down = 0
            return None
        self._down += 1
        if self._down < p.touchdown or (ph.i1 - i) * dt < p.min_remaining:
            return None
        if self.episode is None or k >= self._catch_end():
            return None  # (no catch: the swing brushing the floor)
        step = self.plan.steps[k]
        shift = np.asarray(self.contact.touched[s], dtype=float) - np.array([step.x, step.y])
        plan = shifted_plan(self.plan, k, shift)
        new = self.regenerate(ref, plan, i, ph)
        self.plan, self.before, self.first = plan, plan, k
        self.increments = np.zeros((p.steps_ahead, 2))
        self.shift = np.zeros(2)
        self.last_tick, self._down, self._jump = i, 0, ph.i1
        self.caught_step = k
        self.events.append((float(ref.t[i]), k, shift, shift.copy()))
        return new

    def place(
        self, ref: WalkingReference, i: int, k: int, ph: Phase, err: np.ndarray
    ) -> tuple[FootstepPlan, np.ndarray, np.ndarray] | None:
        """The footsteps ``k, k+1, …`` (``steps_ahead`` of them) re-placed for a DCM error
        ``err`` (beyond the band): step ``k + j`` and the ones after it move by the increment
        ``Δ_j``, chosen in turn as ``Δ_j + r / s_j`` clipped to the landings the legs can make
        (and, for the swing under way, to what it can still cover), with ``s_j`` the
        sensitivity of the reference's DCM now to it and ``r`` what the steps before left
        (``r ← r − s_j ΔΔ_j``). Returns (plan, increments, the first step's wanted shift), or
        None when nothing moves by more than a millimetre."""
        p = self.params
        incs = self.increments.copy()
        r = err.copy()
        plan = self.before
        wanted0 = np.zeros(2)
        changed = False
        for j in range(p.steps_ahead):
            kk = k + j
            if kk >= len(plan.steps) or not r.any():
                break
            s = self.sensitivity(ref, plan, kk, i)
            want = r / s
            if j == 0:
                wanted0 = want.copy()
                if math.hypot(want[0], want[1]) < p.threshold:
                    return None
            total = incs[j] + p.gain * want
            n = math.hypot(total[0], total[1])
            if n > p.max_shift:
                total *= p.max_shift / n
            # the swing sole can move only so far in the time left (bend_rate: peak speed per m)
            if j == 0 and ph.kind == "single":
                room = p.max_foot_speed / bend_rate(ph, i, ref.dt, self.swing)
            else:
                sw = self._swing_phase(kk)
                room = p.max_foot_speed / bend_rate(sw, sw.i0, ref.dt, self.swing)
            change = total - incs[j]
            n = math.hypot(change[0], change[1])
            if n > room:
                total = incs[j] + change * (room / n)
            got = feasible_shift(
                plan, kk, total, self.legs, ref.com_height, ref.foot, p.min_clearance
            )
            r = r - s * (got - incs[j])
            changed = changed or bool(np.max(np.abs(got - incs[j])) >= 1e-3)
            incs[j] = got
            plan = shifted_plan(plan, kk, got)
        if not changed:
            return None
        return plan, incs, wanted0

    def regenerate(
        self, ref: WalkingReference, plan: FootstepPlan, i: int, ph: Phase
    ) -> WalkingReference:
        """The walk re-planned along ``plan`` from tick ``i`` on (ticks before ``i``
        unchanged): soles from :func:`sole_tracks` (the swing under way bent toward its new
        landing), the ZMP path from :func:`zmp_knots`, the CoM by the LIPM generator
        :func:`lipm_com_for_zmp` from the current CoM target."""
        dt = ref.dt
        soles = sole_tracks(plan, self.phases, dt, self.swing)
        kt, kp = zmp_knots(plan, self.phases, self.base.com[0, :2], self.zmp_offset,
                           transfer=self.transfer)  # fmt: skip
        zref = sample_knots(kt, kp, ref.t - ref.t[0])  # the new ZMP path
        fields = soles.reference_fields()
        for name in ("l_sole", "l_sole_yaw", "r_sole", "r_sole_yaw", "l_sole_vel", "r_sole_vel"):
            fields[name] = np.concatenate([getattr(ref, name)[:i], fields[name][i:]])
        # the swing under way: from its current target, bent toward the new landing
        side = plan.steps[ph.step].side
        old = ref.plan.steps[ph.step] if ph.step < len(ref.plan.steps) else None
        if old is not None and ph.kind == "single":
            key = "l_sole" if side == "left" else "r_sole"
            d = plan.steps[ph.step].position - old.position
            g, dg = bend(ph, i, dt, self.swing)
            pos = getattr(ref, key)[i : ph.i1] + d[None, :] * g[:, None]
            vel = getattr(ref, f"{key}_vel")[i : ph.i1] + d[None, :] * dg[:, None]
            fields[key][i : ph.i1] = pos
            fields[f"{key}_vel"][i : ph.i1] = vel
        t = ref.t - ref.t[0]
        later = kt > t[i] + 1e-12
        T = np.concatenate([[t[i]], kt[later]])
        P = np.vstack([zref[i], kp[later]])
        pos, vel, acc = lipm_com_for_zmp(T, P, ref.com[i, :2], self.tc, t[i:])
        com, com_vel, com_acc = ref.com.copy(), ref.com_vel.copy(), ref.com_acc.copy()
        com[i:, :2], com_vel[i:, :2], com_acc[i:, :2] = pos, vel, acc
        return WalkingReference(
            t=ref.t,
            com=com,
            com_vel=com_vel,
            com_acc=com_acc,
            **fields,
            com_height=ref.com_height,
            plan=plan,
            gait=ref.gait,
            name=ref.name,
            zmp_ref=np.concatenate([ref.zmp_ref[:i], zref[i:]])
            if ref.zmp_ref is not None
            else None,
            foot=ref.foot,
            margin=ref.margin,
            g=ref.g,
            meta=dict(ref.meta, replanned=len(self.events) + 1),
            torso_roll=ref.torso_roll,
        )
