"""Servo compliance compensation: feed forward the deflection of each position servo.

An AX-12A position servo gives way under load: its torque ramps with the position error
(:mod:`wbc.sim.actuator`, ``u = p + (|e| − m)/s`` outside the dead band ``m``), so holding a
joint torque ``τ`` costs a steady error. Inverting that law (static, friction ignored)::

    |e|(τ) = m · min(1, |τ| / τ_p) + s · max(0, |τ|/τ_s − p)      (ticks)
    δ(τ)   = sign(τ) · |e|(τ) · rad_per_tick                        (rad, joint direction)

with ``τ_p = p · τ_s`` the punch torque (below it the dead band is blended in linearly so
that δ is continuous through τ = 0) and ``|τ|`` capped at the servo's torque cap (no goal
offset buys more torque than that). For ``p = 0`` this is ``δ = τ / k + m`` with the
stiffness ``k = τ_s / (s · rad_per_tick)`` of :attr:`wbc.sim.actuator.ServoParams.stiffness`.

The load ``τ`` is the static joint torque of the planned configuration with the support
contact(s): the stance sole(s) flat on the floor, then::

    τ = g_j(q) − J_c,jᵀ f     with f the least-norm solution of  J_c,bᵀ f = g_b(q)

(``b``: the 6 floating-base rows, ``J_c`` the stacked 6-D sole Jacobians in the world-aligned
sole frames, ``f`` the contact wrenches). In single support ``f`` is unique (this is the
inverse dynamics with the base held by the stance foot); in double support ``f`` is the
weighted least-norm solution ``min Σ_i |f_i|² / w_i`` with ``w_l = α``, ``w_r = 1 − α`` and α
the CoM's position along the right-to-left sole segment (clipped to 0.02–0.98): the sole
under the CoM carries the weight, and the load moves continuously into single support.
The goal is ``q_plan + δ``, clamped into the joint limits. The servo parameters are the
SAME ones the simulator uses
(:meth:`ServoParams.from_settings` of ``robot.servo_map.settings``): one definition.

A hobby PWM servo (:class:`wbc.sim.actuator.HobbyServoParams`, ``robot.toml`` ``[servo] law =
"hobby_pwm"``) is inverted the same way: full drive ``(|e| − dead band) / band`` past its dead
band, so holding ``τ`` costs (µs of pulse, then rad through the joint's µs per rad of its
SSC-32 map ``ssc32.toml``)::

    |e|(τ) = dead band · min(1, |τ| / (0.05 τ_s)) + band · min(1, |τ| / τ_s)      (µs)

(the dead band blended in over the first 5 % of the stall torque, so δ is continuous at 0).
A servo with no position read-back cannot be corrected from its encoders.

An X-series servo (:class:`wbc.sim.xm430.XServoParams`, ``servos.toml`` protocol 2.0) is
inverted through its P term, ``δ = τ / k`` (:meth:`~wbc.sim.xm430.XServoParams.deflection`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ServoMapError
from ..model import Robot
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT, Recording
from ..servo_map import RAD_PER_TICK
from ..servos.sources import TargetSource
from ..sim.actuator import HobbyServoParams, ServoParams, nominal_servo, pwm_map
from ..sim.xm430 import XServoParams
from ..walking.feasibility import contact_forces

SOLES = {
    SUPPORT_LEFT: ("l_sole",),
    SUPPORT_RIGHT: ("r_sole",),
    SUPPORT_DOUBLE: ("l_sole", "r_sole"),
}


def servo_deflection(tau: np.ndarray, params: ServoParams) -> np.ndarray:
    """Steady position error δ (rad, joint direction) of servos holding torques ``tau`` (N·m),
    the static inverse of the servo law (module docstring)."""
    tau = np.asarray(tau, dtype=float)
    cap = np.minimum(params.torque_cap, params.stall_torque)
    mag = np.minimum(np.abs(tau), cap)
    tau_punch = params.punch * params.stall_torque
    blend = np.where(tau_punch > 0, np.minimum(1.0, mag / np.maximum(tau_punch, 1e-12)), 1.0)
    blend = np.where(mag > 0, blend, 0.0)
    ticks = params.margin * blend + params.slope * np.maximum(
        0.0, mag / params.stall_torque - params.punch
    )
    return np.sign(tau) * ticks * RAD_PER_TICK


#: s: an X-series servo's drive feed-forward (:meth:`CompensatedSource._drive`) takes the
#: goals' velocity and acceleration after smoothing them over this (the OP3's closed loop:
#: walk10_wb deviated 23° unsmoothed, 7.7° at 30 ms; benchmarks/op3.md section 7)
DRIVE_FILTER_S = 0.03

#: the share of the stall torque over which a hobby servo's dead band is blended in
HOBBY_BLEND = 0.05


def hobby_deflection(
    tau: np.ndarray, params: HobbyServoParams, us_per_rad: np.ndarray
) -> np.ndarray:
    """Steady position error δ (rad, joint direction) of hobby PWM servos holding ``tau``
    (N·m) with pulses of ``us_per_rad`` (µs per rad, per joint): the static inverse of the
    hobby law (module docstring)."""
    tau = np.asarray(tau, dtype=float)
    load = np.minimum(np.abs(tau) / params.stall_torque, 1.0)
    us = params.dead_band_us * np.minimum(1.0, load / HOBBY_BLEND)
    us = us + params.proportional_band_us * load
    return np.sign(tau) * us / np.abs(np.asarray(us_per_rad, dtype=float))


class ComplianceCompensator:
    """Goals that pre-load each servo by its expected deflection under the static load.

    ``params`` defaults to the robot's shared servo settings (what the servos are set to).
    ``gain`` scales the feed-forward (1 = the model's deflection).
    """

    def __init__(
        self,
        robot: Robot,
        params: ServoParams | HobbyServoParams | XServoParams | None = None,
        gain: float = 1.0,
    ) -> None:
        if params is None:
            xseries = robot.servo_map is not None and robot.servo_map.protocol == 2.0
            nominal = nominal_servo(robot) if robot.robot_data.servo or xseries else None
            if isinstance(nominal, HobbyServoParams | XServoParams):
                params = nominal
            elif robot.servo_map is None:
                raise ServoMapError(f"compliance compensation needs a servo map for {robot.name}")
            else:
                params = ServoParams.from_settings(robot.servo_map.settings)
        if not np.isfinite(gain) or gain < 0:
            raise ConfigurationError(f"compensation gain must be a finite number >= 0, got {gain}")
        self.robot = robot
        self.params = params
        #: µs of pulse per rad of each joint (hobby servos: their SSC-32 map)
        self.us_per_rad = (
            np.asarray(pwm_map(robot).codec().scale, dtype=float)
            if isinstance(params, HobbyServoParams)
            else None
        )
        self.gain = float(gain)
        #: per joint, × ``gain`` (None: 1 for every joint; ``Gains.ff_sagittal``)
        self.scale: np.ndarray | None = None
        self.model = robot.model
        self.data = robot.model.createData()
        self.sole_ids = {s: robot.frame_id(s) for s in ("l_sole", "r_sole")}

    def _standing(self, joints: np.ndarray, soles: Sequence[str]) -> np.ndarray:
        """The configuration with these joints and the first support sole flat on the floor."""
        q = self.robot.with_joints(joints)
        return self.robot.place_on_ground(q, soles[0])

    def torques(
        self,
        joints: np.ndarray,
        support: int = SUPPORT_DOUBLE,
        accel: np.ndarray | None = None,
        share: float | None = None,
    ) -> np.ndarray:
        """Static joint torques (N·m, model joint order) holding ``joints`` on ``support``;
        ``accel`` (m/s², world): under the field ``g − accel`` instead of gravity (the body
        accelerated as one: ``Gains.ff_inertial``); ``share`` (double support): the left
        sole's share of the load instead of the CoM's place between the soles."""
        if support not in SOLES:
            raise ConfigurationError(f"support must be one of {sorted(SOLES)}, got {support!r}")
        soles = SOLES[support]
        q = self._standing(np.asarray(joints, dtype=float), soles)
        m, d = self.model, self.data
        if accel is None:
            g = pin.computeGeneralizedGravity(m, d, q)
        else:  # (the whole body accelerated by ``accel``, at rest: M a + gravity's, by RNEA)
            a = np.zeros(m.nv)
            a[:3] = pin.XYZQUATToSE3(q[:7]).rotation.T @ np.asarray(accel, dtype=float)
            g = pin.rnea(m, d, q, np.zeros(m.nv), a)
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        jc = np.vstack(
            [pin.getFrameJacobian(m, d, self.sole_ids[s], pin.LOCAL_WORLD_ALIGNED) for s in soles]
        )
        if len(soles) == 2 and share is None:  # weighted least norm: the sole nearer the CoM
            com = pin.centerOfMass(m, d, q, False)[:2]
            pl, pr = (d.oMf[self.sole_ids[s]].translation[:2] for s in soles)
            seg = pl - pr
            share = float((com - pr) @ seg / max(seg @ seg, 1e-12))
        share = 1.0 if share is None else share  # (one sole carries all)
        return g[6:] - jc[:, 6:].T @ contact_forces(jc[:, :6].T, g[:6], share)

    def deflection(self, joints: np.ndarray, support: int = SUPPORT_DOUBLE) -> np.ndarray:
        """Expected servo deflection (rad) at ``joints`` on ``support`` (× ``gain``)."""
        d = self.gain * self.servo_deflection(self.torques(joints, support))
        return d if self.scale is None else d * self.scale

    @property
    def integral(self) -> bool:
        """Whether the servos' position loop has an integral (X-series PI): their static
        deflection then decays (:class:`CompensatedSource` high-passes it)."""
        return isinstance(self.params, XServoParams) and bool(np.any(self.params.ki > 0))

    def servo_deflection(self, tau: np.ndarray) -> np.ndarray:
        """The servos' steady deflection (rad, unscaled) holding ``tau`` (N·m)."""
        if self.us_per_rad is not None:
            return hobby_deflection(tau, self.params, self.us_per_rad)  # type: ignore[arg-type]
        if isinstance(self.params, XServoParams):
            return self.params.deflection(tau)
        return servo_deflection(tau, self.params)  # type: ignore[arg-type]

    def goals(self, joints: np.ndarray, support: int = SUPPORT_DOUBLE) -> np.ndarray:
        """Planned joints plus their deflection, clamped into the joint limits."""
        joints = np.asarray(joints, dtype=float)
        out = joints + self.deflection(joints, support)
        return np.clip(out, self.robot.q_min, self.robot.q_max)


def support_schedule(recording: Recording) -> Callable[[float], int]:
    """The planned support phase of ``recording`` at playback time t (s from its start):
    its ``support`` channel, or double support when it has none."""
    support = recording.channels.get("support")
    if support is None:
        return lambda t: SUPPORT_DOUBLE
    t_rec = recording.t - recording.t[0]
    codes = np.asarray(support, dtype=int)

    def at(t: float) -> int:
        k = int(np.clip(np.searchsorted(t_rec, t, side="right") - 1, 0, len(t_rec) - 1))
        return int(codes[k])

    return at


class EncoderCorrection:
    """An online estimate, per servo, of how far the feed-forward's model is off, from the
    encoders' present positions: the correction of :class:`CompensatedSource`.

    Each tick it sees, per joint, the model's deflection ``δ_m`` (rad, unscaled) and the
    velocity ``v`` of a goal ``g`` it sent, and the present position ``p`` the servo
    then reached; the measured deflection ``d = g − p`` is fitted by exponentially
    forgotten least squares (time constant ``window`` s)::

        d ≈ s · δ_m + β · v        (s: the model's scale, β: the servo's dynamic lag)

    with a prior pulling ``s`` to 1 and β to 0 worth ``prior`` s of data (δ = 0.01 rad,
    v = 0.5 rad/s): a joint the plan never loads keeps the model. Only ``s`` is used — the
    goal becomes ``q + gain · ŝ · δ_m`` — the lag regressor is there so that the walk's
    dynamic error (the reason an integral on planned − present winds up) does not bias it.
    ``ŝ`` stays within ``[s_min, s_max]`` and moves at most ``rate`` per second: a servo
    softer or stiffer than its settings say gets its own scale, and nothing the encoders
    report can make the correction flip sign or exceed ``s_max`` × the model.
    """

    def __init__(
        self,
        n: int,
        window: float = 3.0,
        prior: float = 0.1,
        s_min: float = 0.25,
        s_max: float = 2.0,
        rate: float = 1.0,
    ) -> None:
        for name, v in (("window", window), ("prior", prior), ("rate", rate)):
            if not (math.isfinite(v) and v > 0):
                raise ConfigurationError(
                    f"encoder correction: {name} must be a finite number > 0, got {v}"
                )
        if not (0 < s_min <= 1 <= s_max and math.isfinite(s_max)):
            raise ConfigurationError(
                f"encoder correction: need 0 < s_min <= 1 <= s_max, got {s_min}, {s_max}"
            )
        self.window, self.prior, self.rate = float(window), float(prior), float(rate)
        self.s_min, self.s_max = float(s_min), float(s_max)
        self.scale = np.ones(n)  # ŝ per joint
        self.lag = np.zeros(n)  # β per joint (s)
        # sufficient statistics of the fit: Σ δ², Σ δ v, Σ v², Σ δ d, Σ v d (forgotten)
        self._sums = np.zeros((5, n))

    def update(
        self, delta: np.ndarray, velocity: np.ndarray, measured: np.ndarray, dt: float
    ) -> None:
        """One sample per joint (NaN in ``measured``: not read, skipped); ``dt`` s since the
        last one."""
        if not dt > 0:
            return
        ok = np.isfinite(measured) & np.isfinite(delta) & np.isfinite(velocity)
        d = np.where(ok, measured, 0.0)
        x, v = np.where(ok, delta, 0.0), np.where(ok, velocity, 0.0)
        forget = math.exp(-dt / self.window)
        S = self._sums
        S *= np.where(ok, forget, 1.0)
        S += (x * x, x * v, v * v, x * d, v * d)
        # ridge toward (s, β) = (1, 0): prior seconds of data at δ = 0.01 rad, v = 0.5 rad/s
        w = self.prior / dt
        a, b, c = S[0] + w * 1e-4, S[1], S[2] + w * 0.25
        r1, r2 = S[3] + w * 1e-4, S[4]
        det = a * c - b * b  # > 0: a, c > 0 and Cauchy–Schwarz
        with np.errstate(all="ignore"):  # (garbage in: that joint keeps its estimate)
            s = (r1 * c - r2 * b) / det
            lag = (a * r2 - b * r1) / det
        s = np.where(np.isfinite(s), s, self.scale)
        self.lag = np.where(np.isfinite(lag), lag, self.lag)
        step = self.rate * dt
        self.scale = np.clip(np.clip(s, self.scale - step, self.scale + step),
                             self.s_min, self.s_max)  # fmt: skip


class CompensatedSource:
    """A target source (:class:`wbc.servos.sources.TargetSource`) whose targets carry the
    compliance feed-forward of :class:`ComplianceCompensator`.

    ``support(t)`` gives the planned support phase at playback time ``t``. With
    ``correction`` (an :class:`EncoderCorrection`) and ``present`` (a function returning
    the servos' present positions, rad, NaN unread, or None), the model's deflection is
    rescaled per joint from what the encoders report: the goal is ``q + gain · ŝ · δ_m``
    (``correction=None``: the feed-forward alone, ``ŝ = 1``). The present positions a
    deployment reads right after sending a goal answer the goal before it: they are paired
    with the goal ``delay`` calls back.

    On X-series servos (:class:`~wbc.sim.xm430.XServoParams`: a PI position loop) the load
    also carries the drive torque ``b · q̇ + I_a · q̈`` of the goals
    (:meth:`_drive`), and δ is high-passed with each servo's integral time ``T_i``
    (:meth:`_unabsorbed`): what the integral already holds is not fed forward twice::

        a ← a + (δ − a) · (1 − exp(−Δt / T_i)),    goal = q + gain · ŝ · (δ − a)

    (``a`` = δ at the first call: at rest the integral holds the whole load.)
    """

    def __init__(
        self,
        source: TargetSource,
        compensator: ComplianceCompensator,
        support: Callable[[float], int],
        present: Callable[[], np.ndarray | None] | None = None,
        correction: EncoderCorrection | None = None,
        delay: int = 2,
    ) -> None:
        if correction is not None and present is None:
            raise ConfigurationError("the encoder correction needs the servos' present positions")
        self.source = source
        self.compensator = compensator
        self.support = support
        self.joint_names = tuple(source.joint_names)
        self.present = present
        self.correction = correction
        #: the body's acceleration at time t (m/s², world; None: static): ``Gains.ff_inertial``
        self.accel: Callable[[float], np.ndarray | None] | None = None
        #: the left sole's share of the load in double support at time t (None: by the CoM;
        #: :meth:`ComplianceCompensator.torques`), e.g. :class:`wbc.drive.compensate.LoadRamp`
        self.share: Callable[[float], float | None] | None = None
        self.delay = max(1, int(delay))
        # (t, plan, goal, model deflection, goal velocity) of the last goals sent
        self._sent: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        if hasattr(source, "duration"):
            self.duration = source.duration
        params = compensator.params
        #: the servos' integral time (s, per joint; X-series PI) or None (no integral)
        self._ti = params.integral_time if isinstance(params, XServoParams) else None
        self._absorbed: np.ndarray | None = None  # the integral's share of δ
        self._t_last = 0.0
        self._smoothed: list[tuple[float, np.ndarray]] = []

    def idle(self) -> None:
        """The wrapped source's ``idle()`` (:class:`~wbc.servos.sources.TargetSource`: a live
        controller's preparation for its next tick), if it has one."""
        idle = getattr(self.source, "idle", None)
        if idle is not None:
            idle()

    def warm(self) -> None:
        """The wrapped source's ``warm()`` (:class:`~wbc.servos.sources.TargetSource`: just
        before its next tick's deadline), if it has one."""
        warm = getattr(self.source, "warm", None)
        if warm is not None:
            warm()

    def first(self) -> np.ndarray:
        if self._ti is not None:  # at rest the servos' integral holds the static load
            return np.clip(self.source.first(), self.compensator.robot.q_min,
                           self.compensator.robot.q_max)  # fmt: skip
        return self.compensator.goals(self.source.first(), self.support(0.0))

    def _unabsorbed(self, delta: np.ndarray, t: float) -> np.ndarray:
        """The deflection a servo with an integral (X-series PI, integral time ``T_i``) still
        shows: ``δ`` high-passed, ``δ − a`` with ``a`` following ``δ`` at ``1 / T_i`` (the
        first call at rest: all absorbed); ``δ`` itself on servos without one."""
        if self._ti is None:
            return delta
        if self._absorbed is None:
            self._absorbed = delta.copy()
        else:
            dt = max(t - self._t_last, 0.0)
            self._absorbed += (delta - self._absorbed) * -np.expm1(-dt / self._ti)
        self._t_last = t
        return delta - self._absorbed

    def _drive(self, q: np.ndarray, t: float) -> np.ndarray:
        """The torque (N·m) an X-series servo spends moving its joint along the goals: its
        back-EMF ``b · q̇`` and rotor inertia ``I_a · q̈`` (:class:`XServoParams` damping and
        armature), by backward differences of the goals smoothed over
        :data:`DRIVE_FILTER_S` (the closed loop's feedback is in the goals: unsmoothed, its
        tick-to-tick steps become the feed-forward)."""
        p = self.compensator.params
        assert isinstance(p, XServoParams)
        done = self._smoothed  # (t, smoothed goal) of the last two calls
        v = a = np.zeros_like(q)
        if done and t > done[-1][0]:
            dt = t - done[-1][0]
            q = done[-1][1] + (q - done[-1][1]) * -np.expm1(-dt / DRIVE_FILTER_S)
            v = (q - done[-1][1]) / dt
            if len(done) > 1 and done[-1][0] > done[-2][0]:
                a = (v - (done[-1][1] - done[-2][1]) / (done[-1][0] - done[-2][0])) / dt
        done.append((t, q.copy()))
        if len(done) > 2:
            done.pop(0)
        return p.damping * v + p.armature * a

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        q = self.source(tick, t)
        if q is None:
            return None
        q = np.asarray(q, dtype=float)
        comp = self.compensator
        accel = self.accel(t) if self.accel is not None else None  # (Gains.ff_inertial)
        share = self.share(t) if self.share is not None else None
        tau = comp.torques(q, self.support(t), accel, share)
        if self._ti is not None:
            tau = tau + self._drive(q, t)
        delta = self._unabsorbed(comp.servo_deflection(tau), t)
        sent = self._sent
        corr = self.correction
        if corr is not None and len(sent) >= self.delay:
            now = self.present()
            if now is not None:
                _, _, goal, d_then, v_then = sent[-self.delay]
                dt = t - sent[-1][0]
                corr.update(d_then, v_then, goal - np.asarray(now, dtype=float), dt)
        scale = corr.scale if corr is not None else 1.0
        if comp.scale is not None:  # (per joint: Gains.ff_sagittal)
            scale = scale * comp.scale
        out = np.clip(q + comp.gain * scale * delta, comp.robot.q_min, comp.robot.q_max)
        # the goal's velocity: what the servo lags behind
        velocity = (out - sent[-1][2]) / (t - sent[-1][0]) if sent and t > sent[-1][0] else 0 * q
        sent.append((t, q, out, delta, velocity))
        if len(sent) > self.delay:
            sent.pop(0)
        return out


def compensated(
    source: TargetSource,
    recording: Recording,
    robot: Robot,
    gain: float = 1.0,
    correct: bool = False,
    deployment: Callable[[], object] | None = None,
) -> CompensatedSource:
    """``source`` (playing ``recording``) with the compliance feed-forward on its support
    schedule; ``correct``: rescaled per joint from ``deployment().last_present``
    (:class:`EncoderCorrection`; the :class:`~wbc.servos.playback.Deployment` running it,
    with ``read`` on)."""
    present = correction = None
    if correct:
        if deployment is None:
            raise ConfigurationError(
                "the encoder correction needs the deployment's present positions"
            )
        present = lambda: deployment().last_present  # noqa: E731
        correction = EncoderCorrection(robot.n_joints)
    comp = ComplianceCompensator(robot, gain=gain)
    return CompensatedSource(source, comp, support_schedule(recording), present, correction)


#: ticks: joints whose modelled deflection at rest is smaller than this are not used to
#: identify the stiffness (the encoders' 0.29° steps and the dead band dominate them)
IDENTIFY_MIN_TICKS = 2.0


def identify_stiffness(
    robot: Robot,
    joints: np.ndarray,
    goals: np.ndarray,
    present: np.ndarray,
    params: ServoParams | None = None,
) -> tuple[float, int]:
    """The servos' stiffness relative to ``params`` (default: servos.toml) from a standing
    test: at rest in double support at ``joints``, the servos hold ``goals`` (rad) and the
    encoders read ``present`` (rad, averaged). The known gravity torques τ
    (:meth:`ComplianceCompensator.torques`) make each servo sag by ``δ_m = b + s/k``: ``b``
    the dead band's part of the modelled deflection (:func:`servo_deflection` with no
    ramp), ``s`` the ramp's part (the stiffness scales only the ramp); the least-squares
    scale over the loaded joints (modelled sag ≥ :data:`IDENTIFY_MIN_TICKS`) is
    ``k = Σ s² / Σ s·(δ_m − b)``. Returns ``(k, joints used)``; raises when no joint is loaded
    enough or the sag points against the load."""
    if params is None and robot.servo_map is None:
        raise ConfigurationError(
            f"stiffness identification: {robot.name} has no servos.toml (the AX-12A model)"
        )
    params = params or ServoParams.from_settings(robot.servo_map.settings)
    comp = ComplianceCompensator(robot, params)
    tau = comp.torques(joints, SUPPORT_DOUBLE)
    model = servo_deflection(tau, params)
    band = servo_deflection(tau, replace(params, slope=np.zeros_like(params.slope)))
    sag = np.asarray(goals, dtype=float) - np.asarray(present, dtype=float) - band
    model = model - band
    use = (np.abs(model) >= IDENTIFY_MIN_TICKS * RAD_PER_TICK) & np.isfinite(sag)
    if not np.any(use):
        raise ConfigurationError(
            "stiffness identification: no servo is loaded enough at rest to measure its sag"
        )
    num, den = float(model[use] @ model[use]), float(model[use] @ sag[use])
    if den <= 0:
        raise ConfigurationError(
            "stiffness identification: the servos sag against their gravity load (encoder "
            "offsets or the servo map's signs?)"
        )
    return num / den, int(use.sum())
