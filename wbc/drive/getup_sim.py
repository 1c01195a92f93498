"""Getting up in the simulator: :func:`getup_sim` drops a simulated robot on its front or
back, lets it settle with its torque off (the state the fall detection's safe fall leaves),
runs :func:`wbc.balance.getup_play.get_up` on the simulated bus and IMU and judges the result
(:func:`wbc.drive.sim.judge`): torso upright within ``tilt_deg``, both soles flat on the
floor, the CoM above the feet, still so ``hold_s`` s later. ``benchmarks/getup.py`` runs it
over randomised models.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pinocchio as pin

from ..balance.getup import SIDES_LYING, GetupParams, lowest_point
from ..balance.getup_play import get_up
from ..exceptions import ConfigurationError, WbcError
from ..model import Robot
from .sim import judge, make_sim


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
    watch: Callable[[Any], None] | None = None,
    out: Callable[[str], None] = lambda _line: None,
) -> dict[str, Any]:
    """Drop the simulated robot on ``side``, get it up, judge it (module docstring): the
    record (``success``, ``reason``, ``duration_s``, ``phases``, ``plan_failures``).
    ``supine=False``: leave a robot on its back lying; ``replan=False``: open
    loop, ``compensate`` the compliance feed-forward's gain, ``stiffen=False`` the phases
    at the configured servo stiffness (:func:`~wbc.balance.getup_play.get_up`); the record's
    ``trunk_deg``: the torso's elevation at the start of each phase played. ``watch(sim)``
    is called after every control tick of the get-up (the simulation), ``out`` gets the
    get-up's lines (the phases as they start)."""
    holder: list[Any] = []

    def on_tick() -> None:
        if watch is not None and holder:
            watch(holder[0])

    sim, bus, imu = make_sim(robot, variation, rate, on_tick=on_tick if watch else None)
    holder.append(sim)
    drop(sim, robot, side, yaw)
    t0 = sim.time
    try:
        res = get_up(bus, imu, robot, joints=sim.q()[7:], params=params, rate=rate,
                     out=out, supine=supine, replan=replan,
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
