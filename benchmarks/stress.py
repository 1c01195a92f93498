"""Stress run of the solvers (issue 17): random problems, every stack, solver, backend and path.

    python benchmarks/stress.py --n 10000                      # DAQP, compiled and numpy paths
    python benchmarks/stress.py --n 500 --backends proxqp quadprog osqp

Each trial draws (``numpy.random.default_rng([seed, trial])``): the stack (the README's or
``walk``), weighted or hierarchical, the path (compiled or numpy), single or double support, a
start inside the joint limits or up to 0.05 rad outside, and CoM / swing-foot / torso targets
reachable, far out of reach or upside down; it runs ``--ticks`` control ticks and a converged
pose of ``--iterations`` iterations. It counts: joint-limit violations (a joint beyond its
limit and further out than it started), non-finite outputs, untyped exceptions, hard contacts
not held (tick mode: > ``TICK_CONTACT_TOL`` after a tick; converged: > 1e-6 m at the end),
ticks and poses beyond their time bound (``TICK_TIME_BOUND``, ``POSE_TIME_PER_ITERATION``;
a pose's own work budget spent, ``solve_pose``'s ``max_projection_steps``, counts as one),
typed errors by kind, and the slowest tick and pose. The compiled ticks are built before the
first trial (:func:`compile_first`), so that no tick or pose waits for numba.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from wbc import Kinematics, WbcError, load_robot
from wbc.model import Robot
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.stacks import _initial_targets, load_stack
from wbc.tasks import ComTask, ContactTask, FrameOrientationTask, FramePoseTask, PostureTask

#: a hard contact after one tick: the linearisation's second order (velocity-limited steps)
TICK_CONTACT_TOL = 1e-2
#: a hard contact at the end of a converged pose
POSE_CONTACT_TOL = 1e-6
#: a tick slower than this (s) is a runaway solve. Generous: a bound, not a speed figure (the
#: slowest on the loaded 2-core VM: 1.35 s ProxQP before its caps, 4.5 s quadprog, numpy
#: path; DAQP ~0.3 s), so that a loaded machine does not trip it
TICK_TIME_BOUND = 10.0
#: a converged pose slower than this (s) per iteration is a runaway (also passed to
#: ``solve_pose`` as its ``time_budget``: it raises then instead of running on). Generous:
#: the slowest in the 10,000 DAQP trials took 91 s for 50 iterations on the loaded VM
#: (trial 9547: DAQP level QPs of 500–850 variables, a slack per self-collision row; 2.6 s
#: since the cascade solves such levels over Δq alone, benchmarks/stress.md),
#: ProxQP's hierarchy 453 s before its caps
POSE_TIME_PER_ITERATION = 6.0


#: what solve_pose's SolverError says when its work or time budget is spent
BUDGET_SPENT = "solve_pose spent its"


@dataclass
class Tally:
    trials: int = 0
    ticks: int = 0
    poses: int = 0
    limit_violations: int = 0
    non_finite: int = 0
    untyped: list[str] = field(default_factory=list)
    #: ticks slower than TICK_TIME_BOUND; poses slower than their bound or whose work budget
    #: ran out (solve_pose's SolverError naming it)
    slow_ticks: int = 0
    slow_poses: int = 0
    slow_trials: list[int] = field(default_factory=list)
    #: most Gauss–Newton steps a converged pose spent projecting onto its hard levels
    most_projection_steps: int = 0
    tick_contact_misses: int = 0
    max_tick_contact: float = 0.0
    pose_contact_misses: int = 0
    #: poses whose end no projection brought back onto the hard levels (they end at the last
    #: iterate that held them, not converged: ``PoseResult.fell_back``), and their trials
    fell_back: list[int] = field(default_factory=list)
    max_pose_contact: float = 0.0
    typed: Counter = field(default_factory=Counter)
    #: the trials of each kind of typed error (the first few, to look at)
    typed_trials: dict = field(default_factory=dict)
    #: the run's first tick apart: it loads (or, in a fresh checkout, compiles) the kernels
    first_tick: float = -1.0
    slowest_tick: float = 0.0
    slowest_tick_trial: int = -1
    slowest_pose: float = 0.0
    slowest_pose_trial: int = -1
    miss_trials: list[int] = field(default_factory=list)
    #: print each typed error in full, with its trial and tick (``--show``)
    show: bool = False

    def ok(self) -> bool:
        return not (
            self.limit_violations
            or self.non_finite
            or self.untyped
            or self.tick_contact_misses
            or self.pose_contact_misses
            or self.slow_ticks
            or self.slow_poses
            or self.fell_back
        )


def readme_stack(robot: Robot, q: np.ndarray, kind: str, backend: str, compiled):
    kin = Kinematics(robot, q)
    stack = TaskStack(robot)
    contact = stack.add(ContactTask(robot, "l_sole"), level=0, hard=True)
    contact.make_contact(kin)
    com = stack.add(ComTask(robot, kin.com), level=1, weight=1000)
    swing = stack.add(FramePoseTask(robot, "r_sole", name="swing"), level=1, weight=100)
    swing.set_target_from(kin)
    rot = kin.placement(robot.frame_id("torso")).rotation
    torso = stack.add(FrameOrientationTask(robot, "torso", rot), level=2)
    stack.add(PostureTask(robot, q), level=2, weight=0.01)
    cls = HierarchicalQP if kind == "hierarchical" else WeightedQP
    return cls(stack, backend=backend, compiled=compiled), [contact], com, swing, torso


def walk_stack(robot, q, kind, backend, compiled, double: bool):
    control = load_stack("walk", robot, q, backend=backend, solver=kind, compiled=compiled)
    kin = Kinematics(robot, q)
    if not double:
        control.set_phase("single", "l_sole", "r_sole", kin)
    stack = control.stack
    contacts = [t for t in stack.tasks() if isinstance(t, ContactTask) and t.active]
    swing = stack.task("frame_pose_swing")
    return control.solver, contacts, stack.task("com"), swing, stack.task("torso")


def draw(robot: Robot, rng: np.random.Generator, backends: list[str]) -> dict:
    return {
        "stack": rng.choice(["readme", "walk"]),
        "kind": rng.choice(["hierarchical", "weighted"]),
        "backend": rng.choice(backends),
        "compiled": bool(rng.random() < 0.5),
        "double": bool(rng.random() < 0.5),
        "outside": float(rng.choice([0.0, rng.uniform(0.0, 0.05)])),
        "target": rng.choice(["reachable", "far", "upside_down"]),
        "noise": rng.uniform(-0.2, 0.2, robot.n_joints),
        "offsets": rng.uniform(-1.0, 1.0, (3, 3)),
        "n_out": int(rng.integers(1, 4)),
        "which": rng.permutation(robot.n_joints),
        "sides": rng.random(robot.n_joints) < 0.5,
    }


def start(robot: Robot, p: dict) -> np.ndarray:
    q = robot.configuration("walk_ready")
    q[7:] = np.clip(q[7:] + p["noise"], robot.q_min, robot.q_max)
    if p["outside"]:
        for i in p["which"][: p["n_out"]]:
            q[7 + i] = (
                robot.q_max[i] + p["outside"] if p["sides"][i] else robot.q_min[i] - p["outside"]
            )
    q = robot.place_on_ground(q, "l_sole")
    return q


def move_targets(p: dict, com, swing, torso) -> None:
    """The drawn targets: the CoM and swing sole moved from their anchors (reachable, far),
    the torso turned upside down."""
    scale = {"reachable": 0.02, "far": 0.5, "upside_down": 0.02}[p["target"]]
    com.set_target(com.target + scale * p["offsets"][0])
    swing.set_position_target(swing.target_position + scale * p["offsets"][1])
    if p["target"] == "upside_down":
        torso.set_target(pin.utils.rotate("x", np.pi) @ torso.target)


def replay_targets(robot: Robot, control, q0: np.ndarray, p: dict) -> None:
    """A trial's targets on a ``walk`` control kept from trial to trial (as a control loop
    keeps it): contacts and targets anchored at q0 afresh, then moved as drawn."""
    kin = Kinematics(robot, q0)
    control.forget_anchors()
    _initial_targets(control, kin, set())
    if not p["double"]:
        control.set_phase("single", "l_sole", "r_sole", kin)
    stack = control.stack
    move_targets(p, stack.task("com"), stack.task("frame_pose_swing"), stack.task("torso"))


def run_trial(robot: Robot, p: dict, tally: Tally, ticks: int, iterations: int) -> None:
    """One random problem: ``ticks`` control ticks, then a converged pose from the start."""
    q0 = start(robot, p)
    compiled = None if p["compiled"] else False
    if p["backend"] != "daqp":
        compiled = False
    tally.trials += 1
    for mode in ("ticks", "pose"):
        tick = -1  # the tick an error is raised at (--show; -1: building the stack)
        try:
            if p["stack"] == "readme":
                solver, contacts, com, swing, torso = readme_stack(
                    robot, q0, p["kind"], p["backend"], compiled
                )
            else:
                solver, contacts, com, swing, torso = walk_stack(
                    robot, q0, p["kind"], p["backend"], compiled, p["double"]
                )
            move_targets(p, com, swing, torso)
            if mode == "ticks":
                q = q0
                for _ in range(ticks):
                    tick += 1
                    t = time.perf_counter()
                    q_next = solver.step(q, 0.01)
                    elapsed = time.perf_counter() - t
                    if tally.first_tick < 0.0:
                        tally.first_tick = elapsed
                    elif elapsed > tally.slowest_tick:
                        tally.slowest_tick = elapsed
                        tally.slowest_tick_trial = p.get("trial", -1)
                    if elapsed > TICK_TIME_BOUND:
                        tally.slow_ticks += 1
                        tally.slow_trials.append(p.get("trial", -1))
                    tally.ticks += 1
                    check(robot, q, q_next, tally)
                    kin = Kinematics(robot, q_next)
                    for c in contacts:
                        e = float(abs(c.compute(kin)[1]).max())
                        tally.max_tick_contact = max(tally.max_tick_contact, e)
                        if e > TICK_CONTACT_TOL:
                            tally.tick_contact_misses += 1
                    q = q_next
            else:
                bound = POSE_TIME_PER_ITERATION * max(iterations, 1)
                t = time.perf_counter()
                result = solver.solve_pose(q0, max_iterations=iterations, time_budget=bound)
                elapsed = time.perf_counter() - t
                if elapsed > tally.slowest_pose:
                    tally.slowest_pose = elapsed
                    tally.slowest_pose_trial = p.get("trial", -1)
                if elapsed > bound:  # (checked by the pose before each step: a hair over)
                    tally.slow_poses += 1
                    tally.slow_trials.append(p.get("trial", -1))
                tally.most_projection_steps = max(
                    tally.most_projection_steps, result.projection_steps
                )
                tally.poses += 1
                if result.fell_back:
                    tally.fell_back.append(p.get("trial", -1))
                check(robot, q0, result.q, tally)
                kin = Kinematics(robot, result.q)
                worst = 0.0
                for c in contacts:
                    e = float(abs(c.compute(kin)[1]).max())
                    worst = max(worst, e)
                    tally.max_pose_contact = max(tally.max_pose_contact, e)
                    if e > POSE_CONTACT_TOL:
                        tally.pose_contact_misses += 1
                        tally.miss_trials.append(p.get("trial", -1))
                if tally.show:
                    print(
                        f"trial {p.get('trial', -1)} pose: {elapsed:.2f} s, "
                        f"{result.projection_steps} Gauss–Newton steps, hard contacts {worst:.2g}"
                        + (", fell back" if result.fell_back else "")
                    )
        except WbcError as exc:
            if mode == "pose" and BUDGET_SPENT in str(exc):  # a runaway, stopped
                tally.slow_poses += 1
                tally.slow_trials.append(p.get("trial", -1))
            kind = f"{mode}: {type(exc).__name__}: {str(exc)[:60]}"
            tally.typed[kind] += 1
            tally.typed_trials.setdefault(kind, []).append(p.get("trial", -1))
            if tally.show:
                at = f" tick {tick}" if mode == "ticks" else ""
                print(f"trial {p.get('trial', -1)} {mode}{at}: {type(exc).__name__}: {exc}")
        except Exception as exc:  # counting what is not typed is the point
            tally.untyped.append(f"{mode}: {type(exc).__name__}: {exc}")


def check(robot: Robot, q: np.ndarray, q_next: np.ndarray, tally: Tally) -> None:
    if not np.isfinite(q_next).all():
        tally.non_finite += 1
        return
    j, j0 = q_next[7:], q[7:]
    lo, hi = np.minimum(robot.q_min, j0), np.maximum(robot.q_max, j0)
    tally.limit_violations += int(((j < lo - 1e-12) | (j > hi + 1e-12)).sum())


def compile_first() -> None:
    """Build the package's compiled ticks now if they are not in numba's cache (a fresh
    checkout: about a minute per worker), so that no timed tick or pose waits for them."""
    from wbc.solvers.plan import package_ticks

    ticks = package_ticks()
    ticks.start_build(announce=False)
    ticks.wait_all()


def run(
    n: int,
    backends: list[str],
    ticks: int,
    iterations: int,
    seed: int,
    every: int = 0,
    trials: list[int] | None = None,
    show: bool = False,
) -> Tally:
    """``every`` > 0: print the figures so far every that many trials (long runs);
    ``trials``: run only these trial numbers (each the same draw as in a run of ``n``);
    ``show``: print each typed error in full, with its trial and tick."""
    robot = load_robot("bioloid")
    compile_first()
    tally = Tally(show=show)
    start_time = time.perf_counter()
    for trial in range(n) if trials is None else trials:
        p = draw(robot, np.random.default_rng([seed, trial]), backends)
        p["trial"] = trial
        run_trial(robot, p, tally, ticks, iterations)
        if every and (trial + 1) % every == 0:
            report(tally, start_time)
    return tally


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="number of trials")
    ap.add_argument("--backends", nargs="+", default=["daqp"])
    ap.add_argument("--ticks", type=int, default=50)
    ap.add_argument("--iterations", type=int, default=50)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--every", type=int, default=0, help="print the figures every N trials")
    ap.add_argument(
        "--trials", type=int, nargs="+", help="run only these trial numbers (reproduce one)"
    )
    ap.add_argument(
        "--show",
        action="store_true",
        help="print each typed error in full, and each pose's time, steps and contact error",
    )
    args = ap.parse_args()
    if args.trials is not None and min(args.trials) < 0:
        ap.error("--trials: trial numbers are >= 0")
    start_time = time.perf_counter()
    t = run(
        args.n, args.backends, args.ticks, args.iterations, args.seed, args.every, args.trials,
        args.show,
    )  # fmt: skip
    report(t, start_time)


def report(t: Tally, start_time: float) -> None:
    print(f"trials {t.trials}, ticks {t.ticks}, converged poses {t.poses}")
    print(f"limit violations {t.limit_violations}, non-finite outputs {t.non_finite}")
    print(f"untyped exceptions {len(t.untyped)}")
    for u in t.untyped[:10]:
        print("  ", u)
    print(
        f"hard contact > {TICK_CONTACT_TOL} after a tick: {t.tick_contact_misses} "
        f"(largest {t.max_tick_contact:.3g})"
    )
    print(
        f"hard contact > {POSE_CONTACT_TOL} at the end of a pose: {t.pose_contact_misses} "
        f"(largest {t.max_pose_contact:.3g}; trials {t.miss_trials[:10]})"
    )
    print(
        f"poses whose end could not be projected onto the hard levels (ended at the last "
        f"iterate that held them): {len(t.fell_back)} (trials {t.fell_back[:10]})"
    )
    print(
        f"slowest tick {t.slowest_tick * 1e3:.1f} ms (trial {t.slowest_tick_trial}; the run's "
        f"first tick apart: {t.first_tick:.2f} s), slowest pose {t.slowest_pose:.2f} s "
        f"(trial {t.slowest_pose_trial}); most Gauss–Newton steps in a pose "
        f"{t.most_projection_steps}"
    )
    print(
        f"ticks > {TICK_TIME_BOUND:g} s: {t.slow_ticks}, poses > {POSE_TIME_PER_ITERATION:g} s "
        f"per iteration or out of their work budget: {t.slow_poses} "
        f"(trials {t.slow_trials[:10]})"
    )
    print("typed errors:")
    for what, count in t.typed.most_common(20):
        print(f"  {count:6d}  {what}  (trials {t.typed_trials[what][:12]})")
    print(f"wall time {time.perf_counter() - start_time:.0f} s", flush=True)


if __name__ == "__main__":
    main()
