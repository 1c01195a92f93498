"""The servos' goal latency and response time, measured at the start-up rest (issue 30).

The stiff, late plants the closed loop loses (benchmarks/physics.md, nineteenth session)
are not picked out by the servo lag measured while walking (:mod:`wbc.balance.servo_lag`:
it reads the servo's own following more than its delay). At rest the deployment can ask the
servos directly: a small goal step ``step`` (rad) on a few lightly loaded joints (the arms'
elbows by default, :func:`probe_joints`: the body hardly moves) held ``pre`` s, the measured
step (``step`` more, the same way: the first one took up the gears' backlash, behind which
the encoder would not see the output move) held ``hold`` s, then back. The encoders read
through the same :class:`~wbc.servos.bus.ServoBus` as the walk give the normalised
response ``y(t) = mean_j (x_j(t) − x_j⁰) / step`` (``x⁰``: the mean before the step), and
:func:`fit_response` fits a first-order response after a dead time::

    y(t) = g (1 − exp(−(t − t₀ − L) / T))   for t > t₀ + L, else 0

by least squares over a grid of ``L`` (the goal latency: bus, firmware and the read's own
delay) and ``T`` (the response time: ``b / k``, damping over stiffness, for a position
servo with little load), ``g`` in closed form. Nothing of the simulator's plant is read:
only the goals written and the encoders' answers (the same on hardware).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigurationError

#: s: the dead times the fit tries (0–80 ms, 0.5 ms apart)
LATENCIES = np.arange(0.0, 0.0805, 0.0005)
#: s: the response times the fit tries (2 ms – 0.3 s, log-spaced)
RESPONSES = np.geomspace(0.002, 0.3, 120)


@dataclass(frozen=True)
class ProbeResult:
    """The fit of one goal step: ``latency`` (s, ``L``), ``response`` (s, ``T``), ``gain``
    (``g``: the share of the step the encoders reached), ``rms`` (the fit's residual, in
    steps) and ``joints`` (how many were probed)."""

    latency: float
    response: float
    gain: float
    rms: float
    joints: int

    def line(self) -> str:
        """One line for the loop's report."""
        return (
            f"goal latency {self.latency * 1e3:.1f} ms, response {self.response * 1e3:.1f} ms, "
            f"reached {self.gain:.2f} of the step ({self.joints} joints, fit rms "
            f"{self.rms:.3f})"
        )


def fit_response(t: np.ndarray, y: np.ndarray, t0: float) -> tuple[float, float, float, float]:
    """``(L, T, g, rms)``: the least-squares fit of ``y(t) = g (1 − exp(−(t − t₀ − L) / T))``
    (0 before ``t₀ + L``) to the samples ``(t, y)`` over the grids :data:`LATENCIES` ×
    :data:`RESPONSES`, ``g = Σ y φ / Σ φ²`` for each pair."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(y) & np.isfinite(t)
    t, y = t[ok], y[ok]
    if t.size < 3:
        raise ConfigurationError("goal probe: fewer than 3 encoder samples after the step")
    s = t[None, None, :] - t0 - LATENCIES[:, None, None]
    phi = np.where(s > 0, 1.0 - np.exp(-np.maximum(s, 0.0) / RESPONSES[None, :, None]), 0.0)
    den = np.einsum("lrk,lrk->lr", phi, phi)
    g = np.where(den > 0, np.einsum("lrk,k->lr", phi, y) / np.maximum(den, 1e-12), 0.0)
    res = np.einsum("lrk,lrk->lr", *(2 * [y[None, None, :] - g[:, :, None] * phi]))
    i, j = np.unravel_index(int(np.argmin(res)), res.shape)
    return (float(LATENCIES[i]), float(RESPONSES[j]), float(g[i, j]),
            math.sqrt(float(res[i, j]) / t.size))  # fmt: skip


def probe_joints(robot) -> list[int]:
    """The joints the probe steps: both arms' elbows (the last joint of each arm chain,
    :mod:`wbc.roles`), else the arms' first joints; refused on a robot without arms."""
    arms = robot.roles.arms
    names = [a["elbow"] for a in arms.values() if "elbow" in a]
    if not names:
        names = [next(iter(a.values())) for a in arms.values() if a]
    if not names:
        raise ConfigurationError(f"goal probe: {robot.name} has no arm joint to step at rest")
    return [robot.joint_index(n) for n in names]


class GoalProbe:
    """The probe during the start-up rest (:func:`wbc.balance.live.closed_loop`,
    ``probe``): :meth:`offset` adds ``step`` rad to :attr:`joints`' goals from ``start`` −
    ``pre`` s into the rest, ``2 step`` from ``start`` for ``hold`` s; :meth:`sample` keeps
    each encoder reading (the deployment reads right after its write: a reading taken at the
    tick of time ``t`` is seen at the next one); :meth:`result` fits it
    (:func:`fit_response`) once the step is over."""

    def __init__(self, joints: list[int], step: float = 0.05, start: float = 0.25,
                 hold: float = 0.15, pre: float = 0.15) -> None:  # fmt: skip
        if not (math.isfinite(step) and step != 0 and start >= pre >= 0 and hold > 0):
            raise ConfigurationError(
                f"goal probe: step must be a non-zero number of rad, start >= pre >= 0 s, "
                f"hold > 0 s; got {step}, {start}, {pre}, {hold}"
            )
        self.joints, self.step, self.start, self.hold = list(joints), step, start, hold
        self.pre = pre
        self._t: list[float] = []
        self._x: list[np.ndarray] = []
        self._last_t: float | None = None  # (the tick whose reading the next call sees)
        self._first: float | None = None  # (the rest's first tick)
        self._t0: float | None = None  # (the step's first write)
        self.done: ProbeResult | None = None

    def offset(self, t: float) -> np.ndarray | None:
        """The goal offsets (per probed joint, rad) of the rest's tick at time ``t`` (s,
        the deployment's; the rest's first call starts the probe's clock; None: none)."""
        if self._first is None:
            self._first = t
        rest_t = t - self._first
        if self.start <= rest_t < self.start + self.hold:
            if self._t0 is None:
                self._t0 = t  # (the measured step's first write)
            return np.full(len(self.joints), 2.0 * self.step)
        if self.start - self.pre <= rest_t < self.start:
            return np.full(len(self.joints), self.step)  # (the backlash taken up)
        return None

    def sample(self, t: float, present: np.ndarray | None) -> None:
        """The encoders' last reading (all joints, rad; None: none yet), seen at the tick of
        time ``t``: it was taken at the previous tick's."""
        if present is not None and self._last_t is not None:
            self._t.append(self._last_t)
            self._x.append(np.asarray(present, dtype=float)[self.joints].copy())
        self._last_t = t

    def result(self) -> ProbeResult:
        """The fit of the step's response (kept in :attr:`done`)."""
        if self.done is not None:
            return self.done
        t, x, t0 = np.asarray(self._t), np.asarray(self._x), self._t0
        if t0 is None or t.size == 0:
            raise ConfigurationError("goal probe: the rest is over before the step (start)")
        before = (t < t0) & (t >= t0 - min(0.05, self.pre))
        during = (t >= t0) & (t < t0 + self.hold)
        if not before.any() or during.sum() < 3:
            raise ConfigurationError(
                "goal probe: the rest is too short for the step (start, hold) or the bus "
                "reads nothing"
            )
        base = np.nanmean(x[before], axis=0)
        y = np.nanmean((x[during] - base) / self.step, axis=1)
        L, T, g, rms = fit_response(t[during], y, t0)
        self.done = ProbeResult(L, T, g, rms, len(self.joints))
        return self.done
