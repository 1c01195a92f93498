"""``wbc walk``: run a task stack along a walking reference, report, save, show.

Examples::

    wbc walk                                    # walk stack, 10 steps, one QP per tick
    wbc walk --stack cj_com --trajectory thesis_step --mode converge
    wbc walk --out run.npz --view               # save the recording and replay it in meshcat
    wbc walk --out run.npz --export run.html    # and a self-contained replay page
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..exceptions import WbcError
from ..model import load_robot, print_notes
from .options import add_robot_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_argument(parser)
    parser.add_argument(
        "--stack",
        help="task stack name (tasks/*.toml) or path (default: the robot folder's stack.toml, "
        "else walk)",
    )
    parser.add_argument(
        "--solver", choices=("weighted", "hierarchical"), help="override the stack file's solver"
    )
    parser.add_argument("--backend", help="QP backend: daqp, proxqp, quadprog, osqp")
    parser.add_argument(
        "--trajectory",
        default="walk10",
        help="thesis_step, walk10, turn, lateral (see wbc bench --list)",
    )
    parser.add_argument("--mode", choices=("tick", "converge"), default="tick")
    parser.add_argument("--out", type=Path, help="save the recording (.npz)")
    parser.add_argument("--view", action="store_true", help="replay in meshcat afterwards")
    parser.add_argument(
        "--export", type=Path, metavar="HTML", help="write a self-contained replay page"
    )


def run(args: argparse.Namespace) -> int:
    from ..bench import metrics
    from ..bench.trajectories import build
    from ..stacks import load_stack, robot_stack
    from ..walking.loop import RunOptions, StackController
    from ..walking.loop import run as run_loop

    try:
        robot = load_robot(args.robot)
        print_notes(robot, "walk")
        ref = build(args.trajectory, robot, walking_only=True, on_servos=True)  # (deployable)
        stack, note = robot_stack(robot, args.stack)
        control = load_stack(stack, robot, backend=args.backend, solver=args.solver)
    except WbcError as exc:
        print(f"wbc walk: {exc}", file=sys.stderr)
        return 2
    print(f"wbc walk: {note}")  # which stack runs (the robot folder's, when it has one)
    rec = run_loop(StackController(control), robot, ref, options=RunOptions(mode=args.mode))
    m = metrics.compute(rec, robot)
    print(
        f"{control.name} ({type(control.solver).__name__}, {control.solver.backend.name}) on "
        f"{ref.name}: {len(rec)} ticks, {args.mode} mode"
    )
    print(
        f"  CoM error max/mean {m['com_err_max_mm']:.3f}/{m['com_err_mean_mm']:.3f} mm, "
        f"swing-foot error max/mean {m['foot_err_max_mm']:.3f}/{m['foot_err_mean_mm']:.3f} mm"
    )
    print(
        f"  joint-limit violations {m['limit_violations']} (max {m['limit_violation_max_rad']:.2g}"
        f" rad), penetration {m['penetration_max_mm']:.2f} mm, ZMP margin min "
        f"{m['zmp_margin_min_mm']:.1f} mm, failures {m['failures']}"
    )
    print(f"  time per tick median {m['time_median_us']:.0f} µs, p99 {m['time_p99_us']:.0f} µs")
    path = args.out
    problems = rec.problems()
    if path is not None:
        rec.save(path)
        print(f"recording saved to {path}")
        if problems:  # saved for inspection, marked invalid: wbc deploy refuses it
            print(
                f"wbc walk: the run failed ({'; '.join(problems)}): {path} is marked invalid "
                "(wbc deploy refuses it without --force)",
                file=sys.stderr,
            )
    if args.export or args.view:
        from .view import run as view

        if path is None:
            import tempfile

            path = Path(tempfile.mkdtemp(prefix="wbc-walk-")) / "run.npz"
            rec.save(path)
        view_args = argparse.Namespace(
            recording=str(path),
            robot=args.robot,
            pose="stand",
            speed=1.0,
            loop=False,
            frames=None,
            export=str(args.export) if args.export else None,
            fps=30.0,
            serve=bool(args.view),
            no_browser=False,
            no_wait=False,
        )
        return view(view_args)
    return 0 if m["failures"] == 0 else 1
