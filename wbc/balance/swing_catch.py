"""The swing under a push (:mod:`.stepping`'s catch): the push trigger, the swing's lift and
its landing in the measured frame.

**The push caught in its own step** (:class:`PushTrigger`; ``trigger_jump``, ``lift``): the
dead band swallows a push's first 40 ms and the re-plan came a step later. A jump of the DCM
error along the walk in one tick (a push: 25 mm at 0.6 N·s; unpushed: 14 mm at most, past the
support switch's tick, ``trigger_skip``; and beyond ``trigger_sigma`` × the running RMS of the
per-tick change: a jittery plant is no push) starts the catch at once: that swing's band drops
to ``trigger_band``, the landing correction (:class:`MeasuredLanding`, latched by
``landing_catch``) starts, and the swing target is raised by ``lift`` (:meth:`PushTrigger.
lifted`; lift first, then reach: the pitched body puts the swing toe on the floor 20 ms after
the push).

**The swing landed in the measured frame** (:class:`MeasuredLanding`; ``landing``): the
controller places the swing sole relative to its own base; a pushed robot's base is pitched
about the stance sole (the compliant stance hip yielding), and the sole lands where the same
relative pose puts it from the *measured* base — short and high. :meth:`MeasuredLanding.land`
moves the swing target so that the measured base carries it to the planned place.

**The push caught in its own step** (on by default): a jump of the DCM
error along the walk in one tick starts the catch at once in the pushed swing, with the
landing correction and the swing's lift. Measured (benchmarks/pushes.md): forward 0.547 →
0.703, backward 0.461 → 0.617 N·s; the same randomised plants up. Off: ``{"trigger_jump": 0,
"landing": 0, "lift": 0, "toe_up": 0}``. Options of that catch: ``toe_up`` (on, 0.15 rad:
after a push forward the swing sole turned toe up, the pitched body puts its toe on the
floor; forward 0.703 → 0.719 N·s); off: ``lead`` (the swing target led by the servos' lag),
``slow`` (the triggered swing's clock slowed: a later landing), ``catch_pitch`` (the torso
target turned along the push during the catch: the hip strategy along the walk). Every other
term here is off by default (sideways on ``walk10`` 0.797 → 0.844 N·s; the bound 0.934).

**The catch's later swings** (``catch_swings``, ``catch_hurry``): a push backward leaves the robot
on its heels after the caught landing, the body pitched back; the next swing's sole, placed in the
controller's upright frame, drags its heel on the floor (7–19 N) and lands 70 mm short of its
re-planned landing. With ``catch_swings`` the lift and the landing in the measured frame go on in
that many swings after the triggered one, and ``catch_hurry`` runs the clock faster in the double
supports before them (the next step lifts sooner) and, with ``hurry_single``, in those swings when
they lack the room; the placement is the catch's own (``episode_steps``, :mod:`.stepping`'s
re-plans). After a push backward, the stance sole rolled onto its heel (``landing_tilt``, on): the
estimate anchors its centre on the floor and reads the base low by the heel's drop
(:meth:`~.stepping.StepAdjuster.stance_rise`, from the IMU and the present joints), so the
measured-frame landing put the next sole 13–22 mm high; the correction takes the base that much
higher. In those swings (after a push backward) the footstep may move ``back_shift`` (0.10 m, not
``max_shift``'s 0.08) and the bend run at ``back_foot_speed`` (0.8 m/s, the servos' no-load speed at
the lever): :meth:`~.stepping.StepAdjuster.reach` (backward 0.711 → 0.727 N·s; after any push,
forward 0.852 → 0.688: not done there).
**The double support after a caught landing** (``descend``, ``descend_hold``; off: measured worse,
benchmarks/pushes.md): the landed sole is a support in the plan from its first tick while a body
rolled back on its stance heel keeps it 10–18 mm up; :class:`LandedDescent` lowers its contact
target by the gap the soles' lowest points show, and with ``descend_hold`` the clock stands until it
is down (bounded) — the sole comes down no sooner: its knee extends at the servo's speed behind a
goal already moving at the limiter's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
import pinocchio as pin

from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT
from ..roles import SOLE_FRAMES
from ..walking.footsteps import other_side
from ..walking.reference import WalkingReference
from ..walking.schedule import Phase
from ..walking.spline import smooth
from .push_jump import jumped
from .stepping_params import SteppingParams

#: :func:`_watch`'s state: the last watched tick (``_NO_TICK``: none to compare with), its DCM
#: error (2), the per-tick change's mean square; the last test's change along the walk and the
#: stance sole's heading (cos, sin); then its parameters: ``trigger_jump``, ``trigger_sigma``,
#: the running mean's step ``min(dt / trigger_tau, 1)``, ``trigger_skip``
_W_TICK, _W_ERR, _W_MS, _W_D, _W_HEADING, _W_K, _W_SIZE = 0, 1, 3, 4, 5, 7, 11
_NO_TICK = -10.0
#: :func:`_watch`'s table, per tick of a reference: its support, the stance sole's heading
#: (yaw; the right sole's in double support), the ticks since its phase began, its phase
_T_SUPPORT, _T_YAW, _T_SINCE, _T_PHASE = range(4)


@numba.njit(cache=True, error_model="numpy")
def _watch(
    i: int, dcm: np.ndarray, dcm_ref: np.ndarray, table: np.ndarray, tick: int, state: np.ndarray
) -> bool:
    """:meth:`PushTrigger.watch`'s tick in one compiled call: at tick ``i`` (``table``: the
    reference's rows, ``_T_*``) the DCM error ``e = dcm − dcm_ref`` (horizontal); in single
    support past its first ``trigger_skip`` ticks, against the error of tick ``i − 1`` kept in
    ``state`` (``_W_*``; of the same reference: the caller resets it) and unless a catch
    started in this phase (``tick``: its tick, −1: none), the change along the stance sole's
    heading (``StepAdjuster._heading``) ``d``, tested by :func:`~wbc.balance.push_jump.jumped`
    (both ways). True: a push (``state``: ``d`` and the heading)."""
    row = table[i]
    if row[_T_SUPPORT] == SUPPORT_DOUBLE or row[_T_SINCE] < state[_W_K + 3]:
        state[_W_TICK] = _NO_TICK  # (the support switch: trigger_skip)
        return False
    e0, e1 = dcm[0] - dcm_ref[0], dcm[1] - dcm_ref[1]
    last, l0, l1 = state[_W_TICK], state[_W_ERR], state[_W_ERR + 1]
    state[_W_TICK], state[_W_ERR], state[_W_ERR + 1] = i, e0, e1
    if last != i - 1 or (tick >= 0 and table[tick, _T_PHASE] == row[_T_PHASE]):
        return False
    c, s = math.cos(row[_T_YAW]), math.sin(row[_T_YAW])
    d = c * (e0 - l0) + s * (e1 - l1)  # along the walk
    k = state[_W_K : _W_K + 3]
    fired, state[_W_MS] = jumped(d, True, k[0], k[1], k[2], state[_W_MS])
    state[_W_D], state[_W_HEADING], state[_W_HEADING + 1] = d, c, s
    return fired


class PushTrigger:
    """The push trigger (``trigger_jump``; module docstring): the tick a DCM jump started a
    catch, and the swing's lift in that catch."""

    def __init__(
        self, params: SteppingParams, phases: list[Phase], phase_of: np.ndarray, dt: float
    ) -> None:
        self.params, self.phases, self.phase_of, self.dt = params, phases, phase_of, dt
        self.tick: int | None = None  # tick a DCM jump started a catch (trigger_jump)
        #: the jump's direction (unit, horizontal world) at :attr:`tick` (catch_pitch)
        self.push = np.zeros(2)
        self.forward = False  # the jump was forward along the walk (toe_up)
        self.extra = 0  # carried swings beyond ``catch_swings`` (a re-base: back_rebase_steps)
        #: the last single-support tick and its raw DCM error, the running mean square of
        #: the per-tick change (trigger_sigma): :func:`_watch`'s state
        self._state = np.zeros(_W_SIZE)
        self._state[_W_TICK] = _NO_TICK
        self._since = np.array([i - phases[j].i0 for i, j in enumerate(phase_of)], dtype=float)
        #: the reference of the last tick watched and its :func:`_watch` table
        self._table: tuple[Any, np.ndarray | None] = (None, None)

    def triggered(self, i: int) -> bool:
        """True when a DCM jump (``trigger_jump``) started a catch in tick ``i``'s phase."""
        t = self.tick
        return t is not None and self.phase_of[t] == self.phase_of[i]

    def carried(self, i: int) -> bool:
        """True in the triggered swing (:meth:`triggered`) and in the ``catch_swings`` single
        supports after it: the swings of a multi-step catch that the lift and the landing in
        the measured frame go on in."""
        t = self.tick
        if t is None:
            return False
        if self.phase_of[t] == self.phase_of[i]:
            return True
        n = self.params.catch_swings + self.extra
        ph, pt = self.phases[self.phase_of[i]], self.phases[self.phase_of[t]]
        return n > 0 and ph.kind == "single" and 0 < int(ph.step) - int(pt.step) <= n

    def before_carried(self, i: int) -> bool:
        """True in a double support whose next single support is a carried swing of the
        catch (:meth:`carried`, not the triggered one): ``catch_hurry``'s."""
        j = int(self.phase_of[i])
        if self.tick is None or self.phases[j].kind != "double" or j + 1 >= len(self.phases):
            return False
        return self.carried(self.phases[j + 1].i0)

    def watch(self, ref: WalkingReference, i: int, dcm: np.ndarray, dcm_ref: np.ndarray) -> None:
        """The push trigger (``trigger_jump``): in single support, the DCM error along the walk
        (``dcm`` measured, ``dcm_ref`` the reference ``ref``'s at tick ``i``; along the stance
        sole's heading) jumping by more than ``trigger_jump`` since the last tick, and by more
        than ``trigger_sigma`` × the running RMS of that change (:func:`_watch`; sideways
        pushes: the default catch, measured better toward the swing foot;
        benchmarks/pushes.md)."""
        state, (last, table) = self._state, self._table
        if ref is not last or table is None:  # (a re-planned reference: no jump across it)
            p, support = self.params, ref.support
            yaw = np.where(support == SUPPORT_LEFT, ref.l_sole_yaw, ref.r_sole_yaw)
            table = np.column_stack([support, yaw, self._since, self.phase_of]).astype(float)
            self._table = (ref, table)
            state[_W_TICK] = _NO_TICK
            share = min(ref.dt / max(p.trigger_tau, 1e-9), 1.0)  # (the running mean's step)
            state[_W_K : _W_K + 4] = (p.trigger_jump or 0.0, p.trigger_sigma, share, p.trigger_skip)
        if _watch(i, dcm, dcm_ref, table, -1 if self.tick is None else self.tick, state):
            d = state[_W_D]
            self.tick = i
            self.push = math.copysign(1.0, d) * state[_W_HEADING : _W_HEADING + 2]
            self.forward = bool(d > 0)

    def lifted(
        self, targets: Any, velocity: np.ndarray | None = None, lead: float | None = None
    ) -> Any:
        """``targets`` with the swing sole's target raised by ``lift`` in a triggered catch
        (:meth:`triggered`): blended in over ``lift_time``, out over the swing's last
        ``lift_land`` share (smoothstep both), so that it lands where and when planned; and
        led by ``lead`` s (None: ``lead``'s) of the swing's planned horizontal ``velocity``
        (the servos' lag; blended in over ``lift_time``; nothing at the landing, where the
        swing stops); and turned toe up by ``toe_up`` rad after a push forward
        (:attr:`forward`; blended as the lift; its heel up after a push backward measured
        worse: not done)."""
        p, i = self.params, targets.i
        lead = p.lead if lead is None else lead
        if (p.lift <= 0 and lead <= 0 and p.toe_up <= 0 and p.landing_depth <= 0) or (
            not self.carried(i)
        ):
            return targets
        ph = self.phases[self.phase_of[i]]
        start = self.tick if self.triggered(i) else ph.i0  # (a later swing of the catch)
        w_in = smooth((i - start + 1) * self.dt / max(p.lift_time, 1e-9))
        w_out = smooth((ph.i1 - i) / max(ph.i1 - ph.i0, 1) / max(p.lift_land, 1e-9))
        w = w_in * w_out
        pos = np.array(targets.swing_position, dtype=float)
        lift = p.lift if p.back_lift is None or self.forward else p.back_lift
        pos[2] += lift * w - p.landing_depth * (1.0 - w_out)
        if lead > 0 and velocity is not None:
            pos[:2] += lead * w_in * np.asarray(velocity, dtype=float)[:2]
        if p.toe_up <= 0 or not self.forward:
            return targets.replace(swing_position=pos)
        axis = np.array([-self.push[1], self.push[0], 0.0])  # z × u: the body's fall
        turn = pin.exp3(-p.toe_up * w * axis)  # the swing sole's toe up, against it
        return targets.replace(swing_position=pos, swing_rotation=turn @ targets.swing_rotation)

    def pitched(self, targets: Any) -> Any:
        """``targets`` with the torso target turned about ``z × u`` (``u`` the push along the
        walk: :attr:`push`) by ``catch_pitch`` rad in a triggered catch (hip strategy along
        the walk: the upper body thrown toward the fall; negative: against it), blended in
        over ``pitch_time`` from the trigger, held in that swing and out over the next
        double support (smoothstep both)."""
        p, i, t = self.params, targets.i, self.tick
        if p.catch_pitch == 0.0 or t is None:
            return targets
        j, jt = int(self.phase_of[i]), int(self.phase_of[t])
        if j == jt:
            w = smooth((i - t + 1) * self.dt / max(p.pitch_time, 1e-9))
        elif j == jt + 1:  # the double support after it: released
            ph = self.phases[j]
            w = smooth(1.0 - (i - ph.i0 + 1) / max(ph.i1 - ph.i0, 1))
            w *= smooth((ph.i0 - t) * self.dt / max(p.pitch_time, 1e-9))
        else:
            return targets
        if w <= 0.0:
            return targets
        axis = np.array([-self.push[1], self.push[0], 0.0])  # z × u
        turn = pin.exp3(p.catch_pitch * w * axis)
        return targets.replace(torso_rotation=turn @ np.asarray(targets.torso_rotation))


class MeasuredLanding:
    """The swing sole's target in the measured frame (``landing``; module docstring): the
    tick a catch began in this swing (``landing_catch``) and the correction's running mean
    per stance side (``landing_tau``)."""

    def __init__(
        self,
        params: SteppingParams,
        phases: list[Phase],
        phase_of: np.ndarray,
        dt: float,
        torso_b: np.ndarray,
    ) -> None:
        self.params, self.phases, self.phase_of, self.dt = params, phases, phase_of, dt
        self._torso_b = torso_b  # the torso in the base frame
        self.caught: int | None = None  # tick the DCM error left the band (landing_catch)
        #: the landing correction's running mean per stance side (landing_tau): v, p_r − p_m
        self._landing_mean = np.zeros((2, 6))

    def note(self, i: int, pushed: Callable[[], bool]) -> None:
        """Latch tick ``i`` (single support) as the catch's start in its swing when none is
        latched there yet and ``pushed()`` (the DCM error left the band; with the trigger: the
        DCM jumped)."""
        caught = self.caught is not None and self.phase_of[self.caught] == self.phase_of[i]
        if not caught and pushed():
            self.caught = i

    def land(
        self,
        targets: Any,
        est: Any,
        q: np.ndarray,
        rise: Callable[[], float] | None = None,
        turn: float = 0.0,
    ) -> Any:
        """``targets`` with the swing sole's target moved into the measured frame (single
        support, ``landing`` > 0; else ``targets`` itself). The controller places the swing
        sole relative to *its* base (``p_r``, ``R_r``: ``q``); the robot's base is where the
        estimate puts it (``p_m``, ``R_m``: a push pitches the body about the stance sole and
        the compliant stance hip yields), and the sole lands where the same relative pose puts
        it from there, ``p_m + R_m R_rᵀ (p − p_r)``: short and high. The target
        ``p' = p_r + E (p − p_m)``, ``R' = E R`` with ``E = R_r R_mᵀ`` lands it at ``p``
        (blended by ``w``: ``landing`` × a ramp from ``landing_band`` to twice it on the
        angle of ``E``). ``rise()`` (``landing_tilt``): how far the stance sole's lowest
        corner lies below the floor where the estimate anchors the sole's centre (a sole
        rolled onto its heel: the measured base is that much higher). ``turn`` > 0
        (``landing_turn``): the sole's rotation turned by at most that angle (rad), its
        position by the whole ``E``."""
        p = self.params
        if p.landing <= 0:
            return targets
        since = self.caught
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
        if p.landing_tilt > 0 and rise is not None:  # the stance sole on an edge: base higher
            base_m = base_m + np.array([0.0, 0.0, p.landing_tilt * rise()])
        if p.landing_tau > 0:  # less the running mean (per stance side) of v and p_r − p_m
            mean = self._landing_mean[0 if targets.support == "l_sole" else 1]
            mean += (np.concatenate([v, q[:3] - base_m]) - mean) * min(self.dt / p.landing_tau, 1.0)
            v = v - mean[:3]
            base_m = base_m + mean[3:]
        angle = float(np.linalg.norm(v))
        band = p.landing_band
        w = p.landing * (min(max((angle - band) / band, 0.0), 1.0) if band > 0 else 1.0)
        if p.landing_catch > 0:  # only while a push is caught: since the error left the band
            since = self.caught
            if since is None or self.phase_of[since] != self.phase_of[targets.i]:
                return targets
            w *= smooth((targets.i - since + 1) * self.dt / p.landing_catch)
        if p.landing_blend > 0:  # blended in from lift-off
            ph = self.phases[self.phase_of[targets.i]]
            w *= smooth((targets.i - ph.i0) / max(ph.i1 - ph.i0, 1) / p.landing_blend)
        if w <= 0:
            return targets
        E = pin.exp3(w * v)
        a = w * float(np.linalg.norm(v))
        E_sole = pin.exp3(w * v * (turn / a)) if 0.0 < turn < a else E  # (landing_turn)
        pos = np.asarray(targets.swing_position, dtype=float)
        moved = q[:3] + E @ (pos - base_m)
        if lat != 1.0:  # the lateral part of the move scaled
            side = np.array([-h[1], h[0], 0.0])
            moved = moved - (1.0 - lat) * ((moved - pos) @ side) * side
        return targets.replace(
            swing_position=pos + w * (moved - pos), swing_rotation=E_sole @ targets.swing_rotation
        )


class LandedDescent:
    """The double support after a caught landing (``descend``; :mod:`.stepping`): the sole
    that just landed is a support in the plan from its first tick, but a body rolled back on
    its stance heel keeps it 10–18 mm above the floor, carrying nothing, for 40–60 ms (issue
    30). While it is measured up — its lowest point above the other sole's
    (:meth:`~.estimator.StateEstimator.sole_heights`: the IMU's rotation and the present
    joints; the stance sole on its heel has its lowest corner on the floor) — its contact
    target is lowered: the offset integrates the measured gap, ``d += descend · gap · dt``
    (within ``0 … descend_depth``; a gap below zero takes it back), and is blended out over
    the double support's last ``descend_out`` share (the support after it starts from the
    plan's soles). With ``descend_hold`` > 0 the walk's clock stops while the gap is above
    ``descend_band`` (the stance sole is not lifted off before the landed one carries), at
    most that long per double support."""

    def __init__(
        self, params: SteppingParams, phases: list[Phase], phase_of: np.ndarray, dt: float
    ) -> None:
        self.params, self.phases, self.phase_of, self.dt = params, phases, phase_of, dt
        self._phase = -1  # the double support the offset belongs to
        self.offset = 0.0  # m: how far the landed sole's contact target is lowered
        self.gap = 0.0  # m: the landed sole's lowest point above the other's, last read
        self.held = 0.0  # s the clock has stood in this double support (descend_hold)

    def active(self, i: int, carried: Callable[[int], bool]) -> int | None:
        """The step that landed at the start of tick ``i``'s double support when its swing was
        a caught one (``carried``), else None (a new double support: the offset from zero)."""
        j = int(self.phase_of[i])
        ph = self.phases[j]
        if ph.kind != "double" or j == 0:
            return None
        prev = self.phases[j - 1]
        if prev.kind != "single" or prev.i1 <= prev.i0 or not carried(prev.i1 - 1):
            return None
        if j != self._phase:
            self._phase, self.offset, self.gap, self.held = j, 0.0, 0.0, 0.0
        return int(prev.step)

    def lowered(self, targets: Any, frame: str, gap: float) -> Any:
        """``targets`` with the contact target of ``frame`` (the landed sole) lowered by the
        offset after this tick's measured ``gap`` (m), blended out over the double
        support's last ``descend_out`` share; ``contacts_move`` set (the controller sets the
        contacts' targets this tick)."""
        p = self.params
        self.gap = gap
        self.offset = min(max(self.offset + p.descend * gap * self.dt, 0.0), p.descend_depth)
        ph = self.phases[self.phase_of[targets.i]]
        w = smooth((ph.i1 - targets.i) / max(ph.i1 - ph.i0, 1) / max(p.descend_out, 1e-9))
        d = self.offset * w
        if d <= 0.0:
            return targets
        sole = targets.sole(frame)
        moved = pin.SE3(sole.rotation, sole.translation - np.array([0.0, 0.0, d]))
        return targets.replace(**{frame: moved}, contacts_move=True)

    def holds(self, dt: float) -> bool:
        """True when the walk's clock should stand for ``dt`` more seconds (``descend_hold``):
        the landed sole last measured more than ``descend_band`` up, not yet held that long."""
        p = self.params
        if p.descend_hold <= 0 or self.gap <= p.descend_band:
            return False
        if self.held + dt > p.descend_hold + 1e-9:
            return False
        self.held += dt
        return True


class LandedRebase:
    """``back_rebase`` (:class:`~.stepping.StepAdjuster`): at the first tick of the double
    support after a carried swing of a push backward's catch, where the landed sole stands
    from the other (the estimate's rotation and the present joints: the base cancels) against
    where the plan puts it from that sole; beyond ``back_rebase``, :attr:`pending` (the step,
    its shift) for the adjuster's next tick."""

    def __init__(self, params: SteppingParams, phases: list[Phase], phase_of: np.ndarray) -> None:
        self.params, self.phases, self.phase_of = params, phases, phase_of
        self.pending: tuple[int, np.ndarray] | None = None
        self.seen = -1  # the last double support read

    def note(
        self,
        targets: Any,
        side: Callable[[int], str],
        carried: Callable[[Phase], bool],
        where: Callable[[str], np.ndarray | None],
    ) -> None:
        """Read the landing of the swing before ``targets``' double support (once per double
        support): ``side(step)`` its side, ``carried(phase)`` True for a swing re-based,
        ``where(frame)`` a sole's position (world, m; the estimate's base: only differences
        are used) or None unread."""
        j = int(self.phase_of[targets.i])
        if targets.phase == "single" or j == self.seen or j == 0:
            return
        self.seen = j
        prev = self.phases[j - 1]
        if prev.kind != "single" or not carried(prev):
            return
        landed = side(int(prev.step))
        other = other_side(landed)
        a, b = where(SOLE_FRAMES[landed]), where(SOLE_FRAMES[other])
        if a is None or b is None:
            return
        plan_a = getattr(targets, SOLE_FRAMES[landed]).translation
        plan_b = getattr(targets, SOLE_FRAMES[other]).translation
        shift = (np.asarray(plan_b[:2]) + (a[:2] - b[:2])) - np.asarray(plan_a[:2])
        if math.hypot(float(shift[0]), float(shift[1])) > self.params.back_rebase:
            self.pending = (int(prev.step), shift)


def floored(targets: Any, p: SteppingParams, trigger: PushTrigger, corners: np.ndarray) -> Any:
    """``targets`` with the swing's ground clearance lowered (``landing_floor``;
    :attr:`~wbc.walking.tick_targets.TickTargets.swing_floor`) in a swing the catch of a push
    backward carries (``trigger``'s), over its last ``landing_floor`` share (smoothstep in):
    to the lowest corner (``corners``: the sole's, in its frame) of the swing target (after
    the landing: in the measured frame, where its corners lie on the floor) below the stance
    sole's planned floor, else ``targets``."""
    i = targets.i
    if trigger.forward or not trigger.carried(i):
        return targets
    ph = trigger.phases[trigger.phase_of[i]]
    first = trigger.phases[trigger.phase_of[trigger.tick or 0]].step
    if int(ph.step) - int(first) < p.floor_skip:  # (the catch's first floor_skip swings)
        return targets
    left = (ph.i1 - i) / max(ph.i1 - ph.i0, 1)  # (the swing's share left)
    w = smooth(1.0 - left / p.landing_floor)
    if w <= 0.0:
        return targets
    R = np.asarray(targets.swing_rotation, dtype=float)
    z = float(targets.swing_position[2]) + float(np.min(corners @ R[2]))
    low = z - float(targets.support_placement.translation[2])
    return targets.replace(swing_floor=w * low) if low < 0.0 else targets


def dcm_shifted(
    targets: Any, err: np.ndarray, p: SteppingParams, trigger: PushTrigger, end: int, dt: float
) -> Any:
    """``targets`` with the CoM target moved horizontally by ``−back_dcm · err`` (``err`` the
    DCM error, m), at most ``back_dcm_max`` m, from the ``back_dcm_from``-th phase after the
    trigger's (0: its tick; ramped in over ``back_dcm_time``) until ``back_dcm_steps`` after
    the catch's end step ``end`` (the ankle strategy in a catch: the CoM target ahead of a DCM
    behind its reference puts the CoP behind it); else ``targets``."""
    i, tick, phases = targets.i, int(trigger.tick or 0), trigger.phases
    if phases[trigger.phase_of[i]].step >= end + p.back_dcm_steps:
        return targets
    j = min(int(trigger.phase_of[tick]) + p.back_dcm_from, len(phases) - 1)
    start = phases[j].i0 if p.back_dcm_from else tick
    if i < start:
        return targets
    w = min((i - start) * dt / p.back_dcm_time, 1.0) if p.back_dcm_time > 0 else 1.0
    shift = -w * p.back_dcm * np.asarray(err[:2], dtype=float)
    n, most = math.hypot(float(shift[0]), float(shift[1])), w * p.back_dcm_max
    if n > most:
        shift *= most / n
    return _com_moved(targets, shift)


def walk_shifted(
    targets: Any, err: float, heading: tuple[float, float], gain: float, most: float
) -> Any:
    """``targets`` with the CoM target moved by ``−gain · err`` (``err`` the DCM error along the
    walk's heading ``(cos, sin)``, m), at most ``most`` m along it (``back_dcm_walk``)."""
    d = min(max(-gain * err, -most), most)
    return _com_moved(targets, d * np.asarray(heading, dtype=float))


def _com_moved(targets: Any, shift: np.ndarray) -> Any:
    """``targets`` with the CoM target moved horizontally by ``shift`` (m)."""
    com = np.array(targets.com, dtype=float)
    com[:2] += shift
    return targets.replace(com=com)
