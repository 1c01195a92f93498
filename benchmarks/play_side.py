"""Where a link sits in its gear's play, against what the odometry's reading takes: one driven
random sequence on one randomised Bioloid (as ``benchmarks/drive.py --random``, the defaults),
and beside the walker's own :class:`~wbc.drive.odometry.PlayInverse` shadow estimators fed the
same present positions every control tick (they change nothing the walker does):

* ``main``: the walker's (the side of the reading's last change, the middle after the hold);
* ``raw``: the encoders' reading itself;
* ``oracle``: the simulator's own side (the link less the servo's motor-side position,
  :class:`~wbc.sim.actuator.ServoArray`): the best a side can do on these readings;
* ``load_still`` / ``load_always``: ``PlayInverse(load="still" / "always")``, the side the
  static joint torques' load pushes each link to
  (:meth:`~wbc.balance.compliance.ComplianceCompensator.torques`, the planned support);
* ``holdNNN``: the side kept only NNN ms after the reading's last change (the default 100);
* ``decay30``: the side × exp(−still / 30 ms).

Per estimator: the mean |link − truth| (millidegrees) of the leg joints, stance leg and swing
leg in single support, both in double support (the truth at the tick, the reading a tick
older: the lag is in every estimator alike), and at each landing the swing sole's placement
relative to the stance sole by forward kinematics of the estimate against that of the
simulator's joints (world axes, summed over the landings: the play's share of the leg
odometry's placement error), and averaged over the double support that follows each
landing (the two soles standing, their relative placement fixed). Then, over the leg
joints, the simulator's side of the play (−1 … 1 of half the play) times the reading's
last-change side, by how long the reading has stood still, and times the load's side.
benchmarks/drive.md quotes it::

    nice -n 5 python benchmarks/play_side.py --sequence 13 --model 0
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import drive

import wbc.drive.sim as drive_sim_module
from wbc import load_robot
from wbc.balance.compliance import ComplianceCompensator
from wbc.bench.variation import models
from wbc.drive.commands import random_commands
from wbc.drive.envelope import planning_envelope
from wbc.drive.odometry import PlayInverse
from wbc.geometry import yaw_of
from wbc.types import SUPPORT_DOUBLE

SOLES = {"left": "l_sole", "right": "r_sole"}
SHADOWS = ("load_still", "load_always", "hold005", "hold015", "hold035", "decay30")
ESTIMATORS = ("main", "raw", "oracle", *SHADOWS)
STILL_BINS = ((0, 0.005), (0.005, 0.015), (0.015, 0.035), (0.035, 0.065), (0.065, 0.105),
              (0.105, 0.3), (0.3, math.inf))  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sequence", type=int, default=13)
    ap.add_argument("--model", type=int, default=0)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")
    loads = ComplianceCompensator(robot)
    names = [robot.model.names[i] for i in range(2, robot.model.njoints)]
    leg = ("hip", "knee", "ankle")
    legs = {side: [i for i, n in enumerate(names) if n.startswith(side[0] + "_")
                   and any(k in n for k in leg)] for side in SOLES}  # fmt: skip
    errors: dict[str, dict[str, list]] = {e: {"stance": [], "swing": [], "double": []}
                                          for e in ESTIMATORS}  # fmt: skip
    landings: dict[str, list] = {e: [] for e in ESTIMATORS}
    averaged: dict[str, list] = {e: [] for e in ESTIMATORS}  # over each double support
    sides: list[np.ndarray] = []  # (still s, true side × last-change side, × load side)
    sims: list = []
    base = drive_sim_module.Walker

    class Shadowed(base):  # the run's walker with the shadow estimators beside its own
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            assert self.play is not None, "a model with play"
            play, hold = 2 * self.play.half, self.play.hold
            self.shadow = {
                "load_still": PlayInverse(play, robot.n_joints, hold, "still"),
                "load_always": PlayInverse(play, robot.n_joints, hold, "always"),
                "plain": PlayInverse(play, robot.n_joints, hold),
            }
            self.estimates: dict[str, np.ndarray] = {}
            self._open: tuple | None = None  # the landing whose double support goes on

        def tick(self, dt=None):
            present = self.present()
            q = super().tick(dt)
            if present is None or not sims or self.last is None or self._links is None:
                return q
            sim, step = sims[0], self.engine.dt if dt is None else dt
            support = self.last.support
            push = -np.sign(loads.torques(self._links, support))
            truth = sim.q()[7:]
            servos = sim.servos
            own = self.play
            est = {"main": self._links, "raw": present,
                   "oracle": truth - servos.angles(servos.motor) + present}  # fmt: skip
            for key in ("load_still", "load_always"):
                est[key] = self.shadow[key].update(present, step, push)
            plain = self.shadow["plain"]
            plain.update(present, step)
            for ms in (5, 15, 35):
                est[f"hold{ms:03d}"] = present + plain.half * np.where(
                    plain.still <= ms / 1000.0, plain.side, 0.0
                )
            est["decay30"] = present + plain.half * plain.side * np.exp(-plain.still / 0.03)
            self.estimates = est
            if support == SUPPORT_DOUBLE and self._open is not None:
                self._open[1].append(self._placement_errors(sim, *self._open[0]))
            elif support != SUPPORT_DOUBLE and self._open is not None:
                rows = self._open[1]
                for key in ESTIMATORS if rows else ():
                    averaged[key].append(np.mean([row[key] for row in rows], axis=0))
                self._open = None
            if support == SUPPORT_DOUBLE:
                groups = {"double": legs["left"] + legs["right"]}
            else:
                st = "left" if self.last.support_frame == SOLES["left"] else "right"
                sw = "right" if st == "left" else "left"
                groups = {"stance": legs[st], "swing": legs[sw]}
            for key, value in est.items():
                for group, idx in groups.items():
                    errors[key][group].append(np.abs(value - truth)[idx])
            both = legs["left"] + legs["right"]
            true_side = (truth - servos.angles(servos.motor)) / np.maximum(own.half, 1e-12)
            sides.append(np.c_[own.still[both], (true_side * own.side)[both],
                               (true_side * push)[both]])  # fmt: skip
            return q

        def _placement_errors(self, sim, stance: str, swing: str) -> dict[str, np.ndarray]:
            """Per estimate: the swing sole's placement from the stance sole by forward
            kinematics less that of the simulator's joints (x, y world axes; turn)."""
            frames = [SOLES[swing]]
            (true_rel,) = robot.placements_in(robot.with_joints(sim.q()[7:]),
                                              SOLES[stance], frames)  # fmt: skip
            yaw = yaw_of(sim.site_pose(SOLES[stance]).rotation)
            c, s = math.cos(yaw), math.sin(yaw)
            world = np.array([[c, -s], [s, c]])
            out = {}
            for key, value in self.estimates.items():
                (rel,) = robot.placements_in(robot.with_joints(value), SOLES[stance], frames)
                d = world @ (rel.translation[:2] - true_rel.translation[:2])
                out[key] = np.r_[d, yaw_of(rel.rotation) - yaw_of(true_rel.rotation)]
            return out

        def _landed(self, step):
            out = super()._landed(step)
            if self.estimates and sims:
                stance = "right" if step.side == "left" else "left"
                errs = self._placement_errors(sims[0], stance, step.side)
                for key, value in errs.items():
                    landings[key].append(value)
                self._open = ((stance, step.side), [])  # the double support's ticks to come
            return out

    class Watched(drive_sim_module.Odometer):
        def __init__(self, sim) -> None:
            super().__init__(sim)
            sims.append(sim)

    drive_sim_module.Walker, drive_sim_module.Odometer = Shadowed, Watched
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    cmds = random_commands(np.random.default_rng([args.seed, 1000 + args.sequence]), share,
                           args.duration)  # fmt: skip
    variation = models(robot, args.model + 1, args.seed)[args.model]
    r = drive.run_one(robot, "hqp-daqp", cmds, variation, limits=limits, window=window)
    err = np.subtract(r["travelled_xy_m"], r["commanded_xy_m"])
    print(f"sequence {args.sequence} model {args.model} (play "
          f"{math.degrees(variation.servo_params.backlash):.2f}°): fell {r['fell']}, "
          f"displacement error {1e3 * np.linalg.norm(err):.0f} mm")  # fmt: skip
    for key in ESTIMATORS:
        parts = ", ".join(f"{g} {1e3 * math.degrees(np.mean(np.concatenate(v))):.0f}"
                          for g, v in errors[key].items() if v)  # fmt: skip
        a = np.array(landings[key])
        print(f"  {key:12s} mean |link error| (mdeg): {parts}; {len(a)} landings: Σ placement "
              f"({1e3 * a[:, 0].sum():+.1f}, {1e3 * a[:, 1].sum():+.1f}) mm, Σ |placement| "
              f"{1e3 * np.linalg.norm(a[:, :2], axis=1).sum():.0f} mm, Σ turn "
              f"{math.degrees(a[:, 2].sum()):+.2f}°")  # fmt: skip
    for key in ESTIMATORS:
        a = np.array(averaged[key])
        if a.size:
            print(f"  {key:12s} the placement averaged over each landing's double support "
                  f"({len(a)}): Σ ({1e3 * a[:, 0].sum():+.1f}, {1e3 * a[:, 1].sum():+.1f}) mm, "
                  f"Σ |placement| {1e3 * np.linalg.norm(a[:, :2], axis=1).sum():.0f} mm, "
                  f"Σ turn {math.degrees(a[:, 2].sum()):+.2f}°")  # fmt: skip
    b = np.concatenate(sides)
    for lo, hi in STILL_BINS:
        m = (b[:, 0] >= lo) & (b[:, 0] < hi)
        if m.any():
            print(f"  reading still {1e3 * lo:.0f}–{1e3 * hi:.0f} ms: {m.sum():6d} joint-ticks, "
                  f"the link's side × the last change's {b[m, 1].mean():+.2f}, × the load's "
                  f"{b[m, 2].mean():+.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
