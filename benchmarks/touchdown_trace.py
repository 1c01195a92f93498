"""Where a touch-down's first tick goes through the deployment, stage by stage.

live_warm's walk (:func:`live_warm.play`: a live session played at 50 Hz by the deployment on
the AX-12A emulator, warm-up on), each stage of every tick timed inside it (``perf_counter_ns``
wrappers: ~15 µs a tick more): the tick (:meth:`Session.tick`), its targets
(``StackController._set_targets``), the landing's update (:meth:`SwitchHandover.update`; of it
the anchor's ``set_target``), the kinematics (:meth:`Kinematics.update`), the plan's solve and
its compiled call; ``--hot``: the same compiled call rehearsed three times right after the
tick, its warm start put back first (:func:`wbc.solvers.rehearsal.rehearse`; its best: the
call's own work, hot). Printed per walk: each stage's median over the ticks, over the
touch-downs (a double support's first tick), the lift-offs and the ticks after a touch-down
(benchmarks/self_collision.md, twenty-second session).

Run: ``python benchmarks/touchdown_trace.py [--trajectory walk10] [--stack walk_strict]
[--rounds 2] [--hot]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from live_warm import play

from wbc import load_robot
from wbc.bench.trajectories import build
from wbc.model import Kinematics
from wbc.solvers.plan import _Plan
from wbc.solvers.rehearsal import rehearse
from wbc.tasks import ContactTask
from wbc.walking.controller import StackController
from wbc.walking.handover import SwitchHandover
from wbc.walking.loop import Session

STAGES = (
    ("targets", StackController, "_set_targets"),
    ("landing update", SwitchHandover, "update"),
    ("anchor set_target", ContactTask, "set_target"),
    ("kinematics", Kinematics, "update"),
    ("plan solve", _Plan, "solve"),
)


def instrument(log: list[dict], hot: bool) -> None:
    """Each stage timed (µs) into the current tick's entry of ``log``."""
    now = time.perf_counter_ns
    current: dict = defaultdict(float)

    def timed(name, f):
        def call(*a, **k):
            start = now()
            try:
                return f(*a, **k)
            finally:
                current[name] += (now() - start) / 1e3

        return call

    for name, cls, attr in STAGES:
        setattr(cls, attr, timed(name, getattr(cls, attr)))
    solve = _Plan.solve

    def plan_solve(self, kin, dt):
        entry = self.__dict__.get("_entry")
        if entry is not None and not getattr(entry, "timed", False):
            self._entry = timed("compiled call", entry)
            self._entry.timed = True
        return solve(self, kin, dt)

    _Plan.solve = plan_solve  # type: ignore[method-assign]
    tick = Session.tick

    def traced(self, i):
        plan = self.controller.solver.fast
        warm = plan.warm_start.copy() if hot and plan is not None else None
        current.clear()
        start = now()
        q = tick(self, i)
        row = dict(current, tick=(now() - start) / 1e3, i=i)
        if warm is not None and self.controller.solver.fast is plan:
            best = np.inf
            for _ in range(3):
                np.copyto(plan.warm_start, warm)
                current.clear()
                rehearse(plan, self.controller.solver.kin, self._gap * self.ref.dt)
                best = min(best, current.get("compiled call", np.inf))
            row["hot call"] = best
        log.append(row)
        return q

    Session.tick = traced  # type: ignore[method-assign]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trajectory", default="walk10")
    parser.add_argument("--stack", default="walk_strict")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--hot", action="store_true", help="each tick's call rehearsed, hot")
    args = parser.parse_args()
    robot = load_robot("bioloid")
    ref = build(args.trajectory, robot)
    log: list[dict] = []
    instrument(log, args.hot)
    names = ["tick", *(n for n, _, _ in STAGES), "compiled call"] + ["hot call"] * args.hot
    for r in range(args.rounds):
        log.clear()
        med, _, first_ratio, *_ = play(robot, ref, args.stack, True, 50.0)
        support = ref.support[np.array([row["i"] for row in log])]
        first = np.flatnonzero(support[1:] != support[:-1]) + 1
        groups = {
            "touch-downs": first[support[first] == 0],
            "lift-offs": first[support[first] != 0],
            "after a touch-down": [k + 1 for k in first[support[first] == 0] if k + 1 < len(log)],
        }
        print(f"walk {r}: median tick {med:.0f} µs, slowest first ÷ median {first_ratio:.2f}")
        print(f"{'stage (µs)':20s} {'median':>8s}" + "".join(f" {g:>19s}" for g in groups))
        for name in names:
            t = np.array([row.get(name, 0.0) for row in log])
            cells = "".join(f" {np.median(t[k]):19.1f}" for k in groups.values())
            print(f"{name:20s} {np.median(t):8.1f}{cells}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
