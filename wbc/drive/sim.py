"""A driven walk on the simulated robot: a :class:`~wbc.drive.walker.Walker` deployed on
:class:`~wbc.sim.bus.SimServoBus` + :class:`~wbc.sim.bus.SimImu` (the hardware interfaces),
played from a command sequence, measured: did it fall, where did it go.

The record (:func:`drive_sim`, ``wbc drive --sim --json``): ``fell``, ``fall_time_s``,
``commanded_xy_m`` / ``travelled_xy_m`` (the commanded and the simulated base displacement
in the start frame: x forward, y left), ``commanded_yaw_rad`` / ``travelled_yaw_rad``
(heading change, unwrapped), the walk tick's cost, the steps taken; ``_path`` (not JSON:
rows of time, x, y, heading of the base in the start frame).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..geometry import convex_hull, signed_distance, wrap_angle, yaw_of
from ..model import Robot
from ..walking.loop import Controller
from .commands import Command, CommandScript, integrate
from .walker import Walker

FALL_TILT_DEG = 45.0  # as the physics benchmark (wbc.bench.physics)
FALL_HEIGHT = 0.6


class Odometer:
    """The simulated base's displacement in the start frame and its unwrapped heading
    change, and the fall check (tilt > 45° or the base below 60 % of its start height),
    sampled every control tick."""

    def __init__(self, sim: Any) -> None:
        self.sim = sim
        q = sim.q()
        self.xy0 = q[:2].copy()
        self.z0 = float(q[2])
        R = sim.base_rotation()
        self.R0 = R
        self.yaw0 = yaw_of(R)
        self.yaw = 0.0
        self._last = self.yaw0
        self.fell_at: float | None = None
        self.t0 = sim.time
        self.tilt_max = 0.0
        self.path: list[tuple[float, float, float, float]] = []  # t, x, y (start frame), yaw

    def __call__(self) -> None:
        R = self.sim.base_rotation()
        y = yaw_of(R)
        self.yaw += wrap_angle(y - self._last)
        self._last = y
        up = float(np.clip(R[2, 2], -1.0, 1.0))
        tilt = math.degrees(math.acos(up))
        self.tilt_max = max(self.tilt_max, tilt)
        if self.fell_at is None and (
            tilt > FALL_TILT_DEG or self.sim.q()[2] < FALL_HEIGHT * self.z0
        ):
            self.fell_at = self.sim.time - self.t0
        d = self.displacement()
        self.path.append((self.sim.time - self.t0, float(d[0]), float(d[1]), self.yaw))

    def displacement(self) -> np.ndarray:
        d = self.sim.q()[:2] - self.xy0
        c, s = math.cos(self.yaw0), math.sin(self.yaw0)
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def turned(q: np.ndarray, yaw: float) -> np.ndarray:
    """The configuration ``q`` (free flyer first) turned ``yaw`` rad about the world's z
    axis through the origin."""
    if yaw == 0.0:
        return q
    q = np.array(q, dtype=float)
    Rz = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    M = pin.XYZQUATToSE3(q[:7])
    q[:7] = pin.SE3ToXYZQUAT(pin.SE3(Rz, np.zeros(3)) * M)
    return q


def wait_for_compiled_ticks() -> None:
    """Before a lockstep simulated run: compile the package's control ticks if they are not
    in the disk cache, and wait for them, so that every tick of the run solves on the
    compiled tick. Otherwise, on a cold cache, the solvers solve on the interim path (the
    backend cascade: the same QP, answers that differ in the last bits) until the background
    build ends — a wall-clock moment — and a driven walk, which amplifies the last bit into
    centimetres over 30 s, was not repeatable across processes
    (``tests/test_drive_repeat.py``). (Ticks of task types defined outside the package are
    built when first asked for, as before.) A real-time run does not wait."""
    from ..solvers.plan import start_package_ticks, wait_for_package_ticks

    start_package_ticks()
    wait_for_package_ticks()


def make_sim(robot: Robot, variation: Any = None, rate: float = 100.0, realtime: bool = False,
             on_tick: Callable[[], None] | None = None, start_yaw: float = 0.0,
             model_params: Any = None):  # fmt: skip
    """(simulation, bus, imu) for ``robot`` standing in its standing pose (``variation``: a
    :class:`wbc.bench.physics.Variation`, None: nominal; ``model_params``: the nominal
    plant's :class:`~wbc.sim.model.ModelParams` where ``variation`` is None), turned
    ``start_yaw`` rad about the world's vertical (the floor's frame: a plant with a
    direction of its own shows it)."""
    from ..sim.bus import SimImu, sim_bus
    from ..sim.simulator import Simulation

    v = variation
    sim = Simulation(robot, v.model_params if v else model_params, v.servo_params if v else None)
    sim.reset(turned(robot.configuration("stand"), start_yaw))
    sim.goal_delay = v.latency_s if v else 0.0
    bus = sim_bus(sim, rate, realtime=realtime, latency_ticks=v.latency_ticks if v else 0,
                  on_tick=(lambda _bus: on_tick()) if on_tick else None)  # fmt: skip
    # the randomised IMU (bias and noise) as the physics benchmark's closed loop has it
    imu = SimImu(sim, **v.imu) if v and v.imu else SimImu(sim, gyro_noise=v.imu_noise if v else 0.0)
    return sim, bus, imu


def drive_sim(
    robot: Robot,
    controller: Controller,
    commands: Sequence[Command],
    variation: Any = None,
    settle: float = 1.0,
    realtime: bool = False,
    view: Callable[[Any], None] | None = None,
    walker_options: dict[str, Any] | None = None,
    out: Callable[[str], None] = lambda _line: None,
    push: tuple[float, Sequence[float], float] | None = None,
    get_up: bool = False,
    getup_params: Any = None,
    finish: bool = False,
    start_yaw: float = 0.0,
    model_params: Any = None,
) -> dict[str, Any]:
    """Walk ``commands`` on the simulated robot (module docstring); the run's record.
    ``walker_options``: keyword arguments of :class:`Walker` (``limits``, ``window``,
    ``params``, ``gains``, ``closed``, ``compensate``; ``play`` defaults to the randomised
    servos' backlash, the leg odometry reading through it: ``play=0`` the raw encoders).
    ``push``: ``(start s, force N (world xyz), duration s)`` on the base, a scripted
    shove. ``get_up``: after a fall, what ``wbc drive`` does (:func:`after_fall`); the
    record then says ``got_up`` (the get-up completed and :func:`judge` finds the robot
    standing), its
    ``getup_side``, ``getup_phases`` and ``getup_reason``; ``getup_params``: the get-up
    planner's :class:`~wbc.balance.getup.GetupParams`. ``finish``: at the script's end the
    walker finishes the commanded path before it closes (:meth:`Walker.stop`
    ``finish=True``: at most :data:`~wbc.drive.walker.DRIVE_FINISH_STEPS` steps more; off by
    default: on the random sequences of benchmarks/drive.md it closed the plan's lag but not
    the base's error). ``start_yaw``: the robot starts turned that much (rad) in the
    simulator's world (the record stays in the start frame). ``model_params``: the nominal
    plant's (:class:`~wbc.sim.model.ModelParams`, e.g. its contact options) where
    ``variation`` is None."""
    holder: list[Any] = []

    def on_tick() -> None:
        if holder:
            holder[0]()
            if view is not None:
                view(holder[0].sim)

    if not realtime:
        wait_for_compiled_ticks()  # (repeatable: no interim ticks on a cold cache)
    sim, bus, imu = make_sim(robot, variation, realtime=realtime, on_tick=on_tick,
                             start_yaw=start_yaw, model_params=model_params)  # fmt: skip
    if push is not None:
        start, force, duration = push
        sim.push(force, duration, start=sim.time + start)
    options = dict(walker_options or {})
    if variation is not None:  # the odometry knows the simulated servos' play (as measured)
        options.setdefault("play", float(getattr(variation.servo_params, "backlash", 0.0)))
    walker = Walker(robot, controller, imu, **options)
    odo = Odometer(sim)
    holder.append(odo)
    script = CommandScript(commands)
    end = script.duration
    state: dict[str, Any] = {"stopped_at": None, "offset": 0.0}

    def before(t: float) -> None:
        if odo.fell_at is not None:
            walker.close()
            return
        if walker.calibrating:  # the commands start after the IMU's calibration at rest
            state["offset"] = t
            return
        c = script.at(t - state["offset"])
        if c is not None:
            walker.command(*c.velocity)
            if not walker.walking and t - state["offset"] < end:
                walker.start()
        elif state["stopped_at"] is None:
            walker.stop(finish=finish)
            state["stopped_at"] = t
        elif not walker.walking and t > state["stopped_at"] + settle:
            walker.close()

    walker.before_tick = before
    dep = walker.deployment(bus, out=out)
    result = dep.run()
    recovery: dict[str, Any] = {}
    if get_up and odo.fell_at is not None:
        up = after_fall(bus, imu, robot, out, getup_params)
        standing, why = judge(sim, robot)
        recovery = {"got_up": bool(up.completed and standing), "getup_side": up.side,
                    "getup_phases": up.phases, "getup_reason": up.reason or why}  # fmt: skip
    clipped = [Command(c.duration, *walker.limits.clip(*c.velocity)) for c in commands]
    cmd_xy, cmd_yaw = integrate(clipped)
    travelled = odo.displacement()
    ticks = np.asarray(walker.tick_time) * 1e3
    return {
        "fell": odo.fell_at is not None,
        "fall_time_s": odo.fell_at,
        "commanded_xy_m": [float(v) for v in cmd_xy],
        "travelled_xy_m": [float(v) for v in travelled],
        "commanded_yaw_rad": float(cmd_yaw),
        "travelled_yaw_rad": float(odo.yaw),
        "requested_xy_m": [float(v) for v in integrate(commands)[0]],
        "duration_s": end,
        "steps": walker.engine.steps_taken,
        "finish_errors": [[float(v) for v in e] for e in walker.finish.errors],
        "shortened_steps": walker.engine.shortened,
        "failed_solves": walker.failed_solves,
        "failed_solve_causes": dict(walker.failure_causes),
        "tilt_max_deg": odo.tilt_max,
        "walk_tick_ms_p50": float(np.median(ticks)) if ticks.size else None,
        "walk_tick_ms_p99": float(np.percentile(ticks, 99)) if ticks.size else None,
        "deploy_completed": bool(result.completed),
        "deploy_trip": None if result.trip is None else str(result.trip),
        "limits": walker.limits.as_dict(),
        **recovery,
        **(
            {}
            if walker.flat_liftoff is None
            else {
                "lift_offs_held": walker.flat_liftoff.lift_offs_held,
                "lift_off_ticks_held": walker.flat_liftoff.held,
            }
        ),
        **(
            {}
            if walker.flatten is None
            else {"flatten_largest_deg": math.degrees(walker.flatten.largest)}
        ),
        "_path": np.asarray(odo.path),
    }


def judge(sim: Any, robot: Robot, tilt_deg: float = 10.0) -> tuple[bool, str]:
    """Standing? The torso within ``tilt_deg`` of its attitude in the robot's standing pose
    (the Bioloid's Walk Ready leans its torso 10° forward over flat feet; that is upright
    here), both soles flat on the floor (within 5 mm and 10°), the CoM above the soles'
    hull. The tilt is the angle between the torso's z axis and the standing pose's, turned
    to the left sole's heading; the line also gives the torso's tilt from the vertical."""
    R = sim.site_pose("torso").rotation
    vertical = math.degrees(math.acos(float(np.clip(R[2, 2], -1.0, 1.0))))
    stand = robot.place_on_ground(robot.configuration(robot.stand_pose), "l_sole")
    sole0 = robot.frame_placement(stand, "l_sole").rotation
    z_stand = sole0.T @ robot.frame_placement(stand, "torso").rotation[:, 2]  # in the sole
    Rs = sim.site_pose("l_sole").rotation
    yaw = yaw_of(Rs)
    z_want = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ z_stand
    tilt = math.degrees(math.acos(float(np.clip(R[:, 2] @ z_want, -1.0, 1.0))))
    if tilt > tilt_deg:
        return False, f"torso {tilt:.0f} deg from standing ({vertical:.0f} deg from vertical)"
    half_l, half_w = (0.5 * v for v in robot.foot_size)
    corners = []
    for s in ("l_sole", "r_sole"):
        M = sim.site_pose(s)
        up = math.degrees(math.acos(float(np.clip(M.rotation[2, 2], -1.0, 1.0))))
        if M.translation[2] > 0.005 or up > 10.0:
            return (
                False,
                f"{s} not flat on the floor (z {1e3 * M.translation[2]:.0f} mm, {up:.0f} deg)",
            )
        for dx in (-half_l, half_l):
            for dy in (-half_w, half_w):
                corners.append(M.act(np.array([dx, dy, 0.0]))[:2])
    hull = convex_hull(np.asarray(corners))
    margin = float(signed_distance(hull, sim.com()[:2]))
    if margin < 0:
        return False, f"CoM {1e3 * -margin:.0f} mm outside the feet"
    return True, (
        f"up: torso {tilt:.1f} deg from standing ({vertical:.1f} from vertical), CoM "
        f"{1e3 * margin:.0f} mm inside the feet"
    )


def after_fall(
    bus: Any, imu: Any, robot: Robot, out: Callable[[str], None] = print, params: Any = None
) -> Any:
    """What ``wbc drive`` does after a fall: wait :data:`~wbc.balance.getup_play.
    GETUP_WAIT_S` (the last bounces), then :func:`~wbc.balance.getup_play.get_up` on the
    same bus and IMU (its :class:`~wbc.balance.getup_play.GetupResult`; ``params``: the
    planner's :class:`~wbc.balance.getup.GetupParams`, default its defaults)."""
    from ..balance.getup_play import GETUP_WAIT_S, get_up

    return get_up(bus, imu, robot, wait_s=GETUP_WAIT_S, out=out, params=params)
