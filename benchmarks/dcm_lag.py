"""The walk's own DCM lag before any push, and where it comes from (issue 30, sixteenth session).

The push benchmark's ``step`` loop (``walk10_wb``, wqp-daqp, the closed loop with step
adjustment, the feed-forward at ``--compensate``, the nominal plant), no push. Per tick the
DCM along the walk (x, mm) of

* the reference: ``c_ref + ċ_ref / ω₀`` (the CoM target and its velocity, before the
  stabilizer);
* the solve: the controller's own configuration ``q_cmd`` (its CoM, finite-difference
  velocity);
* the simulator (its CoM and finite-difference velocity) and the estimate;

each beside its error against the reference, split: ``solve`` = ``q_cmd``'s DCM − the
reference's (the whole-body solve's tracking, the plan's own timing), ``servo`` = the DCM of
the measured joints − the DCM of the commanded joints, both taken from the stance sole (the
servos' lag and sag), ``base`` = the rest (the stance sole's own tilt and slip). The
summary: the mean errors before the push and over the run, each at the push, and the servos'
measured lag (:func:`wbc.balance.servo_lag.servo_lag`).

    nice -n 5 python benchmarks/dcm_lag.py [--compensate 0.5] [--gains G] [--stepping S]
"""

from __future__ import annotations

import argparse
from typing import Any

import _args
import numpy as np

from wbc import load_robot
from wbc.balance import best_compensate
from wbc.balance import stabilizer as stab_mod
from wbc.balance.retime import HoldParams
from wbc.balance.stabilizer import Gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import mid_single_support
from wbc.bench.solvers import select


def _rel(robot: Any, q: np.ndarray, sole: str) -> np.ndarray:
    """The CoM of ``q`` in the world axes from ``sole``'s origin, the sole turned flat
    (the joints' share of the CoM's place: the base cancels)."""
    c = robot.com(q)
    P = robot.frame_placement(q, sole)
    return np.asarray(P.rotation.T @ (c - P.translation))


def trace(compensate: float | None, gains: dict, stepping: dict, until: float) -> list[dict]:
    """A row per tick up to ``until`` s of simulation (module docstring)."""
    robot = load_robot("bioloid")
    entry = select(["wqp-daqp"], None, "tick")[0][0]
    ref = traj.build("walk10_wb", robot)
    _, rec = run_entry(entry, robot, ref, "tick")
    ff = best_compensate(robot) if compensate is None else compensate
    spec = ClosedLoopSpec(entry.make, ref, Gains(**gains), True, True,
                          SteppingParams(**stepping), HoldParams())  # fmt: skip
    sims: list[Any] = []
    rows: list[dict] = []
    last: dict[str, Any] = {}
    original = stab_mod.Stabilizer.adjust

    def observed(self, targets, com_vel_ref, q_cmd, dt):
        self.measure_lag = True
        out = original(self, targets, com_vel_ref, q_cmd, dt)
        if not sims or self.last is None or self.calibrating:
            return out
        start = last.setdefault("start", sims[0].time)
        if sims[0].time - start > until:
            return out
        sim, w = sims[0], self.estimator.omega0
        stance = targets.support if targets.phase != "double" else "l_sole"
        q_sim = sim.q()
        q_mix = q_cmd.copy()  # the commanded base, the measured joints
        q_mix[7:] = q_sim[7:]
        now = {
            "t": sim.time,
            "ref": np.asarray(targets.com[:2], dtype=float),
            "vref": np.asarray(com_vel_ref[:2], dtype=float),
            "sim": sim.com()[:2],
            "cmd": robot.com(q_cmd)[:2],
            "r_cmd": _rel(robot, q_cmd, stance)[:2],
            "r_sim": _rel(robot, q_mix, stance)[:2],
            "stance": stance,
        }
        dts = now["t"] - last["t"] if "t" in last else 0.0
        same = "t" in last and last["stance"] == stance and dts > 0
        v = {k: (now[k] - last[k]) / dts if same or (k in ("sim", "cmd") and dts > 0)
             else np.zeros(2) for k in ("sim", "cmd", "r_cmd", "r_sim")}  # fmt: skip
        last.update(now)
        xi = {k: now[k] + v[k] / w for k in ("sim", "cmd", "r_cmd", "r_sim")}
        xi_ref = now["ref"] + now["vref"] / w
        rows.append({
            "t": now["t"], "phase": targets.phase, "support": targets.support,
            "ref": 1e3 * xi_ref[0], "cmd": 1e3 * xi["cmd"][0], "sim": 1e3 * xi["sim"][0],
            "est": 1e3 * float(self.last.dcm[0]),
            "servo": 1e3 * (xi["r_sim"][0] - xi["r_cmd"][0]) if same else float("nan"),
            "c_ref": 1e3 * now["ref"][0], "c_cmd": 1e3 * now["cmd"][0],
            "c_sim": 1e3 * now["sim"][0],
            "c_servo": 1e3 * (now["r_sim"][0] - now["r_cmd"][0]),
            "tau": float(self.servo_lag),
        })  # fmt: skip
        return out

    stab_mod.Stabilizer.adjust = observed  # type: ignore[method-assign]
    try:
        play_closed_loop(spec, robot, None, compensate=ff, on_tick=sims.append,
                         duration=until + 2.0)  # fmt: skip
    finally:
        stab_mod.Stabilizer.adjust = original  # type: ignore[method-assign]
    rows[0]["t_push"] = mid_single_support(rec)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--compensate", type=float, default=None, help="feed-forward (robot's best)")
    _args.settings(p)
    p.add_argument("--until", type=float, default=None, help="s of simulation (the push's)")
    p.add_argument("--every", type=int, default=5, help="print every n-th tick")
    a = p.parse_args()
    rows = trace(a.compensate, a.gains, a.stepping, 10.0 if a.until is None else a.until)
    t_push = rows[0]["t_push"]
    t = np.array([r["t"] for r in rows])
    walk = t - t[0]
    print(f"# push time in the walk's clock {t_push:.3f} s; {len(rows)} ticks")
    print(
        "| walk s | phase | DCM ref | err: sim / est / solve / servo / base (mm) "
        "| CoM err: sim / solve / servo | τ servos ms |"
    )
    print("|---|---|---|---|---|---|")
    for k in range(0, len(rows), a.every):
        r = rows[k]
        sim, solve, servo = r["sim"] - r["ref"], r["cmd"] - r["ref"], r["servo"]
        print(
            f"| {walk[k]:.2f} | {r['phase'][:6]} {r['support'][:1]} | {r['ref']:.1f} "
            f"| {sim:+.1f} / {r['est'] - r['ref']:+.1f} / {solve:+.1f} / {servo:+.1f} / "
            f"{sim - solve - servo:+.1f} | {r['c_sim'] - r['c_ref']:+.1f} / "
            f"{r['c_cmd'] - r['c_ref']:+.1f} / {r['c_servo']:+.1f} | {1e3 * r['tau']:.0f} |"
        )
    at = int(np.argmin(np.abs(walk - t_push)))
    for lo, hi in ((0.3, t_push), (0.3, walk[-1])):
        m = (walk >= lo) & (walk <= hi)
        c = {k: np.array([r[k] for r in rows])[m] for k in ("ref", "cmd", "sim", "est", "servo")}
        print(
            f"## walk {lo:.2f}–{hi:.2f} s, mean DCM err (mm): sim "
            f"{np.mean(c['sim'] - c['ref']):+.1f}, est {np.mean(c['est'] - c['ref']):+.1f}, "
            f"solve {np.mean(c['cmd'] - c['ref']):+.1f}, servo {np.nanmean(c['servo']):+.1f}"
        )
    r = rows[at]
    print(
        f"## at the push ({walk[at]:.2f} s): DCM err sim {r['sim'] - r['ref']:+.1f}, est "
        f"{r['est'] - r['ref']:+.1f}, solve {r['cmd'] - r['ref']:+.1f}, servo "
        f"{r['servo']:+.1f} mm; the servos' measured lag {1e3 * r['tau']:.0f} ms"
    )


if __name__ == "__main__":
    main()
