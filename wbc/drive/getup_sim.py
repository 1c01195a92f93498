"""Getting up in the simulator: :func:`getup_sim` drops a simulated robot on its front or
back, lets it settle with its torque off (the state the fall detection's safe fall leaves),
runs :func:`wbc.balance.getup_play.get_up` on the simulated bus and IMU and judges the result
(:func:`judge`): torso upright within ``tilt_deg``, both soles flat on the floor, the CoM above
the feet, still so ``hold_s`` s later. ``benchmarks/getup.py`` runs it over randomised models.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..balance.getup import SIDES_LYING, GetupParams, lowest_point
from ..balance.getup_play import get_up
from ..exceptions import ConfigurationError, WbcError
from ..geometry import convex_hull, signed_distance
from ..model import Robot
from .sim import make_sim


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
    q[2] = 0.01 - lowest_point(robot, q)
    sim.reset(q, torque=False)
    sim.advance(settle_s)


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
    yaw = math.atan2(Rs[1, 0], Rs[0, 0])
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


def getup_sim(
    robot: Robot,
    side: str,
    variation: Any = None,
    yaw: float = 0.0,
    params: GetupParams | None = None,
    hold_s: float = 2.0,
    rate: float = 50.0,
    supine: bool = True,
    replan: bool = True,
    compensate: float = 1.0,
    stiffen: bool = True,
) -> dict[str, Any]:
    """Drop the simulated robot on ``side``, get it up, judge it (module docstring): the
    record (``success``, ``reason``, ``duration_s``, ``phases``, ``plan_failures``).
    ``supine``: try the (experimental) get-up from the back too; ``replan=False``: open
    loop, ``compensate`` the compliance feed-forward's gain, ``stiffen=False`` the phases
    at the configured servo stiffness (:func:`~wbc.balance.getup_play.get_up`); the record's
    ``trunk_deg``: the torso's elevation at the start of each phase played."""
    sim, bus, imu = make_sim(robot, variation, rate)
    drop(sim, robot, side, yaw)
    t0 = sim.time
    try:
        res = get_up(bus, imu, robot, joints=sim.q()[7:], params=params, rate=rate,
                     out=lambda _line: None, supine=supine, replan=replan,
                     compensate=compensate, stiffen=stiffen)  # fmt: skip
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
        "trunk_deg": dict(zip(res.phases, res.trunk_deg, strict=True)),
    }
