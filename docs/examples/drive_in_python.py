"""Drive the robot from Python: velocity commands to a Walker, played on a ServoBus + Imu.

A :class:`wbc.drive.walker.Walker` plans the footsteps online from the command in force
(``command(vx, vy, wz)``: m/s forward, m/s left, rad/s), re-plans the CoM over a receding
horizon, closes the loop through the servos' present positions and the torso IMU, and solves
any walking controller once per tick. It is a target source: ``walker.deployment(bus)`` plays
it with the safety layer of ``wbc deploy``. Here the bus and the IMU are the MuJoCo-simulated
Bioloid's (the same interfaces as the hardware: :class:`~wbc.servos.dynamixel.DynamixelBus`
and :class:`~wbc.imu_witmotion.WitImu` on a real robot).

``walker.before_tick`` runs before every tick with the playback time: a script, a keyboard
or your own code steers from there (or call ``walker.command`` from another thread).

Run: ``python docs/examples/drive_in_python.py`` (the first run measures the robot's
velocity limits and balance window on the model and caches them).
"""

from __future__ import annotations

import math

from wbc import load_robot
from wbc.drive.sim import Odometer
from wbc.drive.walker import Walker, default_compensate
from wbc.sim.bus import SimImu, SimServoBus
from wbc.sim.simulator import Simulation
from wbc.stacks import load_stack
from wbc.walking.loop import StackController

robot = load_robot("bioloid")
sim = Simulation(robot)  # standing in its standing pose
odometer = Odometer(sim)  # where the simulated base goes (start frame)
bus = SimServoBus(sim, on_tick=lambda _bus: odometer())
# the AX-12A compliance feed-forward, rescaled per servo from the encoders (correct=True)
walker = Walker(robot, StackController(load_stack("walk", robot)), imu=SimImu(sim),
                compensate=default_compensate(robot))  # fmt: skip
lim = walker.limits
print(f"velocity limits: forward {100 * lim.vx_forward:.1f} cm/s, sideways "
      f"{100 * lim.vy:.1f} cm/s, turning {math.degrees(lim.wz):.0f} deg/s")  # fmt: skip


def steer(t: float) -> None:
    """The script: forward, then forward and turning left, then stop and stand."""
    if t < 2.0:
        walker.command(0.05, 0.0, 0.0)
        walker.start()
    elif t < 4.0:
        walker.command(0.03, 0.0, 0.3)
    elif t < 4.1:
        walker.stop()
    elif not walker.walking and t > 5.5:
        walker.close()  # the run ends: the deployment holds the last goals


walker.before_tick = steer
result = walker.deployment(bus, out=lambda _line: None).run()
x, y = odometer.displacement()
print(f"completed: {result.completed}; fell: {odometer.fell_at is not None}; "
      f"{walker.engine.steps_taken} steps; the base moved x {100 * x:.1f} cm, y {100 * y:.1f} "
      f"cm and turned {math.degrees(odometer.yaw):.0f} deg")  # fmt: skip
