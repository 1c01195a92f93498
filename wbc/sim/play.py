"""Play a recording on the simulated robot through the deployment path, and log the physics.

:func:`play` builds a :class:`~wbc.sim.simulator.Simulation` at the recording's first
configuration, drives it with :class:`~wbc.servos.playback.Deployment` on a
:class:`~wbc.sim.bus.SimServoBus` (soft start, clamping, rate limit, watchdog: the code that
drives the real servos), then holds the last goals for ``settle`` seconds. Every control tick
logs the simulated state (:class:`SimLog`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigurationError
from ..geometry import convex_hull, signed_distance
from ..model import Robot
from ..recording import Recording
from ..servos.config import DeployConfig
from ..servos.playback import Deployment, DeployResult
from ..servos.sources import CallableSource, RecordingSource
from .actuator import ServoParams
from .bus import SimServoBus, sim_bus
from .model import ModelParams
from .simulator import Simulation


@dataclass
class SimLog:
    """Per control tick: time (s, simulation clock, 0 = first tick), configuration (wbc
    convention), CoM, CoP (NaN in the air), normal force under each sole, joint goals (rad),
    peak |torque| per joint over the tick (N·m), and which ticks belong to the playback."""

    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    com: list[np.ndarray] = field(default_factory=list)
    cop: list[np.ndarray] = field(default_factory=list)
    sole_force: list[np.ndarray] = field(default_factory=list)
    soles: list[np.ndarray] = field(default_factory=list)  # (2, 3) l, r sole positions
    goal: list[np.ndarray] = field(default_factory=list)
    peak_torque: list[np.ndarray] = field(default_factory=list)
    cop_margin: list[float] = field(default_factory=list)  # m, to the contact points' hull

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


@dataclass
class PlayResult:
    """The deployment's result, the simulation log and the playback start time (s)."""

    deploy: DeployResult
    log: dict[str, np.ndarray]
    playback_start: float
    sim: Simulation


def hull_margin(points: np.ndarray, p: np.ndarray) -> float:
    """Signed distance (m) from ``p`` to the edge of the convex hull of ``points`` (positive
    inside; 0 when the hull is a point or a segment: a foot resting on an edge tips):
    :func:`wbc.geometry.signed_distance` of :func:`wbc.geometry.convex_hull`."""
    pts = np.asarray(points, dtype=float)
    hull = convex_hull(pts[:, :2]) if len(pts) else pts
    if len(hull) < 3:
        return 0.0
    return float(signed_distance(hull, np.asarray(p, dtype=float)[:2]))


class SimLogger:
    """Logs the simulated state into a :class:`SimLog`, called once per control tick (the
    bus's ``on_tick``); :attr:`t0` is the simulation clock at its start."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.log = SimLog()
        self.t0 = sim.time
        m = sim.model
        mj = sim.mj
        self.feet = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, b) for b in sim.robot_feet()]

    def __call__(self, bus: SimServoBus | None = None) -> None:
        sim, log = self.sim, self.log
        log.t.append(sim.time - self.t0)
        log.q.append(sim.q())
        log.com.append(sim.com())
        pts, fz, body = sim.contacts()
        total = fz.sum()
        cop = (pts[:, :2] * fz[:, None]).sum(axis=0) / total if total > 1e-9 else np.full(2, np.nan)
        log.cop.append(cop)
        log.cop_margin.append(hull_margin(pts[fz > 1e-9, :2], cop) if total > 1e-9 else np.nan)
        log.sole_force.append(np.array([fz[body == b].sum() for b in self.feet]))
        log.soles.append(
            np.array([sim.site_pose("l_sole").translation, sim.site_pose("r_sole").translation])
        )
        log.goal.append(sim.servos.goal_angles())
        log.peak_torque.append(sim.reset_peak())


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
        from .bus import SimImu

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
