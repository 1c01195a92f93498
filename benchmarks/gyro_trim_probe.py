"""The gyro's bias as the encoders and the rest can tell it, against the simulator's: per
``benchmarks/slip_probe.py`` recording (its calibrated gyro, the present links with the play
out, the simulated IMU's pose).

* ``--walk``: (a) the zero-velocity update of :class:`wbc.drive.gyro_trim.StanceTrim` — in the
  walking double supports (the soles' relative tilt by the encoders below ``--flat`` °), the
  gyro's heading rate less the torso's turn over the stance sole, over the other sole and
  over their mean by the encoders — against the gyro's true residual there (gyro less the
  simulator's torso), and what the residual is made of: the simulator's soles' own turn
  (their slip) and the encoders' torso turn against the simulator's (the play); the gyro's
  true residual over the whole walk less the rest's vertical bias (what the heading
  integrates with main's estimate);
* ``--rest``: (b) the rest's bias (the odometry's rest after the start-up calibration) as
  its plain mean (main) and over whole periods of the rocking (from the first to the last
  upward zero crossing of the dominant axis' de-meaned rate: raw, or smoothed over 5 ticks
  with a hysteresis of half its spread), about the vertical and per axis, less the gyro's
  true residual at rest (deg/s)::

    nice -n 10 python benchmarks/slip_probe.py --sequence 13 --model 0 --out /tmp/p.npz
    python benchmarks/gyro_trim_probe.py --walk /tmp/p.npz
    python benchmarks/gyro_trim_probe.py --rest /tmp/r_m*_c*.npz
    python benchmarks/gyro_trim_probe.py --known /tmp/p.npz --error 0.051 3.095 0.618
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pinocchio as pin

from wbc import load_robot
from wbc.drive.liftoff import soles_tilt
from wbc.drive.odometry import PoseOdometry
from wbc.geometry import yaw_of
from wbc.roles import SOLE_FRAMES

increment = PoseOdometry._increment


def walk(robot, f: str, flat_deg: float) -> None:
    """(a): the double supports' estimate against the simulator (module docstring)."""
    d = dict(np.load(f))
    t, n = d["t"], len(d["t"])
    dt = float(np.median(np.diff(t)))
    sole_yaw: dict[int, list[float]] = {0: [], 1: []}  # the torso over each sole (encoders)
    tilt = np.zeros(n)
    for k in range(n):
        q = robot.with_joints(d["links"][k])
        for s in (0, 1):
            (torso,) = robot.placements_in(q, SOLE_FRAMES[("left", "right")[s]], ["torso"])
            sole_yaw[s].append(yaw_of(torso.rotation))
        tilt[k] = math.degrees(soles_tilt(robot, q))
    enc = {s: np.unwrap(v) for s, v in sole_yaw.items()}
    torso = np.unwrap([yaw_of(R) for R in d["true_R"]])
    soles = np.unwrap(d["soles"][:, :, 3], axis=0)
    gyro = np.array([increment(d["true_R"][k - 1], d["gyro"][k], dt) for k in range(1, n)])
    rows = []
    for k in range(1, n):
        same = d["double"][k] and d["double"][k - 1] and d["stance"][k] == d["stance"][k - 1]
        if not (same and d["walking"][k]) or max(tilt[k], tilt[k - 1]) > flat_deg:
            continue
        s = int(d["stance"][k])
        o = 1 - s
        rows.append([gyro[k - 1], torso[k] - torso[k - 1], enc[s][k] - enc[s][k - 1],
                     enc[o][k] - enc[o][k - 1], soles[k, s] - soles[k - 1, s],
                     soles[k, o] - soles[k - 1, o]])  # fmt: skip
    g, tr, es, eo, ss, so = np.degrees(np.mean(rows, axis=0)) / dt
    walking = np.flatnonzero(d["walking"][1:])
    whole = math.degrees(np.mean(gyro[walking] - np.diff(torso)[walking]) / dt)
    rest = math.degrees(d["yaw_bias"][walking[0]])
    print(f"{f}: {len(rows)} double-support ticks (soles within {flat_deg}°); deg/s about "
          f"the vertical: gyro − simulator {g - tr:+.3f}; gyro − encoders over the stance "
          f"sole {g - es:+.3f}, the other {g - eo:+.3f}, their mean {g - 0.5 * (es + eo):+.3f}; "
          f"the soles' own turn (simulator) stance {ss:+.3f}, other {so:+.3f}; the torso's "
          f"turn less the encoders' and the sole's: stance {tr - es - ss:+.3f}, other "
          f"{tr - eo - so:+.3f}; the whole walk's gyro − simulator {whole:+.3f}, less the "
          f"rest's bias {rest:+.3f}: {whole - rest:+.3f}")  # fmt: skip


def known(f: str, error_deg: list[float]) -> None:
    """``--known``: the gyro's residual (gyro − the simulator's rate over the tick) less the
    true residual bias at rest and walking (the start-up calibration's error as
    ``slip_probe.py`` prints it, deg/s, torso frame: the residual bias is its negative), and
    the heading's rate error with that 3-axis bias taken out."""
    d = dict(np.load(f))
    t, R, G = d["t"], d["true_R"], d["gyro"]
    dt, n = float(np.median(np.diff(t))), len(t)
    b = -np.radians(error_deg)
    res = np.array([G[k] - pin.log3(R[k - 1].T @ R[k]) / dt for k in range(1, n)]) - b
    yaw = np.unwrap([yaw_of(x) for x in R])
    h = np.array([increment(R[k - 1], G[k] - b, dt) for k in range(1, n)]) - np.diff(yaw)
    for name, at in (("rest", d["resting"][1:]), ("walking", d["walking"][1:])):
        print(f"{f}: {name}: the residual less the true bias (deg/s; roll, pitch, yaw) "
              f"{np.round(np.degrees(res[at].mean(axis=0)), 3)}; the heading's rate with the "
              f"true bias out {math.degrees(h[at].mean() / dt):+.3f}")  # fmt: skip


def upward(x: np.ndarray, hysteresis: float) -> list[int]:
    """The upward zero crossings of ``x`` that follow a dip below −hysteresis × its spread."""
    h, out, armed = hysteresis * float(x.std()), [], False
    for k, v in enumerate(x):
        if v < -h:
            armed = True
        elif armed and v >= 0:
            out.append(k)
            armed = False
    return out


def periods(rate: np.ndarray, smooth: int, hysteresis: float) -> tuple[int, int] | None:
    """[first, last) ticks spanning whole periods of the dominant axis' de-meaned rate."""
    r = rate - rate.mean(axis=0)
    x = r[:, int(np.argmax(r.std(axis=0)))]
    x = np.convolve(x, np.ones(smooth) / smooth, mode="same") if smooth > 1 else x
    up = upward(x, hysteresis)
    return (up[0], up[-1]) if len(up) >= 2 else None


def rest(files: list[str]) -> None:
    """(b): the rest's bias, plain and over whole periods, less the truth (docstring)."""
    errors: dict[str, list[np.ndarray]] = {}
    for f in files:
        d = dict(np.load(f))
        t, R, G = d["t"], d["true_R"], d["gyro"]
        dt = float(np.median(np.diff(t)))
        at = np.flatnonzero(d["resting"])
        a, b = max(1, int(at[0])), int(at[-1]) + 1
        true = np.array([pin.log3(R[k - 1].T @ R[k]) / dt for k in range(a, b)])
        yaw = np.unwrap([yaw_of(x) for x in R[a - 1 : b]])
        heading = np.array([increment(R[k - 1], G[k], dt) for k in range(a, b)]) / dt
        truth = np.r_[np.mean(heading - np.diff(yaw) / dt), (G[a:b] - true).mean(axis=0)]
        line = f"{f}: truth (vertical; roll, pitch, yaw) {np.round(np.degrees(truth), 3)}"
        for name, smooth, hyst in (("plain", 0, 0.0), ("periods", 1, 0.0),
                                   ("periods smoothed", 5, 0.5)):  # fmt: skip
            span = (0, b - a) if name == "plain" else periods(G[a:b], smooth, hyst)
            i, j = span or (0, b - a)
            err = np.degrees(np.r_[heading[i:j].mean(), G[a + i : a + j].mean(axis=0)] - truth)
            errors.setdefault(name, []).append(err)
            line += f" | {name} {t[a + i]:.2f}–{t[a + j - 1]:.2f} s: {np.round(err, 3)}"
        print(line)
    print("mean |error| (deg/s; vertical; roll, pitch, yaw):")
    for name, e in errors.items():
        print(f"  {name:18s} {np.round(np.mean(np.abs(e), axis=0), 3)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walk", nargs="+", default=[], metavar="FILE")
    ap.add_argument("--rest", nargs="+", default=[], metavar="FILE")
    ap.add_argument(
        "--known",
        nargs="+",
        default=[],
        metavar="FILE",
        help="with --error: the residual and the heading with the true bias out",
    )
    ap.add_argument(
        "--error",
        nargs=3,
        type=float,
        default=None,
        metavar=("R", "P", "Y"),
        help="the start-up calibration's error slip_probe.py printed (deg/s)",
    )
    ap.add_argument("--flat", type=float, default=5.0, metavar="DEG",
                    help="--walk: the soles' tilt a tick may have (default 5)")  # fmt: skip
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")
    for f in args.walk:
        walk(robot, f, args.flat)
    if args.rest:
        rest(args.rest)
    if args.known and args.error is None:
        ap.error("--known needs --error R P Y")
    for f in args.known:
        known(f, args.error)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
