"""Play a recording on the simulated robot through the deployment path, and log the physics.

:func:`play` builds a :class:`~wbc.sim.simulator.Simulation` at the recording's first
configuration, drives it with :class:`~wbc.servos.playback.Deployment` on a
:class:`~wbc.sim.bus.SimServoBus` (soft start, clamping, rate limit, watchdog: the code that
drives the real servos), then holds the last goals for ``settle`` seconds. Every control tick
logs the simulated state (:class:`~wbc.sim.log.SimLog`). It lives above the simulator and
the balance package: it wires the deployment, the simulated servos and the feed-forward
(:mod:`wbc.balance.compliance`, :mod:`wbc.balance.feedback`) together.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..exceptions import ConfigurationError
from ..model import Robot
from ..recording import Recording
from ..servos.config import DeployConfig
from ..servos.playback import Deployment
from ..servos.sources import CallableSource, RecordingSource
from ..sim.actuator import ServoParams
from ..sim.bus import SimServoBus, sim_bus
from ..sim.log import PlayResult, SimLogger
from ..sim.model import ModelParams
from ..sim.simulator import Simulation


def play(
    recording: Recording,
    robot: Robot,
    model_params: ModelParams | None = None,
    servo_params: ServoParams | None = None,
    rate: float | None = None,
    latency_ticks: int = 0,
    settle: float = 1.0,
    realtime: bool = False,
    push: tuple[float, np.ndarray, float] | None = None,
    before: Callable[[SimServoBus], None] | None = None,
    on_tick: Callable[[Simulation], None] | None = None,
    limit_tol: float = 1e-3,
    compensate: float = 0.0,
    correct: bool = False,
    gyro: float = 0.0,
    imu_noise: float = 0.0,
    latency_s: float = 0.0,
    imu: dict | None = None,
) -> PlayResult:
    """Play ``recording`` on a simulated ``robot`` (see the module docstring).

    ``rate`` defaults to the recording's own (capped at the deployment's 100 Hz); ``push`` =
    ``(time after playback start, force N (3,), duration s)``; ``before`` may inject faults
    on the bus; ``on_tick`` sees the simulation after every logged tick (a live viewer);
    ``limit_tol`` (rad): targets further beyond a joint limit are refused, as ``wbc deploy
    --limit-tol`` (``inf``: every target is clamped to the limits by the deployment instead).
    ``compensate`` > 0: goals carry that gain × the servo compliance feed-forward
    (:func:`wbc.balance.compliance.compensated`, nominal servo settings: the AX-12A's, or the
    hobby servo of ``robot.toml`` ``[servo]``); ``correct``: rescaled per joint from the
    servos' present positions (:class:`~wbc.balance.compliance.EncoderCorrection`; refused on
    hobby servos, which report none). ``gyro`` > 0: closed loop, the torso
    gyro's feedback on the leg goals (:class:`wbc.balance.feedback.GyroFeedback`, OP3 gains ×
    ``gyro``; gyro noise ``imu_noise`` rad/s, or ``imu``: :class:`~wbc.sim.bus.SimImu`'s
    keyword arguments). ``latency_s``: the servos act on each goal that much later
    (:attr:`Simulation.goal_delay`).
    """
    sim = Simulation(robot, model_params, servo_params)
    sim.goal_delay = latency_s
    sim.reset(recording.q[0])
    if rate is None:
        rate = (
            min(100.0, 1.0 / float(np.median(np.diff(recording.t)))) if len(recording) > 1 else 50.0
        )
    logger = SimLogger(sim)

    def tick(bus: SimServoBus) -> None:
        logger(bus)
        if on_tick is not None:
            on_tick(sim)

    if correct and sim.hobby:
        raise ConfigurationError(
            f"correct: {robot.name}'s hobby PWM servos report no position to correct from"
        )
    bus = sim_bus(sim, rate, realtime=realtime, latency_ticks=latency_ticks, on_tick=tick)
    if before is not None:
        before(bus)
    source = RecordingSource(recording, robot, tol=limit_tol)
    deployment: list[Deployment] = []
    if compensate > 0:
        from ..balance.compliance import compensated

        source = compensated(source, recording, robot, compensate, correct, lambda: deployment[0])
    if gyro > 0:
        from ..balance.feedback import FeedbackSource, GyroFeedback
        from ..sim.bus import SimImu

        sensor = SimImu(sim, **imu) if imu else SimImu(sim, gyro_noise=imu_noise)
        source = FeedbackSource(source, GyroFeedback(robot, sensor, gyro))
    start = sim.time
    if push is not None and compensate > 0:  # the soft start to the compensated goals takes
        inner = source  # time: the push is timed from the playback's first target instead

        def pushed(tick: int, t: float) -> np.ndarray | None:
            if tick == 0 and t == 0.0:
                sim.push(push[1], push[2], start=sim.time + push[0])
            return inner(tick, t)

        source = CallableSource(pushed, inner.first(), inner.joint_names)
    elif push is not None:
        # the soft start is empty when the robot starts at the first pose (checked below)
        sim.push(push[1], push[2], start=start + push[0])
    config = DeployConfig(rate=rate, read=bus.can_read)
    deployment.append(Deployment(bus, source, robot, config, out=lambda _line: None))
    result = deployment[0].run()
    playback_start = start + result.soft_start_ticks / rate
    if result.completed and settle > 0:
        period = 1.0 / rate
        for _ in range(round(settle * rate)):
            sim.advance(period)
            tick(bus)
    return PlayResult(result, logger.log.arrays(), playback_start - logger.t0, sim)
