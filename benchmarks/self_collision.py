"""Cost per tick of the self-collision limit: the walk stack with it on vs off, beside placo.

Controllers, all through the same control loop and clock (:func:`wbc.walking.loop.run`):

* ours — ``tasks/walk.toml`` and ``tasks/walk_strict.toml`` as shipped (self-collision rows
  with the hard level) and the same files without their ``self_collision`` entry, as the
  hierarchical QP (and the weighted QP with ``--weighted``), on the compiled path (the
  collision rows in the compiled active set; a tick it cannot finish is handed back to DAQP);
* placo 0.10.2 — the peer set-up of :mod:`wbc.bench.peers` (walk tasks, joint and velocity
  limits), without collisions, and with ``add_avoid_self_collisions_constraint`` on the same
  URDF with the same geometry pairs (written to a placo ``collisions.json``), the same
  margin / trigger, and hard (placo's default priority is soft, weight 1).

Also printed: the smallest distance between any two of the pairs over the run (our exact
distances, on every controller's joint trajectory), the ticks handed back to DAQP and the
exact distance computations per tick, and the p99 of the first 5 % of the ticks (the start
of a walk). Rounds are interleaved; figures are medians over rounds of each controller's
per-tick median / p99.

``--cold-too``: each of ours also with every level's active sets started cold at each tick
(the hierarchy's last level too: as before it kept its bounds' active set from the last tick,
:meth:`wbc.solvers.plan._Plan.forget_warm_start`), interleaved in the same rounds: the
before / after of that change, side by side.

``--slowest N``: also, per controller, the p99 of each tick's smallest time over the rounds
(the machine's preemptions taken out: with 3 rounds a tick is slow in all three only by its
own work) and its N slowest ticks (tick, µs, support: 0 double, 1 / 2 single; * a phase's
first tick); then the tail of issue 34's deliverable 3 on the same minima: the slowest first
tick of a support phase and the p99 of the walk's first 5 % of ticks, over the median.

``--rows-before``: also each stack with its limit's ``in_tick = false`` (the rows made by
Python before the compiled tick, as until the nineteenth session; the default makes them
inside it, one call from Python for the rows and the solve: issue 34), interleaved in the
same rounds.

``--no-rehearse``: also each stack with its limit without the rehearsal of a support phase's
first tick in the idle part (``rehearse_switch`` off, as until the twentieth session; the
default runs that tick once there and forgets it: :mod:`wbc.solvers.rehearsal`), interleaved
in the same rounds.

``--idle S``: S seconds slept after each tick of every controller (0.02: a 50 Hz loop, as on
a robot: each tick then starts with the caches that the sleep and the machine's other
processes left, where back to back, the default, it finds its code and data from the tick
before; benchmarks/self_collision.md, sixteenth pass).

``--warm``: also each stack with its limit with the solver's ``warm_ahead`` on (the current
layout's tick rehearsed at the end of each idle part, just before the tick:
:meth:`wbc.solvers.base.StackSolver.warm`; with ``--idle`` only: back to back there is no idle
part), interleaved in the same rounds; the warm-up's own time per tick (µs, the ticks' clock;
not in the tick's) printed after the table. ``--warm-lead S [S …]``: S seconds of the idle
part left after the warm-up, a variant each (a real loop wakes before its deadline:
:data:`wbc.servos.playback.WARM_LEAD_S`; 0, the default, warms right before the tick);
``--warm-spin``: each lead > 0 also with the rest of it spun (a busy wait: the scheduler runs
nothing else in it) instead of slept.
``--limit-on``: ours with the limit only (not the stacks without it).

``--world-frame``: also each stack with its limit's ``common_frame = false`` (the rows'
normal in the world, as before the tenth pass; the default fixes it in the frame of the
joints carrying both links: issue 34, ninth and tenth passes).

``--switch-parts``: after each table, where the first tick of a support phase spends its
time: ours with the limit walked ``--rounds`` more times, each tick's parts timed as it runs
(``time.perf_counter_ns`` around the stack's ``set_phase``, the solver's re-plan ``_plan``,
the compiled plan's call and, inside it, the constraints' rows ``ConstraintRows.tick``; the
rest of the loop's tick is the targets, the kinematics and the checks), each tick's smallest
time over the rounds, then the median of the first ticks of the double- and single-support
phases beside the other ticks (µs; these walks are not in the table above: the timers add
~1 µs a tick); "made ahead": the switch made in the idle part before the tick
(``StackController.prepare_phase``, not in the tick's time).

Run: ``python benchmarks/self_collision.py [--rounds 3] [--trajectories walk10 walk10_wb turn]
[--stacks walk walk_strict] [--weighted] [--cpu] [--robot kokone] [--cold-too]
[--slowest 8] [--switch-parts] [--world-frame] [--idle 0.02] [--rows-before]
[--no-rehearse] [--warm] [--warm-lead 0 0.001] [--warm-spin] [--limit-on]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from wbc import Kinematics, load_robot
from wbc.bench.peers import PlacoController, available
from wbc.bench.trajectories import build
from wbc.limits import SelfCollisionConstraint
from wbc.paths import stacks_dir
from wbc.solvers.hierarchical import HierarchicalQP
from wbc.solvers.inequalities import ConstraintRows
from wbc.solvers.plan import _Plan
from wbc.stacks import ControlStack, build_stack
from wbc.walking.loop import StackController, run, run_stepwise


def walk_spec(with_limit: bool, stack: str = "walk") -> dict:
    """tasks/<stack>.toml, with or without its self_collision entries."""
    with open(stacks_dir() / f"{stack}.toml", "rb") as f:
        spec = tomllib.load(f)
    if not with_limit:
        for level in spec["levels"]:
            kept = [c for c in level.get("constraints", []) if c["type"] != "self_collision"]
            if "constraints" in level:
                level["constraints"] = kept
    return spec


def walk_limit(spec: dict) -> dict:
    """The walk file's self_collision entry."""
    return next(
        c
        for lv in spec["levels"]
        for c in lv.get("constraints", [])
        if c["type"] == "self_collision"
    )


@contextlib.contextmanager
def every_level_cold():
    """Every level's active sets started afresh at each tick (the last level's too)."""
    keep = _Plan.forget_warm_start
    _Plan.forget_warm_start = lambda self, keep_damped=False, rows=None: keep(self, False, rows)
    try:
        yield
    finally:
        _Plan.forget_warm_start = keep


class PlacoSelfCollision(PlacoController):
    """The placo peer with its self-collision constraint on our pairs."""

    name = "placo-self-collision"

    def __init__(self, pairs_file: str, margin: float, trigger: float) -> None:
        super().__init__()  # (the robot's stack's tasks, read at start)
        self.pairs_file, self.margin, self.trigger = pairs_file, margin, trigger

    def start(self, robot, q0, ref) -> None:
        import placo

        make = placo.RobotWrapper

        def with_collisions(urdf, *_):  # the peer's set-up, on a wrapper with collisions
            pr = make(urdf, 0)
            pr.load_collision_pairs(self.pairs_file)
            return pr

        placo.RobotWrapper = with_collisions
        try:
            super().start(robot, q0, ref)
        finally:
            placo.RobotWrapper = make
        c = self.solver.add_avoid_self_collisions_constraint()
        c.configure("self_collisions", "hard")  # placo's default is soft (weight 1)
        c.self_collisions_margin = self.margin
        c.self_collisions_trigger = self.trigger


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--trajectories", nargs="+", default=["walk10", "walk10_wb", "turn"])
    parser.add_argument("--stacks", nargs="+", default=["walk", "walk_strict"])
    parser.add_argument("--weighted", action="store_true", help="also the weighted QP")
    parser.add_argument(
        "--cpu", action="store_true", help="time the ticks in CPU time (a loaded machine)"
    )
    parser.add_argument("--robot", default="bioloid", help="a robot folder's name")
    parser.add_argument(
        "--cold-too", action="store_true", help="also ours with every level started cold"
    )
    parser.add_argument(
        "--slowest", type=int, default=0, help="the p99 of the per-tick minima, N slowest ticks"
    )
    parser.add_argument(
        "--switch-parts", action="store_true", help="where a support phase's first tick goes"
    )
    parser.add_argument(
        "--world-frame", action="store_true", help="also ours with common_frame = false"
    )
    parser.add_argument(
        "--idle", type=float, default=0.0, help="s slept after each tick (a robot's loop)"
    )
    parser.add_argument(
        "--rows-before", action="store_true", help="also ours with in_tick = false (rows before)"
    )
    parser.add_argument(
        "--no-rehearse", action="store_true", help="also ours with rehearse_switch off"
    )
    parser.add_argument(
        "--warm", action="store_true", help="also ours with warm_ahead on (with --idle)"
    )
    parser.add_argument(
        "--warm-lead", type=float, nargs="+", default=[0.0],
        help="s of the idle part left after the warm-up (several: a variant each)",
    )  # fmt: skip
    parser.add_argument(
        "--warm-spin", action="store_true",
        help="also each lead > 0 with its rest spun (busy-wait) instead of slept",
    )  # fmt: skip
    parser.add_argument(
        "--limit-on", action="store_true", help="ours with the limit only (not without it)"
    )
    parser.add_argument(
        "--release-small", type=float, nargs="+", default=[], metavar="R",
        help="also ours with the solver's release_small = R (wbc.compiled.lsq_release)",
    )  # fmt: skip
    args = parser.parse_args()
    if args.cpu:  # every controller's tick timer (wbc.walking.loop reads time.perf_counter)
        time.perf_counter = time.process_time
    robot = load_robot(args.robot)
    for trajectory in args.trajectories:
        table(robot, trajectory, args)
    return 0


def table(robot, trajectory: str, args) -> None:
    """One trajectory's table: each stack with and without its limit, placo off and on."""
    ref = build(trajectory, robot)
    entry = walk_limit(walk_spec(True, args.stacks[0]))
    margin, trigger = entry["margin"], entry["trigger"]
    probe = SelfCollisionConstraint(robot, margin, trigger)
    names = [g.name for g in probe.distances.geometry.geometryObjects]
    pairs = [[names.index(a), names.index(b)] for a, b in probe.pair_geoms]
    tmp = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
    json.dump(pairs, tmp)
    tmp.close()

    def ours(spec: dict, kind: str, rehearse: bool = True, warm: bool | None = None, release=0.0):
        def make():
            controller = StackController(build_stack({**spec, "solver": kind}, robot))
            if release:
                controller.solver.release_small = release
            if not rehearse:
                controller.solver.rehearse_switch = False
            if warm is not None:
                controller.solver.warm_ahead = warm
            return controller

        return make

    makers = {}
    leads: dict[str, float] = {}  # (--warm: the warm-up's lead before the tick, s)
    cold = set()
    for stack in args.stacks:
        for kind in ("hierarchical", "weighted") if args.weighted else ("hierarchical",):
            for on in (False, True) if not args.limit_on else (True,):
                label = f"{stack} ({kind}), limit {'on' if on else 'off'}"
                makers[label] = ours(walk_spec(on, stack), kind)
                if on and args.warm:
                    makers[label] = ours(walk_spec(True, stack), kind, warm=False)
                    for lead in args.warm_lead:
                        warm = f"{label}, warm" + (f" {lead * 1e3:g} ms ahead" if lead else "")
                        makers[warm] = ours(walk_spec(True, stack), kind, warm=True)
                        leads[warm] = lead
                        if lead and args.warm_spin:  # (a negative lead: spun)
                            makers[f"{warm}, spun"] = makers[warm]
                            leads[f"{warm}, spun"] = -lead
                if on and args.world_frame:
                    spec = walk_spec(True, stack)
                    walk_limit(spec)["common_frame"] = False
                    makers[f"{label}, world frame"] = ours(spec, kind)
                for release in args.release_small if on else ():
                    makers[f"{label}, release_small {release:g}"] = ours(
                        walk_spec(True, stack), kind, release=release
                    )
                if on and args.no_rehearse:
                    makers[f"{label}, no rehearsal"] = ours(walk_spec(True, stack), kind, False)
                if on and args.rows_before:
                    spec = walk_spec(True, stack)
                    walk_limit(spec)["in_tick"] = False
                    makers[f"{label}, rows before"] = ours(spec, kind)
                if args.cold_too:
                    cold.add(f"{label}, every level cold")
                    makers[f"{label}, every level cold"] = makers[label]
    if available()["placo"]:
        makers["placo 0.10.2, off"] = PlacoController
        makers["placo 0.10.2, self-collision on"] = lambda: PlacoSelfCollision(
            tmp.name, margin, trigger
        )
    stats: dict[str, list[tuple]] = {k: [] for k in makers}
    warm_cost: dict[str, list[float]] = {k: [] for k in makers}
    times: dict[str, list[np.ndarray]] = {k: [] for k in makers}
    kin = Kinematics(robot)
    for _ in range(args.rounds):
        for name, make in makers.items():
            controller = make()
            with every_level_cold() if name in cold else contextlib.nullcontext():
                rec, warmed = walk(controller, robot, ref, args.idle, leads.get(name, 0.0))
            warm_cost[name].append(float(np.mean(warmed)) * 1e6 if warmed.size else np.nan)
            t = rec["solve_time"] * 1e6
            times[name].append(t)
            closest = np.inf
            for q in rec.q:
                kin.update(q)
                closest = min(closest, probe.min_distance(kin))
            back, exact = np.nan, np.nan
            solver = getattr(controller, "solver", None)
            if hasattr(solver, "handed_back_ticks"):
                back = solver.handed_back_ticks
                sc = [
                    c for c in solver.stack.constraints() if isinstance(c, SelfCollisionConstraint)
                ]
                exact = sc[0].distances.exact_computations / len(t) if sc else 0.0
            com = np.linalg.norm(rec["com"] - rec["com_ref"], axis=1).max() * 1e3
            foot = np.linalg.norm(rec["swing"] - rec["swing_ref"], axis=1).max() * 1e3
            head = np.percentile(t[: max(1, len(t) // 20)], 99)  # the first 5 % of the ticks
            support = rec["support"]
            switch = np.flatnonzero(support[1:] != support[:-1]) + 1  # a support phase's first
            first = np.median(t[switch]) if switch.size else np.nan
            single = np.median(t[support != 0]) if (support != 0).any() else np.nan
            stats[name].append(
                (np.median(t), np.percentile(t, 99), head, first, single, com, foot,
                 closest * 1e3, back, exact)
            )  # fmt: skip
    Path(tmp.name).unlink()
    rows = {k: np.median(np.array(v, dtype=float), axis=0) for k, v in stats.items()}
    print(
        f"\n{len(ref)} ticks of {trajectory}, {args.rounds} interleaved rounds; "
        f"{probe.n_pairs} geometry pairs, margin {margin * 1e3:g} mm, trigger {trigger * 1e3:g} mm"
    )
    print(
        "| controller | median µs | p99 µs | p99 first 5 % µs | support switch µs"
        " | single support µs | median / placo off"
        " | p99 / placo off p99 | median / placo on | CoM err max mm | swing err max mm"
        " | closest pair mm | handed back | exact distances / tick |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    placo_off = rows.get("placo 0.10.2, off", [np.nan] * 2)
    placo_on = rows.get("placo 0.10.2, self-collision on", [np.nan])[0]
    for name, (med, p99, head, first, single, com, foot, closest, back, exact) in rows.items():
        fmt_back = "" if np.isnan(back) else f"{back:.0f} / {len(ref)}"
        fmt_exact = "" if np.isnan(exact) else f"{exact:.1f}"
        print(
            f"| {name} | {med:.0f} | {p99:.0f} | {head:.0f} | {first:.0f} | {single:.0f} |"
            f" {med / placo_off[0]:.2f} |"
            f" {p99 / placo_off[1]:.2f} | {med / placo_on:.2f} | {com:.3f} | {foot:.3f} |"
            f" {closest:.2f} | {fmt_back} | {fmt_exact} |"
        )
    if args.warm and args.idle > 0.0:
        print("\nthe idle part's warm-up (µs per tick, mean over the walk, median of the rounds):")
        for name, cost in warm_cost.items():
            if name in leads:
                print(f"- {name}: {np.median(cost):.1f}")
    if args.slowest:
        slowest(times, rec["support"], args.slowest)
    if args.switch_parts:
        switch_parts(robot, ref, args)


def walk(controller, robot, ref, idle: float, lead: float = 0.0):
    """:func:`wbc.walking.loop.run`, with ``idle`` s slept after each tick (0: none, the ticks
    back to back), the controller's :meth:`~wbc.walking.controller.Controller.warm` ``lead``
    s before its end (< 0: ``-lead`` s before it, the rest spun, not slept); and each
    warm-up's time (s, the ticks' clock: empty back to back)."""
    if idle <= 0.0:
        return run(controller, robot, ref), np.zeros(0)
    ticks = run_stepwise(controller, robot, ref)
    warmed = []
    clock = time.perf_counter  # (time.process_time with --cpu)
    while True:
        try:
            next(ticks)
        except StopIteration as end:
            return end.value, np.array(warmed[:-1])  # (the last: after the walk's end)
        time.sleep(idle - abs(lead))
        wake = time.monotonic()
        start = clock()
        controller.warm(ref.dt)
        warmed.append(clock() - start)
        if lead > 0.0:
            time.sleep(max(0.0, lead - (time.monotonic() - wake)))
        elif lead < 0.0:
            while time.monotonic() - wake < -lead:
                pass


def slowest(times: dict[str, list[np.ndarray]], support: np.ndarray, n: int) -> None:
    """Per controller: the p99 of each tick's smallest time over the rounds, and its n
    slowest ticks (tick, µs, support; * the first tick of a support phase); then the
    issue's tail (deliverable 3): the slowest first tick of a support phase and the p99 of the
    walk's first 5 % of ticks, each over the median."""
    first = set((np.flatnonzero(support[1:] != support[:-1]) + 1).tolist())
    print("\neach tick's smallest time over the rounds (preemptions out):")
    tails = []
    for name, runs in times.items():
        t = np.min(runs, axis=0)
        ticks = ", ".join(
            f"{i}{'*' if i in first else ''} {t[i]:.0f} ({support[i]})"
            for i in np.argsort(t)[::-1][:n].tolist()
        )
        med = np.median(t)
        print(f"- {name}: median {med:.1f}, p99 {np.percentile(t, 99):.1f} µs; {ticks}")
        switch = max(t[sorted(first)]) if first else np.nan
        head = np.percentile(t[: max(1, len(t) // 20)], 99)
        tails.append(
            f"- {name}: slowest first tick of a phase {switch:.0f} µs = {switch / med:.2f}×,"
            f" first 5 % p99 {head:.0f} µs = {head / med:.2f}× the median"
        )
    print("\nthe tail (the same minima; target ≤ 2× the median):")
    print("\n".join(tails))


PARTS = ("tick", "set_phase", "re-plan", "plan call", "rows", "ahead")


@contextlib.contextmanager
def timed_parts(acc: dict[str, int]):
    """The parts of :data:`PARTS` but the tick timed into ``acc`` (ns, added up) inside;
    ``ahead``: the support switch made in the idle part before the tick (the loop's
    :meth:`StackController.prepare_phase`: the next tick's ``ahead``, its ``set_phase`` in it)."""
    wrapped = [
        (StackController, "prepare_phase", "ahead"),
        (ControlStack, "set_phase", "set_phase"),
        (HierarchicalQP, "_plan", "re-plan"),
        (_Plan, "solve", "plan call"),
        (ConstraintRows, "tick", "rows"),
    ]
    kept = [(cls, name, cls.__dict__[name]) for cls, name, _ in wrapped]
    ns = time.perf_counter_ns

    def timer(f, label):
        def timed(*a, **k):
            t = ns()
            try:
                return f(*a, **k)
            finally:
                acc[label] += ns() - t

        return timed

    for (cls, name, label), (_, _, f) in zip(wrapped, kept, strict=True):
        setattr(cls, name, timer(f, label))
    try:
        yield
    finally:
        for cls, name, f in kept:
            setattr(cls, name, f)


def switch_parts(robot, ref, args) -> None:
    """Per stack with its limit: the parts of each tick (:func:`timed_parts`), each tick's
    smallest over ``args.rounds`` walks; the medians of the first ticks of the double- and
    single-support phases and of the other ticks, µs."""
    print("\nwhere a support phase's first tick goes (µs, each tick's minimum over the rounds):")
    print(
        "| controller | ticks | n | tick | set_phase | re-plan | plan call | of which rows"
        " | the rest | made ahead |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for stack in args.stacks:
        spec = walk_spec(True, stack)
        runs = []
        for _ in range(args.rounds):
            acc = dict.fromkeys(PARTS, 0)
            per_tick: list[list[int]] = []
            controller = StackController(build_stack({**spec, "solver": "hierarchical"}, robot))
            track = controller.track

            def tick(q, targets, dt, changed, track=track, acc=acc, per_tick=per_tick):
                ahead = acc["ahead"]  # (made after the last tick: this tick's switch)
                for k in acc:
                    acc[k] = 0
                t = time.perf_counter_ns()
                out = track(q, targets, dt, changed)
                acc["tick"] = time.perf_counter_ns() - t
                per_tick.append([*(acc[k] for k in PARTS[:-1]), ahead])
                return out

            controller.track = tick
            with timed_parts(acc):
                rec = run(controller, robot, ref)
            runs.append(np.array(per_tick[-len(rec["solve_time"]) :], dtype=float) / 1e3)
        parts = np.min(np.stack(runs), axis=0)  # (ticks, parts)
        rest = parts[:, 0] - parts[:, 1] - parts[:, 2] - parts[:, 3]
        support = rec["support"]
        switch = np.flatnonzero(support[1:] != support[:-1]) + 1
        groups = {
            "first of double support": switch[support[switch] == 0],
            "first of single support": switch[support[switch] != 0],
            "the others": np.setdiff1d(np.arange(1, len(support)), switch),
        }
        for label, ticks in groups.items():
            if not ticks.size:
                continue
            m = np.median(parts[ticks], axis=0)
            print(
                f"| {stack} | {label} | {ticks.size} | {m[0]:.1f} | {m[1]:.1f} | {m[2]:.1f} |"
                f" {m[3]:.1f} | {m[4]:.1f} | {np.median(rest[ticks]):.1f} | {m[5]:.1f} |"
            )


if __name__ == "__main__":
    raise SystemExit(main())
