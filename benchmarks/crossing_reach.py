"""How far beyond the stance sole's outer edge a crossing step can land (issue 30).

A push away from the swing foot carries the DCM past the stance sole's outer edge; the only
support that can catch it there is the swing sole landed beyond that edge, crossing in front of
or behind the stance sole. This asks the model alone: with the stance sole flat at the origin,
the base free, both legs within their joint limits (the other joints at the stand pose), the
torso tilted at most ``--tilt`` rad, the CoM at least ``--low`` × its standing height above the
floor, the swing sole's centre at most ``--ahead`` m ahead of or behind the stance sole's, the
swing sole's and the torso's yaw from the stance sole's within ``--yaw``, the legs' hip-knee-
ankle lines at least ``--gap`` apart (the legs' self-collision, coarsely) and the swing sole
flat on the floor, clear of the stance sole's rectangle by ``--clearance`` ahead (``front``),
behind (``behind``) or beside it on the far side (``side``), how far past the stance sole's
outer edge does the swing sole's outermost corner reach (mm; negative: short of it)? No
balance, torque or speed constraint: an upper bound on what a crossing step can give.

    python benchmarks/crossing_reach.py [--robot bioloid op3] [--starts 12] [--tilt 0.7] \\
        [--ahead 0.15]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

from wbc.model import load_robot

LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")


def reach(
    name: str,
    mode: str,
    clearance: float,
    starts: int,
    tilt: float,
    low: float,
    ahead: float,
    gap: float,
    yaw: float,
    seed: int = 0,
    start: np.ndarray | None = None,
) -> dict:
    """The best reach beyond the stance (right) sole's outer edge of the swing (left) sole;
    with ``start`` (the joints at the push, the left sole the stance: mirrored), the least
    time the servos need to turn every leg joint from there at its speed limit."""
    robot = load_robot(name)
    model, data = robot.model, robot.model.createData()
    q0 = robot.configuration(robot.stand_pose)
    legs = [robot.joint_index(robot.roles.joint(s, j)) for s in ("left", "right") for j in LEG
            if robot.roles.get(s, j) is not None]  # fmt: skip
    lo, hi = robot.q_min[legs], robot.q_max[legs]
    ls, rs = robot.frame_id("l_sole"), robot.frame_id("r_sole")
    length, width = robot.foot_size
    corners = np.array([[sx * length / 2, sy * width / 2, 0.0] for sx in (-1, 1) for sy in (-1, 1)])
    # the stance (right) sole's outer edge: y = −width/2 in its own frame
    base0 = pin.XYZQUATToSE3(q0[:7])

    def config(x: np.ndarray) -> np.ndarray:
        q = q0.copy()
        base = base0 * pin.exp6(x[:6])
        q[:7] = pin.SE3ToXYZQUAT(base)
        q[7 + np.array(legs)] = x[6:]
        return q

    def frames(x: np.ndarray) -> tuple[pin.SE3, pin.SE3]:
        pin.framesForwardKinematics(model, data, config(x))
        r = data.oMf[rs]
        return r.inverse() * data.oMf[ls], r  # the swing sole in the stance sole's frame

    def swing_corners(x: np.ndarray) -> np.ndarray:
        m, _ = frames(x)
        return (m.rotation @ corners.T).T + m.translation

    def objective(x: np.ndarray) -> float:
        return float(swing_corners(x)[:, 1].min())  # (minimised: the outermost corner)

    def flat(x: np.ndarray) -> np.ndarray:
        m, _ = frames(x)
        return np.array([m.translation[2], m.rotation[0, 2], m.rotation[1, 2]])

    def clear(x: np.ndarray) -> np.ndarray:
        c = swing_corners(x)
        if mode == "front":
            return c[:, 0] - (length / 2 + clearance)
        if mode == "behind":
            return -(length / 2 + clearance) - c[:, 0]
        return -(width / 2 + clearance) - c[:, 1]  # side: wholly beyond the outer edge

    chain = [[model.getJointId(robot.roles.joint(side, j)) for j in ("hip_pitch", "knee",
              "ankle_pitch")] for side in ("left", "right")]  # fmt: skip
    t = np.linspace(0.0, 1.0, 6)[:, None]

    def apart(x: np.ndarray) -> np.ndarray:  # (the legs' hip-knee-ankle lines ``--gap`` apart)
        pin.forwardKinematics(model, data, config(x))
        lines = []
        for ids in chain:
            p = [data.oMi[i].translation for i in ids]
            lines.append(np.vstack([p[0] + t * (p[1] - p[0]), p[1] + t[1:] * (p[2] - p[1])]))
        d = np.linalg.norm(lines[0][:, None, :] - lines[1][None, :, :], axis=2)
        return np.array([float(d.min()) - gap])

    def turned(x: np.ndarray) -> np.ndarray:  # (the swing sole's and the torso's yaw from
        m, r = frames(x)  # the stance sole's within ``--yaw``)
        top = r.inverse().rotation @ data.oMf[torso].rotation  # (after frames' FK)
        heading = np.arctan2(top[1, 0], top[0, 0])
        return yaw - np.abs([float(pin.rpy.matrixToRpy(m.rotation)[2]), float(heading)])

    def near(x: np.ndarray) -> np.ndarray:  # (--ahead: the swing sole's centre that close)
        m, _ = frames(x)
        return np.array([ahead - abs(float(m.translation[0]))])

    rng = np.random.default_rng(seed)
    # the stance sole pinned at its stand placement (base moves with it: its pose relative)
    r0 = robot.frame_placement(q0, "r_sole")

    torso = robot.frame_id("torso")
    height = float(pin.centerOfMass(model, data, q0)[2] - r0.translation[2])

    def upright(x: np.ndarray) -> np.ndarray:
        q = config(x)
        com = pin.centerOfMass(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        up = float(data.oMf[torso].rotation[:, 2] @ data.oMf[rs].rotation[:, 2])
        z = float(data.oMf[rs].rotation[:, 2] @ (com - data.oMf[rs].translation))
        return np.array([up - np.cos(tilt), z - low * height])

    def pinned(x: np.ndarray) -> np.ndarray:
        _, r = frames(x)
        return pin.log6(r0.inverse() * r).vector

    best: dict = {"reach_mm": -1e9}
    bounds = [(-1.0, 1.0)] * 6 + list(zip(lo, hi, strict=True))
    for k in range(starts):
        x0 = np.zeros(6 + len(legs))
        x0[6:] = q0[7 + np.array(legs)] if k == 0 else rng.uniform(lo, hi)
        res = minimize(objective, x0, method="SLSQP", bounds=bounds,
                       constraints=[{"type": "eq", "fun": pinned}, {"type": "eq", "fun": flat},
                                    {"type": "ineq", "fun": clear},
                                    {"type": "ineq", "fun": upright},
                                    {"type": "ineq", "fun": near},
                                    {"type": "ineq", "fun": apart},
                                    {"type": "ineq", "fun": turned}],
                       options={"maxiter": 300, "ftol": 1e-9})  # fmt: skip
        x = res.x
        ok = (np.abs(pinned(x)).max() < 1e-4 and np.abs(flat(x)).max() < 1e-4
              and clear(x).min() > -1e-4 and upright(x).min() > -1e-4
              and near(x).min() > -1e-4 and apart(x).min() > -1e-4
              and turned(x).min() > -1e-4)  # fmt: skip
        if not ok:
            continue
        beyond = -width / 2 - objective(x)  # (m past the outer edge)
        if 1e3 * beyond > best["reach_mm"]:
            m, _ = frames(x)
            turn = float(np.degrees(pin.rpy.matrixToRpy(m.rotation)[2]))
            best = {"reach_mm": round(1e3 * beyond, 1),
                    "swing_sole_mm": [round(1e3 * v, 1) for v in m.translation[:2]],
                    "swing_yaw_deg": round(turn, 1),
                    "legs_rad": {robot.joint_names[j]: round(float(v), 3)
                                 for j, v in zip(legs, x[6:], strict=True)}}  # fmt: skip
            if start is not None:
                need = np.abs(x[6:] - mirrored(robot, start)[legs]) / robot.v_max[legs]
                best["servo_time_s"] = round(float(need.max()), 3)
                best["slowest"] = robot.joint_names[legs[int(np.argmax(need))]]
    return {
        "robot": name,
        "mode": mode,
        "clearance_mm": 1e3 * clearance,
        "tilt": tilt,
        "low": low,
        "ahead_mm": 1e3 * ahead,
        "foot_mm": [1e3 * length, 1e3 * width],
        **best,
    }


def mirrored(robot, joints: np.ndarray) -> np.ndarray:
    """``joints`` with the legs' sides swapped (the yaw and roll joints negated)."""
    out = joints.copy()
    for j in LEG:
        names = [robot.roles.get(side, j) for side in ("left", "right")]
        if None in names:
            continue
        a, b = (robot.joint_index(n) for n in names)
        sign = -1.0 if j.endswith(("yaw", "roll")) else 1.0
        out[a], out[b] = sign * joints[b], sign * joints[a]
    return out


def at_push(robot, walk: str) -> np.ndarray:
    """The plan's joints at mid single support (the push; wqp-daqp): its stance the left
    sole on the robots here (checked)."""
    from wbc.bench.physics import plan
    from wbc.bench.sim_record import mid_single_support

    rec = plan("wqp-daqp", walk, robot)
    k = int(np.searchsorted(rec.t - rec.t[0], mid_single_support(rec)))
    q = rec.q[k]
    low = min(("l_sole", "r_sole"), key=lambda s: robot.frame_placement(q, s).translation[2])
    assert low == "l_sole", low
    return q[7:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", nargs="+", default=["bioloid", "op3"])
    ap.add_argument("--modes", nargs="+", default=["front", "behind", "side"])
    ap.add_argument("--clearance", type=float, default=0.005)
    ap.add_argument("--starts", type=int, default=12)
    ap.add_argument("--tilt", type=float, default=0.7, help="rad: the torso's largest tilt")
    ap.add_argument(
        "--ahead",
        type=float,
        default=1.0,
        help="m: the swing sole's centre at most this far ahead or behind",
    )
    ap.add_argument(
        "--gap",
        type=float,
        default=0.03,
        help="m: the legs' hip-knee-ankle lines at least this far apart",
    )
    ap.add_argument("--yaw", type=float, default=0.6, help="rad: the soles' relative yaw")
    ap.add_argument("--low", type=float, default=0.75, help="the CoM's lowest, × standing")
    ap.add_argument("--walk", default=None, help="the servos' time from this walk's push")
    args = ap.parse_args()
    for name in args.robot:
        start = at_push(load_robot(name), args.walk) if args.walk else None
        for mode in args.modes:
            out = reach(name, mode, args.clearance, args.starts, args.tilt, args.low,
                        args.ahead, args.gap, args.yaw, start=start)  # fmt: skip
            print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
