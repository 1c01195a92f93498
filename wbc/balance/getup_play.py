"""Playing a get-up (:mod:`wbc.balance.getup`) in the closed loop, on any ``ServoBus`` + ``Imu``.

:func:`get_up` reads which side the robot lies on from the IMU (the torso's orientation:
:func:`~wbc.balance.getup.lying_side`), plans the first phase from the measured state
(:func:`~wbc.balance.getup.lying_state`: the servos' positions, the IMU's orientation, the
base put on the floor) and plays it through the deployment's safety layer
(:class:`~wbc.servos.playback.Deployment`: soft start, clamping to the joint limits, rate limit
at the servos' speed, watchdog, safe stop). Each later phase is planned when it starts, from
the state the previous one left: the measured joints and torso orientation, the base placed
where the phase's contacts were planned (:func:`placed`). It ends in the standing pose.

In the simulator: :mod:`wbc.drive.getup_sim` (a robot dropped on its front or back, got up
and judged).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, WbcError
from ..model import Kinematics, Robot
from .getup import (
    GetupParams,
    PhasePlan,
    PhasePlanner,
    ground_frame,
    lying_side,
    lying_state,
    phases_for,
    static_torques,
)

#: s a get-up waits after a fall (its last bounces) in ``wbc drive``
GETUP_WAIT_S = 1.0
#: why a robot on its back is left lying when the get-up from the back is off
SUPINE_NOTE = "lying on the back: the get-up from the back is off (supine=False)"


def placed(
    robot: Robot, joints: np.ndarray, torso_rotation: np.ndarray, anchors: dict[str, np.ndarray]
) -> np.ndarray:
    """The configuration with the measured ``joints`` and torso orientation whose base puts
    the ``anchors``' frames (frame -> planned world position) best where they were planned
    (least squares: the mean offset)."""
    q = lying_state(robot, joints, torso_rotation)
    if anchors:
        kin = Kinematics(robot, q)
        offset = np.mean(
            [p - kin.translation(robot.frame_id(f)) for f, p in anchors.items()], axis=0
        )
        q[:3] += offset
    return q


def torso_rotation(imu: Any, robot: Robot) -> np.ndarray:
    """The torso's world rotation from one IMU reading (the robot's IMU mount applied)."""
    from ..sim.model import imu_mount

    reading = imu.read()
    x, y, z, w = (float(v) for v in reading.orientation)
    R = pin.Quaternion(w, x, y, z).toRotationMatrix()
    mount = imu_mount(robot)
    return R if mount is None else R @ mount.rotation.T


@dataclass
class GetupResult:
    """What :func:`get_up` did: the side, the phases played, the deployment's result."""

    side: str | None
    phases: list[str]
    completed: bool
    plan_failures: int
    deploy: Any = None
    reason: str = ""
    #: per phase played, the torso's elevation (deg: its z axis above the horizontal, 90 =
    #: upright) in the state the phase was planned from (the measured one, closed loop)
    trunk_deg: list[float] = field(default_factory=list)


def get_up(
    bus: Any,
    imu: Any,
    robot: Robot,
    joints: np.ndarray | None = None,
    params: GetupParams | None = None,
    rate: float = 50.0,
    out: Callable[[str], None] = print,
    supine: bool = True,
    wait_s: float = 0.0,
    replan: bool = True,
    compensate: float = 1.0,
    stiffen: bool = True,
) -> GetupResult:
    """Get the robot up from where it lies (module docstring). ``joints``: the present joint
    angles (rad, model order; default: read from ``bus``); ``wait_s``: s to wait first (the
    fall's last bounces). ``replan=False``: each phase planned from the planned end of the
    previous one (open loop: the benchmark's comparison). ``compensate``: the gain of the
    servo compliance feed-forward on the planned goals (each joint pre-loaded by its
    deflection under the phase's static load, :func:`~wbc.balance.getup.static_torques` and
    :mod:`wbc.balance.compliance`; 0: off; off, with a line saying so, on servos it has no
    model of).
    ``stiffen``: the phases' servo stiffness (:attr:`~wbc.balance.getup.Phase.stiffness`,
    written by the deployment through :meth:`~wbc.servos.bus.ServoBus.set_stiffness`;
    False: every phase at the configured stiffness).
    ``supine=False``: a robot on its back is left lying (the result says so)."""
    from ..servos.bus import WALL_CLOCK
    from ..servos.playback import DeployConfig, Deployment
    from ..servos.sources import CallableSource

    if wait_s > 0:  # the fall's last bounces
        (bus.clock or WALL_CLOCK).sleep(wait_s)
    if joints is None:
        bus.open()
        try:
            statuses = bus.read_positions()
        finally:
            bus.close()
        if any(s.position is None for s in statuses):
            raise ConfigurationError("get-up: a servo did not report its position")
        joints = bus.codec.decode(np.array([s.position for s in statuses], dtype=float))
    joints = np.asarray(joints, dtype=float)
    R = torso_rotation(imu, robot)
    side = lying_side(R)
    if side is None:
        return GetupResult(None, [], False, 0, reason="not lying on the front or the back")
    if side == "supine" and not supine:
        return GetupResult(side, [], False, 0, reason=SUPINE_NOTE)
    out(f"get-up: lying {side}")
    planner = PhasePlanner(robot, params)
    q0 = lying_state(planner.robot, np.clip(joints, robot.q_min, robot.q_max), R)
    ground = ground_frame(q0, planner.robot, side)
    phases = phases_for(robot, side)
    state: dict[str, Any] = {"k": -1, "plan": None, "t0": 0.0, "played": [], "failures": 0,
                             "trunk": []}  # fmt: skip
    holder: list[Any] = []

    def start(k: int, t: float, q: np.ndarray) -> PhasePlan:
        plan = planner.plan(phases[k], q, ground)
        state.update(k=k, plan=plan, t0=t)
        state["failures"] += plan.failed_solves
        state["played"].append(phases[k].name)
        z = float(planner.robot.frame_placement(q, "torso").rotation[2, 2])
        state["trunk"].append(float(np.degrees(np.arcsin(np.clip(z, -1.0, 1.0)))))
        out(f"get-up: {phases[k].name}")
        return plan

    first = start(0, 0.0, q0)
    can = bool(getattr(bus, "can_set_stiffness", False))
    if stiffen and not can and any(p.stiffness != 1.0 for p in phases):
        out(f"get-up: the {bus.name} bus cannot stiffen the servos; the phases play as configured")
    stiffen = stiffen and can
    compensator = None
    if compensate > 0:
        from .compliance import ComplianceCompensator

        try:
            compensator = ComplianceCompensator(robot, gain=compensate)
        except WbcError as exc:  # no servo model (no servo map): said, then off
            out(f"get-up: no compliance feed-forward ({exc})")
        if compensator is not None and compensator.integral:  # its phases' slow loads
            compensator = None
            out("get-up: no compliance feed-forward (the servos' integral holds the load)")
    deflections: dict[float, Any] = {}

    def deflection(tau: np.ndarray, stiffness: float) -> np.ndarray:
        """The servos' deflection under ``tau`` at ``stiffness`` × the configured stiffness
        (the ramp ``stiffness`` times steeper: the registers the bus writes)."""
        assert compensator is not None
        if stiffness == 1.0:
            return compensator.servo_deflection(tau)
        if stiffness not in deflections:
            from .compliance import ComplianceCompensator

            params = compensator.params
            deflections[stiffness] = ComplianceCompensator(
                robot, params.scaled(stiffness=stiffness, torque=1.0), compensator.gain
            )
        return deflections[stiffness].servo_deflection(tau)

    def target(tick: int, t: float) -> np.ndarray | None:
        plan = state["plan"]
        s = t - state["t0"]
        if s > plan.t[-1]:
            k = state["k"] + 1
            if k >= len(phases):
                return None
            present = holder[0].last_present if holder else None
            if not replan:  # open loop: from where the plan left it
                q = plan.q[-1]
            elif present is None or not np.all(np.isfinite(present)):
                q = plan.q[-1]
            else:
                q = placed(planner.robot, present, torso_rotation(imu, robot), plan.anchors)
            plan = start(k, t, q)
            s = 0.0
        stiffness = plan.phase.stiffness if stiffen else 1.0
        source.stiffness = stiffness
        i = min(round(s * rate), len(plan.q) - 1)
        if compensator is None:
            return plan.q[i, 7:]
        tau = static_torques(planner.robot, plan.q[i], plan.phase)
        goal = plan.q[i, 7:] + compensator.gain * deflection(tau, stiffness)
        return np.clip(goal, robot.q_min, robot.q_max)

    source = CallableSource(target, first.q[0, 7:], robot.joint_names)
    config = DeployConfig(rate=rate, read=bus.can_read, soft_speed=0.5)
    dep = Deployment(bus, source, robot, config, out=lambda _line: None)
    holder.append(dep)
    result = dep.run()
    done = bool(result.completed) and len(state["played"]) == len(phases)
    return GetupResult(side, state["played"], done, state["failures"], result,
                       trunk_deg=state["trunk"])  # fmt: skip
