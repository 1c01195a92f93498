"""The swing's touch-down read from the sensors (:class:`~.stepping.StepAdjuster`): the early
touch-down (``touchdown``) and the touch-down acceptance (``accept``).

**Early touch-down** (:func:`early`; ``touchdown``, off): during a catch, a swing sole found
down (the estimator's contact detection, ``Gains.contact_band``) that many ticks running lands
where it is: that step and every later one move by its shortfall, the CoM re-planned, the
walk's clock jumps to the landing.

**The touch-down acceptance** (:class:`TouchdownAcceptance`; ``accept``, off): a pushed
robot's catch step lands short (issue 30: after a push backward the third step lands 66 mm
short of its plan) and the controller does not accept it: its own sole is 41 mm behind and 30
mm above the landing (the measured-frame landing on a body pitched back), the plan's contact is
asked of the hard row at once (the Bioloid's stack settles no landing: ``landing_time``) and the
solve fails through the whole double support (``InfeasibleError``: the last configuration held;
benchmarks/pushes.md, eighteenth session) while the real sole stands flat nearer the body.
Accepted, from what a robot senses — the servos' present positions and the IMU (the estimate's
rotation: :meth:`~.estimator.StateEstimator.sole_heights`, ``landed``), no force sensor: in
a swing the catch carries, past ``accept_share`` of it, the swing sole's lowest point within
``accept_down`` of the stance sole's for ``accept_ticks`` ticks running is a touch-down: the
walk's clock jumps to the landing (the support changes now); at that double support (or at
the first tick of the double support after a carried swing, when the sole came down on
time) the landed step is re-based where the sole stands from the other sole (beyond
``accept`` m; every later step moved with it, the CoM re-planned from its target: the DCM
plan restarts from the measured foot), the controller's landing then made to the re-based
place (its stack's own landing; with ``accept_contacts`` the contacts set to the reference's
soles at once, ``contacts_move``: measured, that jump fails the solve as the plan's did; with
``accept_settle`` the landed contact anchored at the solve's sole and walked there, so every
tick solves); the catch goes on ``accept_steps`` more steps. ``accept_lift`` (ticks): in that
double support, the sole to lift next found up (the body turning back over the landed heel
unloads it) that many ticks running starts its swing at once (the clock jumps to the
lift-off).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..roles import SOLE_FRAMES
from ..walking.reference import WalkingReference
from .footholds import shifted_plan


def early(adj: Any, ref: WalkingReference, i: int) -> WalkingReference | None:
    """The walk re-based on an early touch-down (``touchdown``; module docstring) of the
    :class:`~.stepping.StepAdjuster` ``adj``, or None: in a single support (after ``settle``,
    before its last ``min_remaining``) of a catch (a step the DCM's re-plans moved, or the
    next), the swing sole found down (``contact.down``) ``touchdown`` ticks running: step
    ``k`` and every later one move by where it touched less where the plan lands it, the rest
    re-planned (``regenerate``) and the clock jumps to the landing (``rate``)."""
    p = adj.params
    ph = adj.phases[adj.phase_of[i]]
    dt = ref.dt
    if ph.kind != "single" or ph.step >= len(adj.plan.steps):
        adj._down = 0
        return None
    k = int(ph.step)
    s = 0 if adj.plan.steps[k].side == "left" else 1
    early_ = (i - ph.i0) < p.touchdown_share * (ph.i1 - ph.i0)  # (a brushing toe)
    if not adj.contact.down[s] or early_ or (i - ph.i0) * dt < p.settle - 1e-9:
        adj._down = 0
        return None
    adj._down += 1
    if adj._down < p.touchdown or (ph.i1 - i) * dt < p.min_remaining:
        return None
    if adj.episode is None or k >= adj._catch_end():
        return None  # (no catch: the swing brushing the floor)
    step = adj.plan.steps[k]
    shift = np.asarray(adj.contact.touched[s], dtype=float) - np.array([step.x, step.y])
    plan = shifted_plan(adj.plan, k, shift)
    new = adj.regenerate(ref, plan, i, ph)
    adj.plan, adj.before, adj.first = plan, plan, k
    adj.increments = np.zeros((p.steps_ahead, 2))
    adj.shift = np.zeros(2)
    adj.last_tick, adj._down, adj._jump = i, 0, ph.i1
    adj.caught_step = k
    adj.events.append((float(ref.t[i]), k, shift, shift.copy()))
    return new


class TouchdownAcceptance:
    """``accept`` (module docstring): per tick (:meth:`check`, from the step adjuster's
    re-plan) the touch-down and lift-off read from the soles' heights; :meth:`moved` sets the
    contacts of an accepted landing's double support. :attr:`events`: (walk s, kind, step,
    shift m), kind ``"touch"`` (the clock jumped to a landing), ``"land"`` (a double support
    read at its first tick), ``"lift"`` (the clock jumped to a lift-off)."""

    def __init__(self) -> None:
        self.down = 0  # ticks the swing sole has been found down
        self.up = 0  # ticks the sole to lift next has been found up (accept_lift)
        self.landed = -1  # the double support (phase index) of the last accepted landing
        self.lifted = -1  # the double support whose lift-off was taken early
        self.seen = -1  # the last double support read at its first tick
        self.anchor: Any = None  # the landed contact walked to the reference (accept_settle)
        self.events: list[tuple[float, str, int, np.ndarray]] = []

    def check(self, adj: Any, ref: WalkingReference, i: int, q: np.ndarray | None) -> Any:
        """A re-based reference (or None) for tick ``i`` of the step adjuster ``adj``; sets its
        clock's jump (``adj._jump``) at a touch-down or an early lift-off. ``q``: the
        controller's last configuration (the unread joints' stand-in)."""
        p, t = adj.params, adj.trigger
        if t.tick is None or (p.accept_back and t.forward) or q is None:
            return None
        j = int(adj.phase_of[i])
        ph = adj.phases[j]
        if ph.kind == "single":
            self.up = 0
            if not t.carried(i) or ph.step >= len(adj.plan.steps) or self._skipped(adj, ph):
                self.down = 0
                return None
            if (i - ph.i0) < p.accept_share * (ph.i1 - ph.i0) or ph.i1 - i <= 1:
                self.down = 0
                return None
            k = int(ph.step)
            s = 0 if adj.plan.steps[k].side == "left" else 1
            h = adj._heights(q)
            if h is None or float(h[s] - h[1 - s]) > p.accept_down:
                self.down = 0
                return None
            self.down += 1
            if self.down < max(p.accept_ticks, 1):
                return None
            self.down, adj._jump, self.landed = 0, ph.i1, j + 1
            self.events.append((float(ref.t[i]), "touch", k, np.zeros(2)))
            return self._rebased(adj, ref, i, k, q, ph)
        if ph.kind != "double" or j == 0:
            return None
        prev = adj.phases[j - 1]
        if j != self.seen:  # (the double support's first tick)
            self.seen, self.up = j, 0
            if prev.kind != "single" or prev.i1 <= prev.i0 or not t.carried(prev.i1 - 1):
                return None
            if self._skipped(adj, prev):
                return None
            if self.landed == j:
                return None  # (accepted in its swing: re-based there)
            self.landed = j
            self.events.append((float(ref.t[i]), "land", int(prev.step), np.zeros(2)))
            return self._rebased(adj, ref, i, int(prev.step), q, ph)
        if p.accept_lift <= 0 or self.landed != j or self.lifted == j:
            return None
        if j + 1 >= len(adj.phases) or int(prev.step) + 1 >= len(adj.plan.steps):
            return None
        k = int(prev.step)  # the landed step; the other sole lifts next
        s = 0 if adj.plan.steps[k].side == "left" else 1
        h = adj._heights(q)
        if h is None or float(h[1 - s] - h[s]) <= p.accept_down:
            self.up = 0
            return None
        self.up += 1
        if self.up >= p.accept_lift and ph.i1 > i + 1:
            self.up, self.lifted, adj._jump = 0, j, ph.i1
            self.events.append((float(ref.t[i]), "lift", k + 1, np.zeros(2)))
        return None

    @staticmethod
    def _skipped(adj: Any, ph: Any) -> bool:
        """True for the swing ``ph`` among the catch's first ``accept_skip`` carried ones."""
        first = adj.phases[adj.phase_of[adj.trigger.tick]].step
        return int(ph.step) - int(first) < adj.params.accept_skip

    def _rebased(
        self, adj: Any, ref: WalkingReference, i: int, k: int, q: np.ndarray, ph: Any
    ) -> WalkingReference | None:
        """The walk with step ``k`` (and every later one) moved to where its sole stands from
        the other sole, when that is more than ``accept`` from the plan's (else None); the
        catch extended by ``accept_steps``."""
        p, est, present = adj.params, adj.contact, adj.present
        joints = None if est is None or present is None or est.last is None else present()
        if joints is None:
            return None
        step = adj.plan.steps[k]
        side = 0 if step.side == "left" else 1
        names = (SOLE_FRAMES["left"], SOLE_FRAMES["right"])
        j, f = np.asarray(joints, dtype=float), np.asarray(q[7:], dtype=float)
        a = np.asarray(est.landed(names[side], j, f), dtype=float)[:2]
        b = np.asarray(est.landed(names[1 - side], j, f), dtype=float)[:2]
        other = np.asarray(ref.sole("right" if side == 0 else "left")[0][i], dtype=float)[:2]
        shift = other + (a - b) - np.array([step.x, step.y])
        self.events[-1] = (*self.events[-1][:3], shift.copy())
        if math.hypot(float(shift[0]), float(shift[1])) <= p.accept:
            return None
        plan = shifted_plan(adj.plan, k, shift)
        if ph.step >= len(plan.steps):
            return None
        new = adj.regenerate(ref, plan, i, ph)
        adj.plan, adj.before, adj.first, adj.last_tick = plan, plan, k, i
        adj.increments = np.zeros((p.steps_ahead, 2))
        adj.shift = np.zeros(2)
        if adj.episode is not None and p.accept_steps > 0:
            t = adj.trigger
            most = adj.episode + adj._episode_steps() + p.accept_steps
            adj.end = max(adj.end, min(k + 1 + p.accept_steps, most))
            first = int(adj.phases[adj.phase_of[t.tick]].step)
            t.extra = max(t.extra, adj.end - 1 - first - p.catch_swings)
        adj.events.append((float(ref.t[i]), k, shift, shift.copy()))
        return new

    def moved(self, adj: Any, targets: Any) -> Any:
        """``targets`` with ``contacts_move`` set in the double support of an accepted landing
        (``accept_contacts``: the controller's contacts the reference's soles at once;
        ``accept_settle``: the landed contact from the solve's sole, walked to the reference's
        by at most that much per tick)."""
        p = adj.params
        j = int(adj.phase_of[targets.i])
        if targets.phase == "single" or j != self.landed:
            self.anchor = None
            return targets
        if p.accept_settle > 0 and adj._q is not None and j > 0:
            step = adj.plan.steps[int(adj.phases[j - 1].step)]
            frame = SOLE_FRAMES[step.side]
            goal = targets.sole(frame)
            if self.anchor is None:  # (the first tick: where the solve's sole is)
                self.anchor = adj.robot.frame_placement(adj._q, frame)
            a = self.anchor
            d = goal.translation - a.translation
            n = float(np.linalg.norm(d))
            share = 1.0 if n <= p.accept_settle else p.accept_settle / n
            w = pin.log3(goal.rotation @ a.rotation.T)
            self.anchor = pin.SE3(pin.exp3(share * w) @ a.rotation, a.translation + share * d)
            return targets.replace(**{frame: self.anchor}, contacts_move=True)
        if not p.accept_contacts:
            return targets
        return targets.replace(contacts_move=True)
