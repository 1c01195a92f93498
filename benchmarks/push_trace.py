"""One push, traced tick by tick: is the step adjuster triggered, when, and where does the
swing sole go (issue 30)?

A 10 ms torso push at mid first single support of ``walk10_wb`` (as ``pushes.py``), the
closed loop with step adjustment and the feed-forward x0.5 (the push benchmark's ``step``
loop), the nominal plant. Prints the step adjuster's re-plans (walk time, step, the shift
wanted and applied, mm) and, per tick from 30 ms before the push, the estimated DCM error
along the walk beside the simulator's (its CoM and finite-difference velocity), the swing
sole's target and where the simulated sole is (x, z, mm), each sole's floor force (N) and
the torso's pitch change since the push, its pitch and its target's (the stabilizer's), each
sole's pitch (deg; positive: nose down, on the toe); the summary says whether the run fell
as the benchmark counts it (45° or sunk) and why the deployment stopped (``--no-fall``: no
fall detector, the run goes on until it falls). ``--lateral``: the sideways columns instead,
along the push from the stance sole's centre (the DCM, the CoP and the sole's furthest
contact, the swing sole; the hip strategy's roll, the torso's top, the hip and shoulder
rolls; from the pushed single support's stance sole the simulator's DCM ``ξ`` and ``η = ξ +
L / (m h ω₀)``, the DCM with the centroidal angular momentum ``L`` about ``z × u`` returned
(what the hip strategy must bring inside the sole's edge: ``η̇ = ω₀ (η − p) − L / (m h)``,
:mod:`wbc.balance.angular`), ``L`` itself and that sole's hip and ankle roll with their goals:
:func:`lateral_table`). A probe: it observes
:meth:`wbc.balance.stabilizer.Stabilizer.adjust` by wrapping it for the run.

    nice -n 5 python benchmarks/push_trace.py --impulse 0.6 --direction forward
    nice -n 5 python benchmarks/push_trace.py --impulse 0.8 --direction away --lateral
    nice -n 5 python benchmarks/push_trace.py --impulse 0.75 --direction forward --no-fall
    nice -n 5 python benchmarks/push_trace.py --impulse 0.6 --stepping '{"band_x": 0.012}'
    nice -n 5 python benchmarks/push_trace.py --impulse 0.6 --stepping \
        '{"trigger_jump": 0.018, "landing": 1, "landing_catch": 0.02, "lift": 0.015}'

(The swing and torso target columns are the stabilizer's, before the step adjuster's
``land``: the landing correction, the lift, the lead and ``catch_pitch`` are not in them;
the column "sent" is the swing target after ``land``: what the solve is given; then both
soles' z with the controller's own (the last solve's) z and pitch, in the double support after
a caught landing the ``descend`` gap and offset, the knees and the hip and ankle pitches with
their goals.)
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from typing import Any

import _args
import numpy as np

from wbc import load_robot
from wbc.balance import best_compensate
from wbc.balance import stabilizer as stab_mod
from wbc.balance import stepping as step_mod
from wbc.balance.live import loop_rate
from wbc.balance.margin import default_sized_gains
from wbc.balance.retime import HoldParams
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
from wbc.bench.physics import physics_entry, plan
from wbc.bench.pushes import PUSH_DURATION, push_direction
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import mid_single_support, physics_record
from wbc.bench.solvers import select


def trace(
    impulse: float,
    direction: str,
    stepping: dict,
    gains: dict,
    walk: str,
    offset: float,
    fall: bool = True,
    robot_name: str = "bioloid",
    on_commands: bool = False,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(the run's summary and re-plans, a row per tick) of one push (``robot_name``: as
    ``pushes.py --robot``: its stack.toml, feed-forward gain and sized gains;
    ``on_commands``: step adjustment on a bus that reads no positions too)."""
    robot = load_robot(robot_name)
    if robot_name == "bioloid":
        entry = select(["wqp-daqp"], None, "tick")[0][0]
        ref = traj.build(walk, robot)
        _, rec = run_entry(entry, robot, ref, "tick")
    else:  # (as pushes.py: the robot folder's stack, the plan on servos)
        entry = physics_entry("wqp-daqp", robot)
        ref = traj.build(walk, robot)
        rec = plan("wqp-daqp", walk, robot)
    ff = best_compensate(robot)
    t_push = mid_single_support(rec)
    if t_push is None:
        raise SystemExit(f"{walk} has no single support to push in")
    t_push += offset
    u = push_direction(rec, direction)
    force = u * impulse / PUSH_DURATION
    roles = robot.roles
    side_joint = {(side, role): robot.joint_index(j) for side in ("left", "right")
                  for role in ("hip_roll", "shoulder_roll", "ankle_roll", "knee", "hip_pitch",
                               "ankle_pitch")
                  if (j := roles.get(side, role)) is not None}  # fmt: skip
    base = default_sized_gains(robot, ff, 1.0 / loop_rate(ref))[0]  # (as pushes.py's)
    spec = ClosedLoopSpec(entry.make, ref, replace(base, **gains), True, True,
                          SteppingParams(**stepping), HoldParams())  # fmt: skip
    spec = replace(spec, step_on_commands=on_commands)
    if not fall:  # the fall detector off: does the robot come back by itself?
        spec = replace(spec, fall=None)
    sims: list[Any] = []
    rows: list[dict[str, Any]] = []
    last: dict[str, Any] = {}
    original = stab_mod.Stabilizer.adjust

    def observed(self, targets, com_vel_ref, q_cmd, dt):
        out = original(self, targets, com_vel_ref, q_cmd, dt)
        if not sims or self.last is None or self.calibrating:
            return out
        sim, omega = sims[0], self.estimator.omega0
        c = sim.com()
        v = (c - last["c"]) / (sim.time - last["t"]) if last else np.zeros(3)
        last.update(c=c, t=sim.time)
        dcm_ref = targets.com[:2] + com_vel_ref[:2] / omega
        feet = sim.robot_feet()
        _, fz, body = sim.contacts()
        names = [sim.mj.mj_id2name(sim.model, sim.mj.mjtObj.mjOBJ_BODY, int(b)) for b in body]
        force_of = [float(sum(f for f, n in zip(fz, names, strict=True) if n == foot))
                    for foot in feet]  # fmt: skip
        swing = sim.site_pose(targets.swing).translation
        R = sim.base_rotation()
        pts, _, _ = sim.contacts()
        stance_site = "r_sole" if targets.swing == "l_sole" else "l_sole"
        p_st = sim.site_pose(stance_site).translation
        on_stance = [n == feet[0 if stance_site == "l_sole" else 1] for n in names]
        cop = sim.cop()
        edge = max((float((pt - p_st) @ u) for pt, o in zip(pts, on_stance, strict=True) if o),
                   default=float("nan"))  # fmt: skip
        q = sim.q()[7:]
        goals = sim.servos.goal_angles()
        sim.mj.mj_subtreeVel(sim.model, sim.data)  # the centroidal angular momentum
        axis = np.array([-u[1], u[0], 0.0])  # z × u: positive, the top toward u
        L = float(sim.data.subtree_angmom[sim.root] @ axis)
        mass, h = float(sim.model.body_subtreemass[sim.root]), float(ref.com_height)
        top = float(np.asarray(out.torso_rotation)[:, 2] @ u)
        rows.append({
            # each sole's normal tilted along u (deg; positive: rolled onto its u-side edge)
            "tilts": {f: math.degrees(math.asin(float(np.clip(
                sim.site_pose(f).rotation[:, 2] @ u, -1.0, 1.0)))) for f in ("l_sole", "r_sole")},
            "holding": bool(getattr(self._kick, "holding", False)),
            "dcm_u": 1e3 * float((self.last.dcm[:2] - p_st[:2]) @ u[:2]),
            "dcm_u_sim": 1e3 * float((c[:2] + v[:2] / omega - p_st[:2]) @ u[:2]),
            "cop_u": 1e3 * float((cop - p_st[:2]) @ u[:2]) if cop is not None else float("nan"),
            "edge_u": 1e3 * edge,
            "hip": math.degrees(float(np.hypot(*self.hip))),
            "L": L,
            "u": u[:2].copy(), "xi_w": c[:2] + v[:2] / omega,
            "eta_w": c[:2] + v[:2] / omega + u[:2] * L / (mass * h * omega),
            "soles_w": {f: sim.site_pose(f).translation[:2].copy() for f in ("l_sole", "r_sole")},
            "stance_site": stance_site,
            # the DCM with the angular momentum returned: ξ + L / (m h ω₀) (pushes.md)
            "eta_u_sim": 1e3 * (float((c[:2] + v[:2] / omega - p_st[:2]) @ u[:2])
                                + L / (mass * h * omega)),
            "goals": {f"{s[0]}_{r}": math.degrees(float(goals[k]))
                      for (s, r), k in side_joint.items()},
            "roll": math.degrees(math.asin(float(np.clip(R[:, 2] @ u, -1, 1)))),
            "roll_cmd": math.degrees(math.asin(float(np.clip(top, -1, 1)))),
            "swing_u": 1e3 * float((swing - p_st) @ u),
            "target_u": 1e3 * float((np.asarray(out.swing_position, dtype=float) - p_st) @ u),
            "joints": {f"{s[0]}_{r}": math.degrees(float(q[k]))
                       for (s, r), k in side_joint.items()},
            "tau_hip": [float(sim.joint_torques()[side_joint[(s, "hip_roll")]])
                        for s in ("left", "right")],
            "t": sim.time, "phase": targets.phase, "swing": targets.swing,
            "err_est": 1e3 * (self.last.dcm[0] - dcm_ref[0]),
            # the DCM estimate's parts against the simulator's (world, x, y; mm, mm/s): the
            # CoM, its velocity, the stance sole where the estimate and the true joints put
            # it, the ref's DCM (--dcm)
            "c_est": 1e3 * np.asarray(self.last.com[:2], dtype=float),
            "c_sim": 1e3 * c[:2], "v_est": 1e3 * np.asarray(self.last.com_vel[:2], dtype=float),
            "v_sim": 1e3 * v[:2], "dcm_ref": 1e3 * np.asarray(dcm_ref, dtype=float),
            "st_est": 1e3 * self.estimator.landed(stance_site, q, None)[:2],
            "st_sim": 1e3 * p_st[:2], "omega": omega, "R_sim": R.copy(),
            "R_est": np.asarray(self.last.rotation) @ self.estimator.torso_b.T,
            "w_est": np.asarray(self.last.angular_velocity, dtype=float).copy(),
            "pitch_est": math.degrees(math.asin(float(np.clip(-(np.asarray(
                self.last.rotation) @ self.estimator.torso_b.T)[2, 0], -1.0, 1.0)))),
            "err_sim": 1e3 * (c[0] + v[0] / omega - dcm_ref[0]),
            "target": 1e3 * np.asarray(out.swing_position, dtype=float),
            "sole": 1e3 * swing, "f_l": force_of[0], "f_r": force_of[1],
            "z_lr": [1e3 * float(sim.site_pose(f).translation[2]) for f in ("l_sole", "r_sole")],
            "z_cmd": [1e3 * float(robot.frame_placement(q_cmd, f).translation[2])
                      for f in ("l_sole", "r_sole")],
            "pitch_cmd": [math.degrees(math.asin(float(np.clip(
                -robot.frame_placement(q_cmd, f).rotation[2, 0], -1, 1))))
                for f in ("l_sole", "r_sole")],
            "pitch": math.degrees(math.asin(float(np.clip(-R[2, 0], -1.0, 1.0)))),
            "soles": [math.degrees(math.asin(float(np.clip(-sim.site_pose(f).rotation[2, 0],
                                                           -1.0, 1.0))))
                      for f in ("l_sole", "r_sole")],
            "cmd": math.degrees(math.asin(float(np.clip(-np.asarray(out.torso_rotation)[2, 0],
                                                        -1.0, 1.0)))),
        })  # fmt: skip
        return out

    landed_original = step_mod.StepAdjuster.land

    def landed(self, targets, est, q):  # the swing target the step adjuster sends
        out = landed_original(self, targets, est, q)
        if rows:
            rows[-1]["landed"] = 1e3 * np.asarray(out.swing_position, dtype=float)
            rows[-1]["descent"] = (1e3 * self.descent.gap, 1e3 * self.descent.offset)
        return out

    stab_mod.Stabilizer.adjust = observed  # type: ignore[method-assign]
    step_mod.StepAdjuster.land = landed  # type: ignore[method-assign]
    try:
        result, loop = play_closed_loop(spec, robot, None, push=(t_push, force, PUSH_DURATION),
                                        compensate=ff, on_tick=sims.append)  # fmt: skip
    finally:
        stab_mod.Stabilizer.adjust = original  # type: ignore[method-assign]
        step_mod.StepAdjuster.land = landed_original  # type: ignore[method-assign]
    events = loop.stepping.events if loop.stepping is not None else []
    fig = physics_record(rec, result, robot, ref)
    summary = {
        "t_push": t_push,
        "up": bool(result.deploy.completed),
        "fell": fig["fell"],  # (tilted beyond 45° or sunk: the benchmark's fall)
        "fall_time_s": fig["fall_time_s"],
        "stopped": None if result.deploy.completed else str(result.deploy.trip),
        "replans": [(round(float(e[0]), 3), int(e[1]), np.round(1e3 * np.asarray(e[2]), 1).tolist(),
                     np.round(1e3 * np.asarray(e[3]), 1).tolist()) for e in events],
        # the touch-down acceptance's (accept): walk s, touch / land / lift, step, shift mm
        "accepted": [(round(float(e[0]), 3), e[1], int(e[2]),
                      np.round(1e3 * np.asarray(e[3]), 1).tolist())
                     for e in (loop.stepping.accepted.events if loop.stepping else [])],
    }  # fmt: skip
    return summary, rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _args.push(p, impulse=0.6, direction="forward", offset=0.0)
    _args.settings(p)
    p.add_argument("--walk", default="walk10_wb")
    p.add_argument("--robot", default="bioloid", help="robot name (as pushes.py --robot)")
    p.add_argument("--ticks", type=int, default=40, help="ticks printed after the push")
    p.add_argument("--no-fall", action="store_true", help="the fall detector off")
    p.add_argument(
        "--step-on-commands",
        action="store_true",
        help="step adjustment on a bus that reads no positions too (as pushes.py's)",
    )
    p.add_argument(
        "--dcm",
        action="store_true",
        help="the DCM estimate's parts against the simulator's (dcm_table)",
    )
    p.add_argument(
        "--lateral",
        action="store_true",
        help="sideways columns (along the push, from the stance sole's centre)",
    )
    a = p.parse_args()
    summary, rows = trace(a.impulse, a.direction, a.stepping, a.gains, a.walk, a.offset,
                          not a.no_fall, a.robot, a.step_on_commands)  # fmt: skip
    print(json.dumps(summary))
    # the push starts at the first tick whose simulated DCM error jumps (the walk's clock
    # starts after the calibration and soft start: find it in the simulator's time)
    key = "dcm_u_sim" if a.lateral else "err_sim"
    jump = next((k for k in range(1, len(rows))
                 if abs(rows[k][key] - rows[k - 1][key]) > 8.0), 0)  # fmt: skip
    if a.lateral:
        lateral_table(rows, jump, a.ticks)
        return
    if a.dcm:
        dcm_table(rows, jump, a.ticks)
        return
    print(
        "| ms after push | phase | swing | DCM err est / sim mm | swing target x, z | sole x, z "
        "| F left / right N | pitch change ° | torso pitch, target ° | sole pitch l / r ° "
        "| sent x, z | sole z l / r (solved) | landed gap, lowered mm | knee l / r (goal) ° |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    t0, p0 = rows[jump]["t"] if rows else 0.0, rows[jump]["pitch"] if rows else 0.0
    for r in rows[max(jump - 3, 0) : jump + a.ticks]:
        sent = r.get("landed", r["target"])
        gap, low = r.get("descent", (0.0, 0.0)) if r["phase"] == "double" else (0.0, 0.0)
        print(f"| {1e3 * (r['t'] - t0):.0f} | {r['phase']} | {r['swing']} "
              f"| {r['err_est']:.1f} / {r['err_sim']:.1f} "
              f"| {r['target'][0]:.1f}, {r['target'][2]:.1f} | {r['sole'][0]:.1f}, "
              f"{r['sole'][2]:.1f} | {r['f_l']:.1f} / {r['f_r']:.1f} "
              f"| {r['pitch'] - p0:+.1f} | {r['pitch']:+.1f}, {r['cmd']:+.1f} "
              f"| {r['soles'][0]:+.1f} / {r['soles'][1]:+.1f} "
              f"| {sent[0]:.1f}, {sent[2]:.1f} | {r['z_lr'][0]:.1f} / {r['z_lr'][1]:.1f} "
              f"({r['z_cmd'][0]:.1f} / {r['z_cmd'][1]:.1f}; "
              f"{r['pitch_cmd'][0]:+.1f} / {r['pitch_cmd'][1]:+.1f}°) "
              f"| {gap:.1f}, {low:.1f} | {r['joints'].get('l_knee', 0):+.1f} / "
              f"{r['joints'].get('r_knee', 0):+.1f} ({r['goals'].get('l_knee', 0):+.1f} / "
              f"{r['goals'].get('r_knee', 0):+.1f}) "
              + "| " + " / ".join(f"{r['joints'][s + '_hip_pitch']:+.1f}, "
                                  f"{r['joints'][s + '_ankle_pitch']:+.1f} "
                                  f"({r['goals'][s + '_hip_pitch']:+.1f}, "
                                  f"{r['goals'][s + '_ankle_pitch']:+.1f})" for s in "lr")
              + " |")  # fmt: skip


def dcm_table(rows: list[dict[str, Any]], jump: int, ticks: int) -> None:
    """The DCM estimate against the simulator's, in its parts (world x / y, mm; velocities
    mm/s): the DCM error (estimate − reference, simulator − reference), the CoM (estimate −
    simulator), its velocity (estimate, simulator), the stance sole where the estimate and the
    true joints put it less where it is (its anchor's error), the base's pitch (the estimate's,
    the simulator's) and the stance sole's (deg; negative: on the heel)."""
    print(
        "| ms | phase | stance | DCM err x est / sim | DCM err y est / sim | CoM est − sim x, y "
        "| ċ x est / sim | ċ y est / sim | stance sole est − sim x, y | base pitch est / sim "
        "| stance sole pitch |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    t0 = rows[jump]["t"] if rows else 0.0
    for r in rows[max(jump - 3, 0) : jump + ticks]:
        ref = r["dcm_ref"]
        est = r["c_est"] + r["v_est"] / r["omega"] - ref
        sim = r["c_sim"] + r["v_sim"] / r["omega"] - ref
        dc, ds = r["c_est"] - r["c_sim"], r["st_est"] - r["st_sim"]
        s = 0 if r["stance_site"] == "l_sole" else 1
        print(f"| {1e3 * (r['t'] - t0):.0f} | {r['phase']} | {r['stance_site'][0]} "
              f"| {est[0]:.1f} / {sim[0]:.1f} | {est[1]:.1f} / {sim[1]:.1f} "
              f"| {dc[0]:+.1f}, {dc[1]:+.1f} | {r['v_est'][0]:.0f} / {r['v_sim'][0]:.0f} "
              f"| {r['v_est'][1]:.0f} / {r['v_sim'][1]:.0f} | {ds[0]:+.1f}, {ds[1]:+.1f} "
              f"| {r['pitch_est']:+.1f} / {r['pitch']:+.1f} | {r['soles'][s]:+.1f} |")  # fmt: skip


def lateral_table(rows: list[dict[str, Any]], jump: int, ticks: int) -> None:
    """The sideways rows: along the push ``u``, from the stance sole's centre (mm): the DCM
    (estimated / simulated), the CoP and the stance sole's furthest contact point, the
    swing sole and its target; the hip strategy's roll (deg), the torso's top tilted along
    ``u`` and its target's, the hip and shoulder rolls (deg) and the hip rolls' torques; from
    the pushed single support's stance sole (through the double support after it) ``ξ`` and
    ``η`` (the simulator's, mm), ``L`` (kg·m²/s) and that leg's hip and ankle roll (their
    goals), the pushed stance sole's tilt along ``u`` (deg: positive, rolled onto its edge on
    the ``u`` side). (In
    double support "stance" is the sole of the next single support, "swing" the other.)"""
    print(
        "| ms | phase | DCM est / sim | CoP / edge | swing sole u, z / target u | F l / r "
        "| hip roll h | torso top along u, target | hip roll l / r ° (τ N·m) | shoulder l / r ° "
        "| ξ / η from the pushed stance | L | stance hip, ankle roll (goal) ° | sole tilt ° |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    t0 = rows[jump]["t"] if rows else 0.0
    pushed = rows[jump]["stance_site"] if rows else "l_sole"
    side = "l" if pushed == "l_sole" else "r"
    for r in rows[max(jump - 3, 0) : jump + ticks]:
        j, g = r["joints"], r["goals"]
        p0, u = r["soles_w"][pushed], r["u"]
        xi, eta = 1e3 * float((r["xi_w"] - p0) @ u), 1e3 * float((r["eta_w"] - p0) @ u)
        extra = (
            f" {xi:.1f} / {eta:.1f} | {r['L']:+.4f} | {j.get(side + '_hip_roll', 0):+.1f} "
            f"({g.get(side + '_hip_roll', 0):+.1f}), {j.get(side + '_ankle_roll', 0):+.1f} "
            f"({g.get(side + '_ankle_roll', 0):+.1f}) | {r['tilts'][pushed]:+.1f}"
            f"{' held' if r['holding'] else ''} |"
        )
        print(f"| {1e3 * (r['t'] - t0):.0f} | {r['phase']} "
              f"| {r['dcm_u']:.1f} / {r['dcm_u_sim']:.1f} "
              f"| {r['cop_u']:.1f} / {r['edge_u']:.1f} | {r['swing_u']:.1f}, {r['sole'][2]:.1f} / "
              f"{r['target_u']:.1f} | {r['f_l']:.1f} / {r['f_r']:.1f} | {r['hip']:.1f} "
              f"| {r['roll']:+.1f}, {r['roll_cmd']:+.1f} "
              f"| {j.get('l_hip_roll', 0):+.1f} / {j.get('r_hip_roll', 0):+.1f} "
              f"({r['tau_hip'][0]:+.2f} / {r['tau_hip'][1]:+.2f}) "
              f"| {j.get('l_shoulder_roll', 0):+.1f} / "
              f"{j.get('r_shoulder_roll', 0):+.1f} |" + extra)  # fmt: skip


if __name__ == "__main__":
    main()
