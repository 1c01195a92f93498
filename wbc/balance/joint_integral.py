"""A joint-level integral from the encoders (``Gains.j_i``, issue 30; off by default).

Without the feed-forward nothing pre-loads a soft plant's loaded joints: the stance knee
and the hips sag under the body's weight (the servo's goal minus its present position is
its deflection, ``τ / k``), and the whole body stands lower and behind the plan. This term
measures that sag on the loaded legs' joints (the stance leg's in single support, both
legs' in double support) and integrates it, slowly, into an offset added to the solved
goals: ``I ← clip(I (1 − j_i_leak dt) + j_i dt (q_solve − q_present), ±j_i_max)`` — the
solve's goal, not the goal sent (that one includes ``I``: its difference with the present
position would be the deflection again, and the integral would wind up). A leg that
starts swinging lets its integral go, at no more than the joint's speed limit per tick
(its goals never jump); joints whose encoders are not read (NaN) hold theirs. The
offsets keep the goals within the joint limits (the deployment's clip) and each tick's
change within the speed limits; with ``j_i_still`` a joint whose solved goal moves faster
holds its integral. Feedback only: no model of the servos. Measured (issue 30, i30p's
twelfth round, benchmarks/physics.md; no feed-forward, plant-randomised, 150 plants a
seed): ``j_i`` 1 /s, ``j_i_max`` 0.05 rad brings the nominal ``turn_wb`` 19.2 → 12.8° and
keeps the soft plants main loses there, but loses stiff, late plants (145 / 143 against
146 / 148 on seeds 0 / 1): off. Three gates on what is integrated, options (issue 30,
i30n's thirteenth round, benchmarks/physics.md): ``j_i_lag`` (the encoders against the
solved goals of the servos' measured lag ago), ``j_i_sagittal`` (hip pitch, knee and
ankle pitch only), ``j_i_band`` (the difference low-passed and integrated beyond a band).
Two more (issue 30, i30n's fourteenth round): ``j_i_joints`` (which of the loaded legs'
joints integrate, by role: :data:`JOINT_SETS`) and ``j_i_single`` (the integral grows in
single support only; both legs hold or leak theirs in double support): the knees alone,
growing in single support and leaking at 2 /s, keep 148 / 149 of 150 plants on seeds 0 / 1
against 146 / 148, but lose one ``turn_wb`` plant of seed 1's: off. ``j_i_stiff`` (the
fifteenth round): the integral only on servos identified softer than that at start-up
(:func:`wbc.balance.live.closed_loop`'s rest): 148 / 149, but held-out seeds lose soft
plants at the walk's end: off.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..model import Robot
from ..roles import LEG_ROLES, SOLE_FRAMES
from .servo_lag import LAG_MAX

#: the leg roles that carry the weight in the sagittal plane (``j_i_sagittal``)
SAGITTAL = ("hip_pitch", "knee", "ankle_pitch")
#: the joint sets ``j_i_joints`` selects (its value: the index): the six leg joints; without
#: the hip yaw and hip roll (the stalls of stiff, late plants); the knee and ankle pitch; the
#: knee alone (the sag of a soft plant's stance leg is its knee's)
JOINT_SETS = (
    LEG_ROLES,
    ("hip_pitch", "knee", "ankle_pitch", "ankle_roll"),
    ("knee", "ankle_pitch"),
    ("knee",),
)
#: s: the time constant of the low-pass ``j_i_band`` compares with its band
BAND_SMOOTH = 0.1


@numba.njit(cache=True, error_model="numpy")
def _integrate(
    value: np.ndarray,
    last: np.ndarray,
    solved: np.ndarray,
    target: np.ndarray,
    present: np.ndarray,
    loaded: np.ndarray,
    v_max: np.ndarray,
    k: np.ndarray,
    out: np.ndarray,
) -> None:
    """One tick of :meth:`JointIntegral.offsets` in place (``value``, ``last``; the offsets
    also in ``out``); ``target``: what the encoders should read (``solved``, or ``solved``
    as it was the servos' lag ago: ``j_i_lag``); ``k = [rate, most, leak, dt, read (1:
    present given), first (1: no last goals), still (rad/s; 0: none)]``."""
    rate, most, leak, dt, still = k[0], k[1], k[2], k[3], k[6]
    read, first = k[4] > 0.5, k[5] > 0.5
    for j in range(value.shape[0]):
        v = value[j]
        step = 0.5 * v_max[j] * dt  # (half the speed limit: the solve keeps the rest)
        moving = still > 0 and not first and abs(solved[j] - (last[j] - v)) > still * dt
        if loaded[j]:
            if read and math.isfinite(present[j]) and not moving:
                grown = v * (1.0 - leak * dt) + rate * dt * (target[j] - present[j])
                grown = min(max(grown, -most), most)
                v += min(max(grown - v, -step), step)
        else:  # (a swinging leg's, the arms': let go)
            v -= min(max(v, -step), step)
        if not first:  # (the goals sent change within the speed limits)
            fast = v_max[j] * dt
            g = min(max(solved[j] + v, last[j] - fast), last[j] + fast)
            v = min(max(g - solved[j], -most), most)
        value[j] = v
        last[j] = solved[j] + v
        out[j] = v


class JointIntegral:
    """The integral's state for one walk (:meth:`offsets`)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        n = robot.n_joints
        self.value = np.zeros(n)  # rad: the offset per joint (model order)
        names = robot.joint_names
        roles = robot.roles
        #: the loaded joints per stance sole (SOLE_FRAMES' values; "": double support)
        legs = {
            sole: [names.index(roles.joint(side, r)) for r in LEG_ROLES]
            for side, sole in SOLE_FRAMES.items()
        }
        self.loaded = {key: np.zeros(n, dtype=np.bool_) for key in (*legs, "")}
        for sole, idx in legs.items():
            self.loaded[sole][idx] = True
            self.loaded[""][idx] = True

        def kept(roles_kept: tuple[str, ...]) -> dict[str, np.ndarray]:
            """:attr:`loaded` with only the joints of these roles (both legs)."""
            keep = np.zeros(n, dtype=np.bool_)
            keep[[names.index(roles.joint(s, r)) for s in SOLE_FRAMES for r in roles_kept]] = True
            return {key: mask & keep for key, mask in self.loaded.items()}

        #: the same, the sagittal joints only (hip pitch, knee, ankle pitch: j_i_sagittal)
        self.sagittal = kept(SAGITTAL)
        #: the same per joint set of :data:`JOINT_SETS` (``j_i_joints``)
        self.sets = [kept(roles_kept) for roles_kept in JOINT_SETS]
        self._v_max = np.where(np.isfinite(robot.v_max) & (robot.v_max > 0), robot.v_max, 1.0)
        self._last = np.zeros(n)  # the last goals with the offsets (rad)
        self._k = np.zeros(7)
        self._k[5] = 1.0  # (no last goals yet)
        self._none = np.zeros(n)
        #: the solved goals of the last ticks (j_i_lag: a ring, newest at ``_head``)
        self._past = np.zeros((0, n))
        self._head = 0
        self._filled = 0
        self._smooth = np.zeros(n)  # rad: the low-passed target − present (j_i_band)

    def offsets(
        self,
        solved: np.ndarray,
        present: np.ndarray | None,
        stance: str,
        rate: float,
        most: float,
        leak: float,
        dt: float,
        still: float = 0.0,
        delay: float = 0.0,
        sagittal: bool = False,
        band: float = 0.0,
        joints: int = 0,
    ) -> np.ndarray:
        """The offsets (rad, model order) for this tick's solved goals ``solved``, the
        encoders' ``present`` positions (None or NaN: not read), the stance sole ``stance``
        ("" in double support), ``rate`` (1/s: ``j_i``), ``most`` (rad: ``j_i_max``),
        ``leak`` (1/s: ``j_i_leak``), ``dt`` (s), ``still`` (rad/s: ``j_i_still``; a joint
        whose solved goal moves faster holds its integral: its error is then mostly the
        servo's lag, not sag; 0: none), ``delay`` (s; 0: none): the encoders are compared
        with the solved goals of ``delay`` ago (linearly interpolated between ticks; at most
        :data:`~wbc.balance.servo_lag.LAG_MAX` + 2 ticks), not this tick's — the part of the
        difference the servos' lag explains is left out (``j_i_lag``); ``sagittal``: only
        the loaded legs' hip pitch, knee and ankle pitch integrate (the others let go:
        ``j_i_sagittal``); ``band`` (rad; 0: none): the difference, low-passed
        (:data:`BAND_SMOOTH`: a ringing servo's oscillation averages out), integrated only
        beyond ± ``band`` (``j_i_band``: a stiff servo's small tracking error left alone,
        a soft one's sag integrated); ``joints``: the index of the loaded joints' set in
        :data:`JOINT_SETS` that integrates (the others let go: ``j_i_joints``); one compiled
        call (:func:`_integrate`)."""
        k = self._k
        solved = np.asarray(solved, dtype=float)
        target = solved if delay <= 0.0 or dt <= 0.0 else self._delayed(solved, delay, dt)
        if band > 0.0 and present is not None and dt > 0.0:
            p = np.asarray(present, dtype=float)
            e = target - p
            seen = np.isfinite(e)
            a = 1.0 - math.exp(-dt / BAND_SMOOTH)
            self._smooth[seen] += a * (e[seen] - self._smooth[seen])
            m = self._smooth
            target = p + np.sign(m) * np.maximum(np.abs(m) - band, 0.0)
        k[0], k[1], k[2], k[3] = rate, most, leak, dt
        k[4] = 0.0 if present is None else 1.0
        k[6] = still
        out = np.empty(len(self.value))
        loaded = (self.sagittal if sagittal else self.sets[joints])[stance]
        _integrate(self.value, self._last, solved, target,
                   self._none if present is None else np.asarray(present, dtype=float),
                   loaded, self._v_max, k, out)  # fmt: skip
        k[5] = 0.0
        return out

    def _delayed(self, solved: np.ndarray, delay: float, dt: float) -> np.ndarray:
        """``solved`` stored as this tick's, and the solved goals of ``delay`` s ago (the
        oldest stored while fewer ticks have passed)."""
        size = math.ceil(LAG_MAX / dt) + 3
        if self._past.shape[0] != size:
            self._past = np.zeros((size, len(solved)))
            self._head, self._filled = 0, 0
        self._head = (self._head + 1) % size
        self._past[self._head] = solved
        self._filled = min(self._filled + 1, size)
        back = min(delay / dt, self._filled - 1.0)
        i = int(back)
        f = back - i
        a = self._past[(self._head - i) % size]
        if f <= 0.0:
            return a.copy()
        return (1.0 - f) * a + f * self._past[(self._head - i - 1) % size]
