"""A controller solved live on the simulated robot, closed through its sensors, and the
simulated runs of the physics benchmark: :func:`play_closed_loop` (one live run,
:func:`wbc.balance.live.closed_loop` on :class:`~wbc.sim.bus.SimServoBus` +
:class:`~wbc.sim.bus.SimImu`), :func:`simulate` (a plan's physics record, open or closed loop,
on a nominal or randomised plant), :func:`robustness` (the share of randomised plants on which
the run stays up).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..model import Robot
from ..recording import Recording
from .sim_record import physics_record
from .variation import Variation, models

if TYPE_CHECKING:
    from ..servos.playback import DeployResult
    from ..walking.controller import Controller


@dataclass(frozen=True)
class ClosedLoopSpec:
    """The closed loop of a physics run: the controller solved live in the deployment's tick
    with :class:`wbc.balance.stabilizer.Stabilizer` (``gains``; None: the closed loop's
    :func:`~wbc.balance.stabilizer.default_gains` for the run's feed-forward;
    ``enabled=False``: the same live run, open loop), on ``ref``; ``use_imu=False``: encoders
    only."""

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
    #: step adjustment on a bus that reads no positions too (closed_loop's step_on_commands)
    step_on_commands: bool = False


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
    on the robot's simulated bus (:func:`~wbc.sim.bus.sim_bus`) + :class:`~wbc.sim.bus.SimImu`): a
    :class:`wbc.sim.log.PlayResult` and the loop (its per-tick costs, limit excursions).
    ``duration`` (s): only the walk's first seconds (None: all of it); ``on_tick`` sees the
    simulation after every logged tick (a live viewer)."""
    from ..balance.live import closed_loop, loop_rate
    from ..servos.sources import CallableSource
    from ..sim.bus import SimImu, sim_bus
    from ..sim.log import PlayResult, SimLogger
    from ..sim.simulator import Simulation
    from ..walking.loop import start_configuration

    v = variation
    sim = Simulation(robot, v.model_params if v else None, v.servo_params if v else None)
    sim.reset(start_configuration(robot, spec.ref))
    sim.goal_delay = v.latency_s if v else 0.0
    logger = SimLogger(sim)
    if on_tick is not None:
        log_only = logger

        def logger(bus) -> None:
            log_only(bus)
            on_tick(sim)

    rate = loop_rate(spec.ref)  # (closed_loop's deployment rate)
    bus = sim_bus(sim, rate, latency_ticks=v.latency_ticks if v else 0, on_tick=logger)
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
                       servo=spec.servo, step_on_commands=spec.step_on_commands,
                       **cal)  # fmt: skip
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
    played = loop.source.played()  # (the walk off its reference's clock: compared so)
    return PlayResult(result, base.log.arrays(), playback_start - base.t0, sim, played), loop


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
        record["stopped"] = stop_reason(result.deploy)
        return record
    from .play import play

    kw: dict[str, Any] = {"compensate": compensate, "gyro": gyro, "correct": correct}
    if variation is not None:
        kw.update(model_params=variation.model_params, servo_params=variation.servo_params,
                  latency_ticks=variation.latency_ticks, imu_noise=variation.imu_noise,
                  latency_s=variation.latency_s, imu=variation.imu)  # fmt: skip
    result = play(rec, robot, settle=settle, push=push, limit_tol=math.inf, **kw)
    record = physics_record(rec, result, robot)
    record["stopped"] = stop_reason(result.deploy)
    return record


def stop_reason(deploy: DeployResult) -> str | None:
    """Why the deployment stopped before the end of the walk (its trip, else its stop
    action), or ``None`` when it completed."""
    if deploy.completed:
        return None
    return str(deploy.trip) if deploy.trip is not None else str(deploy.stop_action or "stopped")


def closed_loop_figures(loop) -> dict[str, Any]:
    """The closed loop's own figures: goal excursion beyond the joint limits (before the
    deployment's clamp), the estimator + feedback share of the tick, the largest estimated
    torso tilt error."""
    share = loop.source.cost_share()
    controller: Controller = loop.session.controller
    handover = controller.handover
    extra: dict[str, Any] = {}  # (only where a fallback is configured: the stack's)
    if handover is not None and handover.fallback:
        extra["landing_fallbacks"] = handover.fallbacks
    if handover is not None and handover.brace:
        extra["braced_ticks"] = handover.braced
    if controller.relaxes:
        extra["relaxed_solves"] = loop.source.relaxed_ticks
    return extra | {
        "goal_limit_excess_deg": float(np.degrees(max(loop.source.limit_excess, 0.0))),
        "feedback_share": share,
        "estimated_tilt_max_deg": float(np.degrees(loop.stabilizer.max_tilt_error)),
        "failed_solves": loop.source.failed_ticks,  # (walking ticks: held, not solved)
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
    """The share of ``n`` randomised models (seeded) on which the run stays up and walks to
    the end: a run the deployment stopped (e.g. its start-up IMU check refused a rocking
    body) did not walk, so it is not up; it is listed in ``stopped``, a fall in ``falls``."""
    up, falls, stopped = [], [], []
    for k, v in enumerate(models(robot, n, seed)):
        r = simulate(rec, robot, v, settle=settle, compensate=compensate, gyro=gyro,
                     closed=closed, correct=correct)  # fmt: skip
        up.append(not r["fell"] and r["stopped"] is None)
        if r["stopped"] is not None and not r["fell"]:
            stopped.append({"model": k, "reason": r["stopped"], **v.summary})
        if r["fell"]:  # why: when, in which support phase, the most loaded joint
            falls.append({"model": k, "time_s": r["fall_time_s"], "phase": r["fall_phase"],
                          "joint": r["fall_joint"], **v.summary})  # fmt: skip
        if progress:
            progress(k)
    return {"models": n, "seed": seed, "up_fraction": float(np.mean(up)) if up else None,
            "up": [bool(u) for u in up], "falls": falls, "stopped": stopped}  # fmt: skip
