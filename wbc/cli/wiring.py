"""What several commands wire the same way: the servo bus of the parsed options (a real one,
or the simulated robot with ``--sim``), the closed loop's torso IMU, a meshcat view paced to
the wall clock."""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from ..exceptions import ConfigurationError
from ..model import Robot
from ..servos.bus import ServoBus
from ..servos.connect import make_bus as make_servo_bus
from .options import bus_options


def make_bus(args: argparse.Namespace, robot: Robot, port: str | None) -> ServoBus:
    """The bus of the parsed options (not opened): the simulated robot with ``--sim``, else
    the backend named by ``--backend`` (:func:`wbc.servos.connect.make_bus`)."""
    if getattr(args, "sim", False):
        return make_sim_bus(args, robot)
    return make_servo_bus(robot, port, bus_options(args))


def make_sim_bus(args: argparse.Namespace, robot: Robot) -> ServoBus:
    """The simulated bus for ``wbc deploy --sim`` (robot standing in its standing pose):
    the AX-12A bus, or with ``--bus ssc32`` the SSC-32 backend on a simulated board (hobby
    servos: the robot's ``robot.toml`` ``[servo]``)."""
    from ..sim.bus import sim_bus
    from ..sim.simulator import Simulation
    from ..sim.watch import UprightWatch

    sim = Simulation(robot)
    backend = getattr(args, "backend", "dynamixel")
    want = "ssc32" if sim.hobby else "dynamixel"
    if backend != want:
        servo = sim.servo_params.name if sim.hobby else "AX-12A"
        raise ConfigurationError(
            f"--sim: robot {robot.name}'s servos are {servo} ({want} bus): use --bus {want}"
        )
    watch = UprightWatch(sim)
    view = live_view(robot) if getattr(args, "view", False) else None

    def on_tick(bus) -> None:
        watch()
        if view is not None:
            view(sim)

    torque_limit = getattr(args, "torque_limit", None)
    torque_limit = None if torque_limit == 1023 else torque_limit
    return sim_bus(
        sim, args.rate, realtime=args.realtime, torque_limit=torque_limit, on_tick=on_tick,
        on_close=lambda: print(watch.line(), flush=True),
    )  # fmt: skip


def make_imu(args: argparse.Namespace, bus: ServoBus, robot: Robot | None = None, out=print):
    """The torso IMU of the closed loop: the simulated one (--sim), a WitMotion on --imu
    PORT (mounted as ``robot``'s ``robot.toml`` ``[imu]`` says), or None: --encoders-only,
    or no IMU given (said through ``out``)."""
    if args.encoders_only:
        if args.imu:
            raise ConfigurationError("give either --imu PORT or --encoders-only, not both")
        return None
    if args.imu:
        from ..imu_witmotion import WitImu

        mount = None
        if robot is not None:
            from ..sim.model import imu_mount

            mount = imu_mount(robot)
        return WitImu(args.imu, args.imu_baud, mount=mount)
    if getattr(bus, "sim", None) is not None:
        from ..sim.bus import SimImu

        return SimImu(bus.sim)
    out(
        "closed loop: no IMU given (--imu PORT): estimating from the servos' encoders alone "
        "(the stance sole assumed flat; --encoders-only says so without this note)"
    )
    return None


class Pacer:
    """Sleep so that simulated time does not run ahead of the wall clock (lockstep physics,
    shown at real speed: a slow draw never changes what the physics does)."""

    def __init__(self) -> None:
        self.start: tuple[float, float] | None = None

    def __call__(self, sim_time: float) -> None:
        now = time.perf_counter()
        if self.start is None:
            self.start = (now, sim_time)
        ahead = (sim_time - self.start[1]) - (now - self.start[0])
        if ahead > 0:
            time.sleep(ahead)


def live_view(robot: Robot) -> Callable[[Any], None]:
    """A meshcat view following a simulation (call it with the
    :class:`~wbc.sim.simulator.Simulation` once per control tick), paced to the wall clock."""
    from ..viewer import Viewer

    viewer = Viewer(robot)
    print(f"meshcat: {viewer.url}", flush=True)
    pace = Pacer()

    def update(sim) -> None:
        viewer.update(sim.q())  # the deployment plays joints only: no planned CoM here
        pace(sim.time)

    return update
