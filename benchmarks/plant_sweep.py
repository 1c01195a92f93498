"""Which feedback carries the robustness? Closed-loop variants on plant-randomised models.

Every variant runs the controller live in the deployment's tick on N randomised PLANTS
(:func:`wbc.bench.physics.random_model`: servo stiffness ×0.5–2, damping, armature,
friction, backlash ≤ 1°, latency 0–20 ms, IMU bias and noise, masses and CoMs ±15 %, floor
friction) while the controller keeps the nominal ``servos.toml``. Per variant and walk:
models up / N, and on the nominal model the torso deviation and travelled / planned.

    nice -n 5 python benchmarks/plant_sweep.py --models 10 --walks walk10_wb turn_wb \\
        lateral_wb --only "closed" "closed + step"

``--gains`` and ``--stepping`` each take several JSON settings: every variant runs with each
(gains, stepping) pair side by side in one run (:func:`settings`), e.g. the old and the new
default under the same load. ``--margins`` adds a line per walk on the plants nearest a fall:
the fall criterion's angle split into the true tilt and the heading error, the torso
command's share at its clip, the servos' lag behind their goals as the loop measures it
(issue 30: on ``walk10_wb`` and ``turn_wb`` what brings a plant near the 45° line is mostly
its heading).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from _args import json_setting

from wbc import load_robot
from wbc.balance import stabilizer as stab_mod
from wbc.balance.retime import HoldParams
from wbc.balance.stabilizer import Gains, default_gains
from wbc.balance.stepping import SteppingParams
from wbc.bench import trajectories as traj
from wbc.bench.closed_loop import (
    ClosedLoopSpec,
    closed_loop_figures,
    play_closed_loop,
    simulate,
)
from wbc.bench.runner import run_entry
from wbc.bench.sim_record import _planned, _rotation, physics_record, plan_time
from wbc.bench.solvers import SolverEntry, select
from wbc.bench.variation import Variation, models
from wbc.compiled.rows import log3
from wbc.model import Robot
from wbc.recording import Recording
from wbc.sim.log import PlayResult
from wbc.sim.model import CONDIMS

#: label -> (compliance gain, gains, IMU, loop on, stepping); None: the plan played open loop
VARIANTS: dict[str, tuple[float, dict, bool, bool, bool] | None] = {
    "open": None,
    "live, loop off": (0.0, {}, True, False, False),
    "closed": (0.0, {}, True, True, False),
    "closed + step": (0.0, {}, True, True, True),
    "closed + dcm 0.3": (0.0, dict(k_dcm=0.3), True, True, False),
    "closed + dcm 0.3 + step": (0.0, dict(k_dcm=0.3), True, True, True),
    "closed + lean 1": (0.0, dict(k_lean=1.0), True, True, False),
    "closed + joint 1/0.1": (0.0, dict(j_p=1.0, j_d=0.1), True, True, False),
    "closed + torso 4/4": (0.0, dict(k_p=4.0, k_i=4.0), True, True, False),
    "closed, encoders only": (0.0, {}, False, True, False),
    "open ff 0.5": (0.5, {}, True, False, False),
    "closed ff 0.5": (0.5, {}, True, True, False),
    "closed ff 0.5 + step": (0.5, {}, True, True, True),
    "closed ff 0.25 + step": (0.25, {}, True, True, True),
}


def spec_of(
    variant,
    entry,
    ref,
    extra: dict | None = None,
    step_kw: dict | None = None,
    calibrate_s: float | None = None,
    hold: dict | None = None,
):
    """(compensate, ClosedLoopSpec or None) of a variant (``extra``: more Gains keywords,
    ``step_kw``: SteppingParams keywords, ``hold``: HoldParams keywords of the lift-off
    hold), the gains set over the closed loop's default for the variant's feed-forward
    (:func:`wbc.balance.stabilizer.default_gains`)."""
    if variant is None:
        return 0.0, None
    comp, gains, imu, on, step = variant
    stepping = SteppingParams(**(step_kw or {})) if step else None
    chosen = replace(default_gains(comp), **gains, **(extra or {}))
    return comp, ClosedLoopSpec(entry.make, ref, chosen, on, imu, stepping,
                                HoldParams(**(hold or {})), calibrate_s=calibrate_s)  # fmt: skip


def bioloid_entry(solver: str = "wqp-daqp", stack: str | None = None) -> tuple[Robot, SolverEntry]:
    """The Bioloid and ``solver``'s tick entry (``stack``: the wqp-*/hqp-* entries' stack;
    None: the physics one): the controller of the sweep and the traces."""
    return load_robot("bioloid"), select([solver], None, "tick", stack=stack)[0][0]


def planned(robot: Robot, entry: SolverEntry, walk: str) -> tuple[Any, Recording]:
    """``walk``'s reference and ``entry``'s open-loop plan of it: the recording a closed-loop
    run is measured against (:func:`~wbc.bench.sim_record.physics_record`)."""
    ref = traj.build(walk, robot)
    return ref, run_entry(entry, robot, ref, "tick")[1]


@dataclass
class PlantRun:
    """One plant's closed loop as the traces run it (:func:`plant_run`), ready to play."""

    robot: Robot
    ref: Any
    rec: Recording
    plant: Variation | None  # None: the nominal plant
    spec: ClosedLoopSpec
    compensate: float

    def play(self, on_tick: Callable[[Any], None] | None = None) -> tuple[PlayResult, dict]:
        """The run (:func:`~wbc.bench.closed_loop.play_closed_loop`, ``on_tick`` seeing the
        simulation after each logged tick) and its physics record."""
        result, _ = play_closed_loop(
            self.spec, self.robot, self.plant, compensate=self.compensate, on_tick=on_tick
        )
        return result, physics_record(self.rec, result, self.robot, self.ref)


def plant_run(walk: str, seed: int, plant: int, gains: dict, compensate: float = 0.0) -> PlantRun:
    """Plant ``plant`` of seed ``seed`` (:func:`~wbc.bench.variation.models`; < 0: the nominal
    plant) on ``walk`` as the ``closed + step`` variant runs it with the feed-forward's gain
    ``compensate`` (wqp-daqp on the physics stack; the variant's default gains, ``gains`` on
    top; the lift-off hold's defaults)."""
    robot, entry = bioloid_entry()
    ref, rec = planned(robot, entry, walk)
    variation = None if plant < 0 else models(robot, plant + 1, seed)[plant]
    _, spec = spec_of((compensate, {}, True, True, True), entry, ref, gains)
    assert spec is not None
    return PlantRun(robot, ref, rec, variation, spec, compensate)


def settings(gains: list[dict], stepping: list[dict]) -> list[tuple[dict, dict]]:
    """Every (Gains keywords, SteppingParams keywords) pair of ``--gains`` × ``--stepping``,
    in the order given (gains outer): the settings each variant runs with side by side."""
    return [(g, s) for g in gains for s in stepping]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solver", default="wqp-daqp")
    p.add_argument("--stack", help="the wqp-*/hqp-* entries' stack (default: the physics one)")
    p.add_argument("--walks", nargs="+", default=["walk10_wb", "turn_wb", "lateral_wb"])
    p.add_argument("--models", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", nargs="*", help="variant labels to run (default: all)")
    p.add_argument(
        "--gains",
        nargs="+",
        type=json_setting(Gains),
        default=[{}],
        help="JSON of Gains keywords over the variant's default (wbc.balance.stabilizer."
        "default_gains: joint_lag 1, k_d 0.03, k_dcm_i 0.25 without "
        "feed-forward), e.g. "
        "'{\"k_hip\": 0}'; "
        "several: each variant with each, side by side in one run (e.g. the old and the new "
        "default)",
    )
    p.add_argument(
        "--stepping",
        nargs="+",
        type=json_setting(SteppingParams),
        default=[{}],
        help="JSON of SteppingParams keywords; several: as --gains (every pair of the two)",
    )
    p.add_argument(
        "--hold",
        type=json_setting(HoldParams),
        default={},
        help="JSON of HoldParams keywords (the lift-off hold's), e.g. '{\"contact\": true}'",
    )
    p.add_argument("--plants", type=int, nargs="*", help="only these plants of the sweep")
    p.add_argument("--condim", type=int, default=3, choices=CONDIMS,
                   help="the randomised plants' floor contact dimensions (ModelParams.condim; "
                        "the nominal plant keeps its own)")  # fmt: skip
    p.add_argument("--no-nominal", action="store_true", help="skip the nominal plant (screens)")
    p.add_argument(
        "--calibrate",
        type=float,
        default=None,
        help="s at rest for the IMU calibration (default: closed_loop's)",
    )
    p.add_argument(
        "--why",
        action="store_true",
        help="a line per fallen plant: when, in which phase, the joint nearest its stall "
        "torque, re-plans, the plant's servo parameters",
    )
    p.add_argument(
        "--margins",
        action="store_true",
        help="a line per walk: the plants nearest a fall (largest deviation first), each "
        "with its share of the walk's ticks at the torso command's tilt clip and its "
        "largest heading command (a probe on Stabilizer.adjust: margins()); and the median "
        "and the worst-five mean of the survivors' largest deviation",
    )
    args = p.parse_args()
    robot, entry = bioloid_entry(args.solver, args.stack)
    plants = [(k, replace(v, model_params=replace(v.model_params, condim=args.condim)))
              for k, v in enumerate(models(robot, args.models, args.seed))]  # fmt: skip
    if args.plants:
        plants = [plants[k] for k in args.plants]
    print(f"{args.solver} ({entry.stack}), {args.models} randomised plants (seed {args.seed})")
    print(
        "| variant | gains | stepping | walk | nominal dev° | nominal dist | up | fallen models "
        "| dev° per plant | s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for walk in args.walks:
        ref, rec = planned(robot, entry, walk)
        runs = [(label, g, s) for label in VARIANTS for g, s in settings(args.gains, args.stepping)]
        for label, gains, step_kw in runs:
            if args.only and label not in args.only:
                continue
            comp, spec = spec_of(
                VARIANTS[label], entry, ref, gains, step_kw, args.calibrate, args.hold
            )
            started = time.perf_counter()
            r = None if args.no_nominal else simulate(rec, robot, compensate=comp, closed=spec)
            fallen, worst, why, probes = [], [], [], {}
            for k, v in plants:
                if args.margins:
                    with Probe(True) as probe:
                        run, split = split_run(rec, robot, v, comp, spec)
                    probes[k] = (split, probe.figures())
                else:
                    run = simulate(rec, robot, v, compensate=comp, closed=spec)
                worst.append(round(run["orientation_dev_max_deg"], 1))
                if run["fell"]:
                    fallen.append(k)
                    why.append(_why(k, v, run))
            dist = "-" if r is None or r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}"
            nominal = (
                "-" if r is None else "fell" if r["fell"] else f"{r['orientation_dev_max_deg']:.1f}"
            )
            print(
                f"| {label} | {json.dumps(gains)} | {json.dumps(step_kw)} | {walk} | {nominal} "
                f"| {dist} | "
                f"{len(plants) - len(fallen)}/{len(plants)} | {fallen} | {worst} | "
                f"{time.perf_counter() - started:.0f} |",
                flush=True,
            )
            if args.why:
                print("\n".join(why), flush=True)
            if args.margins:
                print(margins(plants, worst, fallen, probes), flush=True)


def split_run(rec, robot, variation, compensate: float, spec) -> tuple[dict, tuple]:
    """:func:`~wbc.bench.closed_loop.simulate`'s record of one closed-loop run and the
    split of its deviation (the fall criterion's angle, ``orientation_dev_max_deg``, counts
    tilt and heading together): the largest true tilt (the angle between the planned and
    the real torso's up axes) and the largest heading error (degrees, both until the fall)."""
    result, loop = play_closed_loop(spec, robot, variation, compensate=compensate)
    record = physics_record(rec, result, robot, spec.ref)
    record.update(closed_loop_figures(loop))
    log = result.log
    t = log["t"] - result.playback_start
    q_plan = _planned(rec, plan_time(result))  # (the reference time the walk played)
    upto = len(t)
    if record["fell"]:
        upto = int(np.searchsorted(t, record["fall_time_s"]))
    split = [tilt_and_heading(_rotation(q_plan[k, 3:7]), _rotation(log["q"][k, 3:7]))
             for k in range(upto)]  # fmt: skip
    return record, tuple(np.max(split, axis=0)) if split else (0.0, 0.0)


def tilt_and_heading(planned: np.ndarray, real: np.ndarray) -> tuple[float, float]:
    """(tilt, heading error) in degrees between two rotations: the angle between their up
    (z) axes and the absolute difference of their headings (x axes' directions in the
    horizontal plane, wrapped to ±180°)."""
    tilt = math.degrees(math.acos(min(1.0, max(-1.0, float(planned[:, 2] @ real[:, 2])))))
    d = math.atan2(real[1, 0], real[0, 0]) - math.atan2(planned[1, 0], planned[0, 0])
    return tilt, abs(math.degrees(math.remainder(d, math.tau)))


class Probe:
    """Observes :meth:`Stabilizer.adjust` during one run (``on``; else nothing): per tick
    the torso command ``log(R_cmd R_refᵀ)`` (the hip strategy's roll included), its tilt
    (horizontal) part against the gains' ``max_tilt`` and its heading part."""

    def __init__(self, on: bool) -> None:
        self.on, self.rows = on, []

    def __enter__(self) -> Probe:
        if self.on:
            self.original = original = stab_mod.Stabilizer.adjust
            rows = self.rows

            def observed(stab, targets, com_vel_ref, q_cmd, dt):
                stab.measure_lag = True  # (measured only when read)
                out = original(stab, targets, com_vel_ref, q_cmd, dt)
                if stab.last is not None:
                    cmd = np.empty(3)
                    R = out.torso_rotation @ targets.torso_rotation.T
                    log3(np.ascontiguousarray(R), cmd)
                    rows.append((math.hypot(cmd[0], cmd[1]) / stab.gains.max_tilt, abs(cmd[2]),
                                 stab.servo_lag))  # fmt: skip
                return out

            stab_mod.Stabilizer.adjust = observed
        return self

    def __exit__(self, *exc) -> None:
        if self.on:
            stab_mod.Stabilizer.adjust = self.original

    def figures(self) -> tuple[float, float, float] | None:
        """(share of ticks with the tilt command at ≥ 99 % of its clip, the largest heading
        command in degrees, the servos' median lag behind their goals in ms as the loop
        measures it: :func:`wbc.balance.servo_lag.servo_lag`), None without rows."""
        if not self.rows:
            return None
        a = np.array(self.rows)
        lag = 1e3 * float(np.median(a[:, 2]))
        return float(np.mean(a[:, 0] >= 0.99)), float(np.degrees(a[:, 1].max())), lag


def margins(plants, worst: list[float], fallen: list[int], probes: dict) -> str:
    """The ``--margins`` line: the survivors' median and worst-five mean largest deviation
    (the fall criterion's angle: tilt and heading, ``orientation_dev_max_deg``), then the
    eight plants of largest deviation (fallen marked), each with its largest true tilt and
    heading error (:func:`split_run`) and its probe's figures (:class:`Probe`); the
    survivors' largest true tilt, median and worst-five mean."""
    keys = [k for k, _ in plants]
    up = sorted(d for k, d in zip(keys, worst, strict=True) if k not in fallen)
    tilts = sorted(probes[k][0][0] for k in keys if k not in fallen and probes[k][0])
    head = "    margins: no survivor"
    if up:
        head = (f"    margins: survivors' largest deviation median {np.median(up):.1f}°, "
                f"worst five {np.mean(up[-5:]):.1f}°; their largest true tilt median "
                f"{np.median(tilts):.1f}°, worst five {np.mean(tilts[-5:]):.1f}°")  # fmt: skip
    order = sorted(zip(worst, keys, strict=True), reverse=True)[:8]
    parts = []
    for d, k in order:
        split, f = probes.get(k, (None, None))
        tag = " fell" if k in fallen else ""
        extra = "" if split is None else f" (tilt {split[0]:.1f}°, heading {split[1]:.1f}°"
        extra += (
            ""
            if f is None
            else f"; tilt cmd at clip {100 * f[0]:.0f}%, heading cmd {f[1]:.1f}°, lag {f[2]:.0f} ms"
        )
        parts.append(f"{k}: {d:.1f}°{tag}{extra}{')' if split is not None else ''}")
    lags = [f"{k}: {probes[k][1][2]:.0f}" for k in keys if probes.get(k, (0, None))[1]]
    return (head + "; nearest a fall: " + "; ".join(parts)
            + "\n    servo lag (ms, median) per plant: " + ", ".join(lags))  # fmt: skip


def _why(k: int, v, run: dict) -> str:
    """One line on a fallen plant: when, where, which joint, what the plant is."""
    s = v.summary
    keys = ("stiffness", "damping", "latency_ms", "backlash_deg", "gyro_bias")
    plant = ", ".join(f"{n} {s[n]:.3g}" for n in keys if n in s)
    return (f"    plant {k}: fell at {run['fall_time_s']:.2f} s in {run['fall_phase']} support, "
            f"{run['fall_joint']}; re-plans {run.get('replans')}; estimated tilt error up to "
            f"{run.get('estimated_tilt_max_deg', float('nan')):.1f}°; {plant}")  # fmt: skip


if __name__ == "__main__":
    main()
