"""Where one control tick's time goes: the parts of a compiled tick, timed one by one.

The core ``walk`` stack (as benchmarks/qp_tick.py) is walked along ``walk10`` to tick 150
(single support); then each part of that tick is called repeatedly at the same configuration:
the loop's tick as benchmarks/qp_tick.py times it, a tick with a support switch (at the
configuration before the walk's next switch, its phase and the one before in turn), setting
the targets, the kinematics, the generated tick (one numba call), calling a do-nothing
compiled function with the same arguments (numba's cost of unboxing them), and the solve alone
(bounds, least squares, integration). Best of 200 × 50 calls, µs. Then the solve alone
(bounds, least squares, integration) of every tick of the walk but the first of each support
phase, replayed at once from the warm start the loop gave it, best of 7 (the active sets'
own tail, without the machine's preemptions): median, p90, p99 and max, µs. Last, the parts of
each tick of the walk timed once as it runs, the first ticks of the support phases apart
(:func:`switch_parts`: where the tail of a walk's tick times comes from).

Run: ``python benchmarks/tick_profile.py`` (writes nothing; figures in qp_tick.md).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from numba import njit, typeof

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from qp_tick import core_walk_spec

from wbc import load_robot
from wbc.bench.trajectories import build
from wbc.compiled import ticks as T
from wbc.stacks import build_stack
from wbc.walking.loop import Session, StackController


def best(f, calls: int = 50, repeats: int = 200) -> float:
    """Best mean µs per call of f over ``repeats`` batches of ``calls`` (short batches: on a
    loaded machine some of them run unpreempted)."""
    f()
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(calls):
            f()
        out.append((time.perf_counter() - t) / calls * 1e6)
    return min(out)


def noop_entry(args: tuple):
    """The entry point of a compiled function that takes ``args`` and does nothing."""
    names = ", ".join(f"a{i}" for i in range(len(args)))
    space: dict = {}
    exec(f"def noop({names}):\n    return 0\n", space)
    noop = njit(space["noop"])
    noop(*args)
    return noop.overloads[tuple(typeof(a) for a in args)].entry_point


def profile(robot, ref, kind: str, at: int = 150) -> dict[str, float]:
    controller = StackController(build_stack({**core_walk_spec(), "solver": kind}, robot))
    session = Session(controller, robot, ref)
    for i in range(at):
        session.tick(i)
    targets = session.targets(at)
    q = session.q.copy()
    # the next support switch of the walk: the configuration before it, the targets of the
    # tick before it and of the switch itself (in turn: a switch at every call)
    phase = (targets.phase, targets.swing)
    switch = next(
        i
        for i in range(at, len(ref))
        if (session.targets(i).phase, session.targets(i).swing) != phase
    )
    for i in range(at, switch):
        session.tick(i)
    q_switch = session.q.copy()
    switched = [session.targets(switch), session.targets(switch - 1)]
    solver = controller.solver
    plan = solver.fast
    args = (q, *plan.packed)  # the tick's arguments: q, the buffers' addresses, the direct ones
    noop = noop_entry(args)

    solve = solve_call(plan, kind)

    return {
        "the loop's tick (controller.track: what qp_tick.py times)": best(
            lambda: controller.track(q, targets, 0.01, False)
        ),
        "a tick with a support switch (set_phase, re-plan; two phases in turn)": best(
            lambda: controller.track(q_switch, switched.reverse() or switched[0], 0.01, True)
        ),
        "setting the targets": best(lambda: controller._set_targets(q, targets, False)),
        "solver.step": best(lambda: solver.step(q, 0.01)),
        "Kinematics.update": best(lambda: solver.kin.update(q)),
        "the generated tick (one numba call)": best(
            lambda: plan.ticks.call(plan.tick_name, plan.variant, args)
        ),
        "calling a no-op with the same arguments": best(lambda: noop(*args)),
        "least squares + integration (the bounds: filled by the tick)": best(solve),
    }


def solve_call(plan, kind: str):
    """The plan's solve alone (bounds, least squares, integration) on its filled rows."""
    g = plan.inequalities
    if kind == "weighted":
        return lambda: T.weighted_solve(
            plan.soft.J, plan.soft.b, plan.hard.J, plan.hard.b, g.G, g.h, g.g_rows, plan.q,
            plan.q_min, plan.q_max, plan.params, plan.lower, plan.upper, plan.state,
            g.working[0], plan.dq, plan.q_next,
        )  # fmt: skip
    return lambda: T.cascade_solve(
        plan.rows.J, plan.rows.b, plan.level_rows, plan.level_hard, g.G, g.h, g.g_rows,
        plan.q, plan.q_min, plan.q_max, plan.params, plan.lower, plan.upper, plan.states,
        g.working, g.h_eff, plan.achieved, plan.dq, plan.q_next,
    )  # fmt: skip


def walk_solves(robot, ref, kind: str) -> list[float]:
    """µs of the solve of each tick of the walk (not the first of a support phase), replayed
    right after the tick from the warm start the loop gave it, best of 7."""
    controller = StackController(build_stack({**core_walk_spec(), "solver": kind}, robot))
    session = Session(controller, robot, ref)
    out = []
    for i in range(len(ref)):
        before = controller.solver.fast
        start = before.warm_start.copy() if before is not None else None
        session.tick(i)
        plan = controller.solver.fast
        if plan is not before or start is None:
            continue  # (a support switch: another layout)
        call = solve_call(plan, kind)
        times = []
        for _ in range(7):
            plan.warm_start[...] = start
            t = time.perf_counter()
            call()
            times.append((time.perf_counter() - t) * 1e6)
        out.append(min(times))
    return out


def switch_parts(robot, ref, kind: str) -> dict[str, np.ndarray]:
    """The parts of each tick of the walk, timed once as the tick runs (the first tick of a
    support phase runs cold: its objects were last touched a phase ago): setting the targets
    (with the phase switch), the kinematics and the re-plan, the compiled call; then that call
    replayed at once from the same warm start (best of 5). µs, per part: (first ticks of the
    support phases, the other ticks)."""
    controller = StackController(build_stack({**core_walk_spec(), "solver": kind}, robot))
    session = Session(controller, robot, ref)
    solver = controller.solver
    ns = time.perf_counter_ns
    rows: dict[bool, list] = {True: [], False: []}
    previous = None
    for i in range(len(ref)):
        targets = session.targets(i)
        key = (targets.phase, targets.support, targets.swing)
        changed, previous = key != previous, key
        if i == 0:
            session.tick(i)
            continue
        q = session.q
        t0 = ns()
        controller._set_targets(q, targets, changed)
        t1 = ns()
        solver.kin.update(q)
        if solver._key != solver.stack.revision:  # the re-plan of StackSolver._solve
            solver._plan() if kind == "hierarchical" else solver._plan(solver.ws.shape[2])
        t2 = ns()
        plan = solver.fast
        start = plan.warm_start.copy()
        plan.solve(solver.kin, ref.dt)
        t3 = ns()
        after, q_next = plan.warm_start.copy(), plan.q_next.copy()
        warm = []
        for _ in range(5):
            plan.warm_start[...] = start
            t = ns()
            plan.solve(solver.kin, ref.dt)
            warm.append(ns() - t)
        plan.warm_start[...] = after
        session.q = q_next
        rows[changed].append((t1 - t0, t2 - t1, t3 - t2, min(warm)))
    return {k: np.array(v) / 1e3 for k, v in rows.items()}


def main() -> int:
    robot = load_robot()
    ref = build("walk10", robot)
    rows = {kind: profile(robot, ref, kind) for kind in ("weighted", "hierarchical")}
    print("| part | weighted µs | hierarchy µs |")
    print("|---|---|---|")
    for part in rows["weighted"]:
        print(f"| {part} | {rows['weighted'][part]:.1f} | {rows['hierarchical'][part]:.1f} |")
    print("\nthe solve of each tick along walk10 (not a switch), replayed, best of 7, µs:")
    print("| solver | median | p90 | p99 | max |")
    print("|---|---|---|---|---|")
    for kind in ("weighted", "hierarchical"):
        t = np.array(walk_solves(robot, ref, kind))
        cells = " | ".join(f"{v:.1f}" for v in np.percentile(t, [50, 90, 99, 100]))
        print(f"| {kind} | {cells} |")
    print("\nthe parts of each tick along walk10, timed once as it runs; medians (p90), µs:")
    print("| solver | ticks | targets (phase switch) | kinematics + re-plan | compiled call |"
          " the call replayed at once |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for kind in ("weighted", "hierarchical"):
        parts = switch_parts(robot, ref, kind)
        for first, name in ((True, "first of a support phase"), (False, "the others")):
            t = parts[first]
            cells = " | ".join(f"{np.median(c):.1f} ({np.percentile(c, 90):.1f})" for c in t.T)
            print(f"| {kind} | {name} ({len(t)}) | {cells} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
