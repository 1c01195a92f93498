"""A simulated robot on MuJoCo, behind the same servo and IMU interfaces as the hardware.

* :mod:`wbc.sim.model` — the MuJoCo model built from any robot folder's URDF at run time;
* :mod:`wbc.sim.actuator` — the servo laws, chosen by the robot's data: the AX-12A
  (compliance, punch, torque limit, speed cap) or a hobby PWM servo behind an SSC-32;
* :mod:`wbc.sim.simulator` — :class:`Simulation`: physics stepping, goals, faults, state;
* :mod:`wbc.sim.bus` — :class:`SimServoBus` and :class:`SimSsc32Bus`, the
  :class:`~wbc.servos.bus.ServoBus` that ``wbc deploy --sim`` drives, and :class:`SimImu`
  (:class:`wbc.imu.Imu`).
* :mod:`wbc.sim.log` — the state logged every control tick of a simulated run;
* :mod:`wbc.sim.watch` — the fall thresholds, and :class:`~wbc.sim.watch.UprightWatch`.

A recording played through the deployment path on it: :func:`wbc.bench.play.play`.

Needs the optional ``mujoco`` package (``pip install 'wbc[physics]'``).
"""

from __future__ import annotations

from ..exceptions import ConfigurationError


def mujoco_module():
    """The ``mujoco`` module, or one clear line saying how to install it."""
    try:
        import mujoco
    except ModuleNotFoundError as exc:
        raise ConfigurationError(
            "wbc.sim needs the optional package 'mujoco': pip install 'wbc[physics]'"
        ) from exc
    return mujoco
