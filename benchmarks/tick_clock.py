"""The two clocks of ``wbc bench --clock`` on the same ticks (benchmarks/tick_clock.md).

    python benchmarks/tick_clock.py ROBOT TRAJECTORY SOLVER... [--rounds N]

Each controller's ``track`` (the part of a tick the benchmark times) is wrapped: the thread's
CPU time (``time.thread_time_ns``) around the wall clock (``time.perf_counter_ns``) around the
call. Per run: median, p99 and largest tick on each clock, the ticks whose wall time exceeds
their CPU time by more than 1 ms (preempted), and the process's CPU time less the thread's
over the run (work on other threads, which the CPU clock would not count). First, each clock's
reading of an empty interval (its cost).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from wbc.bench import trajectories as traj
from wbc.bench.solvers import select
from wbc.model import load_robot
from wbc.walking.loop import RunOptions, run


def _timed(controller, wall: list[int], cpu: list[int]) -> None:
    track = controller.track

    def timed(*args, **kwargs):
        t0 = time.thread_time_ns()
        p0 = time.perf_counter_ns()
        q = track(*args, **kwargs)
        p1 = time.perf_counter_ns()
        t1 = time.thread_time_ns()
        wall.append(p1 - p0)
        cpu.append(t1 - t0)
        return q

    controller.track = timed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("robot")
    ap.add_argument("trajectory")
    ap.add_argument("solvers", nargs="+")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    robot = load_robot(args.robot)
    ref = traj.build(args.trajectory, robot)
    entries, _ = select(args.solvers, None, "tick", "kinematic", None)
    for name, clock in (
        ("perf_counter_ns", time.perf_counter_ns),
        ("thread_time_ns", time.thread_time_ns),
    ):
        z = np.array([-clock() + clock() for _ in range(20000)])
        print(
            f"{name}: empty interval median {np.median(z):.0f} ns, "
            f"p99 {np.percentile(z, 99):.0f} ns"
        )
    out: dict[str, list[tuple[float, float, float, float]]] = {}
    for r in range(args.rounds):
        for e in entries:
            controller = e.make(robot)
            wall: list[int] = []
            cpu: list[int] = []
            _timed(controller, wall, cpu)
            p0, t0 = time.process_time(), time.thread_time()
            rec = run(controller, robot, ref, options=RunOptions())
            p1, t1 = time.process_time(), time.thread_time()
            k = len(wall) - len(rec)  # (a rehearsal's tick first: not a tick of the run)
            W, T = np.array(wall[k:]) / 1e3, np.array(cpu[k:]) / 1e3
            row = (np.median(W), np.percentile(W, 99), np.median(T), np.percentile(T, 99))
            out.setdefault(e.name, []).append(row)
            print(
                f"{args.robot} {args.trajectory} {e.name} round {r}: {len(W)} ticks; wall median "
                f"{row[0]:.1f} p99 {row[1]:.1f} max {W.max():.0f} µs | cpu median {row[2]:.1f} "
                f"p99 {row[3]:.1f} max {T.max():.0f} µs | cpu - wall median "
                f"{np.median(T - W):.2f} µs | preempted (wall - cpu > 1 ms) "
                f"{int(np.sum(W - T > 1000))} | process - thread CPU over the run "
                f"{1e3 * ((p1 - p0) - (t1 - t0)):.1f} ms of {1e3 * (t1 - t0):.0f} ms"
            )
    if "placo" in out:
        for name, rows in out.items():
            for r, (a, b) in enumerate(zip(rows, out["placo"], strict=True)):
                print(
                    f"{name} / placo round {r}: wall median {a[0] / b[0]:.2f} p99 "
                    f"{a[1] / b[1]:.2f} | cpu median {a[2] / b[2]:.2f} p99 {a[3] / b[3]:.2f}"
                )


if __name__ == "__main__":
    main()
