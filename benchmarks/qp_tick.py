"""Per-tick cost of the walking stack: our weighted and 3-level hierarchical QPs vs placo and pink.

The stack (issue 3): support contact(s) hard, swing sole 6-D, CoM, torso orientation, posture,
joint position and servo velocity limits — ``tasks/walk_strict.toml`` (``walk`` in three
strict levels; the weighted QP sees the same soft tasks and weights as ``walk``) without its
CoM-polygon and ground-clearance constraints, which the peers do not get either. All four
controllers follow the same 10-step reference through the same control loop
(:func:`wbc.walking.loop.run`), which times each tick the same way (targets, kinematics,
assembly, solve, integration). Each round walks every controller once, side by side: each
walk in ``--blocks`` blocks of ticks (4), one block of each walk in turn, the order rotated
by one at every block, so that the machine's slower and faster stretches (a fraction of a
second on a shared VM) hit every controller alike (``--blocks 1``: one whole walk after the
other, in a fixed order, as before 2026-12-02 08:00). The first tick of a block follows the
other controllers' blocks: its caches are cold, for every controller alike (~100–150 µs),
and the next ticks are slower too; so the blocks are few: 3 such ticks per walk, fewer than
the 6 above a walk's p99 (blocks of 50 ticks made them the p99 of every controller, and
raised the medians by 1–2 µs). The figures are medians over rounds of each controller's
per-tick median/p99; the ratio to placo is the median over rounds of each round's ratio (both
walks in the same stretch of the machine; since 2026-12-02 15:30: before, the ratio of the two
medians over rounds, which compares different rounds when the machine's speed changes between
them: e.g. per-round ratios 0.62, 0.63, 0.62, 0.62, 0.95 gave 0.95). The per-round ratios of
our compiled solvers to placo follow the table, with that older ratio.

Our solvers run twice: through the compiled kernels (:mod:`wbc.compiled`, the default) and
through the numpy assembly with DAQP on every tick (``compiled=False``).

Then the cost of an active inequality row: that stack in single support (its swing
ground-clearance constraint included), one tick at the same configuration repeated, with the
swing sole's target above the ground (the row inactive: the compiled tick alone) and 5 mm
below it (the row active). Then the first tick after a support switch against the next one;
last, per-tick medians over 5 walks of our compiled solvers and placo (a preemption of the
machine hits one walk, not the median): the first ticks of the support phases against the
others, and the p99 over the ticks — each controller's own tail, comparable on a loaded
machine, where the p99s of the table above are the machine's preemptions.

Run: ``python benchmarks/qp_tick.py [--rounds 5]`` (writes nothing; paste into qp_tick.md).
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from wbc import Kinematics, load_robot
from wbc.bench.peers import PinkController, PlacoController, available
from wbc.bench.trajectories import build
from wbc.paths import stacks_dir
from wbc.stacks import build_stack
from wbc.walking.loop import StackController, run, run_stepwise

WEIGHTED = "weighted QP (compiled)"
HIERARCHICAL = "3-level hierarchical QP (compiled)"


def core_walk_spec() -> dict:
    """tasks/walk_strict.toml (the walk stack in three strict levels) without its
    inequality constraints (what the peers can express)."""
    with open(stacks_dir() / "walk_strict.toml", "rb") as f:
        spec = tomllib.load(f)
    for level in spec["levels"]:
        level.pop("constraints", None)
    return spec


def inequality_ticks(robot, kind: str, repeats: int = 2000) -> tuple[float, float, int, str]:
    """Median µs of a tick with the swing sole's ground-clearance row inactive and active
    (``walk_strict``: the walk stack in three strict levels), how many of the active ticks were
    handed to the backend (the compiled kernels solve the row; a tick goes to the backend only
    if they cannot finish it), and in how many blocks the row was in the compiled solve's
    working set as intended (read from the plan after each block: "inactive / active")."""
    with open(stacks_dir() / "walk_strict.toml", "rb") as f:
        spec = tomllib.load(f)
    control = build_stack({**spec, "solver": kind}, robot)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    control.set_phase("single", "l_sole", "r_sole", kin)
    swing = control.stack.task("frame_pose_swing")
    swing.set_target_from(kin)
    solver = control.solver
    above = swing.target_position.copy()
    times: dict[float, list[float]] = {0.002: [], -0.005: []}  # 2 mm up: inactive; 5 down
    handed = 0
    as_intended = {dz: 0 for dz in times}
    for _ in range(repeats // 50):  # blocks of 50 ticks, interleaved: the same machine load
        for dz, out in times.items():
            swing.set_position_target(above + [0.0, 0.0, dz])
            solver.step(q, 0.01)  # the active set settles
            before = solver.handed_back_ticks
            for _ in range(50):
                t = time.perf_counter()
                solver.step(q, 0.01)
                out.append(time.perf_counter() - t)
            handed += (solver.handed_back_ticks - before) if dz < 0 else 0
            # walk_strict.toml lists the swing's ground clearance (its 4 sole corners) last
            g = solver.fast.inequalities if solver.fast is not None else None
            working = g is not None and bool(g.working[:, g.total - 4 : g.total].any())
            as_intended[dz] += working == (dz < 0)
    medians = [float(np.median(times[dz])) * 1e6 for dz in (0.002, -0.005)]
    blocks = repeats // 50
    return (
        medians[0],
        medians[1],
        handed,
        f"{as_intended[0.002]}/{blocks}, {as_intended[-0.005]}/{blocks}",
    )


def phase_switch_ticks(robot, kind: str, repeats: int = 50) -> tuple[float, float]:
    """Median µs of the first tick after a support switch and of the tick after it (core
    ``walk`` stack, the four phases of a walk in turn)."""
    control = build_stack({**core_walk_spec(), "solver": kind}, robot)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    phases = [
        ("double", "l_sole", "r_sole"), ("single", "l_sole", "r_sole"),
        ("double", "r_sole", "l_sole"), ("single", "r_sole", "l_sole"),
    ]  # fmt: skip
    first, next_ = [], []
    for i in range(repeats * len(phases)):
        control.set_phase(*phases[i % len(phases)], kin)
        for out in (first, next_):
            t = time.perf_counter()
            control.solver.step(q, 0.01)
            out.append(time.perf_counter() - t)
    skip = 2 * len(phases)  # the first visit of each phase builds its layout
    return float(np.median(first[skip:])) * 1e6, float(np.median(next_[skip:])) * 1e6


def walk_tails(robot, ref, makers: dict, walks: int = 5) -> dict[str, tuple[float, float, float]]:
    """Per-tick medians over ``walks`` walks of each controller ``makers[name]()`` builds (a
    preemption hits one walk, not the median), the controllers' walks in turn (walk k of each,
    then walk k + 1: a slower stretch of the machine hits them alike; since 2026-12-02 15:30,
    before all the walks of one controller, then the next's): the median over the first ticks
    of the support phases, over the other ticks, and the p99 over all ticks (the tail a
    controller has of its own, without the machine's preemptions)."""
    from wbc.walking.loop import SUPPORT_DOUBLE, support_roles

    times: dict[str, list] = {name: [] for name in makers}
    for _ in range(walks):
        for name, make in makers.items():
            times[name].append(run(make(), robot, ref)["solve_time"])
    swing = support_roles(ref)[1]
    double = ref.support == SUPPORT_DOUBLE
    first = np.array(
        [i > 0 and (double[i], swing[i]) != (double[i - 1], swing[i - 1]) for i in range(ref.n)]
    )
    out = {}
    for name, ts in times.items():
        t = np.median(np.array(ts), axis=0) * 1e6
        out[name] = (
            float(np.median(t[first])),
            float(np.median(t[~first])),
            float(np.percentile(t, 99)),
        )
    return out


def side_by_side(makers: dict, robot, ref, block: int) -> dict:
    """One walk of each controller ``makers[name]()`` builds (name -> its recording), side by
    side: ``block`` ticks of each walk in turn, the order rotated by one at every block; each
    walk does exactly what :func:`wbc.walking.loop.run` does. ``block`` 0: one whole walk after
    the other, in the order of ``makers``."""
    names = list(makers)
    walks = {name: run_stepwise(makers[name](), robot, ref) for name in names}
    out = {}
    turn = 0
    while walks:
        k = turn % len(names) if block else 0
        for name in names[k:] + names[:k]:
            if name not in walks:
                continue
            try:
                for _ in range(block or ref.n + 1):
                    next(walks[name])
            except StopIteration as end:
                out[name] = end.value
                del walks[name]
        turn += 1
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--trajectory", default="walk10")
    parser.add_argument(
        "--blocks", type=int, default=4, help="blocks per walk, walked in turn (1: whole walks)"
    )
    args = parser.parse_args()
    robot = load_robot()
    ref = build(args.trajectory, robot)
    spec = core_walk_spec()
    if args.blocks < 1:
        parser.error(f"--blocks must be at least 1, got {args.blocks}")
    block = 0 if args.blocks == 1 else -(-ref.n // args.blocks)  # (ticks per block)

    def ours(kind: str, compiled: bool):
        def make():
            control = build_stack({**spec, "solver": kind}, robot)
            control.solver.compiled = compiled
            return StackController(control)

        return make

    makers = {
        WEIGHTED: ours("weighted", True),
        HIERARCHICAL: ours("hierarchical", True),
        "weighted, numpy path (daqp)": ours("weighted", False),
        "hierarchical, numpy path (daqp)": ours("hierarchical", False),
    }
    have = available()
    if have["placo"]:
        makers["placo 0.10.2"] = PlacoController
    if have["pink"]:
        makers["pink (daqp)"] = PinkController
    stats: dict[str, list[tuple[float, float, float, float]]] = {k: [] for k in makers}
    for _ in range(args.rounds):
        for name, rec in side_by_side(makers, robot, ref, block).items():
            t = rec["solve_time"] * 1e6
            com = np.linalg.norm(rec["com"] - rec["com_ref"], axis=1).max() * 1e3
            foot = np.linalg.norm(rec["swing"] - rec["swing_ref"], axis=1).max() * 1e3
            stats[name].append((np.median(t), np.percentile(t, 99), com, foot))
    rows = {k: np.median(np.array(v), axis=0) for k, v in stats.items()}
    ref_name = "placo 0.10.2" if "placo 0.10.2" in rows else next(iter(rows))
    # each round's ratio (the same stretch of the machine for both walks), then their median
    ratios = {
        k: [a[0] / b[0] for a, b in zip(v, stats[ref_name], strict=True)] for k, v in stats.items()
    }
    how = f"side by side in blocks of {block} ticks" if block else "whole walks in turn"
    print(f"{len(ref)} ticks of {args.trajectory}, {args.rounds} rounds, {how}")
    print(
        f"| controller | median µs | p99 µs | median / {ref_name} | CoM err max mm |"
        " swing err max mm |"
    )
    print("|---|---|---|---|---|---|")
    for name, (med, p99, com, foot) in rows.items():
        print(
            f"| {name} | {med:.0f} | {p99:.0f} | {np.median(ratios[name]):.2f} | {com:.3f} |"
            f" {foot:.3f} |"
        )
    if ref_name != WEIGHTED:
        for name in (WEIGHTED, HIERARCHICAL):
            cells = ", ".join(f"{x:.2f}" for x in ratios[name])
            print(
                f"{name}, median / {ref_name}'s per round: {cells} (the ratio of the medians"
                f" over rounds: {rows[name][0] / rows[ref_name][0]:.2f})"
            )
    w, h = rows[WEIGHTED][0], rows[HIERARCHICAL][0]
    print(f"hierarchical / weighted = {h / w:.2f} (compiled); numpy paths:", end=" ")
    print(
        f"{rows['hierarchical, numpy path (daqp)'][0] / rows['weighted, numpy path (daqp)'][0]:.2f}"
    )
    print("\nan active inequality row (walk_strict stack, single support, swing ground clearance):")
    print(
        "| solver | row inactive µs | row active µs | active / inactive | handed to DAQP"
        " | blocks with the row as intended (inactive, active) |"
    )
    print("|---|---|---|---|---|---|")
    for kind in ("weighted", "hierarchical"):
        off, on, handed, intended = inequality_ticks(robot, kind)
        print(f"| {kind} | {off:.0f} | {on:.0f} | {on / off:.2f} | {handed} | {intended} |")
    print()
    for kind in ("weighted", "hierarchical"):
        first, after = phase_switch_ticks(robot, kind)
        print(f"support switch ({kind}): first tick {first:.0f} µs, the next {after:.0f} µs")
    tails = walk_tails(
        robot,
        ref,
        {k: makers[k] for k in (WEIGHTED, HIERARCHICAL, "placo 0.10.2") if k in makers},
    )
    for name, (first, other, p99) in tails.items():
        print(
            f"{args.trajectory} ({name}), per-tick medians over 5 walks: first tick of a support"
            f" phase {first:.0f} µs, the other ticks {other:.0f} µs, p99 {p99:.0f} µs"
            f" ({p99 / tails.get('placo 0.10.2', (0, 0, p99))[2]:.2f} × placo's)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
