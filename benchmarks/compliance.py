"""Servo compliance compensation in the simulator: joint tracking error without it, with the
feed-forward, and with the feed-forward corrected from the encoders (issue 15, item 2).

Each controller's plan (one solve per tick) is played open loop through the deployment path
on the simulated Bioloid (:func:`wbc.bench.play.play`, the AX-12A law of the shared servo
settings) three ways: ``none``; ``ff`` (:mod:`wbc.balance.compliance` feed-forward, ×GAIN);
``ff+enc`` (the same, rescaled per joint online from the servos' present positions,
:class:`wbc.balance.compliance.EncoderCorrection`). Per run: the RMS and largest joint
tracking error (real − planned, over the playback), the RMS error of the stance leg's
hip pitch / knee / ankle pitch in single support, the largest base orientation deviation
and travelled/planned. ``--models N``: the same on N randomised models (servo stiffness
×0.7–1.4, stall torque ×0.8–1, …: :func:`wbc.bench.physics.random_model`; the compensation
only knows the nominal servo settings).

    python benchmarks/compliance.py [--trajectories walk10 static_walk]
        [--solvers wqp-daqp placo] [--gain 1] [--models 0] [--seed 0]
    python benchmarks/compliance.py --standing      # Walk Ready 2 s, servos ×0.7 / ×1.4 stiff
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from wbc import load_robot
from wbc.bench.physics import plan
from wbc.bench.play import play
from wbc.bench.sim_record import _planned, physics_record
from wbc.bench.variation import models
from wbc.recording import SUPPORT_LEFT, SUPPORT_RIGHT

STANCE = ("hip_pitch", "knee", "ankle_pitch")


def tracking(rec, result, robot) -> dict[str, float]:
    """Joint tracking figures of one simulated run (degrees), before any fall."""
    record = physics_record(rec, result, robot)
    log = result.log
    t = log["t"] - result.playback_start
    rec_t = rec.t - rec.t[0]
    end = record["fall_time_s"] if record["fell"] else rec_t[-1]
    on = (t >= 0) & (t <= end)
    err = np.degrees(log["q"][on, 7:] - _planned(rec, t[on])[:, 7:])
    k = np.clip(np.searchsorted(rec_t, t[on], side="right") - 1, 0, len(rec_t) - 1)
    sup = np.asarray(rec["support"])[k]
    stance = []
    for code, side in ((SUPPORT_LEFT, "l"), (SUPPORT_RIGHT, "r")):
        cols = [robot.joint_index(f"{side}_{j}") for j in STANCE]
        stance.append(err[sup == code][:, cols])
    stance = np.concatenate(stance)
    rms_j = np.sqrt(np.mean(stance**2, axis=0)) if len(stance) else np.full(3, np.nan)
    return {
        "rms": float(np.sqrt(np.mean(err**2))),
        "max": float(np.abs(err).max()),
        "stance_hip": float(rms_j[0]),
        "stance_knee": float(rms_j[1]),
        "stance_ankle": float(rms_j[2]),
        "dev": record["orientation_dev_max_deg"],
        "dist": record["distance_ratio"],
        "fell": record["fell"],
    }


MODES = {"none": (0.0, False), "ff": (None, False), "ff+enc": (None, True)}


def run(rec, robot, gain: float, variation=None) -> dict[str, dict[str, float]]:
    out = {}
    for mode, (g, correct) in MODES.items():
        kw = {}
        if variation is not None:
            kw = dict(model_params=variation.model_params, servo_params=variation.servo_params,
                      latency_ticks=variation.latency_ticks)  # fmt: skip
        res = play(rec, robot, settle=0.0, limit_tol=math.inf,
                   compensate=gain if g is None else g, correct=correct, **kw)  # fmt: skip
        out[mode] = tracking(rec, res, robot)
    return out


def standing(robot, gain: float) -> None:
    """Walk Ready held 2 s on servos 0.7× and 1.4× as stiff as their settings: the final
    joint errors with the feed-forward alone and with the encoder correction."""
    from wbc.recording import Recording
    from wbc.sim.actuator import ServoParams

    q = robot.configuration("walk_ready")
    t = np.arange(0.0, 2.0, 0.01)
    rec = Recording(t, np.tile(q, (len(t), 1)), robot.joint_names, {}, {})
    print("| servo stiffness | goals | final RMS° | final max° |")
    print("|---|---|---|---|")
    for stiff in (0.7, 1.4):
        sp = ServoParams.from_settings(robot.servo_map.settings).scaled(stiffness=stiff)
        for mode, correct in (("ff", False), ("ff+enc", True)):
            res = play(rec, robot, settle=0.0, limit_tol=math.inf, compensate=gain,
                       correct=correct, servo_params=sp)  # fmt: skip
            err = np.degrees(np.abs(res.log["q"][-1, 7:] - q[7:]))
            print(f"| ×{stiff} | {mode} | {np.sqrt(np.mean(err**2)):.3f} | {err.max():.3f} |")


def _f(v, fmt: str = ".2f") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trajectories", nargs="+", default=["walk10", "static_walk"])
    p.add_argument("--solvers", nargs="+", default=["wqp-daqp", "placo"])
    p.add_argument("--gain", type=float, default=1.0)
    p.add_argument("--models", type=int, default=0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--standing", action="store_true", help="the standing check only")
    args = p.parse_args()
    robot = load_robot("bioloid")
    if args.standing:
        standing(robot, args.gain)
        return
    print("| trajectory | solver | goals | RMS° | max° | stance hip° | knee° | ankle° "
          "| base dev° | travelled |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.trajectories:
        for solver in args.solvers:
            rec = plan(solver, name, robot)
            for mode, r in run(rec, robot, args.gain).items():
                fell = " (fell)" if r["fell"] else ""
                print(f"| `{name}` | {solver} | {mode} | {_f(r['rms'])} | {_f(r['max'], '.1f')} "
                      f"| {_f(r['stance_hip'])} | {_f(r['stance_knee'])} "
                      f"| {_f(r['stance_ankle'])} | {_f(r['dev'], '.1f')}{fell} "
                      f"| {_f(r['dist'])} |")  # fmt: skip
            if args.models:
                rows = {m: [] for m in MODES}
                for v in models(robot, args.models, args.seed):
                    for mode, r in run(rec, robot, args.gain, v).items():
                        rows[mode].append(r)
                for mode, rs in rows.items():
                    keys = ("rms", "stance_hip", "stance_knee", "stance_ankle", "dev")
                    mean = {k: float(np.nanmean([r[k] for r in rs])) for k in keys}
                    worst = max(r["max"] for r in rs)
                    falls = sum(r["fell"] for r in rs)
                    print(f"| `{name}` ×{args.models} models | {solver} | {mode} "
                          f"| {_f(mean['rms'])} | {_f(worst, '.1f')} | {_f(mean['stance_hip'])} "
                          f"| {_f(mean['stance_knee'])} | {_f(mean['stance_ankle'])} "
                          f"| {_f(mean['dev'], '.1f')} | {falls} fell |")  # fmt: skip


if __name__ == "__main__":
    main()
