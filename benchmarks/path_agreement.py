"""Do the compiled and numpy paths give the same Δq whatever ticks came before? (issue 28)

    python benchmarks/path_agreement.py --n 2000 --ticks 20

One ``walk`` stack solver per kind (hierarchical, weighted) and path (compiled, numpy) is
built once and kept from trial to trial, as a control loop keeps it. Each trial is drawn as
``benchmarks/stress.py`` draws it (``numpy.random.default_rng([seed, trial])``: its kind,
support, start inside or up to 0.05 rad outside the limits, targets reachable, far or upside
down): the targets are anchored at the start afresh, then each path runs ``--ticks`` ticks
from it, each stepping its own q, and every tick's Δq of the two paths is compared. A trial
counts as apart when one tick's Δq differ by more than 1e-9 (and by more than 1e-4), or when
one path raises where the other does not. ``--fresh``: new solvers for every trial (no
history). Prints the counts and the largest gap, with its trial and tick.

``--cost N``: instead, what starting every compiled tick afresh costs: walk10 on the ``walk``
stack (:func:`wbc.walking.loop.run`), each solver's median solve time over its ticks, with
the compiled active sets started afresh (the default) and carried from the last tick (the
warm start as before issue 28: ``_Plan.forget_warm_start`` a no-op), N rounds side by side.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import stress  # benchmarks/stress.py: its draws and stacks (the script's folder is on the path)

from wbc import WbcError, load_robot
from wbc.stacks import load_stack

KINDS = ("hierarchical", "weighted")


def controls(robot) -> dict:
    q = robot.configuration("walk_ready")
    return {
        (kind, compiled): load_stack("walk", robot, q, solver=kind, compiled=compiled)
        for kind in KINDS
        for compiled in (None, False)
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--ticks", type=int, default=20)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--fresh", action="store_true", help="new solvers for every trial")
    ap.add_argument("--cost", type=int, default=0, help="rounds of the warm-start cost instead")
    args = ap.parse_args()
    if args.cost:
        cost(args.cost)
        return
    robot = load_robot("bioloid")
    stress.compile_first()
    kept = controls(robot)
    apart = {kind: [0, 0, 0] for kind in KINDS}  # > 1e-9, > 1e-4, typed errors differ
    trials = dict.fromkeys(KINDS, 0)
    worst = (0.0, -1, -1, "")
    start = time.perf_counter()
    for trial in range(args.n):
        p = stress.draw(robot, np.random.default_rng([args.seed, trial]), ["daqp"])
        q0 = stress.start(robot, p)
        kind = str(p["kind"])
        trials[kind] += 1
        pair = [(controls(robot) if args.fresh else kept)[(kind, c)] for c in (None, False)]
        for control in pair:
            stress.replay_targets(robot, control, q0, p)
        qs = [q0, q0]
        gap = 0.0
        for tick in range(args.ticks):
            out = []
            for k, control in enumerate(pair):
                try:
                    out.append(control.solver.solve(qs[k], 0.01))
                except WbcError as exc:
                    out.append(type(exc).__name__)
            if isinstance(out[0], str) or isinstance(out[1], str):
                apart[kind][2] += out[0] != out[1]
                break
            g = float(abs(out[0] - out[1]).max())
            if g > worst[0]:
                worst = (g, trial, tick, kind)
            gap = max(gap, g)
            qs = [c.solver.integrate(q, dq) for c, q, dq in zip(pair, qs, out, strict=True)]
        apart[kind][0] += gap > 1e-9
        apart[kind][1] += gap > 1e-4
    print(f"{args.n} trials x {args.ticks} ticks, {'fresh' if args.fresh else 'kept'} solvers")
    for kind in KINDS:
        a = apart[kind]
        print(
            f"{kind}: {trials[kind]} trials, apart > 1e-9: {a[0]}, > 1e-4: {a[1]}, "
            f"one path raising alone: {a[2]}"
        )
    print(f"largest gap {worst[0]:.3g} (trial {worst[1]}, tick {worst[2]}, {worst[3]})")
    if not args.fresh:
        for kind in KINDS:
            s = kept[(kind, None)].solver
            print(
                f"{kind} compiled path: {s.compiled_ticks} compiled ticks, "
                f"{s.handed_back_ticks} handed back"
            )
    print(f"{time.perf_counter() - start:.0f} s")


def _gather_only(self, keep_damped=False, rows=None) -> None:
    """The "warm" mode's ``_Plan.forget_warm_start``: no set forgotten, the constraints'
    parameters gathered (the tick leaves that to it)."""
    if rows is not None:
        rows.gather()


def cost(rounds: int) -> None:
    """Median solve time (µs) of each solver along walk10, afresh against warm-started."""
    from wbc.bench.trajectories import build
    from wbc.solvers.plan import _Plan
    from wbc.walking.loop import StackController, run

    stress.compile_first()
    robot = load_robot("bioloid")
    ref = build("walk10", robot)
    forget = _Plan.forget_warm_start
    medians: dict = {}
    for _ in range(rounds):
        for start in ("afresh", "warm"):
            _Plan.forget_warm_start = forget if start == "afresh" else _gather_only
            for kind in KINDS:
                controller = StackController(load_stack("walk", robot, solver=kind), kind)
                times = np.asarray(run(controller, robot, ref)["solve_time"])[5:]
                medians.setdefault((kind, start), []).append(float(np.median(times)) * 1e6)
    _Plan.forget_warm_start = forget
    print("| solver | active sets | median solve µs (median of rounds) | rounds |")
    print("|---|---|---|---|")
    for (kind, start), m in medians.items():
        rows = ", ".join(f"{x:.0f}" for x in m)
        print(f"| {kind} | {start} | {np.median(m):.0f} | {rows} |")


if __name__ == "__main__":
    main()
