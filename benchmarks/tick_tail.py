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
    ap.add_argument("--parts", action="store_true", help="with --walk: each tick's parts")
    ap.add_argument("--slowest", type=int, default=8, help="with --parts: ticks listed")
    ap.add_argument("--evict", type=float, default=0.0, help="with --parts: MB read between ticks")
    ap.add_argument("--sleep", type=float, default=0.0, help="with --parts: s slept between ticks")
    args = ap.parse_args()
    if args.walk and args.parts:
        parts_table(args)
        return
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


#: the parts of :func:`tick_parts` (µs), in the order printed
PARTS = (
    "tick (CPU)", "tick", "outside the cascade", "cascade replayed", "targets", "kinematics",
    "self-collision rows", "other rows", "warm start reset", "compiled tick - cascade",
    "compiled tick replayed - cascade",
    "plan's other Python", "limit check + solved", "solver's other Python", "handover",
    "track's other",
)  # fmt: skip


def tick_parts(
    robot, ref, spec: dict, rounds: int, evict: float = 0.0, sleep: float = 0.0
) -> tuple[dict, dict]:
    """Each tick's parts along ``ref`` (µs: :data:`PARTS`, each tick's smallest over
    ``rounds`` walks in this process) and each tick's collision work (first walk): exact
    distances, separating-axis bounds, close pairs, the limit's rows. ``evict``: MB of another
    array read after each tick (the caches as a loop that sleeps between ticks leaves them:
    other processes run meanwhile); ``sleep``: s slept after each tick (a robot's loop)."""
    from numba import typeof

    from wbc.compiled.ticks import cascade_solve
    from wbc.limits.self_collision import SelfCollisionConstraint
    from wbc.solvers.base import StackSolver
    from wbc.solvers.inequalities import ConstraintRows
    from wbc.solvers.plan import _Plan
    from wbc.stacks import build_stack
    from wbc.walking.handover import SwitchHandover
    from wbc.walking.loop import Session, StackController

    ns = time.perf_counter_ns
    excluded = [0]  # ns of the timers' own copies (taken out of the parts around them)
    cur: dict[str, int] = {}

    def timed(f, label):
        def wrapper(*a, **k):
            e0, t0 = excluded[0], ns()
            try:
                return f(*a, **k)
            finally:
                cur[label] = cur.get(label, 0) + ns() - t0 - (excluded[0] - e0)

        return wrapper

    patched = [
        (StackController, "_set_targets", "targets"), (StackSolver, "_timed_solve", "solve"),
        (StackSolver, "_outside_kin", "outside"), (ConstraintRows, "tick", "rows"),
        (SelfCollisionConstraint, "rows_into", "sc"), (SelfCollisionConstraint, "solved", "ok"),
        (_Plan, "forget_warm_start", "forget"), (_Plan, "solve", "plan"),
        (SwitchHandover, "update", "handover"),
    ]  # fmt: skip
    originals = [
        (cls, name, cls.__dict__[name]) for cls, name, *_ in (*patched, (StackController, "track"))
    ]
    for cls, name, label in patched:
        setattr(cls, name, timed(getattr(cls, name), label))
    track = StackController.track

    def timed_track(*a):  # (the loop's tick: what the benchmarks time, in both clocks)
        c0, t0 = time.thread_time_ns(), ns()
        try:
            return track(*a)
        finally:
            t1, c1 = ns(), time.thread_time_ns()
            cur["tick"], cur["cpu"] = t1 - t0 - excluded[0], c1 - c0 - excluded[0]

    StackController.track = timed_track
    raw: dict[str, list] = {}
    work: dict[str, list] = {}
    other = np.ones(int(evict * 2**17)) if evict > 0 else None
    try:
        for r in range(rounds):
            controller = StackController(build_stack(spec, robot))
            session = Session(controller, robot, ref)
            solver = controller.solver
            solver.kin.update = timed(solver.kin.update, "kin")  # (this solver's only)
            limits = [
                c for c in solver.stack.constraints() if isinstance(c, SelfCollisionConstraint)
            ]
            entries: dict[int, object] = {}
            snap: dict[str, tuple] = {}
            per: dict[str, list] = {k: [] for k in ("cpu", "tick", "cascade", "hot", "entry", *(
                label for *_, label in patched), "kin")}  # fmt: skip
            for i in range(ref.n):
                cur.clear()
                snap.clear()
                counts = limits[0].distances._counts.copy() if limits else None
                session.tick(i)
                excluded[0] = 0
                for label in per:
                    if label not in ("cascade", "hot"):
                        per[label].append(cur.get(label, 0))
                plan = solver.fast
                for layout in solver._layouts.values():  # (each plan's, once it has one)
                    p = getattr(layout, "fast", None)
                    if p is not None and p._entry is not None and id(p) not in entries:
                        entries[id(p)] = p._entry
                        p._entry = _snapshot_entry(p, p._entry, snap, cur, excluded)
                cascade, hot = _replay(plan, snap, cascade_solve, typeof) if snap else (0, 0)
                per["cascade"].append(cascade)
                per["hot"].append(hot)
                if r == 0 and limits:
                    d = limits[0].distances._counts - counts
                    for k, v in (("exact", d[0]), ("axes", d[1]), ("close", limits[0]._n_close),
                                 ("rows", limits[0]._n_rows)):  # fmt: skip
                        work.setdefault(k, []).append(int(v))
                session.prepare_next()
                if other is not None:
                    other.sum()
                if sleep > 0:
                    time.sleep(sleep)
            for k, v in per.items():
                raw.setdefault(k, []).append(v)
    finally:
        for cls, name, f in originals:
            setattr(cls, name, f)
    a = {k: np.asarray(v, dtype=float) / 1e3 for k, v in raw.items()}  # rounds x ticks, µs
    out = {
        "tick (CPU)": a["cpu"], "tick": a["tick"], "outside the cascade": a["tick"] - a["cascade"],
        "cascade replayed": a["cascade"], "targets": a["targets"], "kinematics": a["kin"],
        "self-collision rows": a["sc"], "other rows": a["rows"] - a["sc"],
        "warm start reset": a["forget"], "compiled tick - cascade": a["entry"] - a["cascade"],
        "compiled tick replayed - cascade": a["hot"] - a["cascade"],
        "plan's other Python": a["plan"] - a["rows"] - a["forget"] - a["entry"],
        "limit check + solved": a["outside"] + a["ok"],
        "solver's other Python": a["solve"] - a["kin"] - a["plan"] - a["outside"] - a["ok"],
        "handover": a["handover"],
        "track's other": a["tick"] - a["solve"] - a["targets"] - a["handover"],
    }  # fmt: skip
    out["tick (CPU)"] = np.where(out["tick (CPU)"] > 0, out["tick (CPU)"], np.nan)  # (clock
    # readings across a migration between CPUs can come out negative)
    return {k: np.nanmin(v, axis=0) for k, v in out.items()}, {
        k: np.asarray(v) for k, v in work.items()
    }


def _snapshot_entry(plan, entry, snap: dict, cur: dict, excluded: list):
    """``entry`` (the plan's compiled tick) timed into ``cur["entry"]``, its level states
    kept before and after the call into ``snap`` (for :func:`_replay`; copies not timed)."""
    g = plan.inequalities
    ns = time.perf_counter_ns

    def call(*a):
        e0 = ns()
        snap["before"] = (plan.states.copy(), g.working.copy(), g.h_eff.copy())
        snap["call"] = (entry, a)
        excluded[0] += ns() - e0
        t0 = ns()
        status = entry(*a)
        cur["entry"] = cur.get("entry", 0) + ns() - t0
        e0 = ns()
        snap["after"] = (plan.states.copy(), g.working.copy(), g.h_eff.copy(),
                         plan.achieved.copy(), plan.dq.copy(), plan.q_next.copy())  # fmt: skip
        excluded[0] += ns() - e0
        return status

    return call


def _replay(plan, snap: dict, cascade_solve, typeof) -> tuple[int, int]:
    """ns of the plan's level cascade (:func:`wbc.compiled.ticks.cascade_solve` on the rows
    the tick wrote) and of the whole compiled tick, each from the tick's start (``snap``),
    best of 5; the tick's end put back."""
    g = plan.inequalities
    args = plan.solve_args
    signature = tuple(typeof(x) for x in args)
    if signature not in cascade_solve.overloads:
        cascade_solve(*args)
    entry, tick_args = snap["call"]
    best = []
    for f, a in ((cascade_solve.overloads[signature].entry_point, args), (entry, tick_args)):
        times = []
        for _ in range(5):
            plan.states[...], g.working[...], g.h_eff[...] = snap["before"]
            t0 = time.perf_counter_ns()
            f(*a)
            times.append(time.perf_counter_ns() - t0)
        best.append(min(times))
    (plan.states[...], g.working[...], g.h_eff[...], plan.achieved[...], plan.dq[...],
     plan.q_next[...]) = snap["after"]  # fmt: skip
    return best[0], best[1]


def parts_table(args: argparse.Namespace) -> None:
    """``--walk --parts``: :func:`tick_parts` per stack and trajectory, printed."""
    from wbc.bench.trajectories import build

    sc = _load("self_collision.py", "wbc_self_collision_benchmark")
    robot = load_robot("bioloid")
    for trajectory in args.trajectories:
        ref = build(trajectory, robot)
        support = np.asarray(ref.support)
        for stack in args.stacks:
            spec = {**sc.walk_spec(True, stack), "solver": "hierarchical"}
            p, work = tick_parts(robot, ref, spec, args.rounds, args.evict, args.sleep)
            n = support.size
            first = np.zeros(n, bool)
            first[np.flatnonzero(support[1:] != support[:-1]) + 1] = True
            head = np.arange(n) < 3  # (the walk's first ticks: issue 34's other tail)
            t = p["tick"]
            slow = (t >= np.percentile(t[~head], 99)) & ~head
            groups = {
                "first of double support": first & (support == 0),
                "first of single support": first & (support != 0),
                "second of a phase": np.roll(first, 1) & ~head,
                "slowest 1 %": slow,
                "the others": ~first & ~np.roll(first, 1) & ~head & ~slow,
            }
            evicted = f", {args.evict:g} MB read between ticks" if args.evict else ""
            evicted += f", {args.sleep * 1e3:g} ms slept between ticks" if args.sleep else ""
            print(f"\n{trajectory}, {stack}{evicted}: each tick's smallest over {args.rounds} "
                  "walks, µs (medians of the groups; work: the first walk's exact distances / "
                  "separating-axis bounds / close pairs / rows)")  # fmt: skip
            print("| ticks (n) | " + " | ".join(PARTS) + " | work |")
            print("|---" * (len(PARTS) + 2) + "|")
            for name, sel in groups.items():
                w = "/".join(f"{np.median(v[sel]):.0f}" for v in work.values()) if work else ""
                cells = " | ".join(f"{np.median(p[k][sel]):.1f}" for k in PARTS)
                print(f"| {name} ({sel.sum()}) | {cells} | {w} |")
            for i in np.argsort(np.where(head, 0, t))[::-1][: args.slowest]:
                w = "/".join(str(v[i]) for v in work.values()) if work else ""
                mark = "*" if first[i] else ""
                cells = " | ".join(f"{p[k][i]:.1f}" for k in PARTS)
                print(f"| tick {i} ({support[i]}{mark}) | {cells} | {w} |")


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
