"""The torso feedback's gains sized to the robot's servos: the same gain margin as the design.

:class:`~wbc.balance.stabilizer.Gains` were tuned on the design robot's servos (AX-12A: stiff
enough, heavily damped by their back-EMF and rotor, a 1 ms internal loop). The torso term
(``k_p e + k_i ∫e + k_d ω`` on the torso target, :mod:`wbc.balance.stabilizer`) closes a loop
through the servos that turn the upper body: a command reaches the body after the tick and the
servo's own hold, and a lightly damped servo answers with a resonance. Modelled linearly, per
frequency ω (s = jω)::

    L(s) = C(s) · P(s),   C = k_p + k_i / s + k_d s,
    P(s) = k / (I s² + b s + k) · exp(−s T)

with ``I`` the upper body's moment of inertia about the stance hip's roll axis at the standing
pose (everything but the legs; plus the servo's reflected rotor inertia), ``k`` the servo's
small-error stiffness and ``b`` its back-EMF damping (the robot's servo model,
:func:`wbc.sim.actuator.nominal_servo`), and ``T`` the delay: one control tick (the goal
computed from the last sample and held) plus, on a servo that takes its goal as PWM pulses,
half a pulse frame (the pulse waits for the board's next frame) and half its drive update
period (an analog servo holds its drive between pulses). The **gain margin** is the factor the
whole of ``C`` could grow before ``|L| = 1`` where L's phase crosses −180°.

:func:`torso_gains` scales the torso term's three gains by one factor when the robot's
margin — on its nominal servo and on the randomised models' least damped servo
(:data:`SPREAD`) — is below :data:`TOLERANCE` of the design robot's (:data:`DESIGN_PLANT`, the
Bioloid's AX-12A, at the same tick), to the design's margin; never up. Measured on Kokone
(BMS-380MAX hobby servos: 4× less damped than the AX-12A, a 20 ms analog drive hold;
benchmarks/kokone_sim.md section 0000): the model puts the proportional gain's edge at
0.31–0.35 (the simulator: 0.3 stands, 0.5 falls on keyposes) and the rate gain's at
0.016–0.026 s (the simulator: 0.005 stands, 0.01 falls at a 20 ms tick), against 2.7 and
0.33 s on the Bioloid; the factor is 0.025–0.04 there, 1 on the Bioloid and the OP3.

The hip strategy (``k_hip``, rad of torso roll per m of DCM beyond its band) closes a loop
through the same plant — the torso target rolled, the stance hip roll servo turning the upper
body, the IMU and the kinematics reading the motion back as DCM — so the one factor scales it
too (its ``max_hip``, a geometric bound, stays). Measured on Kokone's ``lateral_wb``, the only
walk on which it fires (benchmarks/kokone_sim.md section 00000): at the design's 100 rad/m it
fired on an estimated DCM 28 mm off the simulated one after a support switch, its own roll
read back swung the estimate by ±90 mm within 60 ms, it sat at ``max_hip`` (34°) and the robot
rolled over after it (the hip roll at stall); scaled (2.5 rad/m) the walk stands, ×2 too, ×4
at 29°.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from ..exceptions import WbcError
from ..model import Robot
from ..roles import joint_axis
from .gains import default_gains
from .stabilizer import Gains


@dataclass(frozen=True)
class TorsoPlant:
    """The linear model of how the torso answers a commanded rotation (module docstring)."""

    inertia: float  # kg·m², upper body about the stance hip's roll axis (+ reflected rotor)
    stiffness: float  # N·m/rad
    damping: float  # N·m·s/rad
    delay: float  # s

    @property
    def damping_ratio(self) -> float:
        """ζ = b / (2 √(k I))."""
        return self.damping / (2.0 * math.sqrt(self.stiffness * self.inertia))


#: the design robot's torso plant (the Bioloid's AX-12A and body: :func:`torso_plant` of it,
#: without the tick, which :func:`gain_margin` adds the same way on both), on which
#: :class:`Gains` were tuned
DESIGN_PLANT = TorsoPlant(0.018697874576515307, 9.15837225654425, 0.2427787267503488, 0.0)
#: a robot whose margin is at least this share of the design's at the same tick keeps the
#: gains: the defaults were halved from gains that tipped plants with latency (k_p 2, k_i 2,
#: k_d 0.1: half the margin), so half the design's margin is where they were seen to fail
TOLERANCE = 0.5
#: the servos' spread the margin must cover: stiffness x2 and back-EMF damping x0.5, the
#: least damped corner of the randomised models' servo draws (wbc.bench.variation: stiffness
#: x0.5-2, damping x0.5-1.5); a lightly damped servo's resonance there is what the rate term
#: (k_d) rings first (benchmarks/kokone_sim.md section 0000)
SPREAD = (2.0, 0.5)


def torso_plant(robot: Robot) -> TorsoPlant | None:
    """The torso's plant on ``robot``'s nominal servo model (module docstring; ``delay``: the
    servo's own, the tick added by :func:`gain_margin`); None without a servo model."""
    from ..sim.actuator import HobbyServoParams, nominal_servo, pwm_map

    try:
        params = nominal_servo(robot)
    except WbcError:
        return None
    model, roles = robot.model, robot.roles
    hip = model.getJointId(roles.joint("left", "hip_roll"))
    legs = set()
    for side in ("left", "right"):
        for name in roles.leg(side):
            legs.update(model.subtrees[model.getJointId(name)])
    data = model.createData()
    pin.forwardKinematics(model, data, robot.configuration("stand"))
    axis = data.oMi[hip].rotation @ joint_axis(model, hip, "torso_plant")
    axis = axis / np.linalg.norm(axis)
    point = data.oMi[hip].translation
    inertia = 0.0
    for j in range(1, model.njoints):
        if j in legs:
            continue
        body = model.inertias[j]
        R, p = data.oMi[j].rotation, data.oMi[j].translation
        c = p + R @ body.lever - point
        c_perp = c - (c @ axis) * axis
        inertia += float(axis @ R @ body.inertia @ R.T @ axis) + body.mass * float(c_perp @ c_perp)
    i = robot.joint_names.index(model.names[hip])
    if isinstance(params, HobbyServoParams):
        channel = next(c for c in pwm_map(robot).channels if c.joint == model.names[hip])
        k = float(params.stiffness(math.degrees(channel.us_per_deg)))
        hold = 0.5 * params.frame_period + 0.5 * params.period
    else:
        k = float(np.asarray(params.stiffness).reshape(-1)[i] if np.ndim(params.stiffness) else
                  params.stiffness)  # fmt: skip
        hold = 0.0
    return TorsoPlant(inertia + params.armature, k, float(params.damping), hold)


def gain_margin(gains: Gains, plant: TorsoPlant, dt: float) -> float:
    """The factor the torso term ``C = k_p + k_i/s + k_d s`` of ``gains`` could grow on
    ``plant`` before the loop oscillates (module docstring), over frequencies up to the
    tick's Nyquist frequency π / ``dt``, the delay the plant's and one tick; inf if the
    phase never crosses −180°."""
    w = np.logspace(-2.0, math.log10(math.pi / dt), 6000)
    s = 1j * w
    P = plant.stiffness / (plant.inertia * s**2 + plant.damping * s + plant.stiffness)
    L = (gains.k_p + gains.k_i / s + gains.k_d * s) * P * np.exp(-s * (plant.delay + dt))
    phase = np.unwrap(np.angle(L))
    cross = np.nonzero(np.diff(np.sign(phase + math.pi)))[0]
    if cross.size == 0:
        return math.inf
    return float(1.0 / np.abs(L[cross[0]]))


def torso_gains(gains: Gains, robot: Robot, dt: float) -> tuple[Gains, float]:
    """``gains`` for ``robot`` at a ``dt`` s tick, and the factor applied: when the torso
    term's gain margin on its servos (:func:`gain_margin`; the smaller of the nominal servo's
    and of the :data:`SPREAD` corner's, each over the design's on the same plant change, the
    same tick) is below :data:`TOLERANCE` of the design's (:data:`DESIGN_PLANT`), k_p, k_i,
    k_d and the hip strategy's k_hip (a loop through the same plant: module docstring) scaled
    by one factor to the design's margin; else (and without a servo model) unchanged,
    factor 1."""
    plant = torso_plant(robot)
    if plant is None:
        return gains, 1.0
    ratio = min(
        gain_margin(gains, _spread(plant, c), dt) / gain_margin(gains, _spread(DESIGN_PLANT, c), dt)
        for c in (False, True)
    )
    if ratio >= TOLERANCE:
        return gains, 1.0
    return replace(gains, k_p=gains.k_p * ratio, k_i=gains.k_i * ratio, k_d=gains.k_d * ratio,
                   k_hip=gains.k_hip * ratio), ratio  # fmt: skip


def _spread(plant: TorsoPlant, corner: bool) -> TorsoPlant:
    """``plant`` (``corner`` False) or its servo at the :data:`SPREAD` corner."""
    if not corner:
        return plant
    stiff, damp = SPREAD
    return replace(plant, stiffness=plant.stiffness * stiff, damping=plant.damping * damp)


def default_sized_gains(robot: Robot, compensate: float, dt: float) -> tuple[Gains, float]:
    """The closed loop's default gains on ``robot`` at a ``dt`` s tick, and the factor
    applied: :func:`~wbc.balance.gains.default_gains` for the feed-forward gain
    ``compensate``, sized to its servos by :func:`torso_gains` (the one definition
    :func:`wbc.balance.live.closed_loop` uses when given no gains, and the push benchmarks'
    base: the design robot's gains as they are tip Kokone over unpushed,
    benchmarks/pushes.md)."""
    return torso_gains(default_gains(compensate), robot, dt)
