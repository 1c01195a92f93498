"""The closed loop's feedback gains (:class:`Gains`) and their measured defaults
(:func:`default_gains`); the feedback itself is :mod:`wbc.balance.stabilizer`'s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigurationError


@dataclass(frozen=True)
class Gains:
    """Feedback gains (each term: :mod:`wbc.balance.stabilizer`'s docstring); 0 turns a term
    off."""

    # issue 30: halved from 2 / 2 / 0.1 s, which tipped plants with 12–16 ms of latency and
    # stiff servos to 44° (benchmarks/physics.md, "Plant-randomised sweep"); with kin_tilt,
    # 2 / 2 keeps one more plant without the feed-forward and brings lateral_wb's nominal to
    # 2.4° / 0.98, but loses three with it (38, 42 on every walk): not the default (issue
    # 30's fourth pass)
    k_p: float = 1.0  # rad/rad torso tilt
    k_i: float = 1.0  # 1/s
    k_d: float = 0.05  # s
    k_dcm: float = 0.0  # m/m
    #: 1/s: integral of the DCM error on the CoM target, along the walk (the torso target's
    #: heading frame): the steady lag a wrong servo model leaves (issue 30); its share clipped
    #: to max_shift. Off here, 0.25 in :data:`NO_FEED_FORWARD_GAINS`
    k_dcm_i: float = 0.0
    k_dcm_i_y: float = 0.0  # 1/s: the same sideways
    k_lean: float = 0.0  # rad/rad: the CoM turned back about the stance sole by k_lean·e
    #: the torso term's part about the target's heading (roll: k_p, k_i and k_d sideways)
    #: scaled by this (1: the same gains on every axis)
    k_roll: float = 1.0
    #: the torso command's part about the torso target's own vertical axis (its twist, what
    #: the hip yaws turn) scaled by this after the clip (1: as is; 0: none): a roll about the
    #: heading of a torso leaned forward is partly a twist, so the tilt feedback drives the
    #: hip yaws (issue 33: through their play and latency the loaded soles stick, slip and
    #: turn; benchmarks/drive.md)
    k_twist: float = 1.0
    k_yaw: float = 1.0  # 0..1: share of the heading error fed back (the gyro's heading)
    #: Hz: the torso command's heading (vertical) part low-passed, first order, at this
    #: cut-off (0: off): the yaw loop's ringing (~5.5 Hz on stiff, late plants: issue 30)
    #: attenuated before it reaches the hip yaw servos
    yaw_cutoff: float = 0.0
    #: rad: the torso command's heading (vertical) part clipped on its own to this, its
    #: tilt part to ``max_tilt`` (and their integrals each to its share over ``k_i``), so a
    #: heading lag (a soft plant's turn) does not eat the tilt's command; 0: the two share
    #: ``max_tilt`` as one vector (issue 30)
    max_yaw: float = 0.0
    #: s: more rate gain on the heading part alone (``k_d`` + this on the vertical gyro
    #: rate): damping for the yaw loop's ringing on stiff, late plants (issue 30)
    yaw_damping: float = 0.0
    #: rad/s: the heading's gain scheduled from the yaw loop's measured ringing (0: off): the
    #: vertical gyro rate high-passed (first order, :data:`RING_HZ`) and its RMS over a
    #: sliding window (:data:`RING_WINDOW` s, exponential) ``r``; the torso command's heading
    #: part scaled by ``min(1, yaw_ring / r)``, full authority while the loop is quiet (a
    #: soft plant's turn lag: a slow rate the high-pass takes out), backed off on a plant
    #: whose servo latency rings the hip yaw (issue 30)
    yaw_ring: float = 0.0
    #: s: the heading's gain scheduled from the servos' measured lag behind their goals
    #: (:func:`~wbc.balance.servo_lag.servo_lag`, ``τ``; 0: off): the torso command's heading
    #: part scaled by ``min(1, lag_yaw / τ)`` — less heading authority on a plant whose
    #: servos follow late (soft: τ 35–60 ms, stiff 5–36 ms). Without the feed-forward, 0.04
    #: keeps 295 of 300 randomised plants against 294 but loses one the default keeps (issue
    #: 30, i30p's seventh round, benchmarks/physics.md): off
    lag_yaw: float = 0.0
    #: s: the walk's clock slowed by the servos' measured lag τ (0: off): ``clip(lag_clock / τ,
    #: clock_min, 1)`` (:func:`.servo_lag.clock_rate`), the DCM reference's velocity alike
    lag_clock: float = 0.0
    clock_min: float = 0.7  # the slowest clock lag_clock sets (0 < clock_min <= 1)
    clock_single: float = 1.0  # the share of lag_clock's slowing in single support (0..1)
    j_p: float = 0.0  # joint level: leg goals turned by OP3 gain × j_p × tilt error
    j_d: float = 0.0  # joint level: ... × j_d × gyro rate (s)
    max_offset: float = 0.2  # rad, per joint
    max_tilt: float = 0.2  # rad
    max_shift: float = 0.02  # m
    k_hip: float = 100.0  # rad/m: hip strategy, the torso rolled toward a DCM beyond hip_band
    hip_band: float = 0.025  # m: DCM offset outward of the stance sole's centre left alone
    max_hip: float = 0.6  # rad: largest hip-strategy roll of the torso target
    hip_release: float = 2.0  # rad/s: how fast the hip-strategy roll may shrink
    #: the hip strategy's roll about the torso's own axis (:mod:`wbc.balance.hip_roll`; 0: off,
    #: about the level axis ``z × u``): the axis less its part along the vertical of 1: the
    #: torso target, 2: the estimated torso — a torso leaned forward is rolled, not twisted.
    #: 2 is the default without the feed-forward (:data:`NO_FEED_FORWARD_GAINS`): 298 of 300
    #: plants on seeds 0–1 against 297 (s0 lateral_wb 18 kept, none lost), held-out seeds 8–9
    #: every walk as before to the 0.1° (119 of 120 both); 1 loses s0 lateral_wb 18 like 0
    #: (issue 30, twentieth session, benchmarks/physics.md). With the feed-forward: 0 (the
    #: pushes, measured with it, not re-measured)
    hip_axis: int = 0
    #: 1: the state estimate's kinematic terms (base, CoM, its velocity, the DCM: what the
    #: step adjuster, the hip strategy and the DCM integral read) at the kinematics' heading,
    #: the stance sole where the plan turned it, while the torso's rotation keeps the gyro's
    #: heading for the heading feedback (0: every term at the gyro's heading). Soles that
    #: slipped round by δ leave a robot balanced about them; in the plan's frame its CoM's
    #: lead along the walk ``a`` reads as a sideways DCM error ``a sin δ`` (issue 30: s1
    #: ``walk10_wb`` 10, the soles 25° round after 2.3 s, four re-plans of the step adjuster
    #: before the spin that ends it; needs ``k_yaw`` > 0, the gyro's heading). Off: without the
    #: feed-forward it keeps s1 walk10_wb 10 and s0 turn_wb 37 (main's two losses on seeds
    #: 0–1) but loses six plants main keeps over seeds 0, 1, 8, 9 (stiff, late ones;
    #: 297 of 300 on seeds 0–1 against 298; benchmarks/physics.md, twenty-first session)
    kin_heading: int = 0
    #: rad: with ``kin_heading``, only the soles' slip beyond this turns the kinematic terms
    #: (the slip's sign kept, its size less the band: a plant whose soles stay within it runs
    #: exactly as without ``kin_heading``). 0.1 keeps s0 turn_wb 37 (not s1 walk10_wb 10) and
    #: loses three plants main keeps (298 of 300 on seeds 0–1, main's count): off
    kin_band: float = 0.0
    #: the hip strategy started by a push (0: off; 0.6: 15 mm at the default band): once a
    #: single support's estimated DCM jumps outward of the stance sole by more than
    #: ``hip_jump`` × ``hip_band`` in one tick (not across the support switch), the whole
    #: ``max_hip`` is asked while the DCM is outward of the sole's centre until the support
    #: changes: the roll starts at once, not 40–50 ms later when the lagging estimate leaves
    #: the band (issue 30, benchmarks/pushes.md: away 0.727 → 0.789 N·s on ``walk10_wb``)
    hip_jump: float = 0.6
    #: rad: the push's hip roll driven to the joint (0: off): once ``hip_jump``'s trigger
    #: fires, the stance hip roll's solved goal is moved by this much further toward the roll
    #: (× the roll's share of ``max_hip``), so the servo spins the upper body at its stall
    #: torque until the joint's range ends it instead of stopping where the whole-body solve
    #: (the CoM held by the stack's heaviest task) leaves it; the roll and the kick then
    #: shrink at ``kick_release`` rad/s, not ``hip_release`` (:meth:`Stabilizer.joint_offsets
    #: <wbc.balance.stabilizer.Stabilizer.joint_offsets>`). Away 0.789 → 0.828 N·s on
    #: ``walk10_wb`` (0.1: 0.813, 0.2: 0.820; 0.4: 0.773, the torso beyond 45° of its plan),
    #: the OP3 1.164 → 1.211; the other pushes and every unpushed plant the same (issue 30,
    #: benchmarks/pushes.md)
    hip_kick: float = 0.3
    kick_release: float = 0.5  # rad/s (> 0 with a kick)
    #: rad: the kick braked before the torso tips past this tilt toward the fall (0: no
    #: brake): ``kick_brake × (θ + kick_lead θ̇ − kick_tilt)⁺`` taken off the kick, ``θ`` the
    #: estimated torso's tilt along the roll, ``θ̇`` its gyro rate (:mod:`wbc.balance.hip_kick`):
    #: the spin out of stall stopped by the servo's whole torque, not by its position error
    #: alone (with the limbs below: away 0.875 → 0.891 N·s on ``walk10_wb``, issue 30)
    kick_tilt: float = 0.7
    kick_lead: float = 0.05  # s: how far ahead the brake reads the tilt
    kick_brake: float = 2.0  # rad of kick taken off per rad of predicted tilt beyond kick_tilt
    #: rad: with the kick, the other leg's hip roll (``counter_leg``) and that side's shoulder
    #: roll (``counter_arm``) moved toward the roll's spin: the swing leg and its arm spun
    #: toward the fall beside the torso (momentum reserves: the torso tilts less for the same
    #: angular momentum), within their joints' limits and speeds (0: off). Away 0.828 → 0.852
    #: (leg 0.4), 0.867 (leg 0.7), 0.875 (+ arm 1.0), 0.891 N·s (+ arm 2.0, the brake) on
    #: ``walk10_wb`` (issue 30, benchmarks/pushes.md); the leg at 1.0 with ``kick_hold``
    #: 0.035: 0.906 (alone, either: 0.891), but the OP3 1.516 → 1.117 (the leg at 1.0
    #: alone: 1.469): not the default
    counter_leg: float = 0.7
    counter_arm: float = 2.0
    #: with ``counter_leg``: the leg's goal capped at this × the hip roll that swings the leg's
    #: CoM under the other hip (from the robot's model at its stand pose, :func:`wbc.balance.
    #: hip_kick.under_angle`: the Bioloid π/2, never reached within its leg; the OP3 0.65
    #: rad): a per-robot size for ``counter_leg`` (0: off, the fixed rad). With
    #: ``counter_leg`` 1.0: the OP3's away grid 14 of 21 pushes up (1.0 rad: 11; main's 0.7:
    #: 15), the Bioloid's unchanged: off (issue 30, benchmarks/pushes.md)
    counter_under: float = 0.0
    #: rad: after a push's kick, the limbs (``counter_leg``, ``counter_arm``) not brought
    #: back while the pushed stance sole stays rolled onto its edge toward the fall by more
    #: than this (its normal's tilt, from the IMU and the encoders): returning them then
    #: gives back angular momentum with the DCM still at the edge (0: off). With
    #: ``counter_leg`` 1.0: away 0.891 → 0.906 N·s on ``walk10_wb`` (0.02 and 0.05: the same;
    #: alone 0.891); the OP3's away 1.516 → 1.086 with it: the hold acted while the pushed
    #: sole was in its own swing (traced, thirteenth session). Held now only in the double
    #: support after the pushed single support: the Bioloid 0.906 with ``counter_leg`` 1.0,
    #: the OP3 1.195 (a grid of 21 pushes: 9 up against main's 15; ``counter_leg`` 1.0
    #: alone 11, the hold alone 13): off (issue 30, benchmarks/pushes.md)
    kick_hold: float = 0.0
    #: s: ``kick_hold``'s tilt read without a break for this long before the limbs are held
    #: (a one-tick reading at the support switch, the sole flat: no hold; 0: at once). 0.05
    #: with ``kick_hold`` 0.035: the OP3's away grid 12 → 13 of 21 (main 15), the Bioloid's
    #: with ``counter_leg`` 1.0 unchanged (11 of 18): off (benchmarks/pushes.md)
    kick_hold_for: float = 0.0
    #: with the kick: the limbs held (as ``kick_hold``) while the DCM measured from the
    #: kinematics alone (the IMU's rotation and the encoders, relative to the pushed stance
    #: sole: :meth:`~wbc.balance.hip_kick.HipKick.sole_dcm`) is beyond that sole's outer
    #: edge along the push (its distance from the sole's centre above this × the sole's half
    #: extent, :attr:`wbc.model.Robot.foot_size`; 1: the edge), released when it comes back
    #: inside: a hold triggered by the state (with ``kick_hold`` > 0 as well: both must
    #: read; 0: off). 1.0 or 0.8: the OP3's away grid main's 21 outcomes (the estimate's
    #: fused DCM instead: 7 of 21, thrown 100 mm off at the catch's support switch); the
    #: Bioloid's with ``counter_leg`` 1.0 that leg's alone (11 of 18; it holds only in falls
    #: under way: the Bioloid's hang is the CoP on the edge, the DCM inside): off, it
    #: changes no outcome (issue 30, benchmarks/pushes.md)
    kick_hold_edge: float = 0.0
    #: m: after a push away from the swing foot (``hip_jump``'s trigger), the CoM target
    #: raised by this within ``rise_time`` s, held while the trigger or the push's kick lasts,
    #: then lowered over ``rise_back`` s (:mod:`wbc.balance.push_rise`: the body driven up
    #: while the CoM is inside the edge the CoP is on pulls it back; 0: off). 0.015 on
    #: ``walk10_wb``: away pushes just above main's bounds 5 of 5 up against 2, held out
    #: (±22.5 ms) 7 of 14 against 5, every push main keeps kept; the other directions, the
    #: nominal walks and 20 plants unchanged; but the OP3's away pushes fail 53–138 solves a
    #: run with it: off (issue 30, benchmarks/pushes.md)
    push_rise: float = 0.0
    rise_time: float = 0.03  # s (> 0)
    rise_back: float = 0.3  # s (> 0)
    #: the push's rise clipped to this share of the loaded legs' room to extend (the CoM
    #: target's rise before a stance leg is straight, from the model's legs:
    #: :func:`wbc.balance.push_rise.leg_room`; 0: not clipped). With ``push_rise`` 0.015:
    #: 0.5 and 0.75 end the OP3's failed solves (its hard contact and self-collision rows
    #: with the legs near straight) but each loses 2 of main's 4 OP3 away survivors (1.0–1.6
    #: N·s); the Bioloid's screen 3 and 4 of 5 (0.015 alone 5, main 2): off (issue 30,
    #: benchmarks/pushes.md)
    rise_room: float = 0.0
    #: rad: the push's rise capped each tick so that the commanded configuration's loaded
    #: knees stay at least this bent (the CoM target at most the loaded legs' room to rise
    #: above the commanded CoM, read from the commanded ``q``, the torso's roll included:
    #: :class:`wbc.balance.push_rise.KneeRoom`; 0: not capped). On the OP3 the failed
    #: solves are not at straight knees (the landed leg 9.7 mm from straight at the first):
    #: 0.1 and 0.3 change nothing there: off (issue 30, benchmarks/pushes.md)
    rise_knee: float = 0.0
    #: s: the push's rise held at most this long from the trigger, then lowered (over
    #: ``rise_back``) even while the trigger or the kick lasts (0: held while they last).
    #: 0.1 with ``rise_back`` 0.15 (the rise gone before the OP3's catch step lands): no
    #: failed solve on the OP3, but one of its away survivors lost (1.4 N·s) and the
    #: Bioloid's screen 3 of 5 (``push_rise`` alone 5, main 2): off (benchmarks/pushes.md)
    rise_hold: float = 0.0
    #: 1: the push's rise held only in single support: lowered (over ``rise_back``) from
    #: the next double support on (0: held through it). The OP3's first failed solve is
    #: that double support's first tick: it fails as without (off; benchmarks/pushes.md)
    rise_single: float = 0.0
    #: 1/s: the state estimate's tilt pulled toward the stance legs' kinematics (the stance
    #: sole flat; :class:`~wbc.balance.estimator.StateEstimator` ``kin_gain``) besides the
    #: accelerometer's 0.2 /s: a gyro bias the calibration at rest leaves (the body rocking
    #: on its compliant servos, the encoders missing the backlash) tilts the estimate by
    #: bias / (0.2 + kin_tilt) instead of bias / 0.2 (issue 30, benchmarks/physics.md); used
    #: when the Stabilizer builds its estimator (not with one given: ``wbc drive``'s)
    kin_tilt: float = 0.5
    #: m: a sole landing further than this from its planned placement anchors the state
    #: estimate where it landed until it lifts (``StateEstimator`` ``anchor_band``; 0: off)
    anchor_band: float = 0.0
    #: m (0: off): a landed sole judged for ``anchor_band`` / ``back_anchor`` only once its
    #: lowest point is within this of the other's (``StateEstimator`` ``anchor_down``: not
    #: while it is still in the air at its first support tick, where ``back_anchor`` 0.02 put
    #: the catch's second sole 23–50 mm off). 0.003 by default, with ``real_step``: 48 of 80
    #: backward pushes against 43 (issue 30, benchmarks/pushes.md)
    anchor_down: float = 0.003
    #: m: a sole whose lowest point stands more than this above the other's carries no
    #: weight: the estimate anchors on the soles that do (``StateEstimator`` ``contact_band``:
    #: from the encoders' kinematics and the IMU's tilt; 0: the plan's support). 0.004
    #: moves no push beyond rounding and loses a ringing plant with the feed-forward
    #: (benchmarks/pushes.md, issue 30's seventh pass): off
    contact_band: float = 0.0
    #: m (0: off): in a double support, a planned sole whose lowest point stands more than
    #: this above the other's is left out of the state estimate (base, CoM velocity, DCM:
    #: :meth:`~wbc.balance.estimator.StateEstimator.loaded`) until it is down; the
    #: feedback's support (hip strategy, fall detector) stays the plan's. After a caught
    #: landing the landed sole is still in the air 2–4 ticks, moving back with the swing:
    #: averaged in, it halves the CoM velocity read (issue 30)
    support_down: float = 0.0
    #: 1: the estimate's kinematic terms (base, CoM, its velocity, the DCM) use the filter's
    #: rotation of the tick the joints were read (a tick before the IMU sample: the
    #: deployment reads right after the goals; StateEstimator ``joint_lag``); 0: this tick's.
    #: Off here, on in :data:`NO_FEED_FORWARD_GAINS` (the default without the feed-forward):
    #: it keeps more plants on turn_wb and lateral_wb; alone it loses plant 42 on walk10_wb;
    #: with k_d 0.03, 147 against 143 of 150 without the feed-forward, 2 fewer on walk10_wb
    #: with it (issue 30's sixth pass)
    joint_lag: float = 0.0
    #: 1: the estimate and the feedback stepped by the real time since the last tick (the
    #: session's ``at_time`` clock) where the walk's clock skipped (or repeated) reference ticks
    #: (``Session._step``); 0: by the walk's reference time since the last solved tick, which
    #: the step timing's clock (``catch_hurry`` 3×, ``hurry_single``) makes up to 3× the real
    #: step: the gyro integrated 3× over (the tilt 8–15° off in a catch's double support), the
    #: CoM velocity read at 1/3. On by default: with ``anchor_down`` 0.003 and ``back_anchor``
    #: 0.02, 48 of 80 backward pushes against 43 (held out 31 of 47 against 26; 3 of the old
    #: default's lost), the bisected bound 0.758 against 0.734 N·s; every other direction at
    #: its bound, the nominal walks and 20 plants unchanged (issue 30, benchmarks/pushes.md,
    #: twenty-second session)
    real_step: float = 1.0
    #: share of the double support in which the closed loop's reference moves its ZMP to the
    #: landed sole, the sway narrowed within the walk's margin (0: the plan as it is)
    transfer: float = 0.15
    #: the footsteps take the heading (:mod:`wbc.balance.step_yaw`; 0: off): at each
    #: lift-off the stance sole's measured heading error against the controller's, beyond
    #: ``step_yaw_band``, × this turns the swing sole's target rotation (clipped to
    #: ``max_step_yaw``, ramped, never nearer the stance sole than the plans' clearance);
    #: the landed sole keeps it while down. Issue 30 (i30p's tenth round, benchmarks/
    #: physics.md): a soft plant's turning walk under-turns every step
    step_yaw: float = 0.0
    max_step_yaw: float = 0.35  # rad: step_yaw's largest turn of the swing target
    step_yaw_band: float = 0.0  # rad: the stance sole's heading error step_yaw leaves alone
    #: rad/s: step_yaw only on a step whose reference heading turned at least this fast over
    #: the double support before it (a turning walk's; 0: every step)
    step_yaw_turn: float = 0.0
    #: step_yaw's swing angle within this × the step's planned turn (its swing sole's
    #: landing yaw less its stance sole's: StepYaw.plan) of the stance sole's kept yaw: a
    #: straight or closing step lands parallel to the stance sole (0: no window)
    step_yaw_cap: float = 0.0
    #: 1/s: the loaded legs' sag (solved goal − encoder) integrated into their goals
    #: (:mod:`wbc.balance.joint_integral`; 0: off), at most ``j_i_max`` rad, leaking at
    #: ``j_i_leak`` 1/s; a leg that swings lets it go
    j_i: float = 0.0
    j_i_max: float = 0.1
    j_i_leak: float = 0.5
    #: rad/s: j_i holds on a joint whose solved goal moves faster (its error then the servo's
    #: lag, not sag; 0: integrate always)
    j_i_still: float = 0.0
    #: j_i's encoders compared with the solved goals of (a tick + j_i_lag × the servos'
    #: measured lag, :func:`~wbc.balance.servo_lag.servo_lag`) ago, not this tick's: the
    #: tracking error a late servo shows on a moving goal is not integrated, its sag is
    #: (0: this tick's goals). 1: a soft plant's sag eaten with its lag (s0 turn_wb 38 lost
    #: again; s1 turn_wb 46 of 50): off
    j_i_lag: float = 0.0
    #: 1: j_i on the loaded legs' hip pitch, knee and ankle pitch only (their yaw and roll
    #: joints let go); 0: the six joints of each loaded leg
    j_i_sagittal: float = 0.0
    #: rad: j_i integrates its low-passed difference (0.1 s) only beyond ± this (0: all).
    #: 0.06 (with j_i 1, j_i_max 0.05): 149 / 145 of 150 on seeds 0 / 1 against main's
    #: 146 / 148 without the feed-forward (issue 30, i30n; benchmarks/physics.md): off
    j_i_band: float = 0.0
    #: which of the loaded legs' joints j_i integrates (the others let go): 0 the six, 1
    #: all but the hip yaw and hip roll, 2 the knee and ankle pitch, 3 the knee
    #: (:data:`~wbc.balance.joint_integral.JOINT_SETS`)
    j_i_joints: float = 0.0
    #: 1: j_i grows (and leaks) in single support only; in double support both legs hold
    #: theirs; 2: it grows in single support only and leaks in double support too (0: both
    #: legs' sag integrated in double support too). 2 with j_i_joints 3, j_i 1, j_i_max
    #: 0.05, j_i_leak 2: 148 / 149 of 150 on seeds 0 / 1 against main's 146 / 148 without
    #: the feed-forward, but s1 turn_wb 50 -> 49 (issue 30, i30n's fourteenth round;
    #: benchmarks/physics.md): off
    j_i_single: float = 0.0
    #: j_i only on servos softer than this × servos.toml's (0: always): the stiffness
    #: identified at rest at start-up (:func:`wbc.balance.live.closed_loop`'s rest,
    #: :func:`~wbc.balance.compliance.identify_stiffness`); j_i stays off while it is not
    #: identified (no rest, a bus that reads nothing) — the sag of a soft plant integrated,
    #: a stiff, late plant's tracking error left alone. 0.75 over j_i 1, j_i_max 0.05,
    #: j_i_joints 3, j_i_single 2, j_i_leak 2: 148 / 149 of 150 on seeds 0 / 1 against main's
    #: 146 / 148 without the feed-forward, but held out, seed 2's soft plants 57 of 60
    #: against 58 (and seed 3's at 0.62, 49 of 51 against 50): soft plants traded at the
    #: walk's end (issue 30, i30n's fifteenth round; benchmarks/physics.md): off
    j_i_stiff: float = 0.0
    #: s: the closed loop plays its reference this far ahead of the walk's clock, every
    #: target at once (the servos' lag led; issue 30, sixteenth session, benchmarks/
    #: pushes.md; 0: off)
    ref_lead: float = 0.0
    #: s: the goals led by this × the solved joints' velocity (each joint's, a tick's
    #: difference: the servos' lag led at the goal, the solve and its targets untouched;
    #: issue 30, sixteenth session; 0: off)
    goal_lead: float = 0.0
    #: 1: ``goal_lead`` on the pitch joints of the legs on the floor only (hip pitch, knee,
    #: ankle pitch of the tick's planned support: the loaded joints that lag); 0: every joint
    goal_lead_stance: float = 0.0
    #: the compliance feed-forward on the legs' pitch joints (hip pitch, knee, ankle pitch:
    #: the sag along the walk) × this over the others' (1: the same; issue 30, sixteenth
    #: session, benchmarks/pushes.md)
    ff_sagittal: float = 1.0
    #: the compliance feed-forward's torques under the gravito-inertial field ``g − this ×
    #: c̈_ref`` (the plan's CoM acceleration: the stance ankle fed the planned CoP's moment,
    #: not the CoM's; 0: gravity alone, the static model; issue 30, sixteenth session)
    ff_inertial: float = 0.0
    #: 1: ``ff_inertial``'s field along the walk's heading only, and only while the plan's
    #: CoM is behind its ZMP (``c̈`` backward); 0: the whole ``c̈`` (issue 30, seventeenth
    #: session, benchmarks/pushes.md; :mod:`wbc.balance.inertial_ff`). On ``walk10_wb`` the
    #: plan's CoM leads its ZMP through each single support: shut there. With
    #: ``ff_inertial_band`` 0.005 (k 1.0) forward, toward and away keep main's bounds but 3 of
    #: main's 5 screened backward pushes stand: off
    ff_inertial_back: float = 0.0
    #: m: ``ff_inertial``'s field × ``clip(−e / this, 0, 1)``, ``e`` the estimated DCM's
    #: error along the heading (``ξ − ξ_ref``): fed while the DCM lags, released on a push
    #: forward (0: no gate; alone it loses every forward push at main's bounds: off)
    ff_inertial_band: float = 0.0
    #: 1: ``ff_inertial`` takes the walk's first plan's ``c̈`` (the unpushed walk's, as the
    #: sixteenth session measured it), not the re-planned catch's; 0: the re-planned plan's
    ff_inertial_first: float = 0.0
    #: m: the band's gate opens from this lag on, ``clip((−e − this) / band, 0, 1)`` (0: from
    #: a DCM on its reference; > 0: the unpushed walk's own lag left out, a push backward in)
    ff_inertial_from: float = 0.0
    #: m the CoM target moves up (+; −: down) on servos identified at rest softer than
    #: ``lift_stiff`` × servos.toml's (0: off; :mod:`wbc.balance.stance_lift`). −0.008
    #: without the feed-forward: 148 / 149 of 150 on seeds 0 / 1 against main's 146 / 148;
    #: held out, the soft plants of seed 2: 59 of 60 against 58, seed 3: 77 of 78 against 77
    #: (one traded), seed 4: 41 of 42 against 38; −0.004 and −0.012 each lose another plant:
    #: off (issue 30, i30s's sixteenth round; benchmarks/physics.md)
    lift: float = 0.0
    lift_stiff: float = 0.75
    #: the walk's clock rate (0 < · ≤ 1) from the reference's final double support on, on
    #: servos identified at rest softer than ``lift_stiff`` × servos.toml's (1: off;
    #: :mod:`wbc.balance.stance_lift`). Slowing the end moves which soft plant falls: 0.6
    #: from 0.4 or 0.9 s earlier (``end_lead``) loses 1–2 dev-seed plants ``lift`` keeps
    #: (issue 30, i30e's seventeenth session; benchmarks/physics.md): off
    end_clock: float = 1.0
    end_lead: float = 0.0  # s: end_clock's (end_leak's) start this long before that support
    #: /s: on the same plants and from the same time on, the DCM integral (``k_dcm_i``'s: the
    #: walk's steady lag taken as a forward CoM shift) leaks at this rate, the shift not
    #: carried into the stop (0: off). With ``lift`` −0.008 and ``end_lead`` 0.4: the soft
    #: plants of seeds 0–6 391 of 393 against main's 378 (fresh seed 6: 72 of 72 against
    #: 68), no walk losing; off until a full 150-plant seed is run side by side (issue 30,
    #: i30e's seventeenth session; benchmarks/physics.md)
    end_leak: float = 0.0
    #: s: on the same plants, the hip strategy (``k_hip``, its push trigger with it) held off
    #: for this long from the start of each single support: there the plan's new stance sole
    #: may not carry the robot yet (a soft stance knee that sagged and rolled the body toward
    #: its side lands the swing foot late), the DCM estimated against it already reads
    #: outward and the strategy would throw the torso toward that side at once (0: off;
    #: :mod:`wbc.balance.stance_lift`). 1.0 (longer than any single support: the strategy off
    #: on soft plants) keeps the two soft plants E loses (s2 turn_wb 8, s4 turn_wb 33) and
    #: loses none E keeps over seeds 0-7; the held-out seeds had none left to gain and no
    #: push was measured on a soft plant: off (issue 30, i30g's eighteenth session;
    #: benchmarks/physics.md)
    soft_hip: float = 0.0
    #: ``k_twist`` × this on servos identified at rest at least ``lift_stiff`` ×
    #: servos.toml's (stiff; 1: off; :mod:`wbc.balance.stiff_twist`): on stiff servos that
    #: follow late the hip yaws' loop rings and spins the stance sole. 0.5 keeps the three
    #: stiff plants main loses on seeds 0 / 1 without the feed-forward and loses three it
    #: keeps (148 / 149 of 150 either way; nominal turn_wb 19.2° → 22.4°); 0.75: 149 / 149
    #: but two plants main keeps lost; held-out seed 8 59 of 60 as main: off (issue 30,
    #: nineteenth session, benchmarks/physics.md)
    stiff_twist: float = 1.0
    #: rad: the start-up goal probe's step (0: off; :mod:`wbc.balance.goal_probe`): during
    #: the rest the arms' elbows step by this and back, the encoders' response gives the
    #: servos' goal latency and response time (said, kept in ``ClosedLoop.goal_probe``)
    probe_step: float = 0.0

    def check(self) -> Gains:
        for name in (
            "k_p",
            "k_i",
            "k_d",
            "k_dcm",
            "k_dcm_i",
            "k_dcm_i_y",
            "k_lean",
            "k_roll",
            "k_twist",
            "kin_band",
            "k_yaw",
            "yaw_cutoff",
            "max_yaw",
            "yaw_damping",
            "yaw_ring",
            "lag_yaw",
            "lag_clock",
            "clock_single",
            "j_p",
            "j_d",
            "max_tilt",
            "max_shift",
            "max_offset",
            "kin_tilt",
            "anchor_band",
            "anchor_down",
            "contact_band",
            "support_down",
            "joint_lag",
            "real_step",
            "k_hip",
            "hip_band",
            "max_hip",
            "hip_release",
            "hip_jump",
            "hip_kick",
            "kick_release",
            "kick_tilt",
            "kick_lead",
            "kick_brake",
            "counter_leg",
            "counter_arm",
            "kick_hold",
            "kick_hold_for",
            "kick_hold_edge",
            "counter_under",
            "push_rise",
            "rise_room",
            "rise_knee",
            "rise_hold",
            "rise_single",
            "transfer",
            "step_yaw",
            "max_step_yaw",
            "step_yaw_band",
            "step_yaw_turn",
            "step_yaw_cap",
            "j_i",
            "j_i_max",
            "j_i_leak",
            "j_i_still",
            "j_i_lag",
            "j_i_sagittal",
            "j_i_band",
            "j_i_joints",
            "j_i_single",
            "j_i_stiff",
            "ref_lead",
            "goal_lead",
            "goal_lead_stance",
            "ff_sagittal",
            "ff_inertial",
            "ff_inertial_back",
            "ff_inertial_band",
            "ff_inertial_first",
            "ff_inertial_from",
            "lift_stiff",
            "end_lead",
            "end_leak",
            "soft_hip",
            "stiff_twist",
            "probe_step",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ConfigurationError(
                    f"stabilizer gain {name} must be a finite number >= 0, got {v}"
                )
        if not np.isfinite(self.lift):
            raise ConfigurationError(f"stabilizer gain lift must be finite, got {self.lift}")
        if self.j_i_single not in (0, 1, 2):
            raise ConfigurationError(
                f"stabilizer gain j_i_single: 0, 1 or 2, got {self.j_i_single}"
            )
        if self.ff_inertial_back not in (0, 1) or self.ff_inertial_first not in (0, 1):
            raise ConfigurationError(
                "stabilizer gains ff_inertial_back, ff_inertial_first: 0 or 1, got "
                f"{self.ff_inertial_back}, {self.ff_inertial_first}"
            )
        if self.kin_heading not in (0, 1):
            raise ConfigurationError(f"stabilizer gain kin_heading: 0 or 1, got {self.kin_heading}")
        if self.hip_axis not in (0, 1, 2):
            raise ConfigurationError(f"stabilizer gain hip_axis: 0, 1 or 2, got {self.hip_axis}")
        if self.j_i_joints not in (0, 1, 2, 3):
            raise ConfigurationError(
                f"stabilizer gain j_i_joints: 0, 1, 2 or 3, got {self.j_i_joints}"
            )
        if not 0.0 < self.clock_min <= 1.0:
            raise ConfigurationError(f"stabilizer gain clock_min: (0, 1], got {self.clock_min}")
        if not 0.0 < self.end_clock <= 1.0:
            raise ConfigurationError(f"stabilizer gain end_clock: (0, 1], got {self.end_clock}")
        if not (np.isfinite(self.rise_time) and self.rise_time > 0) or not (
            np.isfinite(self.rise_back) and self.rise_back > 0
        ):
            raise ConfigurationError(
                f"stabilizer gains rise_time, rise_back must be finite numbers > 0, got "
                f"{self.rise_time}, {self.rise_back}"
            )
        if self.hip_kick > 0 and self.kick_release <= 0:
            raise ConfigurationError("stabilizer gain kick_release must be > 0 with hip_kick")
        if self.transfer > 1 or self.clock_single > 1:
            raise ConfigurationError(f"stabilizer gains transfer, clock_single: [0, 1], got "
                                     f"{self.transfer}, {self.clock_single}")  # fmt: skip
        return self


#: the closed loop's default gains without the compliance feed-forward (``compensate`` 0: a
#: robot whose servo model is unknown, ``--compensate 0``): the estimator's timing
#: (``joint_lag``) and less torso rate gain (``k_d`` 0.03 s) keep 147 of 150 randomised plants
#: up against :class:`Gains`' 143 (``turn_wb`` 48, ``lateral_wb`` 49, ``walk10_wb`` 50; with
#: the feed-forward they lose two on ``walk10_wb``, so it keeps :class:`Gains`: issue 30's
#: sixth pass); the DCM integral along the walk (``k_dcm_i`` 0.25 /s) takes the soft plants'
#: steady lag (nothing pre-loads their knees: the body sags back, the DCM 30–55 mm behind):
#: 150 of 150 (issue 30's ninth pass, benchmarks/physics.md). The heading command
#: low-passed at 2 Hz (``yaw_cutoff``) measured 295 of 300 plants against 293 (seeds 0 and
#: 1, the three walks) on one code and 293 against 294 on the next (2026-12-05's final main:
#: the same knife-edge plants flip with rounding elsewhere), the OP3 147 of 150 against 148:
#: no better, so off (benchmarks/physics.md, issue 30, i30p's third round). On plants whose
#: servos identify soft at the start-up rest (below ``lift_stiff``): the CoM target 8 mm lower
#: (``lift``) and the DCM integral leaked from 0.4 s before the final double support
#: (``end_leak`` 2 /s, ``end_lead``): soft plants kept 391 of 393 over seeds 0–6 against 378,
#: every seed gaining, the fresh seed 6 72 of 72 against 68; stiffer plants untouched
#: (issue 30, the seventeenth session's i30e, benchmarks/physics.md). The hip strategy's roll
#: about the estimated torso's own axis (``hip_axis`` 2): s0 lateral_wb 18 kept, nothing lost
#: on seeds 0–1 lateral_wb nor held-out seeds 8–9 (issue 30, twentieth session)
NO_FEED_FORWARD_GAINS = Gains(
    k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, lift=-0.008, end_leak=2.0, end_lead=0.4, hip_axis=2
)


def default_gains(compensate: float) -> Gains:
    """The closed loop's default gains for a feed-forward gain ``compensate``: the measured
    best of each, :data:`NO_FEED_FORWARD_GAINS` at 0, :class:`Gains` above (the one
    definition :func:`wbc.balance.live.closed_loop` and every command use when no gains are
    given)."""
    return NO_FEED_FORWARD_GAINS if compensate <= 0 else Gains()
