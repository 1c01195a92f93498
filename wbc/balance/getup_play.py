"""Playing a get-up (:mod:`wbc.balance.getup`) in the closed loop, on any ``ServoBus`` + ``Imu``.

:func:`get_up` reads which side the robot lies on from the IMU (the torso's orientation:
:func:`~wbc.balance.getup.lying_side`), plans the first phase from the measured state
(:func:`~wbc.balance.getup.lying_state`: the servos' positions, the IMU's orientation, the
base put on the floor) and plays it through the deployment's safety layer
(:class:`~wbc.servos.playback.Deployment`: soft start, clamping to the joint limits, rate limit
at the servos' speed, watchdog, safe stop). Each later phase is planned when it starts, from
the state the previous one left: the measured joints and torso orientation, the base placed
where the phase's contacts were planned (:func:`placed`). It ends in the standing pose.

:func:`getup_sim` drops a simulated robot on its front or back, lets it settle with its
torque off (the state the fall detection's safe fall leaves), runs :func:`get_up` and judges
the result (:func:`judge`): torso upright within ``tilt_deg``, both soles flat on the floor,
the CoM above the feet, still so ``hold_s`` later.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, WbcError
from ..geometry import convex_hull, signed_distance
from ..model import Kinematics, Robot
from .getup import (
    SIDES_LYING,
    GetupParams,
    PhasePlan,
    PhasePlanner,
    ground_frame,
    lying_side,
    lying_state,
    phases_for,
)

#: why a robot on its back is left lying by default
SUPINE_NOTE = (
    "lying on the back: the get-up from the back does not work yet (the arms cannot lift the "
    "trunk: benchmarks/getup.md); turn the robot onto its front"
)


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


def get_up(
    bus: Any,
    imu: Any,
    robot: Robot,
    joints: np.ndarray | None = None,
    params: GetupParams | None = None,
    rate: float = 50.0,
    out: Callable[[str], None] = print,
    supine: bool = False,
    wait_s: float = 0.0,
) -> GetupResult:
    """Get the robot up from where it lies (module docstring). ``joints``: the present joint
    angles (rad, model order; default: read from ``bus``); ``wait_s``: s to wait first (the
    fall's last bounces).
    ``supine``: also try the get-up from the back (experimental: it fails in the simulator,
    benchmarks/getup.md); without it a robot on its back is left lying, and the result says
    so."""
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
    state: dict[str, Any] = {"k": -1, "plan": None, "t0": 0.0, "played": [], "failures": 0}
    holder: list[Any] = []

    def start(k: int, t: float, q: np.ndarray) -> PhasePlan:
        plan = planner.plan(phases[k], q, ground)
        state.update(k=k, plan=plan, t0=t)
        state["failures"] += plan.failed_solves
        state["played"].append(phases[k].name)
        out(f"get-up: {phases[k].name}")
        return plan

    first = start(0, 0.0, q0)

    def target(tick: int, t: float) -> np.ndarray | None:
        plan = state["plan"]
        s = t - state["t0"]
        if s > plan.t[-1]:
            k = state["k"] + 1
            if k >= len(phases):
                return None
            present = holder[0].last_present if holder else None
            if present is None or not np.all(np.isfinite(present)):
                present = plan.q[-1, 7:]
            q = placed(planner.robot, present, torso_rotation(imu, robot), plan.anchors)
            plan = start(k, t, q)
            s = 0.0
        i = min(round(s * rate), len(plan.q) - 1)
        return plan.q[i, 7:]

    source = CallableSource(target, first.q[0, 7:], robot.joint_names)
    config = DeployConfig(rate=rate, read=bus.can_read, soft_speed=0.5)
    dep = Deployment(bus, source, robot, config, out=lambda _line: None)
    holder.append(dep)
    result = dep.run()
    done = bool(result.completed) and len(state["played"]) == len(phases)
    return GetupResult(side, state["played"], done, state["failures"], result)


# ---------------------------------------------------------------------- the simulator
def drop(sim: Any, robot: Robot, side: str, yaw: float = 0.0, settle_s: float = 1.5) -> None:
    """Lay the simulated robot on ``side`` (its crouch/stand pose, torque off) and let it
    settle ``settle_s`` s: the state a safe fall leaves."""
    if side not in SIDES_LYING:
        raise ConfigurationError(f"side must be one of {SIDES_LYING}, got {side!r}")
    q = robot.configuration(robot.stand_pose)
    pitch = math.pi / 2 if side == "prone" else -math.pi / 2
    R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ pin.rpy.rpyToMatrix(0.0, pitch, 0.0)
    q[3:7] = pin.Quaternion(R).coeffs()
    q[2] = 0.0
    q[2] = 0.01 - lying_state_height(robot, q)
    sim.reset(q, torque=False)
    sim.advance(settle_s)


def lying_state_height(robot: Robot, q: np.ndarray) -> float:
    from .getup import lowest_point

    return lowest_point(robot, q)


def judge(sim: Any, robot: Robot, tilt_deg: float = 10.0) -> tuple[bool, str]:
    """Standing? Torso within ``tilt_deg`` of upright, both soles flat on the floor (within
    5 mm and 10°), the CoM above the soles' hull."""
    R = sim.site_pose("torso").rotation
    tilt = math.degrees(math.acos(float(np.clip(R[2, 2], -1.0, 1.0))))
    if tilt > tilt_deg:
        return False, f"torso tilted {tilt:.0f} deg"
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
    return True, f"up: tilt {tilt:.1f} deg, CoM {1e3 * margin:.0f} mm inside the feet"


def getup_sim(
    robot: Robot,
    side: str,
    variation: Any = None,
    yaw: float = 0.0,
    params: GetupParams | None = None,
    hold_s: float = 2.0,
    rate: float = 50.0,
    supine: bool = True,
) -> dict[str, Any]:
    """Drop the simulated robot on ``side``, get it up, judge it (module docstring): the
    record (``success``, ``reason``, ``duration_s``, ``phases``, ``plan_failures``).
    ``supine``: try the (experimental) get-up from the back too."""
    from ..drive.sim import make_sim

    sim, bus, imu = make_sim(robot, variation, rate)
    drop(sim, robot, side, yaw)
    t0 = sim.time
    try:
        res = get_up(bus, imu, robot, joints=sim.q()[7:], params=params, rate=rate,
                     out=lambda _line: None, supine=supine)  # fmt: skip
    except WbcError as exc:
        return {"side": side, "success": False, "reason": f"error: {exc}", "duration_s": None,
                "phases": [], "plan_failures": 0}  # fmt: skip
    duration = sim.time - t0
    ok, why = judge(sim, robot)
    if ok and hold_s > 0:
        sim.advance(hold_s)
        ok, why = judge(sim, robot)
        why = why if ok else f"fell back within {hold_s:g} s: {why}"
    if not res.completed:
        ok, why = False, f"motion not completed ({res.reason or (res.deploy and res.deploy.trip)})"
    return {
        "side": side,
        "success": bool(ok),
        "reason": why,
        "duration_s": duration,
        "phases": res.phases,
        "plan_failures": res.plan_failures,
    }
