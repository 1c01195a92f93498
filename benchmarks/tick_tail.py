"""The tail of the control tick's time: on random problems (issue 28), and along walks (issue
34: the first tick of a support phase, the first ticks of a walk).

    python benchmarks/tick_tail.py --n 400 --ticks 10
    python benchmarks/tick_tail.py --walk --rounds 5 --cpu

Random problems: trials drawn as ``benchmarks/stress.py`` draws them (seed 2024), always on
the ``walk`` stack (hard contacts and self-collision rows), DAQP, compiled or numpy path as
drawn; ``--ticks`` ticks each. Ticks from starts outside the limits or inside a collision
margin are infeasible as linearised and go through the recovery re-solve; they make the tail.
Prints the median, p99 and largest tick time (ms) and the ticks above 5 and 20 ms, with the
slowest trials, and the Gauss–Newton steps of the ticks' recoveries (``recovery_steps``, at
most ``TICK_RECOVERY_STEPS``); the first ``--skip`` trials (4) are left out (they load the
kernels).

``--walk``: each stack of ``--stacks`` (walk, walk_strict), with and without its
self-collision entry, the hierarchical QP compiled, along each of ``--trajectories`` by
:func:`wbc.walking.loop.run` (``--rounds`` interleaved rounds; ``--cpu``: ticks timed in CPU
time). Per run: the median tick, the median of the support phases' first ticks (*switch*),
the walk's first tick and the p99 of its first 5 % of ticks; each also as a ratio to the run's
median (issue 34's target: <= 2). Figures are medians over rounds.
"""

from __future__ import annotations

import argparse
import importlib.util
import resource
import sys
import time
from pathlib import Path

import numpy as np

from wbc import WbcError, load_robot
from wbc.solvers.recovery import TICK_RECOVERY_STEPS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--ticks", type=int, default=10)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--skip", type=int, default=4)
    ap.add_argument("--walk", action="store_true", help="the walks' support switches instead")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--trajectories", nargs="+", default=["walk10", "walk10_wb", "turn"])
    ap.add_argument("--stacks", nargs="+", default=["walk", "walk_strict"])
    ap.add_argument("--cpu", action="store_true", help="time the ticks in CPU time")
    args = ap.parse_args()
    if args.walk:
        walks(args)
        return
    stress = _load("stress.py", "wbc_stress_benchmark")
    stress.compile_first()
    robot = load_robot("bioloid")
    times, where, steps = [], [], []
    for trial in range(args.n):
        p = stress.draw(robot, np.random.default_rng([args.seed, trial]), ["daqp"])
        q = stress.start(robot, p)
        compiled = None if p["compiled"] else False
        solver, _, com, swing, torso = stress.walk_stack(
            robot, q, p["kind"], "daqp", compiled, p["double"]
        )
        stress.move_targets(p, com, swing, torso)
        for tick in range(args.ticks):
            start = time.perf_counter()
            try:
                q = solver.step(q, 0.01)
            except WbcError:
                break
            finally:
                if trial >= args.skip:
                    times.append(time.perf_counter() - start)
                    where.append((trial, tick))
                    steps.append(solver.recovery_steps)
    t = np.asarray(times) * 1e3
    order = np.argsort(t)[::-1][:5]
    print(
        f"{t.size} ticks: median {np.median(t):.2f} ms, p99 {np.percentile(t, 99):.1f} ms, "
        f"largest {t.max():.1f} ms; above 5 ms: {(t > 5).sum()}, above 20 ms: {(t > 20).sum()}"
    )
    print("slowest (trial, tick): " + ", ".join(f"{where[i]} {t[i]:.1f} ms" for i in order))
    s = np.asarray(steps)
    most = np.argsort(s)[::-1][:5]
    print(
        f"Gauss–Newton steps of a tick's recovery: ticks with any {(s > 0).sum()}, most "
        f"{s.max()} (at most {TICK_RECOVERY_STEPS}); the most (trial, tick): "
        + ", ".join(f"{where[i]} {s[i]} ({t[i]:.1f} ms)" for i in most)
    )


def walks(args: argparse.Namespace) -> None:
    """The support switches' and the first ticks' times along walks (``--walk``)."""
    from wbc.bench.trajectories import build
    from wbc.stacks import build_stack
    from wbc.walking.loop import StackController, run

    if args.cpu:  # the loop's tick timer (wbc.walking.loop reads time.perf_counter)
        time.perf_counter = time.process_time
    sc = _load("self_collision.py", "wbc_self_collision_benchmark")
    robot = load_robot("bioloid")
    refs = {name: build(name, robot) for name in args.trajectories}
    runs = [(trajectory, stack, on) for trajectory in args.trajectories
            for stack in args.stacks for on in (False, True)]  # fmt: skip
    figures: dict[tuple, list] = {r: [] for r in runs}
    for _ in range(args.rounds):
        for trajectory, stack, on in runs:
            spec = {**sc.walk_spec(on, stack), "solver": "hierarchical"}
            controller = StackController(build_stack(spec, robot))
            switches = [0]
            start = controller.start

            def started(*a, start=start, s=switches) -> None:
                start(*a)
                s[0] = _switches()  # (the first tick's count from here)

            controller.start = started  # type: ignore[method-assign]
            rec = run(
                controller,
                robot,
                refs[trajectory],
                on_tick=lambda *_, s=switches: s.append(_switches()),
            )
            t = rec["solve_time"] * 1e6
            quiet = np.diff(switches) == 0  # no other process ran during the tick
            support = rec["support"]
            switch = np.flatnonzero(support[1:] != support[:-1]) + 1
            first = t[: max(1, t.size // 20)]
            median = np.median(t)
            figures[(trajectory, stack, on)].append(
                (median, np.median(t[switch]), t[0], np.percentile(first, 99),
                 np.percentile(first[quiet[: first.size]], 99), switch.size,
                 first.size - quiet[: first.size].sum())
            )  # fmt: skip
    clock = "CPU" if args.cpu else "wall-clock"
    print(f"{args.rounds} interleaved rounds, {clock} µs (medians over rounds)")
    print(
        "| trajectory | stack | self-collision | median | switch | switch / median "
        "| first tick | first / median | p99 first 5 % | p99 first 5 % / median "
        "| p99 first 5 %, ticks not preempted | / median | preempted | switches |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (trajectory, stack, on), rows in figures.items():
        a = np.asarray(rows)
        ratios = np.median(a[:, 1:5] / a[:, :1], axis=0)  # (each round's ratio)
        med, sw, first, head, quiet, n, preempted = np.median(a, axis=0)
        print(
            f"| {trajectory} | {stack} | {'on' if on else 'off'} | {med:.1f} | {sw:.1f} |"
            f" {ratios[0]:.2f} | {first:.1f} | {ratios[1]:.2f} | {head:.1f} | {ratios[2]:.2f} |"
            f" {quiet:.1f} | {ratios[3]:.2f} | {preempted:.0f} | {n:.0f} |"
        )


def _switches() -> int:
    """This process's context switches so far (a tick during which another process ran is
    preempted: its time, CPU time included, carries the caches that process evicted)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_nivcsw + usage.ru_nvcsw


def _load(filename: str, name: str):
    """A module of this folder (benchmarks/ is no package)."""
    path = Path(__file__).with_name(filename)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


if __name__ == "__main__":
    main()
