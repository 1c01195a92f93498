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

**The swing landed in the measured frame** (``landing``), **the push caught in its own step**
(``trigger_jump``, ``lift``; on by default), the catch's later swings, the double support after
a caught landing and the re-based landing (``catch_swings``, ``descend``, ``back_rebase``):
:mod:`.swing_catch`. **Step timing** (``hurry``; off): in a double support pushed along the
walk, the walk's clock runs faster (:meth:`StepAdjuster.rate`, read by the session's ``at_time``).

What no step can do: a push *away from the swing foot* (the physics benchmark's lateral push)
sends the DCM toward the stance sole's outer edge; a step of the swing foot cannot land beyond
that edge (the legs would cross), so once the DCM is past it the robot falls whatever the
steps (LIPM, :func:`capture_bounds`: 0.934 N·s on ``walk10``, benchmarks/pushes.md).

**Multi-step recovery** (``until_inside``; off): the catch goes on step after step while
each next single support still finds the DCM error beyond the band, then rests. **The
landing time** (``hurry_single``; on): in a single support being caught, the clock runs
faster when the swing lacks the room for the shift the error asks (:meth:`rate`), at most
``hurry``× (1: off), in a swing the trigger's catch of a push backward carries at most
``catch_hurry``×. With ``catch_band`` a catch under way takes the whole error, not the dead
band's less.

**The touch-down acceptance** (``accept``; off): :mod:`.touchdown`. **Early touch-down**
(``touchdown``; off; needs the estimator's contact detection,
``Gains.contact_band``): a push forward pitches the body about the stance toe and the swing
sole's toe meets the floor early, short of its landing (issue 30: 20 mm short at 0.6 N·s).
During a catch, a swing sole found down that many ticks running lands where it is: that step
and every later one move by its shortfall (the rest of the plan re-based on the landed
foothold, the CoM re-planned from it) and the walk's clock jumps to the landing
(:meth:`StepAdjuster.rate`), so the next step takes the catch; ``touchdown_share``: a touch
counts only after that share of the swing (the toe brushing the floor early in a pushed swing
is no landing). Measured: one bisection step
forward, costs the walk without the feed-forward (the next swing's toe meets the floor too:
steps of a few mm; benchmarks/pushes.md, seventh pass).

The parameters: :mod:`.stepping_params`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import TrajectoryError
from ..geometry import sole_corners
from ..model import Robot
from ..recording import SUPPORT_DOUBLE
from ..roles import SOLE_FRAMES
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
from .footholds import bend, bend_rate, dead_zone, feasible_shift, shifted_plan
from .stepping_params import BAND_X, BAND_Y, TRIGGER_SHARE, SteppingParams
from .stretch import SwingStretch
from .swing_catch import (
    LandedDescent,
    LandedRebase,
    MeasuredLanding,
    PushTrigger,
    dcm_shifted,
    floored,
    walk_shifted,
)
from .touchdown import TouchdownAcceptance, early

__all__ = ["BAND_X", "BAND_Y", "TRIGGER_SHARE", "StepAdjuster", "SteppingParams", "can_step"]


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
        self.robot = robot  # (accept_settle: the solve's sole)
        self._corners = sole_corners(*robot.foot_size)  # (landing_floor)
        torso = robot.model.frames[robot.frame_id("torso")]
        torso_b = torso.placement.rotation.copy()  # the torso in the base frame
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
        #: the push trigger and the swing's lift (trigger_jump, lift; :mod:`.swing_catch`)
        self.trigger = PushTrigger(self.params, self.phases, self.phase_of, ref.dt)
        #: the swing's landing in the measured frame (landing, landing_catch)
        self.landing = MeasuredLanding(self.params, self.phases, self.phase_of, ref.dt, torso_b)
        #: the landed sole lowered in the double support after a caught landing (descend)
        self.descent = LandedDescent(self.params, self.phases, self.phase_of, ref.dt)
        self.rebase = LandedRebase(self.params, self.phases, self.phase_of)  # (back_rebase)
        self.accepted = TouchdownAcceptance()  # (accept: :mod:`.touchdown`)
        self.stretched = SwingStretch(self.params.stretch)  # (stretch: :mod:`.stretch`)
        self._q: np.ndarray | None = None  # the last solve's configuration (:meth:`land`)
        self._dcm: tuple = (None, None)  # (a reference, its DCM per tick: _dcm_ref)
        self.plan = ref.plan
        self.current: WalkingReference | None = None  # the walk's reference (:meth:`update`)
        #: the state estimator whose contact detection (``contact_band``) the touch-down reads
        #: (set by wbc.balance.live.closed_loop; None: no touch-down)
        self.contact: Any = None
        #: the servos' present positions (rad, model order; NaN or None: unread), as the
        #: stabilizer reads them (set by wbc.balance.live.closed_loop; None: ``landing_tilt``
        #: not done)
        self.present: Callable[[], np.ndarray | None] | None = None
        #: (tick, m): the swing sole's distance to its landing (``back_reach``: :meth:`rate`)
        self.reach_left: tuple[int, float] = (-1, 0.0)
        self.back_caught = False  # :meth:`land` saw a push backward caught (:meth:`banded`)
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
        return max(self.episode + self._episode_steps(), self.end)

    def _episode_steps(self) -> int:
        """``episode_steps``, or ``back_episode`` (> 0) after a push backward the trigger
        caught."""
        p, t = self.params, self.trigger
        return (
            p.back_episode
            if p.back_episode > 0 and t.tick is not None and not t.forward
            else p.episode_steps
        )

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
        """``targets`` with the swing sole's target raised in a triggered catch
        (:meth:`PushTrigger.lifted`) and moved into the measured frame
        (:meth:`MeasuredLanding.land`; single support, else ``targets`` itself)."""
        targets = self.trigger.pitched(targets) if self.enabled else targets
        self._q = q
        if self.params.back_dcm > 0 and self.enabled:  # (the ankle strategy in the catch)
            targets = self._dcm_moved(targets, est)
        targets = self.released(targets, est)
        if self.params.back_anchor > 0 and self.contact is not None and self.enabled:
            t = self.trigger  # (back_anchor: from the next tick on, :meth:`banded`)
            if t.tick is not None and not t.forward:
                self.back_caught = True
        if targets.phase != "single":
            if self.params.accept > 0 and self.enabled:  # (an accepted landing's contacts)
                targets = self.accepted.moved(self, targets)
            if self.params.back_rebase > 0 and self.enabled:
                self._rebase_note(targets, q)
            step = self._descending(targets.i)
            if step is None:
                return targets
            h = self._heights(q)
            if h is None:
                return targets
            side = self.plan.steps[step].side
            s = 0 if side == "left" else 1  # (h: SOLE_FRAMES order, left first)
            return self.descent.lowered(targets, SOLE_FRAMES[side], float(h[s] - h[1 - s]))
        vel, p, ref = None, self.params, self.current
        back = self.trigger.tick is not None and not self.trigger.forward  # (a push backward)
        later = back and self.trigger.carried(targets.i)  # (past back_skip: back_turn, _lead)
        later = later and self._back_skipped(self.phases[self.phase_of[targets.i]])
        lead = p.back_lead if later and p.back_lead > 0 else p.lead
        if lead > 0 and ref is not None and targets.i < ref.n:  # (lead)
            vel = ref.sole_velocity("left" if targets.swing == "l_sole" else "right")[targets.i]
        # (the stance sole's roll read after a push backward, on its heel; after a push
        # forward, on its toe, measured worse: forward 0.852 → 0.820 N·s)
        rise = None if self.trigger.forward else (lambda: self.stance_rise(targets, q))
        if later and p.back_reach > 0:  # (a swing the catch carries, past back_skip)
            self._reach_left(targets, q)
        turn = p.landing_turn if back else 0.0
        if later and p.back_turn is not None:  # (back_turn; 0: not turned)
            turn = max(p.back_turn, 1e-12)
        lifted = self.trigger.lifted(targets, vel, lead)
        return self.floor(self.landing.land(lifted, est, q, rise, turn))

    def _rebase_note(self, targets: Any, q: np.ndarray) -> None:
        """``back_rebase``: :meth:`LandedRebase.note` after a push backward's carried swing."""
        t, est, present = self.trigger, self.contact, self.present
        if int(self.phase_of[targets.i]) == self.rebase.seen or t.tick is None or t.forward:
            return
        joints = None if est is None or present is None or est.last is None else present()
        if joints is None:
            return
        j, f = np.asarray(joints, dtype=float), np.asarray(q[7:], dtype=float)
        self.rebase.note(targets, lambda k: self.plan.steps[k].side,
                         lambda ph: t.carried(ph.i0) and self._back_skipped(ph),
                         lambda frame: est.landed(frame, j, f))  # fmt: skip

    def banded(self, targets: Any) -> Any:
        """``targets`` with ``anchor_band`` ``back_anchor`` once :meth:`land` saw a push
        backward caught (for the walk; the estimator's own band, if any, wins)."""
        if not self.back_caught or self.contact is None or self.contact.anchor_band > 0:
            return targets
        return targets.replace(anchor_band=self.params.back_anchor)

    def _reach_left(self, targets: Any, q: np.ndarray) -> None:
        """``back_reach``: the swing sole's distance (m) to its landing, the sole where the
        estimate and the present joints put it, for :meth:`rate` (called in a carried swing
        past ``back_skip``)."""
        i, est, present = targets.i, self.contact, self.present
        joints = None if est is None or present is None or est.last is None else present()
        if joints is None:
            return
        sole = est.landed(targets.swing, np.asarray(joints, float), np.asarray(q[7:], float))
        step = self.plan.steps[self.phases[self.phase_of[i]].step]
        self.reach_left = (i, math.hypot(step.x - float(sole[0]), step.y - float(sole[1])))

    def released(self, targets: Any, est: Any) -> Any:
        """``targets`` with the torso target turned ``back_torso`` of the way to the measured
        torso (``est.rotation``) after a push backward the trigger caught, in the swings the
        catch carries and the double supports before them; else ``targets``."""
        p, t, i = self.params, self.trigger, targets.i
        if p.back_torso <= 0 or not self.enabled or t.tick is None or t.forward:
            return targets
        if not (t.carried(i) or t.before_carried(i)):
            return targets
        j = int(self.phase_of[i])
        if not self._back_skipped(self.phases[j if self.phases[j].kind == "single" else j + 1]):
            return targets  # (the catch's first back_skip swings)
        R = np.asarray(targets.torso_rotation, dtype=float)
        v = pin.log3(np.asarray(est.rotation, dtype=float) @ R.T)
        return targets.replace(torso_rotation=pin.exp3(p.back_torso * v) @ R)

    def _back_skipped(self, ph: Phase) -> bool:
        """True when the swing ``ph`` is past the catch's first ``back_skip`` swings."""
        first = self.phases[self.phase_of[self.trigger.tick or 0]].step
        return int(ph.step) - int(first) >= self.params.back_skip

    def floor(self, targets: Any) -> Any:
        """``targets`` with the swing's ground clearance lowered (``landing_floor``:
        :func:`~.swing_catch.floored`), else ``targets``."""
        if self.params.landing_floor <= 0 or not self.enabled:
            return targets
        return floored(targets, self.params, self.trigger, self._corners)

    def _dcm_moved(self, targets: Any, est: Any) -> Any:
        """``targets`` with the CoM target moved against the DCM error (``back_dcm``:
        :func:`~.swing_catch.dcm_shifted`) while the catch of a push backward is on."""
        t, ref, i, p = self.trigger, self.current, targets.i, self.params
        if ref is None or i >= ref.n:
            return targets
        walk = p.back_dcm_walk  # (the whole walk, along it; else the catch of a push backward)
        if not walk and (t.tick is None or t.forward or self.episode is None):
            return targets
        err = np.asarray(est.dcm[:2], dtype=float) - self._dcm_ref(ref, i)
        if walk:
            c, s = self._heading(ref, i)
            x = min(c * err[0] + s * err[1], 0.0)  # (only a DCM behind its reference)
            return walk_shifted(targets, x, (c, s), p.back_dcm, p.back_dcm_max)
        return dcm_shifted(targets, err, p, t, self._catch_end(), ref.dt)

    def stance_rise(self, targets: Any, q: np.ndarray) -> float:
        """How far (m, ≥ 0) the stance sole's lowest corner lies below the floor where the
        estimate anchors its centre (:meth:`~.estimator.StateEstimator.sole_heights`: the
        IMU's rotation and the present joints): a sole rolled onto its heel (a push
        backward: 15–25°) reads the base that much low (``landing_tilt``; 0 without the
        estimator or the present positions)."""
        h = self._heights(q)
        if h is None:
            return 0.0
        s = 0 if targets.support == "l_sole" else 1
        floor = float(targets.support_placement.translation[2])
        return max(0.0, floor - float(h[s]))

    def _heights(self, q: np.ndarray) -> np.ndarray | None:
        """Both soles' lowest points (m, SOLE_FRAMES order) where the estimator's last estimate
        and the present joints put them (:meth:`~.estimator.StateEstimator.sole_heights`;
        the joints ``q`` solved last stand in for the unread), or None without them."""
        est, present = self.contact, self.present
        if est is None or present is None or est.last is None:
            return None
        joints = present()
        if joints is None:
            return None
        return est.sole_heights(np.asarray(joints, dtype=float), np.asarray(q[7:], dtype=float))

    def _descending(self, i: int) -> int | None:
        """The step that landed at tick ``i``'s double support when ``descend`` lowers it (the
        swing before it a caught one after a push backward: :class:`LandedDescent`), else
        None."""
        if self.params.descend <= 0 or not self.enabled or self.trigger.forward:
            return None
        return self.descent.active(i, self.trigger.carried)

    def triggered(self, i: int) -> bool:
        """True when a DCM jump (``trigger_jump``) started a catch in tick ``i``'s phase."""
        return self.trigger.triggered(i)

    @property
    def hurries(self) -> bool:
        """False when :meth:`rate` is 1 at every tick (``hurry``, ``catch_hurry`` and ``slow``
        1 and no ``touchdown``, or off): not called."""
        p = self.params
        return self.enabled and (
            p.hurry != 1.0
            or p.catch_hurry != 1.0
            or p.touchdown > 0
            or p.accept > 0
            or p.slow != 1.0
            or p.stretch > 0
            or (p.descend > 0 and p.descend_hold > 0)
        )

    @property
    def lands(self) -> bool:
        """False when :meth:`land` returns its targets at every tick (``landing`` and
        ``lift`` 0)."""
        p = self.params
        on = (
            p.lift,
            p.lead,
            p.toe_up,
            abs(p.catch_pitch),
            p.landing_depth,
            p.descend,
            p.back_dcm,
            p.accept,
        )
        return p.landing > 0 or (self.enabled and max(on) > 0)

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
        if not self.enabled:
            return 1.0
        if p.descend_hold > 0 and self._descending(i) is not None and self.descent.holds(ref.dt):
            return 0.0  # (the landed sole still up: the clock stands, descend_hold)
        if p.slow != 1.0 and ref.support[i] != SUPPORT_DOUBLE and self.triggered(i):
            return p.slow  # (a triggered swing: its landing later)
        if p.stretch > 0 and (r := self.stretched.rate(int(self.phase_of[i]))) is not None:
            return r  # (stretch: the pushed swing given the time its landing needs)
        if p.hurry == 1.0 and p.catch_hurry == 1.0:
            return 1.0
        if ref.support[i] != SUPPORT_DOUBLE:  # single support: while a catch is on
            if not p.hurry_single or self.episode is None:
                return 1.0
            # (at most hurry×; in a swing the catch of a push backward carries, catch_hurry×
            # if more: after a push forward measured worse, forward 0.852 → 0.820 N·s)
            back = self.trigger.carried(i) and not self.trigger.forward
            cap = max(p.hurry, p.catch_hurry) if back else p.hurry
            if cap == 1.0:
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
            v = self.reach(i)[1] / bend_rate(ph, i, ref.dt, self.swing) / left
            best = math.log(v / (self.omega * e)) / self.omega if v > self.omega * e else 0.0
            if back and p.back_runaway > 0 and self._back_skipped(ph):  # (back_runaway)
                run = math.log(max(p.back_runaway / e, 1.0)) / self.omega
                best = min(best, run) if best > 0 else 0.0
            out = min(max(left / max(best, p.min_remaining), 1.0), cap)
            d = self.reach_left[1] if back and p.back_reach > 0 and self.reach_left[0] == i else 0
            return min(out, max(left * p.back_reach / d, 1.0)) if d > 0 else out  # (back_reach)
        speed = p.catch_hurry if self.trigger.before_carried(i) else p.hurry  # (catch_hurry)
        if p.back_hurry > 0 and speed == p.catch_hurry and self.trigger.before_carried(i):
            nxt = self.phases[self.phase_of[i] + 1]  # (back_hurry: before a later swing)
            speed = p.back_hurry if not self.trigger.forward and self._back_skipped(nxt) else speed
        if speed == 1.0:
            return 1.0
        e = np.asarray(dcm[:2], float) - self._dcm_ref(ref, i)
        c, s = self._heading(ref, i)
        return speed if abs(c * e[0] + s * e[1]) > p.hurry_band else 1.0

    def reach(self, i: int) -> tuple[float, float]:
        """(``max_shift``, ``max_foot_speed``) for the swing of tick ``i``: in a swing the
        catch of a push backward carries (the trigger's, :meth:`~.swing_catch.PushTrigger.
        carried`), ``back_shift`` and ``back_foot_speed`` instead (0: the same)."""
        p = self.params
        if (p.back_shift > 0 or p.back_foot_speed > 0) and (
            self.trigger.carried(i) and not self.trigger.forward
        ):
            later = p.back_later if not self.trigger.triggered(i) else 0.0  # (back_later)
            return later or p.back_shift or p.max_shift, p.back_foot_speed or p.max_foot_speed
        return p.max_shift, p.max_foot_speed

    def _swing_phase(self, k: int) -> Phase:
        """The single support in which step ``k`` swings."""
        return next(ph for ph in self.phases if ph.kind == "single" and ph.step == k)

    def update(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> WalkingReference | None:
        """:meth:`replan`, and the reference the walk follows after it kept
        (:attr:`current`: the swing's planned velocity, ``lead``)."""
        new = self.replan(ref, i, dcm)
        self.current = new if new is not None else ref
        return new

    def replan(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> WalkingReference | None:
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
            self.trigger.watch(ref, i, dcm, self._dcm_ref(ref, i))
        if p.landing_catch > 0 and ref.support[i] != SUPPORT_DOUBLE:
            # the tick the DCM error left the band in this swing (with trigger_jump: the
            # tick of the jump; an unpushed walk leaving the band is no push)
            jumps = (p.trigger_jump or 0.0) > 0
            self.landing.note(
                i,
                lambda: (
                    self.trigger.carried(i) if jumps else bool(self.error(ref, i, dcm)[1].any())
                ),
            )
        if self.rebase.pending is not None:
            return self._rebased(ref, i)
        if p.accept > 0 and self.contact is not None:
            new = self.accepted.check(self, ref, i, self._q)
            if new is not None:
                return new
        if p.touchdown > 0 and self.contact is not None:
            new = early(self, ref, i)
            if new is not None:
                return new
        if i - self.last_tick < p.hold_ticks:
            return None
        ph = self.phases[self.phase_of[i]]
        if ph.kind == "single":
            dt = ref.dt
            last = p.trigger_remaining if self.triggered(i) else p.min_remaining
            if (ph.i1 - i) * dt < last or (i - ph.i0) * dt < p.settle - 1e-9:
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
        steps = self._episode_steps()
        if self.episode is not None and steps > 0:
            end = self._catch_end()
            if (  # multi-step recovery: the DCM still outside the band on the next step
                k == end and self.caught_step == k - 1 and k < self.episode + steps + p.until_inside
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

    def _rebased(self, ref: WalkingReference, i: int) -> WalkingReference:
        """The walk re-based on a landed sole (``back_rebase``: :class:`LandedRebase`'s
        pending step and shift, it and every later step moved, the rest re-planned), the
        catch extended by ``back_rebase_steps`` (re-planned and carried)."""
        p, (k, shift) = self.params, self.rebase.pending or (0, np.zeros(2))
        self.rebase.pending = None
        plan = shifted_plan(self.plan, k, shift)
        new = self.regenerate(ref, plan, i, self.phases[self.phase_of[i]])
        self.plan, self.before, self.first, self.last_tick = plan, plan, k, i
        self.increments = np.zeros((p.steps_ahead, 2))
        if self.episode is not None and p.back_rebase_steps > 0 and self.trigger.tick is not None:
            most = self.episode + self._episode_steps() + p.back_rebase_steps
            self.end = max(self.end, min(k + 1 + p.back_rebase_steps, most))
            first = int(self.phases[self.phase_of[self.trigger.tick]].step)
            self.trigger.extra = max(self.trigger.extra, self.end - 1 - first - p.catch_swings)
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
            sw = ph if j == 0 and ph.kind == "single" else self._swing_phase(kk)
            at = i if sw is ph else sw.i0
            most, speed = self.reach(at)
            total = incs[j] + p.gain * want
            n = math.hypot(total[0], total[1])
            if n > most:
                total *= most / n
            # the swing sole can move only so far in the time left (bend_rate: peak speed per m)
            room = speed / bend_rate(sw, at, ref.dt, self.swing)
            change = total - incs[j]
            n = math.hypot(change[0], change[1])
            later = p.stretch_later > 0 and self.trigger.carried(i)  # (stretch_later)
            if sw is ph and (self.trigger.triggered(i) or later) and not self.trigger.forward:
                room = self.stretched.room(int(self.phase_of[i]), room, n)  # (stretch)
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
