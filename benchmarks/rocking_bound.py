"""The away push's rigid rocking figure (issue 30): the body locked at the push, rocking on the
stance sole's outer edge.

The benchmark's push acts at the torso's CoM (``push_point``), above the robot's CoM. A body
that locks every joint at the push and rocks about the stance sole's outer edge stays up while
its kinetic energy about that edge is below the potential energy that brings its CoM over it:
``½ L² / I_e ≤ m g (r − h)``, ``L = L₀ + J (p − e) × u`` its angular momentum about the edge
(``L₀`` the walk's own at the push, from the plan's joint velocities), ``I_e`` the locked
body's inertia about the edge (its centroidal composite inertia plus ``m d²``), ``r`` the
CoM's distance from the edge, ``h`` its height above it. No hip strategy, no limbs, no step:
what a stiff body rocking on its edge takes, the figure the measured away push is to be read
against (with the whole-body parts' figures, benchmarks/pushes.md).

    python benchmarks/rocking_bound.py [--robot bioloid] [--trajectory walk10_wb]
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pinocchio as pin

from wbc.balance.angular import push_point
from wbc.bench.physics import plan
from wbc.bench.pushes import push_direction
from wbc.bench.sim_record import mid_single_support
from wbc.model import load_robot


def rocking(robot, rec, u: np.ndarray, t: float) -> dict:
    """The largest push (N·s) along ``u`` (horizontal, unit) at ``t`` s (the plan's
    configuration and velocity) that a locked body rocking on the stance sole's edge takes."""
    model, data = robot.model, robot.model.createData()
    k = int(np.searchsorted(rec.t - rec.t[0], t))
    q = rec.q[k]
    v = pin.difference(model, rec.q[k - 1], rec.q[k + 1]) / float(rec.t[k + 1] - rec.t[k - 1])
    pin.forwardKinematics(model, data, q, v)
    pin.updateFramePlacements(model, data)
    com = pin.centerOfMass(model, data, q, v)
    vcom = data.vcom[0].copy()
    soles = {s: data.oMf[robot.frame_id(s)] for s in ("l_sole", "r_sole")}
    stance = min(soles, key=lambda s: soles[s].translation[2])  # (the lower sole)
    sole = soles[stance]
    length, width = robot.foot_size
    r = sole.rotation
    reach = 0.5 * length * abs(r[:2, 0] @ u) + 0.5 * width * abs(r[:2, 1] @ u)
    edge = sole.translation.copy()
    edge[:2] += reach * u  # (a point of the outer edge's line)
    u3 = np.r_[u, 0.0]
    a = np.cross([0.0, 0.0, 1.0], u3)
    if np.cross(a, [0.0, 0.0, 1.0]) @ u3 < 0:
        a = -a  # (a positive turn about a tips the top toward u)
    pin.ccrba(model, data, q, v)
    inertia, mass = data.Ig.inertia.copy(), float(data.mass[0])
    lever = com - edge
    l0 = float(a @ (data.hg.angular + mass * np.cross(lever, vcom)))
    perp = lever - (lever @ a) * a
    i_e = float(a @ inertia @ a + mass * perp @ perp)
    moment = float(a @ np.cross(push_point(robot, q) - edge, u3))  # (m per N·s)
    d, h = float(-(lever[:2] @ u)), float(lever[2])
    energy = mass * 9.81 * (math.hypot(d, h) - h)
    room = math.sqrt(2.0 * i_e * energy)
    return {"stance": stance, "com_inside_edge_mm": round(1e3 * d, 1),
            "com_height_mm": round(1e3 * h, 1), "push_moment_mm": round(1e3 * moment, 1),
            "I_edge": round(i_e, 5), "I_com": round(float(a @ inertia @ a), 5),
            "L_walk": round(l0, 4), "energy_J": round(energy, 4),
            "rocking_ns": round((room - l0) / moment, 3),
            "from_rest_ns": round(room / moment, 3)}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--trajectory", default="walk10_wb")
    ap.add_argument("--solver", default="wqp-daqp")
    ap.add_argument("--offsets", type=float, nargs="+", default=[-0.03, 0.0, 0.03])
    args = ap.parse_args()
    robot = load_robot(args.robot)
    rec = plan(args.solver, args.trajectory, robot)
    t = mid_single_support(rec)
    u = np.asarray(push_direction(rec, "away"), float)[:2]
    u = u / np.linalg.norm(u)
    for off in args.offsets:
        out = rocking(robot, rec, u, t + off)
        print(json.dumps({"robot": args.robot, "offset_s": off, **out}), flush=True)


if __name__ == "__main__":
    main()
