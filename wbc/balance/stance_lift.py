"""The CoM target moved vertically on plants identified soft (``Gains.lift``, off).

A soft servo plant (issue 30: servos softer than ``servos.toml``, no feed-forward) loses
the walk's end with a stance knee near its stall torque. ``lift`` (m) moves the walk's CoM
target vertically (+: up; −: down, the way measured better: −8 mm kept every soft plant of
seeds 0 and 1, but traded one on a held-out seed; benchmarks/physics.md) once the
stiffness identified at the start-up rest (:func:`wbc.balance.live.closed_loop`'s rest,
:func:`~wbc.balance.compliance.identify_stiffness`) is below ``lift_stiff`` × servos.toml's,
ramped in over the walk's first :data:`LIFT_RAMP` s. Not identified, nothing moves.
:class:`LiftedStabilizer` is the :class:`~wbc.balance.stabilizer.Stabilizer` with the
move applied to its adjusted targets (the closed loop builds it only when ``lift`` or
``end_clock`` is set: off, the stabilizer is main's).

The walk's end (issue 30, seventeenth session; both off): on the same soft plants, from
the reference's final double support on (``end_lead`` s earlier), the walk's clock runs at
``Gains.end_clock`` (the body brought to rest over both feet more slowly: :func:`end_rate`,
read by :meth:`wbc.walking.loop.Session.at_time` as the ``lag_clock``'s rate is) and the
DCM integral (``k_dcm_i``'s: the walk's steady lag behind its reference, taken as a
forward CoM shift) leaks at ``Gains.end_leak`` /s, so the shift that carried the walk is
not carried into the stop (a soft plant pitched over its toes after the last landing).

The single support's start (issue 30, eighteenth session; off): on the same plants the hip
strategy (``Gains.k_hip``) is held off for the first ``Gains.soft_hip`` s of each single
support (its band moved out of reach, :data:`HIP_OFF_BAND`: the roll it holds is released
as in a double support). A soft stance knee sags and rolls the body toward its own side,
the swing foot lands late, and when the plan's next single support starts the robot still
stands on the sole the plan lifts: the DCM estimated against the new stance sole then reads
outward of it and the strategy threw the torso toward that side at once (traced:
benchmarks/physics.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..types import SUPPORT_DOUBLE
from ..walking.reference import WalkingReference
from .hip_roll import _K_BAND, _K_HIP_JUMP
from .stabilizer import Stabilizer

#: s: the lift ramped in from the walk's first tick (the rest's pose, then the lifted one)
LIFT_RAMP = 0.5
#: m: the hip strategy's band while ``soft_hip`` holds it off (no DCM is that far outward)
HIP_OFF_BAND = 1.0


def identified_soft(stiff: float, scale: float | None) -> bool:
    """True for a plant identified at ``scale`` × servos.toml's below ``lift_stiff``
    ``stiff`` (None: not identified, False): the plants ``lift`` and the walk's end act on."""
    return scale is not None and scale < stiff


def lift_height(lift: float, stiff: float, scale: float | None, t: float) -> float:
    """m the CoM target moves up at walk time ``t`` (s) with ``lift`` and ``lift_stiff``
    ``stiff`` for a plant identified at ``scale`` × servos.toml's (None: not identified)."""
    if lift == 0.0 or not identified_soft(stiff, scale):
        return 0.0
    return lift * min(max(t / LIFT_RAMP, 0.0), 1.0)


def final_double_start(ref: WalkingReference) -> float | None:
    """s: the reference time (``ref.t``'s) its final double support starts (None: the
    reference ends in single support, or is double support throughout)."""
    support = np.asarray(ref.support)
    if len(support) == 0 or support[-1] != SUPPORT_DOUBLE:
        return None
    single = np.flatnonzero(support != SUPPORT_DOUBLE)
    return None if len(single) == 0 else float(ref.t[single[-1] + 1])


def at_end(stiff: float, scale: float | None, t: float, start: float | None) -> bool:
    """True at reference time ``t`` (s) from the final double support's ``start`` on
    (:func:`final_double_start`) for a plant identified at ``scale`` × servos.toml's below
    ``lift_stiff`` ``stiff`` (not identified, or no final double support: False)."""
    return identified_soft(stiff, scale) and start is not None and t >= start - 1e-9


def end_rate(end_clock: float, stiff: float, scale: float | None, t: float,
             start: float | None) -> float:  # fmt: skip
    """The walk's clock rate at reference time ``t`` (s) with ``end_clock`` and ``lift_stiff``
    ``stiff`` for a plant identified at ``scale`` × servos.toml's: ``end_clock`` where
    :func:`at_end`, else 1."""
    return end_clock if at_end(stiff, scale, t, start) else 1.0


class LiftedStabilizer(Stabilizer):
    """A :class:`~wbc.balance.stabilizer.Stabilizer` whose adjusted CoM target moves up by
    :func:`lift_height` (``Gains.lift``, ``Gains.lift_stiff``) and whose walk's clock runs
    at :func:`end_rate` (``Gains.end_clock``), its DCM integral leaking at the walk's end
    (``Gains.end_leak``; :attr:`end_start` set by the closed loop) and its hip strategy held
    at each single support's start (``Gains.soft_hip``: each tick's band, :meth:`hip_band`;
    the gains are never changed)."""

    t0: float | None = None  # the reference time of the walk's first tick
    end_start: float | None = None  # the reference's final double support (end_clock)
    _sole = ""  # the stance sole of the single support under way ("": none)
    _single = 0.0  # s of it so far
    _banded: tuple = (None, 0.0, None)  # (the gains' consts, a band, them with it: _consts)

    def _track_single(self, targets, dt: float) -> None:
        """The single support under way (its stance sole) and the time into it (``soft_hip``)."""
        if targets.phase != "single":
            self._sole, self._single = "", 0.0
        elif targets.support != self._sole:
            self._sole, self._single = targets.support, 0.0
        else:
            self._single += float(dt)

    def hip_band(self) -> float:
        """m: this tick's hip-strategy band: during the first ``soft_hip`` s of a single
        support on a plant identified soft, :data:`HIP_OFF_BAND` (out of reach), else
        ``Gains.hip_band``."""
        g = self.gains
        early = g.soft_hip > 0 and self._sole != "" and self._single < g.soft_hip - 1e-9
        if early and identified_soft(g.lift_stiff, self.stiffness_scale):
            return HIP_OFF_BAND
        return g.hip_band

    def _consts(self) -> np.ndarray:
        """:meth:`Stabilizer._consts` with this tick's :meth:`hip_band` (a copy when it is
        not the gains': the band and the push trigger's ``hip_jump`` × band)."""
        k, band = super()._consts(), self.hip_band()
        if band == k[_K_BAND]:
            return k
        base, held, banded = self._banded
        if base is not k or held != band:
            banded = k.copy()
            banded[_K_BAND], banded[_K_HIP_JUMP] = band, self.gains.hip_jump * band
            self._banded = (k, band, banded)
        return banded

    def adjust(self, targets, com_vel_ref: np.ndarray, q_cmd: np.ndarray, dt: float):
        """:meth:`Stabilizer.adjust` (the single support tracked first for ``soft_hip``, its
        DCM integral leaked at the walk's end), then the CoM target lifted and the next
        tick's clock set (not during the rest)."""
        g = self.gains
        if g.soft_hip > 0 and self.enabled and not self.calibrating:  # (soft_hip)
            self._track_single(targets, dt)
        if g.end_leak > 0 and self.enabled and not self.calibrating:  # (end_leak)
            t = float(targets.t) + g.end_lead
            if at_end(g.lift_stiff, self.stiffness_scale, t, self.end_start):
                self.dcm_integral *= math.exp(-g.end_leak * float(dt))
        out = super().adjust(targets, com_vel_ref, q_cmd, dt)
        if not self.enabled or self.calibrating:
            return out
        if self.t0 is None:
            self.t0 = float(targets.t)
        if g.end_clock != 1.0:  # (the next tick's clock: Session.at_time reads it)
            s = self.stiffness_scale
            t = float(targets.t) + g.end_lead  # (end_lead: from that long before)
            self.clock = end_rate(g.end_clock, g.lift_stiff, s, t, self.end_start)
        dz = lift_height(g.lift, g.lift_stiff, self.stiffness_scale, float(targets.t) - self.t0)
        if dz == 0.0:
            return out
        com = np.array(out.com, dtype=float)  # (a copy: the reference's row is shared)
        com[2] += dz
        return out.retarget(com, out.torso_rotation)
