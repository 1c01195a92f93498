"""``wbc bench --physics``: does the robot stay up when the plan reaches the servos?

Every controller's run (planned by :func:`wbc.bench.runner.run_entry`) is played through the
deployment path on the simulated robot (:func:`wbc.sim.play.play`). Per run:

* ``fell`` and ``fall_time_s``: the torso deviates more than 45° from the planned base
  orientation or drops below 60 % of its planned height; ``fall_phase`` and
  ``fall_joint`` (the joint with the highest torque / stall in the 0.5 s before the fall)
  say why;
* ``orientation_dev_max_deg``: the largest angle between the real and the planned base
  orientation (before any fall);
* ``distance_ratio``: real base displacement along the planned one / the planned one (None
  after a fall);
* ``foot_slip_max_mm``: how far a sole slides while planned and loaded as a support;
* ``tracking_err_max_deg``: the largest |real − planned| joint angle (and its joint);
* ``torque_peak_ratio``: peak |servo torque| / stall torque (and its joint);
* ``cop_margin_min_mm``: the smallest distance of the real CoP (from the contact forces) to
  the edge of the real contact polygon during single support (0 = tipping over an edge).

Robustness (``--robustness N --seed S``): N randomised models (:func:`random_model`);
``up_fraction`` = the share that stay up. Push (``--push``): a 10 ms force on the torso at
mid first single support, forward, backward, sideways toward and away from the swing foot
(:data:`PUSH_DIRECTIONS`), each beside its LIPM bound (:func:`push_bounds`); the largest
impulse survived (N·s) by bisection over 0–3 N·s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..balance import add_compensate_argument, check_compensate_encoders, resolve_compensate
from ..exceptions import ConfigurationError, TrajectoryError, WbcError
from ..model import Robot
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_NAMES, SUPPORT_RIGHT, Recording

FALL_TILT_DEG = 45.0
FALL_HEIGHT = 0.6
PUSH_DURATION = 0.01
PUSH_MAX_NS = 3.0
PUSH_STEPS = 7
#: the default solvers of --physics: one per controller (the QP backends give the same joints)
DEFAULT_SOLVERS = (
    "wqp-daqp", "hqp-daqp", "qp-vat", "qp-vatl", "qp-cj_foot", "qp-cj_com", "qp-cjl_foot",
    "qp-cjl_com", "pinv-vat", "pinv-vatl", "pinv-cj_foot", "pinv-cj_com", "pinv-cjl_foot",
    "pinv-cjl_com", "placo", "pink",
)  # fmt: skip

#: record key -> (description, unit)
PHYSICS_KEYS: dict[str, tuple[str, str]] = {
    "fell": ("fell", ""),
    "fall_time_s": ("fell at", "s"),
    "fall_phase": ("support phase at the fall", ""),
    "fall_joint": ("most loaded joint before the fall", ""),
    "orientation_dev_max_deg": ("max base orientation deviation from plan", "deg"),
    "torso_ref_dev_max_deg": ("max torso deviation from the reference's orientation", "deg"),
    "distance_ratio": ("travelled / planned distance", ""),
    "foot_slip_max_mm": ("max foot slip while in support", "mm"),
    "tracking_err_max_deg": ("max joint tracking error", "deg"),
    "tracking_joint": ("joint of the max tracking error", ""),
    "tracking_err_rms_deg": ("RMS joint tracking error over the playback", "deg"),
    "torque_peak_ratio": ("peak servo torque / stall", ""),
    "torque_joint": ("joint of the peak torque", ""),
    "cop_margin_min_mm": ("min real CoP margin in single support", "mm"),
    "swing_lift_max_mm": ("max lift of the planned swing sole in single support", "mm"),
    "swing_unloaded_share": ("share of single support with the swing sole unloaded", ""),
    "deploy_completed": ("deployment completed (no safe stop)", ""),
}


# ---------------------------------------------------------------------- planning
def physics_stack(robot: Robot, stack: str | None = None) -> str | None:
    """The stack of the wqp-*/hqp-* entries on a body (``wbc sim``, ``wbc bench --physics``,
    the closed loop): ``stack`` if given, else the robot folder's ``stack.toml``, else None
    (the benchmark's own, :data:`wbc.bench.solvers.BENCH_STACKS`)."""
    from ..stacks import robot_stack

    if stack is None and robot.default_stack is None:
        return None
    return str(robot_stack(robot, stack)[0])


def plan(solver: str, trajectory: str, robot: Robot) -> Recording:
    """The recording of one benchmark solver on one trajectory (one solve per tick); the
    wqp-*/hqp-* solvers load the robot folder's stack.toml when it has one."""
    from . import trajectories as traj
    from .runner import run_entry
    from .solvers import select

    entries, notes = select([solver], None, "tick", stack=physics_stack(robot))
    if not entries:
        raise ConfigurationError(f"solver {solver!r} cannot run here: {'; '.join(notes)}")
    exact = [e for e in entries if e.name == solver]
    _, rec = run_entry((exact or entries)[0], robot, traj.build(trajectory, robot), "tick")
    return rec


# ---------------------------------------------------------------------- randomised models
#: the plant's randomised ranges (:func:`random_model`): name -> (low, high)
PLANT_RANGES: dict[str, tuple[float, float]] = {
    "stiffness": (0.5, 2.0),  # × the servo's nominal small-error stiffness (log-uniform)
    "damping": (0.5, 1.5),  # × nominal back-EMF damping
    "armature": (0.4, 2.4),  # × nominal reflected rotor inertia
    "friction": (0.0, 2.0),  # × nominal gear friction
    "torque": (0.8, 1.0),  # × stall torque
    "backlash_deg": (0.0, 1.0),  # play between motor and link
    "latency_ms": (0.0, 20.0),  # goal write -> the servos acting on it
    "mass": (0.85, 1.15),  # × each link's mass (and inertia)
    "com": (-0.15, 0.15),  # each link's CoM moved by this share of its distance to the joint
    "floor_friction": (0.5, 1.0),
    "gyro_bias": (0.0, 0.02),  # rad/s, standard deviation of the constant bias per axis
    "gyro_noise": (0.0, 0.02),  # rad/s white noise
    "acc_bias": (0.0, 0.3),  # m/s², standard deviation of the constant bias per axis
    "acc_noise": (0.0, 0.2),  # m/s² white noise
}
#: m: the smallest lever a link's CoM offset is drawn against (links whose CoM sits on the
#: joint axis still get a few mm)
COM_LEVER_MIN = 0.02


@dataclass(frozen=True)
class Variation:
    """One randomised plant: what :func:`wbc.sim.play.play` needs, plus its description.

    The controller never sees it: the feed-forward (:mod:`wbc.balance.compliance`) and the
    estimator keep the robot's nominal servo settings and model."""

    model_params: Any
    servo_params: Any
    latency_ticks: int  # whole control ticks of bus latency (0 here: see latency_s)
    imu_noise: float  # gyro white noise, rad/s
    summary: dict[str, float]
    latency_s: float = 0.0  # s from a goal write to the servos acting on it
    imu: dict[str, float] = field(default_factory=dict)  # SimImu keyword arguments

    def play_kwargs(self) -> dict[str, Any]:
        """The plant as :func:`wbc.sim.play.play`'s keyword arguments (every randomised part:
        model, servos, latency, IMU)."""
        return {
            "model_params": self.model_params,
            "servo_params": self.servo_params,
            "latency_ticks": self.latency_ticks,
            "imu_noise": self.imu_noise,
            "latency_s": self.latency_s,
            "imu": self.imu,
        }


def random_model(robot: Robot, rng: np.random.Generator) -> Variation:
    """A randomised PLANT (:data:`PLANT_RANGES`), generic over the robot's servo law
    (:func:`wbc.sim.actuator.nominal_servo`): the servos' stiffness ×0.5–2 (log-uniform),
    damping ×0.5–1.5, armature ×0.4–2.4, gear friction ×0–2, stall torque ×0.8–1, backlash
    0–1°, goal latency 0–20 ms (any value, not whole ticks), each link's mass ×0.85–1.15
    and CoM moved ±15 % of its distance from the link's joint (at least
    :data:`COM_LEVER_MIN`) per axis, floor friction 0.5–1, the IMU's gyro / accelerometer
    bias (constant per run) and white noise. The controller keeps the nominal model."""
    from ..sim.actuator import nominal_servo
    from ..sim.model import ModelParams, build_spec, link_names

    r = PLANT_RANGES

    def draw(key: str, size=None):
        return rng.uniform(*r[key], size)

    nominal = nominal_servo(robot)
    spec = build_spec(robot)
    links = link_names(spec)
    bodies = {b.name: b for b in spec.bodies}
    lever = np.array([max(float(np.linalg.norm(bodies[n].ipos)), COM_LEVER_MIN) for n in links])
    stiff = float(np.exp(rng.uniform(np.log(r["stiffness"][0]), np.log(r["stiffness"][1]))))
    damping = nominal.damping * draw("damping")
    armature = nominal.armature * draw("armature")
    friction = nominal.friction_loss * draw("friction")
    torque = draw("torque")
    backlash = np.radians(draw("backlash_deg"))
    latency = draw("latency_ms") * 1e-3
    mp = ModelParams(
        floor_friction=draw("floor_friction"),
        armature=armature,
        damping=damping,
        friction_loss=friction,
        mass_scale=draw("mass", len(links)),
        com_offset=draw("com", (len(links), 3)) * lever[:, None],
    )
    # stiffness × stiff exactly: the ramp steepened by stiff / torque, the stall torque × torque
    sp = nominal.scaled(stiffness=stiff / torque, torque=torque)
    names = {f.name for f in fields(sp)}
    sp = replace(sp, **{k: v for k, v in (("armature", armature), ("friction_loss", friction),
                                          ("damping", damping), ("backlash", backlash))
                        if k in names})  # fmt: skip
    if "torque_cap" in names:  # AX-12A: scaled() moved the cap; the stall torque follows
        sp = replace(sp, stall_torque=sp.stall_torque * torque)
    imu = dict(gyro_bias_std=draw("gyro_bias"), gyro_noise=draw("gyro_noise"),
               acc_bias_std=draw("acc_bias"), acc_noise=draw("acc_noise"),
               seed=int(rng.integers(2**31)))  # fmt: skip
    summary = dict(stiffness=stiff, damping=damping, armature=armature, friction=friction,
                   torque=torque, backlash_deg=float(np.degrees(backlash)),
                   latency_ms=latency * 1e3, floor_friction=mp.floor_friction,
                   gyro_bias=imu["gyro_bias_std"], acc_bias=imu["acc_bias_std"])  # fmt: skip
    return Variation(mp, sp, 0, imu["gyro_noise"], summary, latency, imu)


def models(robot: Robot, n: int, seed: int) -> list[Variation]:
    """``n`` randomised models; model ``k`` depends only on ``(seed, k)``."""
    return [random_model(robot, np.random.default_rng([seed, k])) for k in range(n)]


# ---------------------------------------------------------------------- metrics
def _planned(rec: Recording, t: np.ndarray) -> np.ndarray:
    """Planned configurations at times ``t`` (s from the recording's start; clamped)."""
    t_rec = rec.t - rec.t[0]
    tc = np.clip(t, t_rec[0], t_rec[-1])
    q = np.stack([np.interp(tc, t_rec, rec.q[:, j]) for j in range(rec.q.shape[1])], axis=1)
    q[:, 3:7] /= np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    return q


def _rotation(quat_xyzw: np.ndarray) -> np.ndarray:
    return pin.Quaternion(np.asarray(quat_xyzw)).toRotationMatrix()


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0))))


def physics_record(rec: Recording, result, robot: Robot, ref=None) -> dict[str, Any]:
    """The physics figures of one simulated run (see the module docstring); with the walking
    reference ``ref``, also ``torso_ref_dev_max_deg``: the largest angle between the real
    torso and the torso orientation the reference asks for (the plan may deviate from it)."""
    log = result.log
    t = log["t"] - result.playback_start
    q_real = log["q"]
    q_plan = _planned(rec, t)
    n = len(t)
    dev = np.array([_angle(_rotation(q_plan[k, 3:7]), _rotation(q_real[k, 3:7])) for k in range(n)])
    low = q_real[:, 2] < FALL_HEIGHT * q_plan[:, 2]
    fallen = (dev > FALL_TILT_DEG) | low
    fall_k = int(np.argmax(fallen)) if np.any(fallen) else None
    upto = n if fall_k is None else fall_k
    rec_t = rec.t - rec.t[0]
    support = rec.channels.get("support")
    sup = (
        support[np.clip(np.searchsorted(rec_t, t, side="right") - 1, 0, len(rec_t) - 1)]
        if support is not None
        else np.zeros(n, int)
    )
    names = robot.joint_names
    stall = result.sim.servo_params.stall_torque
    record: dict[str, Any] = {"fell": fall_k is not None}
    record["fall_time_s"] = float(t[fall_k]) if fall_k is not None else None
    if fall_k is not None:
        record["fall_phase"] = SUPPORT_NAMES.get(int(sup[fall_k]), "?")
        window = (t > t[fall_k] - 0.5) & (t <= t[fall_k])
        load = log["peak_torque"][window].max(axis=0) / stall
        j = int(np.argmax(load))
        record["fall_joint"] = f"{names[j]} ({load[j]:.2f} stall)"
    else:
        record["fall_phase"] = record["fall_joint"] = None
    record["orientation_dev_max_deg"] = float(dev[:upto].max()) if upto else 0.0
    if ref is not None:
        from ..walking.loop import heading_free

        start = pin.XYZQUATToSE3(rec.q[0, :7]).rotation  # the base is the torso
        wanted = ref.torso_rotations(heading_free(start))
        k_ref = np.clip(np.round((t + rec.t[0] - ref.t[0]) / ref.dt).astype(int), 0, ref.n - 1)
        played = np.arange(n) < upto
        rdev = [_angle(wanted[k_ref[k]], _rotation(q_real[k, 3:7])) for k in np.flatnonzero(played)]
        record["torso_ref_dev_max_deg"] = float(max(rdev)) if rdev else 0.0
    # distance along the planned displacement of the base (playback part only)
    play_end = min(upto, int(np.searchsorted(t, rec_t[-1], side="right")))
    d_plan = q_plan[play_end - 1, :2] - q_plan[0, :2] if play_end else np.zeros(2)
    planned = float(np.linalg.norm(d_plan))
    if planned > 0.01 and play_end and fall_k is None:  # none if it fell: not travel
        moved = (q_real[play_end - 1, :2] - q_real[0, :2]) @ d_plan / planned
        record["distance_ratio"] = float(moved / planned)
    else:
        record["distance_ratio"] = None
    record["planned_distance_mm"] = planned * 1e3
    # foot slip: a sole's horizontal travel while planned in support and carrying load
    weight = robot.total_mass * 9.81
    slip = 0.0
    for side, code in ((0, SUPPORT_LEFT), (1, SUPPORT_RIGHT)):
        planned_support = (sup == SUPPORT_DOUBLE) | (sup == code)
        loaded = log["sole_force"][:, side] > 0.05 * weight
        on = planned_support & loaded
        on[upto:] = False
        anchor = None
        for k in range(n):
            if on[k]:
                if anchor is None:
                    anchor = log["soles"][k, side, :2]
                slip = max(slip, float(np.linalg.norm(log["soles"][k, side, :2] - anchor)))
            else:
                anchor = None
    record["foot_slip_max_mm"] = slip * 1e3
    err = np.abs(q_real[:upto, 7:] - q_plan[:upto, 7:]) if upto else np.zeros((1, len(names)))
    j = int(np.argmax(err.max(axis=0)))
    record["tracking_err_max_deg"] = float(np.degrees(err.max()))
    record["tracking_joint"] = names[j]
    played = (t >= 0) & (t <= rec_t[-1]) & (np.arange(n) < upto)
    sq = (q_real[played, 7:] - q_plan[played, 7:]) ** 2
    record["tracking_err_rms_deg"] = float(np.degrees(np.sqrt(sq.mean()))) if sq.size else None
    peak = log["peak_torque"][:upto].max(axis=0) if upto else np.zeros(len(names))
    j = int(np.argmax(peak))
    record["torque_peak_ratio"] = float(peak[j] / stall)
    record["torque_joint"] = names[j]
    single = (sup != SUPPORT_DOUBLE) & (np.arange(n) < upto) & (t >= 0) & (t <= rec_t[-1])
    margins = log["cop_margin"][single]
    margins = margins[np.isfinite(margins)]
    record["cop_margin_min_mm"] = float(margins.min() * 1e3) if margins.size else None
    # the planned swing sole: how high it rises, how often it carries < 5 % of the weight
    swing = np.where(sup == SUPPORT_LEFT, 1, 0)  # right support: the left sole swings
    ks = np.flatnonzero(single)
    if ks.size:
        z = log["soles"][ks, swing[ks], 2] - log["soles"][0, swing[ks], 2]
        record["swing_lift_max_mm"] = float(z.max() * 1e3)
        force = log["sole_force"][ks, swing[ks]]
        record["swing_unloaded_share"] = float(np.mean(force < 0.05 * weight))
    else:
        record["swing_lift_max_mm"] = record["swing_unloaded_share"] = None
    record["deploy_completed"] = bool(result.deploy.completed)
    if not result.deploy.completed:
        record["deploy_trip"] = str(result.deploy.trip)
    record["sim_time_s"] = float(log["t"][-1]) if n else 0.0
    record["_series"] = {"t": t, "dev": dev}
    return record


def mid_single_support(rec: Recording) -> float | None:
    """Time (s from the start) of the middle of the recording's first single support."""
    support = rec.channels.get("support")
    if support is None:
        return None
    single = np.flatnonzero(np.asarray(support) != SUPPORT_DOUBLE)
    if not single.size:
        return None
    start = single[0]
    end = start
    while end + 1 < len(support) and support[end + 1] == support[start]:
        end += 1
    return float(0.5 * (rec.t[start] + rec.t[end]) - rec.t[0])


def simulated_recording(rec: Recording, result, robot: Robot) -> Recording:
    """The simulated run as a recording (real q, CoM and CoP beside the planned ones)."""
    log = result.log
    t = log["t"] - result.playback_start
    keep = np.r_[True, np.diff(t) > 1e-9]
    t, q = t[keep], log["q"][keep]
    rec_t = rec.t - rec.t[0]
    tc = np.clip(t, rec_t[0], rec_t[-1])
    channels = {"com": log["com"][keep], "zmp": log["cop"][keep]}
    for name, src in (("com_ref", "com"), ("zmp_ref", "zmp"), ("swing_ref", "swing")):
        if src in rec.channels:
            ref = np.asarray(rec.channels[src], dtype=float)
            channels[name] = np.stack(
                [np.interp(tc, rec_t, ref[:, j]) for j in range(ref.shape[1])], axis=1
            )
    if "swing_is_left" in rec.channels:  # the real sole of the planned swing side
        k = np.clip(np.searchsorted(rec_t, tc, side="right") - 1, 0, len(rec_t) - 1)
        left = np.asarray(rec["swing_is_left"], dtype=bool)[k]
        soles = log["soles"][keep]
        channels["swing"] = np.where(left[:, None], soles[:, 0], soles[:, 1])
    if "support" in rec.channels:
        k = np.clip(np.searchsorted(rec_t, tc, side="right") - 1, 0, len(rec_t) - 1)
        channels["support"] = np.asarray(rec["support"])[k]
    meta = dict(rec.meta, simulated=True)
    return Recording(t - t[0], q, robot.joint_names, channels, meta)


# ---------------------------------------------------------------------- runs
@dataclass(frozen=True)
class ClosedLoopSpec:
    """The closed loop of a physics run: the controller solved live in the deployment's tick
    with :class:`wbc.balance.stabilizer.Stabilizer` (``gains``; ``enabled=False``: the same
    live run, open loop), on ``ref``; ``use_imu=False``: encoders only."""

    make: Callable[[Robot], Any]
    ref: Any
    gains: Any = None
    enabled: bool = True
    use_imu: bool = True
    stepping: Any = None  # wbc.balance.stepping.SteppingParams: re-plan steps from the DCM
    #: wbc.balance.retime.HoldParams: lift-offs wait for the DCM (None: never)
    hold: Any = field(default_factory=lambda: _default_hold())
    #: wbc.balance.fall.FallParams: fall detection and the safe fall (None: off)
    fall: Any = field(default_factory=lambda: _default_fall())
    #: the feed-forward's servo model (wbc.balance.live.closed_loop's ``servo``)
    servo: Any = None
    calibrate_s: float | None = None  # s at rest before the walk (None: closed_loop's default)


def _default_fall():
    from ..balance.fall import FallParams

    return FallParams()


def _default_hold():
    from ..balance.retime import HoldParams

    return HoldParams()


def play_closed_loop(
    spec: ClosedLoopSpec,
    robot: Robot,
    variation: Variation | None = None,
    push: tuple[float, Sequence[float], float] | None = None,
    settle: float = 1.0,
    compensate: float = 0.0,
    correct: bool = False,
    duration: float | None = None,
    on_tick: Callable[[Any], None] | None = None,
):
    """One live closed-loop run on the simulated robot (:func:`wbc.balance.live.closed_loop`
    on :class:`~wbc.sim.bus.SimServoBus` + :class:`~wbc.sim.bus.SimImu`): a
    :class:`wbc.sim.play.PlayResult` and the loop (its per-tick costs, limit excursions).
    ``duration`` (s): only the walk's first seconds (None: all of it); ``on_tick`` sees the
    simulation after every logged tick (a live viewer)."""
    from ..balance.live import closed_loop
    from ..servos.sources import CallableSource
    from ..sim.bus import SimImu, SimServoBus
    from ..sim.play import PlayResult, _Logger
    from ..sim.simulator import Simulation
    from ..walking.loop import start_configuration

    v = variation
    sim = Simulation(robot, v.model_params if v else None, v.servo_params if v else None)
    sim.reset(start_configuration(robot, spec.ref))
    sim.goal_delay = v.latency_s if v else 0.0
    logger = _Logger(sim)
    if on_tick is not None:
        log_only = logger

        def logger(bus) -> None:
            log_only(bus)
            on_tick(sim)

    bus = SimServoBus(sim, latency_ticks=v.latency_ticks if v else 0, on_tick=logger)
    imu = None
    if spec.use_imu:
        imu = (
            SimImu(sim, **v.imu)
            if v and v.imu
            else SimImu(sim, gyro_noise=v.imu_noise if v else 0.0)
        )
    cal = {} if spec.calibrate_s is None else {"calibrate_s": spec.calibrate_s}
    loop = closed_loop(bus, robot, spec.make(robot), spec.ref, imu, spec.gains, spec.enabled,
                       compensate, correct, out=lambda _line: None, duration=duration,
                       stepping=spec.stepping, hold=spec.hold, fall=spec.fall,
                       servo=spec.servo, **cal)  # fmt: skip
    dep = loop.deployment
    start = sim.time
    if push is not None:  # timed from the playback's first target (after any soft start)
        inner = dep.source

        # the walk starts at the calibration's last tick (wbc.balance.live.SessionSource)
        calib = max(loop.stabilizer.calibration_ticks - 1, 0) / dep.config.rate

        def pushed(tick: int, t: float) -> np.ndarray | None:
            if tick == 0 and t == 0.0:
                sim.push(push[1], push[2], start=sim.time + calib + push[0])
            return inner(tick, t)

        dep.source = CallableSource(pushed, inner.first(), inner.joint_names)
    result = dep.run()
    rate = dep.config.rate
    playback_start = start + result.soft_start_ticks / rate + loop.source.start_offset
    if settle > 0:  # (after a safe stop too: the fall goes on)
        for _ in range(round(settle * rate)):
            sim.advance(1.0 / rate)
            logger(bus)
    base = log_only if on_tick is not None else logger
    return PlayResult(result, base.log.arrays(), playback_start - base.t0, sim), loop


def simulate(
    rec: Recording,
    robot: Robot,
    variation: Variation | None = None,
    push: tuple[float, Sequence[float], float] | None = None,
    settle: float = 1.0,
    compensate: float = 0.0,
    gyro: float = 0.0,
    closed: ClosedLoopSpec | None = None,
    correct: bool = False,
) -> dict[str, Any]:
    """One simulated run of a planned recording: its physics record (``compensate``: the
    gain of the servo compliance feed-forward, :mod:`wbc.balance.compliance`; ``gyro``: the
    scale of the torso gyro feedback, :mod:`wbc.balance.feedback`; 0 = off; ``correct``: the
    feed-forward rescaled from the encoders, :class:`~wbc.balance.compliance.EncoderCorrection`).
    With
    ``closed``, the controller runs live (:func:`play_closed_loop`) and ``rec`` (its open-loop
    plan) is what the run is measured against."""
    if closed is not None:
        result, loop = play_closed_loop(closed, robot, variation, push, settle, compensate,
                                        correct)  # fmt: skip
        record = physics_record(rec, result, robot, closed.ref)
        record.update(closed_loop_figures(loop))
        return record
    from ..sim.play import play

    kw: dict[str, Any] = {"compensate": compensate, "gyro": gyro, "correct": correct}
    if variation is not None:
        kw.update(model_params=variation.model_params, servo_params=variation.servo_params,
                  latency_ticks=variation.latency_ticks, imu_noise=variation.imu_noise,
                  latency_s=variation.latency_s, imu=variation.imu)  # fmt: skip
    result = play(rec, robot, settle=settle, push=push, limit_tol=math.inf, **kw)
    return physics_record(rec, result, robot)


def closed_loop_figures(loop) -> dict[str, Any]:
    """The closed loop's own figures: goal excursion beyond the joint limits (before the
    deployment's clamp), the estimator + feedback share of the tick, the largest estimated
    torso tilt error."""
    share = loop.source.cost_share()
    return {
        "goal_limit_excess_deg": float(np.degrees(max(loop.source.limit_excess, 0.0))),
        "feedback_share": share,
        "estimated_tilt_max_deg": float(np.degrees(loop.stabilizer.max_tilt_error)),
        "failed_solves": int(loop.session.failed),
        "replans": len(loop.stepping.events) if loop.stepping is not None else None,
        "holds": loop.hold.holds if loop.hold is not None else None,
        "held_s": loop.hold.held if loop.hold is not None else None,
        "hold_worst_mm": 1e3 * loop.hold.worst if loop.hold is not None else None,
    }


def robustness(
    rec: Recording,
    robot: Robot,
    n: int,
    seed: int,
    progress: Callable[[int], None] | None = None,
    settle: float = 1.0,
    compensate: float = 0.0,
    gyro: float = 0.0,
    closed: ClosedLoopSpec | None = None,
    correct: bool = False,
) -> dict[str, Any]:
    """The share of ``n`` randomised models (seeded) on which the run stays up."""
    up, falls = [], []
    for k, v in enumerate(models(robot, n, seed)):
        r = simulate(rec, robot, v, settle=settle, compensate=compensate, gyro=gyro,
                     closed=closed, correct=correct)  # fmt: skip
        up.append(not r["fell"])
        if r["fell"]:  # why: when, in which support phase, the most loaded joint
            falls.append({"model": k, "time_s": r["fall_time_s"], "phase": r["fall_phase"],
                          "joint": r["fall_joint"], **v.summary})  # fmt: skip
        if progress:
            progress(k)
    return {"models": n, "seed": seed, "up_fraction": float(np.mean(up)) if up else None,
            "up": [bool(u) for u in up], "falls": falls}  # fmt: skip


#: the directions of ``--push`` (``lateral`` is ``away``: the side no step can reach)
PUSH_DIRECTIONS = ("forward", "backward", "toward", "away")


def push_direction(rec: Recording, kind: str) -> np.ndarray:
    """``forward`` (+x), ``backward`` (−x), ``away`` (alias ``lateral``: sideways away from
    the swing foot, +y when standing on the left sole, −y on the right, the side where no
    step can catch the robot) or ``toward`` (sideways toward the swing foot)."""
    if kind == "forward":
        return np.array([1.0, 0.0, 0.0])
    if kind == "backward":
        return np.array([-1.0, 0.0, 0.0])
    if kind not in ("lateral", "away", "toward"):
        raise ConfigurationError(
            f"push direction must be one of {', '.join(PUSH_DIRECTIONS)} (or lateral), got {kind!r}"
        )
    t = mid_single_support(rec)
    support = rec.channels.get("support")
    if t is None or support is None:
        raise TrajectoryError("a sideways push needs a single-support phase in the recording")
    k = int(np.clip(np.searchsorted(rec.t - rec.t[0], t, side="right") - 1, 0, len(rec) - 1))
    away = 1.0 if support[k] == SUPPORT_LEFT else -1.0
    return np.array([0.0, away if kind != "toward" else -away, 0.0])


def push_bounds(ref, robot: Robot) -> dict[str, float] | None:
    """Each push direction's physical bound (N·s, LIPM, :func:`wbc.balance.stepping.
    capture_bounds`): ``away`` the CoP at the stance sole's edge; ``forward``, ``backward``,
    ``toward`` one step landing as far as the swing sole gets in the time left (None when
    ``ref`` is not a walk with a single support)."""
    from ..balance.stepping import capture_bounds
    from ..walking.legs import LegGeometry

    try:
        b = capture_bounds(ref, robot.total_mass,
                           LegGeometry.from_robot(robot, robot.configuration("stand")))  # fmt: skip
    except (StopIteration, AttributeError, KeyError, WbcError):
        return None
    return {"away": float(b["away_ns"]), "forward": float(b["forward_in_time_ns"]),
            "backward": float(b["backward_in_time_ns"]),
            "toward": float(b["toward_in_time_ns"])}  # fmt: skip


def largest_push(
    rec: Recording,
    robot: Robot,
    direction: Sequence[float] | str,
    max_impulse: float = PUSH_MAX_NS,
    steps: int = PUSH_STEPS,
    settle: float = 1.0,
    compensate: float = 0.0,
    gyro: float = 0.0,
    closed: ClosedLoopSpec | None = None,
    correct: bool = False,
) -> float | None:
    """Largest impulse (N·s) along ``direction`` at mid single support that the run survives
    (bisection over [0, max_impulse] in ``steps`` halvings); None if it falls unpushed."""
    t_push = mid_single_support(rec)
    if t_push is None:
        return None
    if isinstance(direction, str):
        direction = push_direction(rec, direction)
    u = np.asarray(direction, dtype=float) / np.linalg.norm(direction)

    def survives(impulse: float) -> bool:
        force = u * impulse / PUSH_DURATION
        push = (t_push, force, PUSH_DURATION)
        run = simulate(rec, robot, push=push, settle=settle, compensate=compensate, gyro=gyro,
                       closed=closed, correct=correct)  # fmt: skip
        return not run["fell"]

    if not survives(0.0):
        return None
    lo, hi = 0.0, max_impulse
    if survives(hi):
        return hi
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if survives(mid) else (lo, mid)
    return lo


# ---------------------------------------------------------------------- bench hook
def add_physics_arguments(parser) -> None:
    """The ``wbc bench`` options of the physics benchmark."""
    from ..cli import number

    parser.add_argument(
        "--physics",
        action="store_true",
        help="play every run through the deploy path on the simulated robot (wbc[physics])",
    )
    parser.add_argument(
        "--robustness",
        type=number(0, 10000, integer=True),
        default=0,
        metavar="N",
        help="--physics: N randomised models",
    )
    parser.add_argument(
        "--seed", type=number(0, integer=True), default=0, help="--robustness: random seed"
    )
    parser.add_argument(
        "--push",
        action="store_true",
        help="--physics: largest survived torso impulse (N·s) forward, backward, toward and "
        "away from the swing foot, each beside its physical bound",
    )
    add_compensate_argument(parser, "--physics: servo compliance feed-forward on the goals")
    parser.add_argument(
        "--closed-loop",
        action="store_true",
        help="--physics: the closed-loop rows (the default; kept for old command lines)",
    )
    parser.add_argument(
        "--open-loop",
        action="store_true",
        help="--physics: only the plans played open loop (by default each controller also "
        "runs live in the deployment's tick, closed through the torso IMU and the servos' "
        "present positions, with step adjustment: wbc.balance.live), no feed-forward unless "
        "--compensate",
    )
    parser.add_argument(
        "--encoders-only",
        action="store_true",
        help="closed loop: estimate from the servos' positions alone (no IMU)",
    )
    parser.add_argument(
        "--stepping",
        action="store_true",
        help="closed loop: step adjustment (the default; kept for old command lines)",
    )
    parser.add_argument(
        "--no-stepping",
        action="store_true",
        help="closed loop: no step placement from the measured DCM (wbc.balance.stepping)",
    )
    parser.add_argument(
        "--gyro",
        type=number(0, 10),
        default=0.0,
        metavar="SCALE",
        help="--physics: closed loop, torso gyro feedback on the leg goals (OP3 gains x SCALE; "
        "wbc.balance.feedback)",
    )


def run_physics_command(args, console, robot: Robot, entries) -> int:
    """``wbc bench --physics``: the table, and the records in ``--json``."""
    import platform

    from . import trajectories as traj

    if args.robustness < 0:
        raise ConfigurationError(f"--robustness must be >= 0, got {args.robustness}")
    if args.open_loop and (args.closed_loop or args.encoders_only or args.stepping):
        raise ConfigurationError(
            "--open-loop: no --closed-loop, --encoders-only or --stepping with it"
        )
    resolve_compensate(args, robot, best=not args.open_loop)
    if not (math.isfinite(args.compensate) and args.compensate >= 0):
        raise ConfigurationError(
            f"--compensate GAIN must be a finite number >= 0, got {args.compensate}"
        )
    check_compensate_encoders(args)
    if not (math.isfinite(args.gyro) and args.gyro >= 0):
        raise ConfigurationError(f"--gyro SCALE must be a finite number >= 0, got {args.gyro}")
    if args.mode != "tick":
        raise ConfigurationError("--physics plays real-time plans: use --mode tick (the default)")
    names = [t for t in args.trajectories if t != traj.STATIC_COM]
    refs = {t: traj.build(t, robot) for t in names}
    started = time.perf_counter()
    records = run_physics(args, console, robot, entries, refs)
    elapsed = time.perf_counter() - started
    console.print(f"{len(records)} simulated runs in {elapsed:.1f} s on {platform.node()}")
    if args.json:
        from .cli import write_records

        write_records(args.json, records, elapsed_s=elapsed)
        console.print(f"records in {args.json}")
    return 0


def stabilizer_gains(args):
    """The closed loop's gains: :class:`wbc.balance.stabilizer.Gains` defaults."""
    from ..balance.stabilizer import Gains

    return Gains()


def run_physics(args, console, robot: Robot, entries, refs: dict) -> list[dict[str, Any]]:
    """Called by ``wbc bench --physics``: every entry on every trajectory in the simulator."""
    from rich.table import Table

    from .runner import run_entry, save_recording

    entries = [e for e in entries if e.real_time]  # plans are one solve per tick
    if not (args.solvers or args.families):
        entries = [e for e in entries if e.name.split("@")[0] in DEFAULT_SOLVERS]
    records: list[dict[str, Any]] = []
    series = {}
    comp = getattr(args, "compensate", 0.0) or 0.0
    gyro = getattr(args, "gyro", 0.0)
    from ..sim.actuator import servo_kind

    closed_loop = not getattr(args, "open_loop", False)
    if closed_loop and servo_kind(robot) == "hobby_pwm":
        console.print(f"open loop only: {robot.name}'s hobby servos report no positions")
        closed_loop = False
    gains = stabilizer_gains(args) if closed_loop else None
    for name, ref in refs.items():
        for entry in entries:
            console.print(f"[dim]physics: {entry.name} on {name}[/]")
            _, rec = run_entry(entry, robot, ref, "tick")
            if args.record:
                save_recording(rec, args.record, entry.name, name)
            excess = np.maximum(robot.q_min - rec.joints, rec.joints - robot.q_max).max()
            specs: list[ClosedLoopSpec | None] = [None]
            if closed_loop:
                from ..balance.stepping import SteppingParams

                imu = not getattr(args, "encoders_only", False)
                step = None if getattr(args, "no_stepping", False) else SteppingParams()
                specs.append(ClosedLoopSpec(entry.make, ref, gains, True, imu, step))
            for spec in specs:
                loop = {"compensate": comp, "gyro": gyro if spec is None else 0.0,
                        "correct": getattr(args, "compensate_encoders", False)}  # fmt: skip
                started = time.perf_counter()
                try:  # beyond the joint limits: clamped by the deployment (wbc deploy refuses
                    # it unless --limit-tol allows it)
                    if spec is None:
                        from ..sim.play import play

                        result = play(rec, robot, settle=1.0, limit_tol=math.inf, **loop)
                        extra: dict[str, Any] = {}
                    else:
                        result, cl = play_closed_loop(spec, robot, compensate=comp,
                                                      correct=loop["correct"])  # fmt: skip
                        extra = closed_loop_figures(cl)
                except WbcError as exc:
                    console.print(f"[red]{entry.name} on {name}: {exc}[/]")
                    records.append({"solver": entry.name, "family": entry.family,
                                    "trajectory": name, "error": str(exc)})  # fmt: skip
                    continue
                r = physics_record(rec, result, robot, ref)
                r.update(extra)
                r["loop"] = (
                    "open" if spec is None else "closed" + ("+step" if spec.stepping else "")
                )
                r["plan_limit_excess_deg"] = float(np.degrees(max(excess, 0.0)))
                r["clamped_ticks"] = int(result.deploy.limits.clamped.max())
                wall = time.perf_counter() - started
                r.update(solver=entry.name, family=entry.family, stack=entry.stack,
                         trajectory=name, **loop,
                         sim_steps=int(result.sim.steps), wall_s=wall,
                         steps_per_s=result.sim.steps / wall,
                         realtime_factor=r["sim_time_s"] / wall)  # fmt: skip
                label = entry.name if spec is None else f"{entry.name} {r['loop']}"
                series[(label, name)] = (r.pop("_series"), rec, result)
                if args.record:  # the simulated run beside the plan (wbc view replays both)
                    simulated_recording(rec, result, robot).save(
                        Path(args.record) / f"{label.replace(' ', '_')}__{name}__sim.npz"
                    )
                kw = dict(loop, closed=spec)
                if args.robustness:
                    started = time.perf_counter()
                    rob = robustness(rec, robot, args.robustness, args.seed, **kw)
                    r["robustness"] = rob
                    r["up_fraction"] = rob["up_fraction"]
                    r["sweep_wall_s"] = time.perf_counter() - started
                if args.push:
                    for d in PUSH_DIRECTIONS:
                        r[f"push_{d}_ns"] = largest_push(rec, robot, d, **kw)
                    r["push_lateral_ns"] = r["push_away_ns"]
                    r["push_bounds_ns"] = push_bounds(ref, robot)
                records.append(r)
    for name in refs:
        rows = [r for r in records if r["trajectory"] == name and "error" not in r]
        title = f"physics: {name} (deploy path, simulated {_servo_name(robot)})"
        title += f", compliance feed-forward ×{comp:g}" if comp else ""
        title += ", open vs closed loop" if closed_loop else ""
        table = Table(title=title + (f", gyro feedback ×{gyro:g} (open)" if gyro else ""))
        cols = ["solver", "loop", "fell s", "dev°", "ref°", "dist", "slip", "err°", "rms°", "τ/τs"]
        cols += ["CoP mm", "lift mm"]
        if args.robustness:
            cols.append(f"up/{args.robustness}")
        if args.push:
            cols += ["push fwd", "bwd", "toward", "away"]
        for c in cols:
            table.add_column(c, justify="left" if c == "solver" else "right")
        for r in rows:
            cells = [
                r["solver"],
                r["loop"],
                "-" if not r["fell"] else f"{r['fall_time_s']:.2f}",
                f"{r['orientation_dev_max_deg']:.1f}",
                f"{r['torso_ref_dev_max_deg']:.1f}",
                "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}",
                f"{r['foot_slip_max_mm']:.1f}",
                f"{r['tracking_err_max_deg']:.1f}",
                "-" if r["tracking_err_rms_deg"] is None else f"{r['tracking_err_rms_deg']:.2f}",
                f"{r['torque_peak_ratio']:.2f}",
                "-" if r["cop_margin_min_mm"] is None else f"{r['cop_margin_min_mm']:.1f}",
                "-" if r["swing_lift_max_mm"] is None else f"{r['swing_lift_max_mm']:.1f}",
            ]
            if args.robustness:
                cells.append(f"{r['up_fraction']:.2f}")
            if args.push:
                cells += [_ns(r[f"push_{d}_ns"]) for d in PUSH_DIRECTIONS]
            table.add_row(*cells)
        console.print(table)
        bounds = rows[0].get("push_bounds_ns") if rows and args.push else None
        if bounds:
            console.print(
                "  push bounds (N·s, LIPM: one step in the swing's time left; away: the CoP at "
                "the stance sole's edge): "
                + ", ".join(f"{d} {bounds[d]:.3f}" for d in PUSH_DIRECTIONS)
            )
        for r in rows:
            if r["loop"].startswith("closed"):
                share = r.get("feedback_share")
                console.print(
                    f"  {r['solver']} {r['loop']} loop: estimator + feedback "
                    f"{'-' if share is None else f'{100 * share:.0f} %'} of the tick (median); "
                    f"goals beyond a joint limit before clamping: "
                    f"{r['goal_limit_excess_deg']:.2f}° max"
                )
            if r["fell"]:
                console.print(
                    f"  {r['solver']}: fell at {r['fall_time_s']:.2f} s in {r['fall_phase']} "
                    f"support; most loaded: {r['fall_joint']}"
                )
            falls = r.get("robustness", {}).get("falls", [])
            if falls:
                console.print(f"  {r['solver']}: {fall_summary(falls)}")
    if args.plots:
        for (solver, name), (s, rec, result) in series.items():
            label = solver.replace(" ", "_")
            physics_figure(s, rec, result, args.plots / f"physics_{label}__{name}.png")
    return records


def fall_summary(falls: list[dict[str, Any]]) -> str:
    """One line on why randomised models fell: phases, most loaded joints, latency share."""
    from collections import Counter

    phases = Counter(f["phase"] for f in falls)
    joints = Counter(str(f["joint"]).split(" ")[0] for f in falls)
    late = sum(1 for f in falls if f.get("latency")) / len(falls)
    return (
        f"{len(falls)} falls: phase "
        + ", ".join(f"{k} {v}" for k, v in phases.most_common())
        + "; most loaded "
        + ", ".join(f"{k} {v}" for k, v in joints.most_common(3))
        + f"; {late:.0%} with one-tick latency"
    )


def _ns(v: float | None) -> str:
    return "fell" if v is None else f"{v:.3f}"


def _servo_name(robot: Robot) -> str:
    """The robot's simulated servo model (AX-12A, or its robot.toml [servo] name)."""
    from ..sim.actuator import nominal_servo

    return getattr(nominal_servo(robot), "name", "AX-12A")


def physics_figure(series: dict, rec: Recording, result, path: Path) -> Path:
    """Deviation from the planned base orientation over time; real vs planned CoM and
    CoP/ZMP (lateral y) over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = result.log
    t = series["t"]
    rec_t = rec.t - rec.t[0]
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t, series["dev"], color="C3")
    ax[0].set_ylabel("base orientation\ndeviation (deg)")
    ax[0].axhline(FALL_TILT_DEG, color="k", lw=0.5, ls="--")
    ax[1].plot(rec_t, rec["com"][:, 1] * 1e3, "C0--", label="CoM planned")
    ax[1].plot(t, log["com"][:, 1] * 1e3, "C0", label="CoM real")
    if "zmp" in rec.channels:
        ax[1].plot(rec_t, rec["zmp"][:, 1] * 1e3, "C2--", label="ZMP planned")
    ax[1].plot(t, log["cop"][:, 1] * 1e3, "C2", lw=0.8, label="CoP real")
    ax[1].set_ylabel("lateral y (mm)")
    ax[1].set_xlabel("time (s)")
    ax[1].legend(fontsize=7, ncol=4)
    fig.suptitle(f"{rec.meta.get('controller', '')} on {rec.meta.get('trajectory', '')}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def physics_summary_lines(records: list[dict[str, Any]]) -> list[str]:
    """Plain-text lines (≤ 100 columns) of the physics table."""
    records = [r for r in records if "error" not in r]
    out = [f"{'solver':<14}{'traj':<12}{'fell s':>7}{'dev°':>7}{'dist':>6}{'slip mm':>8}"
           f"{'err°':>6}{'τ/τs':>6}{'CoP mm':>7}{'up':>6}{'p lat':>7}{'p fwd':>7}"]  # fmt: skip
    for r in records:
        fell = f"{r['fall_time_s']:.2f}" if r["fell"] else "-"
        dist = "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}"
        cop = "-" if r["cop_margin_min_mm"] is None else f"{r['cop_margin_min_mm']:.1f}"
        up = "-" if r.get("up_fraction") is None else f"{r['up_fraction']:.2f}"
        out.append(
            f"{r['solver']:<14}{r['trajectory']:<12}{fell:>7}{r['orientation_dev_max_deg']:>7.1f}"
            f"{dist:>6}{r['foot_slip_max_mm']:>8.1f}{r['tracking_err_max_deg']:>6.1f}"
            f"{r['torque_peak_ratio']:>6.2f}{cop:>7}{up:>6}"
            f"{_ns(r['push_lateral_ns']) if 'push_lateral_ns' in r else '-':>7}"
            f"{_ns(r['push_forward_ns']) if 'push_forward_ns' in r else '-':>7}"
        )
    return out
