"""Randomised plants for the physics benchmark's robustness sweep (``wbc bench --physics
--robustness N --seed S``): :func:`random_model` draws one from :data:`PLANT_RANGES`,
:func:`models` N of them, seeded; :func:`wbc.bench.closed_loop.simulate` plays a run on one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from ..model import Robot

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
    """One randomised plant: what :func:`wbc.bench.play.play` needs, plus its description.

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
        """The plant as :func:`wbc.bench.play.play`'s keyword arguments (every randomised part:
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
