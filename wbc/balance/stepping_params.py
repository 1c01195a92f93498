"""The step adjuster's parameters (:class:`SteppingParams`, :mod:`.stepping`): when and how far
the footsteps move, the push trigger, the swing's lift and its landing in the measured frame
(:mod:`.swing_catch`); the dead bands of a robot that states none."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..exceptions import ConfigurationError
from ..model import Robot
from .push_jump import JUMP_SIGMA, JUMP_TAU

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
    #: s: ... in a swing whose push the trigger caught (``trigger_jump``): a push late in the
    #: swing re-plans once more (with the 20 mm lift, backward 0.609 → 0.617 N·s; 30 ms in
    #: every swing: 0.625, but the unpushed ``lateral_wb`` re-planned once more;
    #: benchmarks/pushes.md)
    trigger_remaining: float = 0.03
    min_clearance: float = 0.005  # m between the feet (as the footstep plans)
    max_shift: float = 0.08  # m: largest shift of a step from the plan before its re-plans
    max_foot_speed: float = 0.6  # m/s: peak speed the bend adds to the swing sole (≈ 0.75 of
    # the AX-12A's no-load speed at the ~0.13 m hip-to-ankle lever)
    #: m, m/s: ``max_shift`` and ``max_foot_speed`` in the swings the catch of a push backward
    #: carries (:meth:`~.stepping.StepAdjuster.reach`; 0: the same): the body falling back
    #: on its heels needs the reach and the first swing's room (its bend at the AX-12A's
    #: no-load speed at the lever, the limiter holding every goal within the servos'
    #: speed); after a push forward measured worse (0.852 → 0.688 N·s), kept there
    back_shift: float = 0.1
    back_foot_speed: float = 0.8
    #: m (0: ``back_shift``): the reach of the catch's later swings (the carried ones after
    #: the triggered swing): their re-plans wanted 110–140 mm after a 0.80 N·s push at 0 ms
    #: and were cut at ``back_shift``; the legs' own reach (``feasible_shift``) still bounds
    #: them (issue 30, benchmarks/pushes.md)
    back_later: float = 0.0
    #: 1: the catch's later carried swings stretched as the triggered one (``stretch``: the
    #: clock slowed while their re-planned landing is beyond the room their time left gives;
    #: 0: only the triggered swing). On by default: of 80 backward pushes 50 against 48
    #: (held out 32 of 47 against 31), none of the old default's lost; forward, toward, away
    #: at their bounds, the nominal walks, 20 plants and the OP3's backward screen unchanged
    #: (issue 30, benchmarks/pushes.md, twenty-third session)
    stretch_later: float = 1.0
    hold_ticks: int = 3  # ticks between two re-plans
    #: a catch re-plans the step it starts in and episode_steps − 1 after it (0: every later
    #: step, which keeps the walk rocking sideways after a push), then rests rest_steps steps
    episode_steps: int = 2
    #: ... after a push backward the trigger caught (0: ``episode_steps``): the body on its
    #: heels falls in the third swing, at the plan's pace (240 ms) and not re-planned; with
    #: ``landing_turn`` 0.5: backward 0.727 → 0.734 N·s, the other three and the OP3's
    #: backward identical (benchmarks/pushes.md; ``episode_steps`` 3 after any push: 0.719)
    back_episode: int = 3
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
    #: the share of the stance sole's roll onto an edge the measured base takes in the
    #: landing correction (its lowest corner below the floor, :meth:`~.stepping.StepAdjuster.
    #: stance_rise`: the estimate anchors the sole's centre on the floor, so a sole rolled
    #: onto its heel reads the base low and the swing sole lands high; 0: off) (1: at a push
    #: backward the second step's target at its landing 27 → 11 mm up, the sole 22 → 13 mm;
    #: with ``hurry_single``: backward 0.695 → 0.711 N·s; benchmarks/pushes.md; not after a
    #: push forward, the sole on its toe: forward 0.852 → 0.820)
    landing_tilt: float = 1.0
    #: m: in a catch's swings (:meth:`~.swing_catch.PushTrigger.carried`), the swing sole's
    #: target lowered by this much at the landing (blended in over the lift's ``lift_land``
    #: share): the servos' lag and a body rolling back on its stance heel keep the sole
    #: above the floor at the planned landing (0: off)
    landing_depth: float = 0.0
    #: the measured floor: in the swings the catch of a push backward carries, over the
    #: swing's last ``landing_floor`` share (smoothstep in), the swing sole's ground clearance
    #: in the solve lowered to the lowest corner of its target in the measured frame
    #: (:meth:`~.stepping.StepAdjuster.floor`; ``TickTargets.swing_floor``): that target,
    #: turned toe down by the torso's error, has its toe on the controller's own floor, which
    #: held the sole 15–40 mm above it (0: off)
    landing_floor: float = 0.0
    #: ... not in the catch's first ``floor_skip`` swings (1: from the swing after the
    #: triggered one)
    floor_skip: int = 0
    #: rad: after a push backward the trigger caught, the swing sole's rotation in the
    #: measured frame turned by at most this angle (its position by the whole correction):
    #: the torso's error, 30–45° in the third swing of a 0.8 N·s push, turns the sole toe
    #: down 35–47° in the solve, its toe on the controller's floor 25–40 mm above its target
    #: (0: the whole correction; 0.25: the first swing's heel on the floor; 0.4 lost a push
    #: the default keeps; with ``back_episode`` 3: backward 0.727 → 0.734 N·s)
    landing_turn: float = 0.5
    #: share (0: off): after a push backward the trigger caught, in the swings the catch
    #: carries and the double supports before them, the torso target turned this share of the
    #: way to the measured torso (the stabilizer's clipped target, +21.7° against a torso at
    #: −9° in the third swing of a 0.8 N·s push, turns the measured-frame landing)
    back_torso: float = 0.0
    #: m (0: off): after a push backward, in a swing the catch carries, its landing no later
    #: than the time the DCM error (LIPM) takes to grow to this (``hurry_single``'s clock,
    #: at most ``catch_hurry``×), though the room rule would leave it longer
    back_runaway: float = 0.0
    #: m (0: off): after a push backward the trigger caught, the estimator's ``anchor_band``
    #: from then on (a sole landing further than this from its plan anchored where it landed:
    #: the catch's short second step, 50 mm behind its plan at 0.8 N·s; on: backward 0.734 →
    #: 0.742 N·s, the other three and the OP3's backward identical; 0.02–0.04 lose pushes;
    #: benchmarks/pushes.md); 0.02 since ``Gains.real_step`` and ``anchor_down`` (the sole
    #: judged once down): with them, 48 of 80 backward pushes against 43 (twenty-second session)
    back_anchor: float = 0.02
    #: m/s (0: off): after a push backward, in a swing the catch carries, ``hurry_single``'s
    #: clock no faster than leaves the swing sole (where the estimate and the present joints
    #: put it) the time to reach its re-planned landing at this speed: the third swing of a
    #: 0.8 N·s push, hurried 1.6×, landed 66 mm short of it, its sole still loaded for the
    #: first 30 ms (:meth:`~.stepping.StepAdjuster.rate`) (off: 0.8 with ``back_skip`` 2 lands
    #: it 12 mm further and falls 0.09 s later, no push more; in every swing loses one;
    #: benchmarks/pushes.md)
    back_reach: float = 0.0
    #: rad (None: ``landing_turn``): ``landing_turn`` in the swings past ``back_skip`` (0: the
    #: sole's rotation the torso target's, not turned into the measured frame at all) (off:
    #: 0, 0.25 and 0.8 in the third swing lose 2–4 of 5 screened pushes)
    back_turn: float | None = None
    #: s (0: ``lead``): ``lead`` in the swings past ``back_skip`` after a push backward (off:
    #: 0.03–0.06 from the second or third swing lose 3–4 of 5 screened pushes)
    back_lead: float = 0.0
    #: × (0: ``catch_hurry``): ``catch_hurry`` in the double supports before the swings past
    #: ``back_skip`` after a push backward (the third swing's sole still loaded at lift-off)
    #: (off: 1.5 and 2 before the third swing lose one of 5 screened pushes)
    back_hurry: float = 0.0
    #: m (0: off): after a push backward, at the first tick of the double support after a
    #: carried swing past ``back_skip``, where the landed sole stands from the other sole (the
    #: IMU's rotation and the present joints: no base, no drift) against the plan; beyond this,
    #: that step and every later one re-based on it (:class:`~.swing_catch.LandedRebase`), the
    #: CoM re-planned: the third sole of a 0.8 N·s push lands 66 mm short and the solve, its
    #: target left at the plan, holds that sole 24 mm up toward it while the body tips back
    #: (off: with ``back_skip`` 2 the 8 screened backward pushes main's; at every carried
    #: landing 1 of main's 5 kept; benchmarks/pushes.md)
    back_rebase: float = 0.0
    #: steps: a re-base (``back_rebase``) extends the catch (re-planned, carried) to this many
    #: steps after the re-based one (at most this many past ``back_episode``)
    back_rebase_steps: int = 1
    #: m/m (0: off): after a push backward the trigger caught, while the catch is on (and
    #: ``back_dcm_steps`` steps after it), the CoM target moved by ``−back_dcm`` × the DCM
    #: error (the estimate's less the reference's), at most ``back_dcm_max`` m: the ankle
    #: strategy (``Gains.k_dcm``'s term) in the catch alone, the unpushed walk untouched (off:
    #: 1–3 of 8 screened backward pushes against main's 5 at every gain, ramp and start)
    back_dcm: float = 0.0
    back_dcm_max: float = 0.02
    back_dcm_steps: int = 0
    #: s: ... ramped in over this time from its start (0: at once); phases: ... from the start
    #: of the ``back_dcm_from``-th phase after the trigger's (0: the trigger's tick)
    back_dcm_time: float = 0.0
    back_dcm_from: int = 0
    #: True: ``back_dcm`` over the whole walk instead (no trigger), along the walk's heading and
    #: only against a DCM behind its reference (off: with ``back_dcm`` 1.0 backward 0.742 →
    #: 0.789 N·s, forward 0.852 → 0.773, away 0.891 → 0.578; ``Gains.k_dcm`` 1.0: 0.781,
    #: 0.656, 0.922; benchmarks/pushes.md)
    back_dcm_walk: bool = False
    #: swings: neither ``back_torso``, ``back_runaway``, ``back_reach``, ``back_turn``,
    #: ``back_lead`` nor ``back_hurry`` in the catch's first ones
    back_skip: int = 0
    #: m: the lift (``lift``) in the swings the catch of a push backward carries (None: ``lift``)
    back_lift: float | None = None
    #: 1/s: in the double support after a caught landing (:class:`~.swing_catch.
    #: LandedDescent`), the landed sole's contact target lowered by ``d``, ``d += descend ·
    #: gap · dt`` (``gap``: its lowest point measured above the other sole's), within
    #: ``0 … descend_depth`` m, blended out over the double support's last ``descend_out``
    #: share (0: off); ``descend_hold`` s: the walk's clock stands, at most that long, while
    #: the gap is above ``descend_band`` m (0: not held) (off: measured worse, every push
    #: of the backward screen the same or sooner down; the landed knee extends at the servo's
    #: speed behind a goal the limiter already moves at its own; benchmarks/pushes.md)
    descend: float = 0.0
    descend_depth: float = 0.02
    descend_out: float = 0.3
    descend_hold: float = 0.0
    descend_band: float = 0.003
    #: s: > 0: the correction less its running mean per stance side (this time constant):
    #: a plant's steady lag of its plan left alone, a push's departure from it corrected
    landing_tau: float = 0.0
    #: step timing: in double support, while the DCM error along the walk (heading frame) is
    #: beyond ``hurry_band``, the walk's clock runs ``hurry`` times as fast (the next lift-off
    #: and landing come earlier; :meth:`StepAdjuster.rate`; 1: off)
    hurry: float = 1.0
    hurry_band: float = 0.03
    #: step timing in a swing whose push the trigger caught (``trigger_jump``): from the
    #: trigger on, the walk's clock runs ``slow`` times as fast (the landing later: the
    #: lagging servos bring the swing sole to its re-planned landing; 1: off)
    slow: float = 1.0
    #: share (0: off): after a push backward, in the swing the trigger caught, when a
    #: re-planned landing asks more than the swing's time left covers at the foot speed, the
    #: walk's clock slowed so that it does, the time left at most ``1 + stretch`` times as
    #: long, until a re-plan in reach (:mod:`.stretch`) (0.3: of 80 backward pushes at seven
    #: push times every one main keeps and 8 more, 43 against 35, 27 of them at times no
    #: earlier screen used 16 against 11; forward, toward, away, the unpushed walks and 20
    #: randomised plants unchanged: it never acted there; 0.5: 25 of 53 against 24;
    #: benchmarks/pushes.md)
    stretch: float = 0.3
    #: step timing in single support too: during a catch (the DCM error ``e`` beyond the dead
    #: band), the landing comes sooner when that leaves the swing more room beyond the shift
    #: it needs (LIPM: the shift needed grows as ``e e^{ω T}``, the room as ``v T``): the clock
    #: runs ``T / T*``, ``T* = ln(v / (ω e)) / ω``, at most ``hurry``× (:meth:`rate`); in a
    #: swing the catch of a push backward carries (the trigger's, :meth:`~.swing_catch.
    #: PushTrigger.carried`) at most ``catch_hurry``× if more (on: with ``hurry`` 1 only those
    #: swings; with ``landing_tilt``: backward 0.695 → 0.711 N·s; forward measured worse, not
    #: done: 0.852 → 0.820; benchmarks/pushes.md)
    hurry_single: bool = True
    #: m: once a catch has re-planned a step, the dead band of its later re-plans (None: the
    #: band): the band decides whether to catch, the catch then takes the whole error
    catch_band: float | None = None
    #: early touch-down (needs the estimator's contact detection, ``Gains.contact_band``):
    #: during a catch, a swing sole found down on the floor for this many ticks running lands
    #: where it is: that step and every later one re-based on it (moved by its shortfall),
    #: the CoM reference re-planned, the walk's clock jumps to the landing (0: off)
    touchdown: int = 0
    #: the early touch-down counts a sole found down only after this share of its swing (a
    #: toe brushing the floor early in a pushed swing is no landing; 0: from ``settle``)
    touchdown_share: float = 0.0
    #: m: the touch-down acceptance (:mod:`.touchdown`; 0: off): in a swing the catch carries
    #: (past ``accept_share`` of it) the swing sole found down by the encoders and the IMU
    #: (its lowest point within ``accept_down`` of the stance sole's, ``accept_ticks`` ticks
    #: running) lands: the walk's clock jumps to the landing and, when it stands more than
    #: this from its planned place (from the stance sole), that step and every later one are
    #: re-based where it stands; at the double support after a carried swing not accepted in
    #: it, the same re-base; the catch goes on ``accept_steps`` more steps
    accept: float = 0.0
    accept_down: float = 0.004
    accept_ticks: int = 2
    accept_share: float = 0.6
    accept_steps: int = 1
    #: ticks: in the double support after an accepted landing, the sole to lift next found
    #: up (beyond ``accept_down`` above the landed one) that many ticks running: its swing
    #: starts now (the clock jumps to the lift-off; 0: off)
    accept_lift: int = 0
    accept_back: bool = True  # ... only after a push backward (False: any push)
    accept_skip: int = 0  # ... not in the catch's first that many carried swings
    #: the double support of an accepted landing sets the controller's contacts to the
    #: reference's soles at once (``contacts_move``; off: the stack's own landing). Measured:
    #: the contact's jump fails the solve through that double support (the last configuration
    #: held)
    accept_contacts: bool = False
    #: m per tick (0: off): the accepted double support's landed contact anchored where the
    #: solve's sole is and walked to the reference's by at most this much per tick
    #: (``contacts_move``): the catch's landing asks the hard contact row for the solve's miss
    #: (40–60 mm) in one tick, infeasible through the double support on the Bioloid (no
    #: ``landing_time`` in its stack)
    accept_settle: float = 0.0
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
    trigger_sigma: float = JUMP_SIGMA
    trigger_tau: float = JUMP_TAU
    #: m: once triggered, the swing sole's target raised by this much (blended in over
    #: ``lift_time`` s, out over the swing's last ``lift_land`` share so that it lands on
    #: time): the push pitches the body about the stance toe and the swing toe meets the
    #: floor 20 ms later, short of any re-planned landing (lift first, then reach; 0: off)
    #: (20 mm over 40 ms: the 15 mm over 30 ms before it at the same mean speed, 0.5 m/s;
    #: forward 0.648 → 0.703 N·s, benchmarks/pushes.md)
    lift: float = 0.02
    lift_time: float = 0.04
    lift_land: float = 0.3
    #: rad: once triggered, the torso target turned toward the push along the walk by this
    #: much (the hip strategy along the walk; negative: pitched against it), blended in over
    #: ``pitch_time`` s, out over the next double support (:meth:`PushTrigger.pitched`; 0: off)
    catch_pitch: float = 0.0
    pitch_time: float = 0.05
    #: s: once triggered, the swing sole's target led by this much of its planned horizontal
    #: velocity (the servos' lag: the swing sole follows its target ~30 ms late, and lands
    #: short of a re-planned landing; :meth:`PushTrigger.lifted`; 0: off)
    lead: float = 0.0
    #: rad: once a push forward is triggered, the swing sole's target turned toe up by this
    #: much (the body pitched about the stance toe puts the swing toe on the floor, 6–9 N
    #: for 50 ms at 0.75 N·s), blended as the lift (0: off; heel up after a push backward
    #: measured worse: not done) (0.15: forward 0.703 → 0.719 N·s, the rest unchanged;
    #: benchmarks/pushes.md)
    toe_up: float = 0.15
    #: multi-step recovery's swings: the lift and the landing in the measured frame go on in
    #: this many swings after the triggered one (:meth:`PushTrigger.carried`): a push backward
    #: leaves the body pitched back on its heels and the next swing's sole, placed in the
    #: controller's upright frame, drags its heel on the floor (0: the triggered swing only)
    #: (2, with ``catch_hurry`` 3: backward 0.617 → 0.695, forward 0.719 → 0.852 N·s, toward
    #: and away unchanged; benchmarks/pushes.md)
    catch_swings: int = 2
    #: step timing in a multi-step catch: in a double support before a carried swing
    #: (``catch_swings``), while the DCM error along the walk is beyond ``hurry_band``, the
    #: walk's clock runs this many times as fast (the next step lifts sooner: the body on its
    #: heels loses less; :meth:`StepAdjuster.rate`; 1: off; the other double supports: ``hurry``)
    catch_hurry: float = 3.0

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

    def measured(self, robot: Robot) -> bool:
        """True when both dead bands are ``robot``'s own — stated here or in its ``robot.toml``
        ``[balance.stepping]`` — rather than the Bioloid's defaults (:data:`BAND_X`,
        :data:`BAND_Y`), which re-plan other robots' unpushed walks (benchmarks/op3.md,
        benchmarks/robots.md)."""
        data = getattr(robot, "robot_data", None)
        stated = data.balance.get("stepping", {}) if data is not None else {}
        return all(getattr(self, k) is not None or k in stated for k in ("band_x", "band_y"))

    def check(self) -> SteppingParams:
        for name in (
            "threshold", "gain", "min_remaining", "min_clearance", "max_shift", "max_foot_speed",
            "back_shift", "back_foot_speed", "back_later", "stretch_later",
            "band_x", "band_y", "settle", "baseline_tau", "landing", "landing_band",
            "landing_lateral", "landing_blend", "landing_catch", "landing_tau", "landing_tilt",
            "landing_depth", "landing_floor", "landing_turn", "back_torso", "back_runaway",
            "back_anchor", "back_reach", "back_turn", "back_lead", "back_rebase",
            "back_dcm", "back_dcm_max", "back_dcm_time",
            "back_hurry",
            "back_lift", "descend",
            "descend_depth", "descend_out",
            "descend_hold", "descend_band", "hurry",
            "hurry_band", "catch_band", "band_travel", "trigger_jump", "trigger_band", "lift",
            "lift_time", "lift_land", "trigger_sigma", "trigger_tau", "trigger_remaining",
            "pitch_time", "lead", "toe_up", "accept", "accept_down", "accept_settle", "stretch",
        ):  # fmt: skip
            v = getattr(self, name)
            if v is None and name in (
                "band_x",
                "band_y",
                "catch_band",
                "trigger_jump",
                "back_lift",
                "back_turn",
            ):
                continue  # (the robot's: for_robot)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"stepping: {name} must be a finite number >= 0, got {v}")
        if not (math.isfinite(self.catch_pitch) and abs(self.catch_pitch) <= 1.0):
            raise ConfigurationError(
                f"stepping: catch_pitch must be finite, within ±1 rad, got {self.catch_pitch}"
            )
        if self.back_torso > 1.0:
            raise ConfigurationError(
                f"stepping: back_torso must be a share in [0, 1], got {self.back_torso}"
            )
        if self.landing_floor > 1.0:
            raise ConfigurationError(
                f"stepping: landing_floor must be a share in [0, 1], got {self.landing_floor}"
            )
        if not 0.0 <= self.accept_share < 1.0:
            raise ConfigurationError(
                f"stepping: accept_share must be in [0, 1), got {self.accept_share}"
            )
        if not 0.0 <= self.touchdown_share < 1.0:
            raise ConfigurationError(
                f"stepping: touchdown_share must be in [0, 1), got {self.touchdown_share}"
            )
        if not 0.0 < self.slow <= 1.0:
            raise ConfigurationError(f"stepping: slow must be in (0, 1], got {self.slow}")
        for name in ("hurry", "catch_hurry"):
            if not getattr(self, name) >= 1.0:
                raise ConfigurationError(
                    f"stepping: {name} must be >= 1 (a clock speed), got {getattr(self, name)}"
                )
        if int(self.steps_ahead) != self.steps_ahead or self.steps_ahead < 1:
            raise ConfigurationError(
                f"stepping: steps_ahead must be an integer >= 1, got {self.steps_ahead}"
            )
        for name in (
            "episode_steps", "rest_steps", "until_inside", "touchdown", "trigger_skip",
            "catch_swings", "floor_skip", "back_episode", "back_skip", "back_rebase_steps",
            "back_dcm_steps", "back_dcm_from", "accept_ticks", "accept_steps", "accept_lift",
            "accept_skip",
        ):  # fmt: skip
            v = getattr(self, name)
            if int(v) != v or v < 0:
                raise ConfigurationError(f"stepping: {name} must be an integer >= 0, got {v}")
        if int(self.hold_ticks) != self.hold_ticks or self.hold_ticks < 1:
            raise ConfigurationError(
                f"stepping: hold_ticks must be an integer >= 1, got {self.hold_ticks}"
            )
        return self
