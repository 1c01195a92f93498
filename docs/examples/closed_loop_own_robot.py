"""Closed-loop walking on YOUR robot or simulator: bring a ServoBus and an Imu, wbc does the rest.

``wbc.balance.live.closed_loop`` runs a walking controller live inside the deployment's tick
(soft start, clamping to the joint limits, rate limit, watchdog, safe stop) and closes the loop
through two interfaces you implement:

* a :class:`wbc.servos.bus.ServoBus` — write goal commands, read present positions (the
  encoders; the state estimator needs them every tick);
* a :class:`wbc.imu.Imu` — ``read()`` returns an :class:`wbc.imu.ImuReading` of the torso IMU
  (orientation quaternion x, y, z, w; gyro rad/s and specific force m/s² in the IMU frame).

Here both come from a toy simulator (servos that follow their goals with a first-order lag, a
torso that leans with the servos' sag): replace ``ToySimulator`` by your physics engine or your
hardware. A lockstep simulator also gives the bus a ``clock`` (``now()``, ``sleep(dt)`` runs
the physics), so the run goes as fast as the computer allows. The MuJoCo model that ships with
wbc is wired the same way::

    from wbc.sim import Simulation, SimServoBus, SimImu
    sim = Simulation(robot)
    loop = closed_loop(SimServoBus(sim), robot, controller, ref, imu=SimImu(sim))

Run: ``python docs/examples/closed_loop_own_robot.py`` (the first 2 s of the walk, open and
closed loop: the closed loop's figures).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from wbc import load_robot
from wbc.balance.live import closed_loop
from wbc.balance.stabilizer import Gains
from wbc.bench.trajectories import build
from wbc.imu import GRAVITY, Imu, ImuReading
from wbc.servos.bus import COMM_OK, BusBudget, ServoBus, ServoStatus
from wbc.servos.protocol1 import ax_codec
from wbc.stacks import load_stack
from wbc.walking.loop import StackController, start_configuration


class ToySimulator:
    """A stand-in for your simulator: joints lag their goals (time constant ``tau``) and the
    whole body leans about the left sole by ``sag`` rad per rad of the legs' mean lag."""

    def __init__(self, robot, q0: np.ndarray, tau: float = 0.03, sag: float = 0.3) -> None:
        self.robot, self.q = robot, q0.copy()
        self.goal = q0[7:].copy()
        self.tau, self.sag, self.time = tau, sag, 0.0
        self.rate = np.zeros(3)

    def step(self, dt: float) -> None:
        joints = self.q[7:]
        lag = self.goal - joints
        joints += lag * (1.0 - np.exp(-dt / self.tau))
        lean = self.sag * float(np.mean(lag[:12]))  # the legs' lag tips the body (roll)
        before = self.torso()
        q = self.robot.place_on_ground(self.q, "l_sole")
        pivot = self.robot.frame_placement(q, "l_sole").translation
        R = pin.exp3(np.array([lean, 0.0, 0.0]))  # about the sole's origin
        tilt = pin.SE3(R, pivot - R @ pivot)
        self.q[:7] = pin.SE3ToXYZQUAT(tilt * pin.XYZQUATToSE3(q[:7]))
        self.rate = pin.log3(before.T @ self.torso()) / dt
        self.time += dt

    def torso(self) -> np.ndarray:
        return pin.XYZQUATToSE3(self.q[:7]).rotation  # the base is the torso


class ToyClock:
    """Lockstep time: the deployment's scheduler sleeps by running the simulator."""

    def __init__(self, sim: ToySimulator) -> None:
        self.sim = sim

    def now(self) -> float:
        return self.sim.time

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.sim.step(seconds)


class ToyBus(ServoBus):
    """Your servos: integer goal commands in, present positions out (model joint order)."""

    name = "toy"
    can_read = True
    servo_speed = 6.0  # rad/s

    def __init__(self, sim: ToySimulator) -> None:
        robot = sim.robot
        super().__init__(ax_codec(robot.servo_map), list(robot.joint_names))
        self.sim = sim
        self.clock = ToyClock(sim)

    def open(self) -> None: ...
    def close(self) -> None: ...
    def identify(self) -> None: ...
    def configure(self) -> None: ...
    def set_torque(self, enabled: bool) -> None: ...
    def set_speed(self, rad_per_s: float) -> None: ...

    def write_goals(self, cmds: np.ndarray) -> str:
        self.sim.goal = self.codec.decode(self.check_goals(cmds))
        return COMM_OK

    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        present = self.codec.encode_float(self.sim.q[7:])
        return [ServoStatus(i, position=float(present[i])) for i in (indices or range(self.n))]

    def poll(self, index: int) -> ServoStatus:
        return self.read_positions([index])[0]

    def budget(self, read_positions: bool) -> BusBudget:
        return BusBudget("toy", 1_000_000, ())


class ToyImu(Imu):
    """Your torso IMU: orientation, gyro rate, specific force (at rest: +g up)."""

    name = "toy-imu"

    def __init__(self, sim: ToySimulator) -> None:
        self.sim = sim

    def read(self) -> ImuReading:
        R = self.sim.torso()
        quat = pin.Quaternion(R).coeffs()  # x, y, z, w
        return ImuReading(self.sim.time, quat, self.sim.rate, R.T @ np.array([0, 0, GRAVITY]))


def main(duration: float | None = None, closed: bool = True) -> dict:
    """Walk ``walk10`` (or its first ``duration`` s) on the toy robot; returns the figures."""
    robot = load_robot("bioloid")
    ref = build("walk10", robot)
    sim = ToySimulator(robot, start_configuration(robot, ref))
    controller = StackController(load_stack("walk", robot))
    loop = closed_loop(
        ToyBus(sim), robot, controller, ref, imu=ToyImu(sim), gains=Gains(), enabled=closed,
        out=lambda line: None, duration=duration,
    )  # fmt: skip
    result = loop.deployment.run()
    return {
        "completed": result.completed,
        "ticks": result.timing.ticks,
        "feedback_share": loop.source.cost_share(),
        "estimated_tilt_max_deg": float(np.degrees(loop.stabilizer.max_tilt_error)),
        "goal_limit_excess_rad": loop.source.limit_excess,
    }


if __name__ == "__main__":
    for closed in (False, True):
        print("closed loop" if closed else "open loop", main(duration=2.0, closed=closed))
