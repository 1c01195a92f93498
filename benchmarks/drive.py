"""Driving benchmark: velocity-commanded walks on the simulated robot, closed loop.

Four parts (each optional):

* ``--scripted``: straight, sideways, turning, backward and mixed command scripts at the
  planning limits on the nominal model: fell, the travelled displacement and heading against
  the commanded, the walk tick's cost (engine + feedback + solve);
* ``--random N``: N random command sequences (a new command every 2–5 s anywhere inside
  the velocity envelope, ``--duration`` s each) on ``--models M`` randomised models
  (:func:`wbc.bench.physics.random_model`, seeded): falls, the displacement error
  ``|travelled − commanded| / |commanded|`` and the heading error likewise, rated on the
  runs that stay up (a fallen run counts as a fall only);
* ``--envelope``: per axis, the command speeds ``--speeds`` × the planning limit walked
  for ``--hold`` s on ``--models`` randomised models: the fastest that stays up on all;
* ``--tick``: the walk tick's cost alone (no physics), engine alone and engine + feedback +
  solve, per controller.

    nice -n 5 python benchmarks/drive.py --scripted --tick --json results/drive.json
    nice -n 5 python benchmarks/drive.py --random 20 --models 20 --duration 30   # the target
    nice -n 5 python benchmarks/drive.py --envelope --models 20

Figures and the exact commands they came from: benchmarks/drive.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")  # time the compiled ticks, not the interim

from wbc import load_robot
from wbc.bench.solvers import registry
from wbc.bench.variation import models
from wbc.drive.commands import Command, random_commands, walked
from wbc.drive.envelope import planning_envelope
from wbc.drive.sim import drive_sim
from wbc.drive.walker import DRIVE_GAINS, default_compensate
from wbc.sim.model import CONDIMS, FRICTION_CONES, ModelParams
from wbc.walking.engine import EngineParams, VelocityLimits


def scripts(lim) -> dict[str, list[Command]]:
    """The scripted sequences at the planning limits."""
    return {
        "forward": [Command(10.0, lim.vx_forward)],
        "backward": [Command(10.0, -lim.vx_backward)],
        "left": [Command(10.0, 0.0, lim.vy)],
        "right": [Command(10.0, 0.0, -lim.vy)],
        "turn_left": [Command(10.0, 0.0, 0.0, lim.wz)],
        "turn_right": [Command(10.0, 0.0, 0.0, -lim.wz)],
        "mixed": [
            Command(3.0, 0.7 * lim.vx_forward),
            Command(3.0, 0.0, 0.7 * lim.vy),
            Command(3.0, 0.3 * lim.vx_forward, 0.0, 0.6 * lim.wz),
            Command(2.0),
            Command(3.0, -0.6 * lim.vx_backward, -0.3 * lim.vy),
        ],
    }


def errors(r: dict, commands=None) -> dict:
    """Displacement and heading errors of a run (relative where the command is not tiny);
    with ``commands`` (clipped to the run's limits, as ``commanded_xy_m``) also the path
    walked and the turn made on the way (:func:`wbc.drive.commands.walked`) and the errors
    relative to them."""
    c, t = np.asarray(r["commanded_xy_m"]), np.asarray(r["travelled_xy_m"])
    dxy = float(np.linalg.norm(t - c))
    nc = float(np.linalg.norm(c))
    dyaw = abs(r["travelled_yaw_rad"] - r["commanded_yaw_rad"])
    cy = abs(r["commanded_yaw_rad"])
    return {
        "xy_error_m": dxy,
        "xy_error_rel": dxy / nc if nc > 0.05 else None,
        "yaw_error_rad": dyaw,
        "yaw_error_rel": dyaw / cy if cy > 0.3 else None,
        **(path_errors(r, commands, dxy, dyaw) if commands is not None else {}),
    }


def path_errors(r: dict, commands, dxy: float, dyaw: float) -> dict:
    """The commanded path's length and turn (the commands clipped to ``r["limits"]``) and
    the displacement and heading errors relative to them."""
    lim = VelocityLimits(**r["limits"])
    path, turn = walked([Command(c.duration, *lim.clip(*c.velocity)) for c in commands])
    return {
        "commanded_path_m": path, "commanded_turn_rad": turn,
        "xy_error_path_rel": dxy / path if path > 0.05 else None,
        "yaw_error_turn_rel": dyaw / turn if turn > 0.3 else None,
    }  # fmt: skip


def steady_velocity(path: np.ndarray, t0: float, t1: float) -> list[float]:
    """The base's mean velocity between ``t0`` and ``t1`` s (a line fitted to x, y and the
    heading over time, start frame): the speed the walk keeps once started."""
    sel = (path[:, 0] >= t0) & (path[:, 0] <= t1)
    if sel.sum() < 10:
        return [math.nan] * 3
    t = path[sel, 0]
    return [float(np.polyfit(t, path[sel, k], 1)[0]) for k in (1, 2, 3)]


def run_one(robot, solver: str, commands, variation=None, limits=None, window=None,
            correct: bool = True, compensate: float | None = None,
            calibrate: float | None = None, calibrate_settle: float | None = None,
            track: bool = True,
            contact_reach: float | None = None, contact_rate: float | None = None,
            yaw_rest: float | None = None, finish: bool = False,
            stride_gain: float | None = None, yaw_learn: float | None = None,
            lift_gain: float | None = None, filter_heading: bool = False,
            encoder_rest: bool = False, rest_rotation: bool = False,
            play: str | float | None = None, play_hold: float | None = None,
            play_lift: bool = False,
            play_load: str | None = None, params=None, keep_clear: bool = True,
            landing_share: float | None = None, landing_contact: bool = True,
            base_hold: float | None = None,
            finish_steps: int | None = None, finish_xy: bool = False,
            heading_gain: float | None = None, quiet_stand: str | None = None,
            twist: float | None = None, slip_gain: float | None = None,
            load_ramp: bool = False, flat_liftoff: float | None = None,
            flatten: float | None = None, flatten_band: float | None = None,
            gyro_trim: float | None = None, rest_periods: bool = False,
            yaw_momentum: float | None = None, yaw_momentum_step: bool = False,
            **kw):  # fmt: skip
    entry = registry("physics")[solver]
    gain = default_compensate(correct=correct) if compensate is None else compensate
    options = {"compensate": gain, "correct": correct, "track": track}
    if not keep_clear:  # (the Walker's default: True)
        options["keep_clear"] = False
    given = {  # (the Walker's own defaults where not given)
        "calibrate_s": calibrate, "settle_s": calibrate_settle,
        "contact_reach": contact_reach, "contact_rate": contact_rate,
        "yaw_rest_s": yaw_rest, "stride_gain": stride_gain, "yaw_learn": yaw_learn,
        "lift_gain": lift_gain, "params": params,
        "filter_heading": filter_heading or None, "encoder_rest": encoder_rest or None,
        "rest_rotation": rest_rotation or None,
        "play_hold": play_hold, "play_lift": play_lift or None, "play_load": play_load,
        "hold": base_hold, "landing_share": landing_share,
        "landing_contact": None if landing_contact else False,
        "finish_steps": finish_steps, "finish_xy": finish_xy or None,
        "heading_gain": heading_gain, "quiet_stand": quiet_stand, "slip_gain": slip_gain,
        "load_ramp": load_ramp or None, "flat_liftoff": flat_liftoff, "flatten": flatten,
        "flatten_band": flatten_band, "gyro_trim": gyro_trim,
        "rest_periods": rest_periods or None,
    }  # fmt: skip
    options.update({key: value for key, value in given.items() if value is not None})
    if twist is not None:
        options["gains"] = replace(DRIVE_GAINS[track], k_twist=twist)
    if play is not None:
        options["play"] = play_of(play, variation)
    if limits is not None:
        options.update(limits=limits, window=window)
    controller = (entry.make(robot) if yaw_momentum is None else
                  with_yaw_momentum(robot, solver, yaw_momentum, yaw_momentum_step))  # fmt: skip
    r = drive_sim(robot, controller, commands, variation, walker_options=options,
                  finish=finish, **kw)  # fmt: skip
    r.update(errors(r, commands))
    return r


def with_yaw_momentum(robot, solver: str, weight: float, step: bool = False):
    """The solver's stack (a wqp-/hqp- entry's file) with a yaw-momentum task
    (:class:`wbc.tasks.YawMomentumTask`, target 0: no vertical angular momentum) at
    ``weight`` in its last level; ``step``: its target the reference torso's yaw step
    (the task's ``follow``)."""
    import tomllib

    from wbc.stacks import build_stack, stack_file
    from wbc.walking.controller import StackController

    entry = registry("physics")[solver]
    kind, backend = solver.split("-", 1)
    spec = tomllib.loads(stack_file(entry.stack).read_text())
    spec["solver"] = {"wqp": "weighted", "hqp": "hierarchical"}[kind]
    spec["levels"][-1]["tasks"] = [*spec["levels"][-1]["tasks"],
                                   {"type": "yaw_momentum", "weight": weight,
                                    "follow": step}]  # fmt: skip
    return StackController(build_stack(spec, robot, backend=backend), solver)


def play_of(play: str | float, variation=None) -> float:
    """The encoders' play the walker takes out (rad): ``"model"`` the simulated servos' own
    (the randomised model's backlash; the nominal model has none; what ``drive_sim`` gives
    by default), a number: degrees."""
    if play == "model":
        return float(getattr(variation.servo_params, "backlash", 0.0)) if variation else 0.0
    return math.radians(float(play))


def play_arg(text: str) -> str | float:
    """``--play``'s value: ``model`` or degrees (>= 0)."""
    if text == "model":
        return text
    value = float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"--play: 'model' or degrees >= 0, got {text}")
    return value


def tick_cost(robot, solvers: list[str], seconds: float = 6.0) -> dict:
    """The walk tick without physics: engine alone, and engine + estimator/feedback (on
    the commanded joints as the present ones, no IMU) + solve, per controller; µs."""
    from wbc.drive.walker import Walker

    out = {}
    for solver in solvers:
        walker = Walker(robot, registry("physics")[solver].make(robot), None)
        walker.present = lambda w=walker: w.q[7:]
        walker.command(0.6 * walker.limits.vx_forward, 0.0, 0.4 * walker.limits.wz)
        walker.start()
        for _ in range(50):  # warm up
            walker.tick()
        walker.tick_time.clear()
        n = round(seconds / walker.engine.dt)
        for _ in range(n):
            walker.tick()
        t = np.asarray(walker.tick_time) * 1e6
        out[solver] = {"p50_us": float(np.median(t)), "p99_us": float(np.percentile(t, 99)),
                       "max_us": float(t.max()), "ticks": int(t.size)}  # fmt: skip
    from wbc.walking.engine import WalkEngine
    from wbc.walking.reference import StandingState

    limits, window = planning_envelope(robot)
    e = WalkEngine(StandingState.from_robot(robot, robot.configuration("stand")), None, limits,
                   walker.engine.foot, walker.engine.legs, window)  # fmt: skip
    e.command(0.6 * limits.vx_forward, 0.0, 0.4 * limits.wz)
    e.start()
    ts = []
    for _ in range(round(seconds / e.dt)):
        t0 = time.perf_counter()
        e.tick()
        ts.append(time.perf_counter() - t0)
    t = np.asarray(ts) * 1e6
    out["engine"] = {"p50_us": float(np.median(t)), "p99_us": float(np.percentile(t, 99)),
                     "max_us": float(t.max()), "ticks": int(t.size)}  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="bioloid")
    ap.add_argument("--solver", default="hqp-daqp")
    ap.add_argument("--scripted", action="store_true")
    ap.add_argument("--only", nargs="*", help="--scripted: these scripts only")
    ap.add_argument("--random", type=int, default=0, metavar="N")
    ap.add_argument("--first", type=int, default=0, metavar="I",
                    help="--random: sequences I .. I+N-1 (a set split over processes)")  # fmt: skip
    ap.add_argument("--models", type=int, default=20)
    ap.add_argument("--first-model", type=int, default=0, metavar="K",
                    help="--random: models K .. M-1 of the --models M (a set split over "
                         "processes)")  # fmt: skip
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--envelope", action="store_true")
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0])
    ap.add_argument("--axes", nargs="+", default=["forward", "left", "turn_left"])
    ap.add_argument("--hold", type=float, default=8.0)
    ap.add_argument("--tick", nargs="*", metavar="SOLVER")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--compensate", type=float, default=None,
                    help="the compliance feed-forward's gain (default: 0.75 with the encoders' "
                         "correction, 0.5 without)")  # fmt: skip
    ap.add_argument("--no-correct", dest="correct", action="store_false",
                    help="the compliance feed-forward on the model alone (no per-servo scale "
                         "from the encoders, Walker(correct=False))")  # fmt: skip
    ap.add_argument("--no-track", dest="track", action="store_false",
                    help="no outer loop on the IMU-aided pose odometry (Walker(track=False): "
                         "the steps aim from the legs' odometry alone)")  # fmt: skip
    ap.add_argument(
        "--calibrate",
        type=float,
        default=None,
        metavar="S",
        help="the IMU's rest before the walk (default: the Walker's, CALIBRATE_S)",
    )
    ap.add_argument("--contact-reach", type=float, default=None, metavar="M",
                    help="how far the stance contact slides toward a measured landing in "
                         "single support (m; default the Walker's DRIVE_CONTACT_REACH; 0: the "
                         "planned soles)")  # fmt: skip
    ap.add_argument(
        "--contact-rate",
        type=float,
        default=None,
        metavar="M_S",
        help="how fast it slides (m/s; default the Walker's DRIVE_CONTACT_RATE)",
    )
    ap.add_argument("--yaw-rest", type=float, default=None, metavar="S",
                    help="the rest after the IMU's calibration that learns the gyro's bias "
                         "about the vertical (default: the Walker's DRIVE_YAW_REST_S; 0: "
                         "none, the default before 2026-12-05 11:40 UTC)")  # fmt: skip
    ap.add_argument("--stride-gain", type=float, default=None, metavar="G",
                    help="the largest gain on the planned stride for steps measured short "
                         "(default: the Walker's DRIVE_STRIDE_GAIN; 1: none)")  # fmt: skip
    ap.add_argument("--yaw-learn", type=float, default=None, metavar="K",
                    help="the gain of the gyro's vertical bias learnt while walking (default: "
                         "the Walker's DRIVE_YAW_LEARN; 0: at rest only)")  # fmt: skip
    ap.add_argument("--lift-gain", type=float, default=None, metavar="G",
                    help="the largest gain on the planned swing apex for a swing sole "
                         "measured low (default: the Walker's DRIVE_LIFT_GAIN; "
                         "1: none)")  # fmt: skip
    ap.add_argument("--filter-heading", action="store_true",
                    help="the outer loop's heading on the attitude filter's rate (the gyro "
                         "with the filter's bias correction; "
                         "Walker(filter_heading=True))")  # fmt: skip
    ap.add_argument(
        "--calibrate-settle",
        type=float,
        default=None,
        metavar="S",
        help="the IMU's calibration rests up to S s more until the gyro is still "
        "and takes its quietest window (Walker(settle_s=S); default 0: off)",
    )
    ap.add_argument("--rest-rotation", action="store_true",
                    help="the rest learns the gyro's whole bias (3 axes) less the torso's "
                         "rotation over the soles seen by the encoders, taken out of the rate "
                         "(Walker(rest_rotation=True); default off)")  # fmt: skip
    ap.add_argument("--gyro-trim", type=float, default=None, metavar="T0",
                    help="the gyro's bias trimmed in walking double supports against the "
                         "encoders, a prior of T0 s (Walker(gyro_trim=T0); default 0: "
                         "off)")  # fmt: skip
    ap.add_argument("--imu-integrate", action="store_true",
                    help="the simulated gyro reads the rotation since its last reading over "
                         "the time since it (SimImu(integrate=True); default off)")  # fmt: skip
    ap.add_argument("--rest-periods", action="store_true",
                    help="the rest's vertical gyro bias over whole periods of the torso's "
                         "rocking (Walker(rest_periods=True); default off)")  # fmt: skip
    ap.add_argument("--encoder-rest", action=argparse.BooleanOptionalAction, default=False,
                    help="the rest's vertical gyro bias less the torso's turn seen by the "
                         "encoders (Walker(encoder_rest=True); default off: not better on "
                         "the random set, benchmarks/drive.md)")  # fmt: skip
    ap.add_argument("--finish", action="store_true",
                    help="at each script's end the walker finishes the commanded path first "
                         "(Walker.stop(finish=True))")  # fmt: skip
    ap.add_argument("--plain-closing", action="store_true",
                    help="a stop's closing step beside the stance sole, not on the commanded "
                         "pose (EngineParams(close_on_target=False): the default before "
                         "2026-12-05 19:00 UTC)")  # fmt: skip
    ap.add_argument("--swing-settle", type=float, default=None, metavar="F",
                    help="the share of each swing at its end in which the sole only comes "
                         "down (EngineParams(settle=F); default the engine's)")  # fmt: skip
    ap.add_argument("--transfer", type=float, default=None, metavar="F",
                    help="the share of each double support within which the planned ZMP moves "
                         "onto the landed sole (EngineParams(transfer=F); default the "
                         "engine's)")  # fmt: skip
    ap.add_argument("--double-support", type=float, default=None, metavar="F",
                    help="the share of each 0.5 s step in double support (EngineParams' "
                         "GaitTiming(double_support_ratio=F); default the engine's 0.2; the "
                         "velocity limits stay the default gait's)")  # fmt: skip
    ap.add_argument("--heading-gain", type=float, default=None, metavar="K",
                    help="the share of the gyro's stance-sole heading the odometry takes at "
                         "each landing, the rest the encoders' chain (Walker(heading_gain=K); "
                         "default the Walker's)")  # fmt: skip
    ap.add_argument("--quiet-stand", choices=["off", "standing", "end"], default=None,
                    help="when the robot stands still, no torso feedback: 'end' from the "
                         "closing step's landing, 'standing' once the engine stands, 'off' "
                         "never (Walker(quiet_stand=...); default the Walker's, "
                         "wbc.drive.stand.DRIVE_QUIET_STAND)")  # fmt: skip
    ap.add_argument("--twist", type=float, default=None, metavar="K",
                    help="the torso's tilt command's part about the torso's own vertical "
                         "axis (what turns the hip yaws) scaled by K (Gains.k_twist; default "
                         "the Walker's, wbc.drive.walker.DRIVE_K_TWIST; 1: main's before "
                         "2026-12-06 21:00 UTC)")  # fmt: skip
    ap.add_argument("--settle", type=float, default=None, metavar="S",
                    help="s the robot stands after the walk ends before the run's figures "
                         "are taken (wbc.drive.sim.run's settle; default its 1 s)")  # fmt: skip
    ap.add_argument("--play", type=play_arg, default=None, metavar="model|DEG",
                    help="the encoders' gear play taken out of the walker's odometry "
                         "(Walker(play=...)): 'model' the simulated servos' own (the default, "
                         "drive_sim's), or degrees (0: the raw encoders, as before)")  # fmt: skip
    ap.add_argument("--play-hold", type=float, default=None, metavar="S",
                    help="with --play: how long a still encoder keeps its side of the play "
                         "(Walker(play_hold=S); default the Walker's)")  # fmt: skip
    ap.add_argument("--play-lift", action="store_true",
                    help="with --play: the swing's lift measured through it too "
                         "(Walker(play_lift=True))")  # fmt: skip
    ap.add_argument("--play-load", choices=["off", "still", "always"], default=None,
                    help="with --play: the loaded links' side of the play from the static "
                         "joint torques (Walker(play_load=...)): 'still' for the readings "
                         "standing still, 'always'; default the Walker's (off)")  # fmt: skip
    ap.add_argument("--landing-share", type=float, default=None, metavar="F",
                    help="each landing's placement the mean over the last share F of its "
                         "double support (Walker(landing_share=F); default the Walker's, 0: "
                         "the landing's tick alone)")  # fmt: skip
    ap.add_argument("--landing-odometry-only", dest="landing_contact", action="store_false",
                    help="with --landing-share: the mean for the outer loop's odometry only, "
                         "the engine's measured contact the landing's tick "
                         "(Walker(landing_contact=False))")  # fmt: skip
    ap.add_argument("--no-keep-clear", dest="keep_clear", action="store_false",
                    help="the stance contact's move toward the measured sole not kept clear "
                         "of the swing's planned landing (Walker(keep_clear=False): the "
                         "behaviour before 2026-12-06, failed solves turning on the "
                         "spot)")  # fmt: skip
    ap.add_argument("--base-hold", type=float, default=None, metavar="M",
                    help="after each stop, the base brought onto its commanded place, the CoM "
                         "target shifted at most M m (Walker(hold=M); default the Walker's, "
                         "0: off; measured with 0.02, DRIVE_HOLD)")  # fmt: skip
    ap.add_argument("--finish-steps", type=int, default=None, metavar="N",
                    help="finish steps after a stop when the closing step's measured landing "
                         "is off the commanded pose (the Walker's default: "
                         "DRIVE_FINISH_STEPS_AFTER, 0: none)")  # fmt: skip
    ap.add_argument("--finish-xy", action="store_true",
                    help="finish steps correct the measured position too (default: the "
                         "heading alone)")  # fmt: skip
    ap.add_argument("--friction-cone", choices=FRICTION_CONES, default=None,
                    help="the simulated floor's friction cone (ModelParams.friction_cone; "
                         "default: the plant's, pyramidal)")  # fmt: skip
    ap.add_argument("--impratio", type=float, default=None, metavar="R",
                    help="MuJoCo's impratio (ModelParams.impratio; default 1)")  # fmt: skip
    ap.add_argument("--condim", type=int, default=None, choices=CONDIMS,
                    help="the simulated floor's contact dimensions (ModelParams.condim; "
                         "default 3; 4: torsional friction)")  # fmt: skip
    ap.add_argument("--noslip", type=int, default=None, metavar="N",
                    help="MuJoCo's noslip iterations (ModelParams.noslip_iterations; "
                         "default 0)")  # fmt: skip
    ap.add_argument("--start-yaw", type=float, default=0.0, metavar="DEG",
                    help="the robot starts turned DEG about the simulator's vertical (the record "
                         "stays in the start frame)")  # fmt: skip
    ap.add_argument("--slip-gain", type=float, default=None, metavar="K",
                    help="the walker's slip_gain: the stance sole's slide by the IMU, this share "
                         "of it in the odometry (wbc.drive.slip; default 0, off)")  # fmt: skip
    ap.add_argument("--load-ramp", action="store_true",
                    help="the compliance feed-forward's load moved from sole to sole over each "
                         "walking double support, min-jerk (Walker(load_ramp=True); default "
                         "off: split by the CoM's place)")  # fmt: skip
    ap.add_argument("--flat-liftoff", type=float, default=None, metavar="DEG",
                    help="a lift-off waits while the soles' normals by the encoders differ by "
                         "more than DEG (Walker(flat_liftoff=DEG); default off)")  # fmt: skip
    ap.add_argument("--flatten", type=float, default=None, metavar="RATE",
                    help="a landed sole's contact target tilted against its tilt by the "
                         "encoders over the double support, an integral loop at RATE 1/s "
                         "(Walker(flatten=RATE); default off)")  # fmt: skip
    ap.add_argument("--flatten-band", type=float, default=None, metavar="DEG",
                    help="with --flatten: the tilt's dead band (Walker(flatten_band=DEG); "
                         "default 0)")  # fmt: skip
    ap.add_argument("--yaw-momentum", type=float, default=None, metavar="W",
                    help="a yaw-momentum task (the step's vertical angular momentum about the "
                         "CoM, as the locked body's turn) at weight W in the stack's last level "
                         "(wbc.tasks.YawMomentumTask; default off)")  # fmt: skip
    ap.add_argument("--yaw-momentum-step", action="store_true",
                    help="with --yaw-momentum: its target the reference torso's yaw step a "
                         "tick (default 0)")  # fmt: skip
    ap.add_argument("--json", type=Path)
    ap.add_argument("--plots", type=Path)
    args = ap.parse_args(argv)
    contact = {key: value for key, value in (("friction_cone", args.friction_cone),
                                             ("impratio", args.impratio),
                                             ("noslip_iterations", args.noslip),
                                             ("condim", args.condim))
               if value is not None}  # fmt: skip
    robot = load_robot(args.robot)
    limits, window = planning_envelope(robot)
    print(f"planning limits: forward {100 * limits.vx_forward:.2f} cm/s, backward "
          f"{100 * limits.vx_backward:.2f} cm/s, sideways {100 * limits.vy:.2f} cm/s, turning "
          f"{math.degrees(limits.wz):.1f} deg/s", flush=True)  # fmt: skip
    record: dict = {"robot": robot.name, "solver": args.solver, "limits": limits.as_dict(),
                    "argv": sys.argv[1:], "correct": args.correct, "track": args.track,
                    "compensate": args.compensate, "contact": contact,
                    "start_yaw_deg": args.start_yaw}  # fmt: skip
    paths = {}
    loop = {
        "correct": args.correct,
        "compensate": args.compensate,
        "calibrate": args.calibrate,
        "calibrate_settle": args.calibrate_settle,
        "track": args.track,
        "contact_reach": args.contact_reach,
        "contact_rate": args.contact_rate,
        "yaw_rest": args.yaw_rest,
        "finish": args.finish,
        "stride_gain": args.stride_gain,
        "yaw_learn": args.yaw_learn,
        "lift_gain": args.lift_gain,
        "filter_heading": args.filter_heading,
        "encoder_rest": args.encoder_rest,
        "rest_rotation": args.rest_rotation,
        "gyro_trim": args.gyro_trim,
        "rest_periods": args.rest_periods,
        "play": args.play,
        "play_hold": args.play_hold,
        "play_lift": args.play_lift,
        "play_load": {"off": ""}.get(args.play_load, args.play_load),
        "keep_clear": args.keep_clear,
        "landing_share": args.landing_share,
        "landing_contact": args.landing_contact,
        "base_hold": args.base_hold,
        "finish_steps": args.finish_steps,
        "finish_xy": args.finish_xy,
        "heading_gain": args.heading_gain,
        "quiet_stand": {"off": ""}.get(args.quiet_stand, args.quiet_stand),
        "twist": args.twist,
        "slip_gain": args.slip_gain,
        "load_ramp": args.load_ramp,
        "flat_liftoff": args.flat_liftoff,
        "flatten": args.flatten,
        "flatten_band": args.flatten_band,
        "yaw_momentum": args.yaw_momentum,
        "yaw_momentum_step": args.yaw_momentum_step,
        "start_yaw": math.radians(args.start_yaw),
        "params": None
        if not args.plain_closing
        and args.swing_settle is None
        and args.transfer is None
        and args.double_support is None
        else EngineParams(
            close_on_target=not args.plain_closing,
            **({} if args.swing_settle is None else {"settle": args.swing_settle}),
            **({} if args.transfer is None else {"transfer": args.transfer}),
            **(
                {}
                if args.double_support is None
                else {
                    "timing": replace(
                        EngineParams().timing, double_support_ratio=args.double_support
                    )
                }
            ),
        ),
    }
    if args.settle is not None:
        if not args.settle >= 0:  # (NaN too)
            ap.error(f"--settle must be >= 0 s, got {args.settle}")
        loop["settle"] = args.settle
    if args.tick is not None:
        solvers = args.tick or ["hqp-daqp", "wqp-daqp", "qp-vat", "placo", "pink"]
        record["tick"] = tick_cost(robot, solvers)
        for k, v in record["tick"].items():
            print(f"tick {k}: p50 {v['p50_us']:.0f} µs, p99 {v['p99_us']:.0f} µs, "
                  f"max {v['max_us']:.0f} µs", flush=True)  # fmt: skip
    if args.scripted:
        record["scripted"] = {}
        for name, cmds in scripts(limits).items():
            if args.only and name not in args.only:
                continue
            t0 = time.perf_counter()
            r = run_one(robot, args.solver, cmds, limits=limits, window=window,
                        model_params=ModelParams(**contact), **loop)  # fmt: skip
            paths[name] = (r.pop("_path"), cmds)
            if len(cmds) == 1:  # the speed kept from 3 s in to 1 s before the stop
                r["steady_velocity"] = steady_velocity(paths[name][0], 3.0, cmds[0].duration - 1)
            record["scripted"][name] = r
            rel = r["xy_error_rel"]
            cy, ty = math.degrees(r["commanded_yaw_rad"]), math.degrees(r["travelled_yaw_rad"])
            print(f"{name:10s} fell {r['fell']!s:5s} commanded {np.round(r['commanded_xy_m'], 3)}"
                  f" m {cy:.0f}° travelled {np.round(r['travelled_xy_m'], 3)} m {ty:.0f}°"
                  f" xy err {'-' if rel is None else f'{100 * rel:.0f} %'} steady "
                  f"{np.round(r.get('steady_velocity', []), 4)} "
                  f"tick p50 {r['walk_tick_ms_p50']:.2f} ms ({time.perf_counter() - t0:.0f} s)"
                  f" failed solves {r['failed_solves']}", flush=True)  # fmt: skip
    variations = models(robot, args.models, args.seed) if (args.random or args.envelope) else []
    if contact:  # the randomised plants with the contact options asked for
        variations = [replace(v, model_params=replace(v.model_params, **contact))
                      for v in variations]  # fmt: skip
    if args.imu_integrate:  # the simulated gyro a delta-angle IMU's (SimImu(integrate=True))
        variations = [replace(v, imu={**v.imu, "integrate": True}) for v in variations]
    if args.random:
        runs = []
        share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
        for i in range(args.first, args.first + args.random):
            cmds = random_commands(np.random.default_rng([args.seed, 1000 + i]), share,
                                   args.duration)  # fmt: skip
            for k, v in enumerate(variations):
                if k < args.first_model:
                    continue
                r = run_one(robot, args.solver, cmds, v, limits=limits, window=window, **loop)
                r.pop("_path")
                runs.append({"sequence": i, "model": k, **r})
                print(f"sequence {i} model {k}: fell {r['fell']} xy err "
                      f"{r['xy_error_m'] * 1000:.0f} mm ({r['xy_error_rel']}) yaw err "
                      f"{math.degrees(r['yaw_error_rad']):.1f}° ({r['yaw_error_rel']}); "
                      f"of the path {1000 * r['commanded_path_m']:.0f} mm: "
                      f"{r['xy_error_path_rel']}, of the turn "
                      f"{math.degrees(r['commanded_turn_rad']):.0f}°: {r['yaw_error_turn_rel']}; "
                      f"failed solves {r['failed_solves']}", flush=True)  # fmt: skip
                for cause, n in r["failed_solve_causes"].items():
                    print(f"  {n} × {cause}", flush=True)
        up = [r for r in runs if not r["fell"]]  # (a fallen run's displacement is the fall's)
        causes: Counter[str] = Counter()
        for r in runs:
            causes.update(r["failed_solve_causes"])
        rel = [r["xy_error_rel"] for r in up if r["xy_error_rel"] is not None]
        yrel = [r["yaw_error_rel"] for r in up if r["yaw_error_rel"] is not None]
        prel = [r["xy_error_path_rel"] for r in up if r["xy_error_path_rel"] is not None]
        trel = [r["yaw_error_turn_rel"] for r in up if r["yaw_error_turn_rel"] is not None]
        record["random"] = {
            "runs": runs,
            "falls": int(sum(r["fell"] for r in runs)),
            "within_15pct_xy": int(sum(x <= 0.15 for x in rel)), "xy_rated": len(rel),
            "within_15pct_yaw": int(sum(x <= 0.15 for x in yrel)), "yaw_rated": len(yrel),
            "xy_error_path_rel_max": max(prel, default=None),
            "yaw_error_turn_rel_max": max(trel, default=None),
            "xy_error_m_median": float(np.median([r["xy_error_m"] for r in up])) if up else None,
            "failed_solves": int(sum(r["failed_solves"] for r in runs)),
            "runs_with_failed_solves": int(sum(r["failed_solves"] > 0 for r in runs)),
            "failed_solve_causes": dict(causes),
        }  # fmt: skip
        print(f"random: {len(runs)} runs, {record['random']['falls']} falls; of the runs up: "
              f"displacement within 15 %: {record['random']['within_15pct_xy']}/{len(rel)}, "
              f"heading within 15 %: {record['random']['within_15pct_yaw']}/{len(yrel)}, "
              f"median displacement error {record['random']['xy_error_m_median']} m; "
              f"the largest error of the path walked {max(prel, default=None)}, of the turn "
              f"made {max(trel, default=None)}; "
              f"failed solves {record['random']['failed_solves']} in "
              f"{record['random']['runs_with_failed_solves']} runs")  # fmt: skip
        for cause, n in causes.most_common():
            print(f"  {n} × {cause}")
    if args.envelope:
        env = {}
        for axis in args.axes:
            env[axis] = []
            for s in args.speeds:
                cmd = scripts(limits)[axis][0]
                c = Command(args.hold, s * cmd.vx, s * cmd.vy, s * cmd.wz)
                scaled = type(limits)(*(s * v for v in limits.as_dict().values()))
                fell, failed = [], 0
                for k, v in enumerate(variations):
                    r = run_one(robot, args.solver, [c], v, limits=scaled, window=window, **loop)
                    if r["fell"]:
                        fell.append(k)
                    failed += r["failed_solves"]
                up = len(variations) - len(fell)
                env[axis].append({"speed": [c.vx, c.vy, c.wz], "up": up,
                                  "models": len(variations), "fell": fell,
                                  "failed_solves": failed})  # fmt: skip
                print(f"envelope {axis} ×{s:g}: {up}/{len(variations)} up (fell: models "
                      f"{fell or 'none'}; failed solves {failed})", flush=True)  # fmt: skip
        record["envelope"] = env
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(record, indent=1, default=float))
    if args.plots and paths:
        plot_paths(paths, args.plots / "drive_paths.png")
    return 0


def plot_paths(paths: dict, out: Path) -> None:
    """The scripted runs' base paths beside the commanded ones (start frame)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wbc.drive.commands import integrate

    fig, ax = plt.subplots(figsize=(7, 6))
    for k, (name, (path, cmds)) in enumerate(paths.items()):
        color = f"C{k}"
        ax.plot(path[:, 1], path[:, 2], color=color, label=f"{name} (simulated)")
        pts = [np.zeros(2)]
        acc: list[Command] = []
        for c in cmds:
            for f in np.linspace(0.1, 1.0, 10):
                pts.append(integrate([*acc, Command(f * c.duration, c.vx, c.vy, c.wz)])[0])
            acc.append(c)
        pts = np.array(pts)
        ax.plot(pts[:, 0], pts[:, 1], "--", color=color, alpha=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, start frame)")
    ax.set_ylabel("y (m)")
    ax.set_title("driven walks: simulated base (solid) and commanded (dashed)")
    ax.legend(fontsize=7)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    sys.exit(main())
