"""The push's rise: the CoM target raised after a push away from the swing foot (issue 30).

A push out past the stance sole's outer edge leaves the CoP on that edge ``e`` and the CoM
``x`` inside it: the LIPM with a varying height, ``ẍ = (x − e)(g + z̈)/z``, pulls the CoM
back the harder the more the body accelerates upward while ``x − e < 0``; the rise's end
(``z̈ < 0``) gives some back, later, with the CoM nearer the edge, so the net is a catch
(``Δẋ ≈ −a τ² ẋ / z`` for an up-and-stop of ``a`` over ``τ`` each, ``ẋ`` the push's CoM
speed). Lowering instead loses it (benchmarks/pushes.md, twenty-second session).

:class:`PushRise` (``Gains.push_rise`` m; 0: off): from the tick the hip strategy's push
trigger fires (``hip_jump``) the CoM target's height is raised to ``push_rise`` within
``rise_time`` s, held while the trigger is latched or the push's kick lasts (until the hip
strategy's roll is back to 0; at most ``rise_hold`` s from the trigger when > 0; only in
single support with ``rise_single``), then lowered back at ``push_rise / rise_back`` m/s.

The rise is clipped to the loaded legs' room (``rise_room`` > 0: that share of it; 0: not
clipped): with the pelvis model of :class:`~wbc.walking.legs.LegGeometry` a hip ``d_v`` above
its ankle and ``d_h`` beside it can rise ``√(R² − d_h²) − d_v`` before the leg is straight
(``R``: :attr:`~wbc.walking.legs.LegGeometry.max_reach`), computed from the CoM target as
given and the contact soles (the stance sole in single support, both in double).

Or on the commanded configuration (``rise_knee`` > 0 rad, :class:`KneeRoom`): each tick the
CoM target is kept at most ``room`` above the commanded configuration's CoM, ``room`` the
least of the loaded legs' ``√(D² − d_h²) − d_v`` with their hip and ankle pitch joints'
offset (``d_h`` across, ``d_v`` up) read from the commanded ``q`` (the torso's roll
included) and ``D`` the hip-to-ankle distance with the knee ``rise_knee`` short of
straight: the rise never asks a loaded knee straighter than that.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

if TYPE_CHECKING:
    from ..model import Robot
    from ..walking.legs import LegGeometry
    from ..walking.tick_targets import TickTargets
    from .gains import Gains


def straight_room(legs: LegGeometry, hip: np.ndarray, sole: np.ndarray) -> np.ndarray:
    """How far (m) each hip (N, 3) can rise above its sole (N, 3) before the leg is straight:
    ``√(R² − d_h²) − d_v`` (hip-above-ankle ``d_v``, beside it ``d_h``, ``R``:
    :attr:`LegGeometry.max_reach <wbc.walking.legs.LegGeometry.max_reach>`)."""
    d = np.atleast_2d(hip) - np.atleast_2d(sole)
    d_h2 = d[:, 0] ** 2 + d[:, 1] ** 2
    return np.sqrt(np.maximum(legs.max_reach**2 - d_h2, 0.0)) - (d[:, 2] - legs.ankle_height)


def loaded_soles(targets: TickTargets) -> tuple[str, ...]:
    """The soles ``targets`` load: the support sole in single support, both in double."""
    return ("l_sole", "r_sole") if targets.phase == "double" else (targets.support,)


def leg_room(legs: LegGeometry, targets: TickTargets, com: np.ndarray) -> float:
    """How far (m) the CoM target ``com`` can rise before a loaded leg of ``targets`` (the
    support sole in single support, both soles in double) is straight: the least
    :func:`straight_room` of those legs, their hips from
    :meth:`LegGeometry.hips <wbc.walking.legs.LegGeometry.hips>`; negative when a leg is
    already beyond its reach."""
    l_sole, r_sole = targets.l_sole.translation, targets.r_sole.translation
    x = targets.torso_rotation[:2, 0]
    lh, rh = legs.hips(com, np.array([np.arctan2(x[1], x[0])]), l_sole, r_sole)
    loaded = loaded_soles(targets)
    room = np.inf
    for name, hip, sole in (("l_sole", lh, l_sole), ("r_sole", rh, r_sole)):
        if name in loaded:
            room = min(room, float(straight_room(legs, hip, sole)[0]))
    return float(room)


class KneeRoom:
    """The loaded legs' room to rise on a configuration (``Gains.rise_knee``): how far the
    hips can rise, the soles held, before a loaded knee is within ``bend`` rad of straight."""

    __slots__ = ("_data", "_ids", "_model", "bend", "reach")

    def __init__(self, robot: Robot, bend: float) -> None:
        model = self._model = robot.model
        self._data = pin.Data(model)
        roles = robot.roles
        self._ids = {
            side: tuple(
                model.getJointId(roles.joint(name, r)) for r in ("hip_pitch", "ankle_pitch")
            )
            for side, name in (("l_sole", "left"), ("r_sole", "right"))
        }
        self.bend = bend
        self.reach = self.bent_reach(robot, bend)

    def bent_reach(self, robot: Robot, bend: float) -> float:
        """The left hip-to-ankle distance (m) with the knee ``bend`` rad from its straightest
        (the knee's value of largest distance within its limits), bent the way it bends at
        the standing pose."""
        k = robot.joint_index(robot.roles.joint("left", "knee"))
        lo, hi = float(robot.q_min[k]), float(robot.q_max[k])
        values = np.linspace(lo, hi, 721)
        dist = [self._distance(robot, k, v) for v in values]
        straight = float(values[int(np.argmax(dist))])
        stand = float(robot.configuration("stand")[7 + k])
        keep = float(np.clip(straight + np.sign(stand - straight) * bend, lo, hi))
        return self._distance(robot, k, keep)

    def _distance(self, robot: Robot, k: int, value: float) -> float:
        q = robot.neutral().copy()
        q[7 + k] = value
        pin.forwardKinematics(self._model, self._data, q)
        hip, ankle = (self._data.oMi[i].translation for i in self._ids["l_sole"])
        return float(np.linalg.norm(hip - ankle))

    def room(self, q: np.ndarray, loaded: tuple[str, ...]) -> tuple[float, float]:
        """(the CoM's height on ``q``, m; the least room, m, of the ``loaded`` legs, by sole
        name, to rise before its hip is :attr:`reach` from its ankle: ``√(reach² − d_h²) −
        d_v``, negative when beyond)."""
        com_z = float(pin.centerOfMass(self._model, self._data, q)[2])  # (and the joints)
        room = np.inf
        for side in loaded:
            hip, ankle = (self._data.oMi[i].translation for i in self._ids[side])
            d = hip - ankle
            up = np.sqrt(max(self.reach**2 - d[0] ** 2 - d[1] ** 2, 0.0)) - d[2]
            room = min(room, float(up))
        return com_z, float(room)


class PushRise:
    """The rise's state for one walk (:meth:`raised`, called by
    :meth:`Stabilizer.adjust <wbc.balance.stabilizer.Stabilizer.adjust>`)."""

    __slots__ = ("done", "dz", "knee", "since")

    def __init__(self) -> None:
        self.dz = 0.0  # m: the CoM target's height offset now
        self.since = 0.0  # s since the push trigger fired (0: not pushed)
        self.done = False  # (lowered before the trigger ended: hold, rise_single)
        self.knee: KneeRoom | None = None  # (rise_knee's, built at its first use)

    def knee_cap(
        self, robot: Robot, bend: float, q: np.ndarray, targets: TickTargets, com: np.ndarray
    ) -> float:
        """The most (m) the CoM target ``com`` may rise this tick so that it is no more than
        the loaded legs' room (their knees ``bend`` rad from straight, :class:`KneeRoom`)
        above the CoM of the commanded configuration ``q``."""
        if self.knee is None or self.knee.bend != bend:
            self.knee = KneeRoom(robot, bend)
        com_z, up = self.knee.room(q, loaded_soles(targets))
        return com_z + up - float(com[2])

    def update(
        self,
        pushed: bool,
        dt: float,
        rise: float,
        rise_time: float,
        back: float,
        cap: float = np.inf,
        hold: float = np.inf,
    ) -> float:
        """The height offset (m) for this tick: ``rise × min(t / rise_time, 1)`` ``t`` s after
        the trigger while ``pushed`` and ``t`` ≤ ``hold`` (never lower than it already is),
        else back toward 0 at ``rise / back`` m/s (raised again only after ``pushed`` has
        ended); never above ``cap`` (m; the legs' room), nor below 0."""
        if pushed:
            self.since += dt
        else:
            self.since, self.done = 0.0, False
        if pushed and not self.done and self.since <= hold:
            self.dz = max(self.dz, rise * min(self.since / rise_time, 1.0))
        else:
            self.done = pushed  # (lowered while pushed: not raised again until it ends)
            self.dz = max(self.dz - rise * dt / back, 0.0)
        self.dz = max(min(self.dz, cap), 0.0)
        return self.dz

    def raised(
        self,
        com: np.ndarray,
        pushed: bool,
        dt: float,
        g: Gains,
        room: float = np.inf,
        cap: float = np.inf,
        double: bool = False,
    ) -> np.ndarray:
        """``com`` (the CoM target, world) raised by this tick's offset (``g``: the
        :class:`~wbc.balance.gains.Gains`; ``room``: the loaded legs' room, :func:`leg_room`,
        of which ``g.rise_room`` is used when > 0; ``cap``: the most it may be, m, e.g.
        :class:`KneeRoom`'s; ``double``: a double support, where ``g.rise_single`` > 0 lowers
        it; ``com`` itself when the offset is 0)."""
        cap = min(cap, g.rise_room * room if g.rise_room > 0 else np.inf)
        hold = g.rise_hold if g.rise_hold > 0 else np.inf
        if g.rise_single > 0 and double:  # (rise_single: lowered from the landing on)
            hold = min(hold, 0.0)
        dz = self.update(pushed, dt, g.push_rise, g.rise_time, g.rise_back, cap, hold)
        if dz == 0.0:
            return com
        out = np.array(com, dtype=float)
        out[2] += dz
        return out
