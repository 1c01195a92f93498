"""``wbc bench``: every solver family on the same trajectories, side by side.

Examples::

    wbc bench                                   # all families, thesis step + 10-step walk
    wbc bench --families qp-hierarchical peer --trajectories walk10
    wbc bench --mode converge --solvers hqp-daqp pinv-vat nlp-ipopt --trajectories thesis_step
    wbc bench --trajectories static_com         # ch. 3 CoM placement set
    wbc bench --json out/bench.json --record out/runs --plots out/plots
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable, Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TextIO

from rich import box
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from ..bench import trajectories as traj
from ..bench.solvers import BENCH_STACKS, FAMILIES, registry, select
from ..exceptions import ConfigurationError
from ..model import Robot, load_robot, print_notes
from ..walking.clock import CLOCKS
from .options import (
    add_compensate_arguments,
    add_encoders_only_argument,
    add_robot_argument,
    add_stepping_arguments,
    check_compensate_encoders,
    number,
    resolve_compensate,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_robot_argument(parser)
    parser.add_argument(
        "--solvers",
        nargs="+",
        metavar="NAME",
        help="solver names or prefixes (default: all); see --list",
    )
    parser.add_argument(
        "--families",
        nargs="+",
        metavar="FAMILY",
        help=f"restrict to families: {', '.join(FAMILIES)}",
    )
    parser.add_argument(
        "--trajectories",
        nargs="+",
        default=list(traj.DEFAULT),
        metavar="NAME",
        help=f"from {', '.join(traj.names())}",
    )
    parser.add_argument(
        "--stack",
        metavar="NAME",
        help="task stack of the wqp-*/hqp-* entries, by name in tasks/ or .toml path (default: "
        f"{BENCH_STACKS['kinematic']}, the strict hierarchy, for the kinematic benchmark; "
        f"{BENCH_STACKS['physics']}, the recommended one, with --physics)",
    )
    parser.add_argument(
        "--mode",
        choices=("tick", "converge"),
        default="tick",
        help="one QP/iteration per control tick (real time), or iterate every pose to convergence",
    )
    parser.add_argument(
        "--tol",
        type=positive_float,
        default=1e-6,
        help="converged mode: step tolerance, a number > 0 (max |Δq|, m / rad)",
    )
    parser.add_argument(
        "--max-iterations",
        type=positive_int,
        default=100,
        help="converged mode: iteration cap per pose, an integer >= 1",
    )
    parser.add_argument(
        "--clock",
        choices=tuple(CLOCKS),
        default="cpu",
        help="the ticks' timings: the thread's CPU time (the default: what a tick costs, the "
        "operating system's preemptions left out) or the wall clock (preemptions included: "
        "the p99 of a loaded machine); the tables and the records (time_clock) name it",
    )
    parser.add_argument("--json", type=Path, metavar="FILE", help="write one record per run")
    parser.add_argument(
        "--record", type=Path, metavar="DIR", help="save each run as <solver>__<trajectory>.npz"
    )
    parser.add_argument("--plots", type=Path, metavar="DIR", help="write figures")
    parser.add_argument("--list", action="store_true", help="list solvers and trajectories")
    parser.add_argument(
        "--wide", action="store_true", help="every column (~190 characters) instead of ~100"
    )
    parser.add_argument(
        "--verbose", action="store_true", help="let the solvers print (OSQP, IPOPT, ...)"
    )
    add_physics_arguments(parser)  # --physics, --robustness, --seed, --push, ...


#: argparse types: a finite number > 0, an integer >= 1 (:func:`wbc.cli.number`)
positive_float = number(0, lo_open=True)
positive_int = number(1, integer=True)


def _list(console: Console) -> int:
    table = Table(title="solvers")
    table.add_column("name")
    table.add_column("family")
    for e in registry("kinematic").values():
        table.add_row(e.name, e.family + ("" if e.real_time else " (converged mode only)"))
    console.print(table)
    console.print(
        f"wqp-*/hqp-* load the stack [bold]{BENCH_STACKS['kinematic']}[/] in the kinematic "
        f"benchmark and [bold]{BENCH_STACKS['physics']}[/] with --physics (--stack: another)"
    )
    for name, (_, text) in traj.TRAJECTORIES.items():
        console.print(f"trajectory [bold]{name}[/]: {text}")
    console.print(f"trajectory [bold]{traj.STATIC_COM}[/]: the static CoM placement set, ch. 3")
    return 0


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        if value != 0 and (abs(value) >= 1e4 or abs(value) < 1e-3):
            return f"{value:.2e}"
        return f"{value:.{digits}g}"
    return str(value)


def _thesis_values(record: dict[str, Any]) -> tuple[Any, Any, Any]:
    """The thesis's own CoM / foot error (mm) and time (ms per pose) for the rows that
    correspond to its experiments; None where it gives none."""
    if record["trajectory"] == "static_com":
        return record.get("thesis_com_err_mm"), None, record.get("thesis_time_ms")
    if record["trajectory"] != "thesis_step":
        return None, None, None
    from ..pinv.thesis_data import THESIS_WALKING

    scheme = record["solver"].split("-", 1)[-1]
    row = THESIS_WALKING.get(scheme) if record["solver"].startswith(("pinv-", "qp-")) else None
    if row is None:
        return None, None, None
    return row["com_max_mm"], row["foot_max_mm"], row["ms_per_pose"]


def _thesis_columns(record: dict[str, Any]) -> tuple[str, str, str]:
    """:func:`_thesis_values` as table cells."""
    com, foot, ms = _thesis_values(record)
    return _fmt(com), _fmt(foot), "-" if ms is None else f"{ms} ms"


def _print_wide(console: Console, records: list[dict[str, Any]], mode: str) -> None:
    """Every column (``--wide``; about 190 characters)."""
    for name in dict.fromkeys(r["trajectory"] for r in records):
        rows = [r for r in records if r["trajectory"] == name]
        table = Table(
            title=f"{name} ({mode} mode){_stack_note(rows)}"
            if name != "static_com"
            else "static_com (ch. 3, converged)",
            show_lines=False,
        )
        for col in (
            "solver",
            "family",
            "CoM err max/mean mm",
            "foot err max/mean mm",
            "limit viol. (n / max rad)",
            "penetr. mm",
            "CoM margin min mm",
            "ZMP margin min mm",
            f"{_clock(rows)} µs median / p99",
            "iter",
            "fail",
            "thesis CoM / foot mm",
            "thesis time",
        ):
            table.add_column(col, justify="left" if col in ("solver", "family") else "right")
        for r in rows:
            t_com, t_foot, t_time = _thesis_columns(r)
            table.add_row(
                r["solver"],
                r["family"],
                f"{_fmt(r['com_err_max_mm'])} / {_fmt(r['com_err_mean_mm'])}",
                f"{_fmt(r.get('foot_err_max_mm'))} / {_fmt(r.get('foot_err_mean_mm'))}",
                f"{_fmt(r.get('limit_violations'))} / {_fmt(r.get('limit_violation_max_rad'))}",
                _fmt(r.get("penetration_max_mm")),
                _fmt(r.get("com_margin_min_mm")),
                _fmt(r.get("zmp_margin_min_mm")),
                f"{_fmt(r['time_median_us'], 4)} / {_fmt(r.get('time_p99_us'), 4)}",
                _fmt(r.get("iterations_mean")),
                _fmt(r.get("failures")),
                f"{t_com} / {t_foot}",
                t_time,
            )
        console.print(table)


def _short(value: Any) -> str:
    """Two significant digits, short exponents: 0.0022, 4.3, 158, 8.5e-4; ``-`` if unknown."""
    if value is None:
        return "-"
    if isinstance(value, int) or value == 0:
        return str(int(value)) if float(value).is_integer() else str(value)
    a = abs(value)
    if a >= 100:
        return f"{value:.0f}"
    if a >= 1e-3:
        return f"{value:.2g}"
    mantissa, exponent = f"{value:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _pair(a: Any, b: Any) -> str:
    """``a / b``; ``-`` when neither is known (the column is then dropped)."""
    if a is None and b is None:
        return "-"
    return f"{_short(a)} / {_short(b)}"


def _time(r: dict[str, Any], mode: str) -> str:
    """Median / p99 per tick in µs (tick mode); the median per pose in ms (converged mode)."""
    med, p99 = r.get("time_median_us"), r.get("time_p99_us")
    if mode == "tick":
        return f"{med:.0f} / {p99:.0f}" if p99 is not None else f"{med:.0f}"
    return _short(med * 1e-3)


def _clock(rows: list[dict[str, Any]]) -> str:
    """The clock of the rows' times (``cpu``, ``wall``; ``cpu/wall`` if they mix)."""
    return "/".join(dict.fromkeys(str(r.get("time_clock", "wall")) for r in rows))


def _compact_columns(
    mode: str, gait: str | None, clock: str = "wall"
) -> list[tuple[str, Callable[[dict[str, Any]], str]]]:
    """(header with units, cell of a record) of the compact table. The balance margin is the
    CoM's on a static gait and the ZMP's on a dynamic one (``--wide`` shows both); the times'
    header names their ``clock``."""
    margin = "com" if gait == "static" else "zmp"
    if mode == "tick":
        errors: list[tuple[str, Callable[[dict[str, Any]], str]]] = [
            ("CoM err mm\nmax / mean", lambda r: _pair(r["com_err_max_mm"], r["com_err_mean_mm"])),
            (
                "swing err mm\nmax / mean",
                lambda r: _pair(r.get("foot_err_max_mm"), r.get("foot_err_mean_mm")),
            ),
        ]
    else:  # converged: the maxima (as the thesis reports them)
        errors = [
            ("CoM err\nmax mm", lambda r: _short(r["com_err_max_mm"])),
            ("swing err\nmax mm", lambda r: _short(r.get("foot_err_max_mm"))),
        ]
    columns: list[tuple[str, Callable[[dict[str, Any]], str]]] = [
        ("solver", lambda r: r["solver"]),
        *errors,
        ("limit\nviol.", lambda r: _short(r.get("limit_violations"))),
    ]
    if mode == "tick":  # converged poses are not a motion: no penetration or balance figure
        columns += [
            ("penetr.\nmm", lambda r: _short(r.get("penetration_max_mm"))),
            (
                f"{'CoM' if margin == 'com' else 'ZMP'}\nmargin mm",
                lambda r: _short(r.get(f"{margin}_margin_min_mm")),
            ),
        ]
    if mode == "tick":
        columns.append((f"{clock} µs/tick\nmed. / p99", lambda r: _time(r, mode)))
    else:
        columns += [
            (f"{clock} ms/pose\nmedian", lambda r: _time(r, mode)),
            ("iter", lambda r: _short(r.get("iterations_mean"))),
            # the thesis's figures are per converged pose: beside converged runs only
            ("thesis mm\nCoM / foot", lambda r: _pair(*_thesis_values(r)[:2])),
            ("thesis\nms / pose", lambda r: _short(_thesis_values(r)[2])),
        ]
    columns.append(("fail", lambda r: _short(r.get("failures"))))
    return columns


LEGEND = (
    "err: distance from the reference, by forward kinematics of the returned joints. "
    "limit viol.: ticks × joints beyond a joint limit. penetr.: depth of the swing sole's "
    "lowest corner below the ground. margin: smallest signed distance to the support "
    "polygon's edge (+ inside) of the balance point: the CoM on a static gait (thesis_step), "
    "the ZMP on a dynamic one (walk10, turn, lateral), whose CoM leaves the polygon by design "
    "(its CoM margin, negative, is in --wide). fail: ticks the solver could not solve. The "
    "thesis's own figures (per converged pose) appear beside converged runs. Times: the "
    "thread's CPU time (cpu, the default: preemptions by other processes left out) or the "
    "wall clock (--clock wall). --wide: every column; --verbose: solver output."
)


def _stack_note(rows: list[dict[str, Any]]) -> str:
    """``, wqp/hqp: <stack>`` for a table with rows of the walking stack's entries."""
    stacks = dict.fromkeys(  # (the static CoM rows run no stack: they have none)
        r["stack"]
        for r in rows
        if r.get("family") in ("qp-weighted", "qp-hierarchical") and r.get("stack") is not None
    )
    return f", wqp/hqp: {', '.join(str(s) for s in stacks)}" if stacks else ""


def _print_tables(console: Console, records: list[dict[str, Any]], mode: str) -> None:
    """The compact tables (key figures, about 100 characters wide) and their legend."""
    for name in dict.fromkeys(r["trajectory"] for r in records):
        rows = [r for r in records if r["trajectory"] == name]
        row_mode = "converge" if name == traj.STATIC_COM else mode
        columns = _compact_columns(row_mode, rows[0].get("gait"), _clock(rows))
        cells = [[fn(r) for _, fn in columns] for r in rows]
        keep = [k for k in range(len(columns)) if any(c[k] not in ("-", "- / -") for c in cells)]
        title = f"{name} ({row_mode} mode)" if name != traj.STATIC_COM else f"{name} (ch. 3)"
        title += _stack_note(rows)
        table = Table(title=title, box=box.SIMPLE_HEAD, show_edge=False, padding=(0, 1, 0, 0))
        for k in keep:
            table.add_column(
                columns[k][0],
                justify="left" if k == 0 else "right",
                no_wrap=True,
                min_width=max(len(c[k]) for c in cells) if k == 0 else None,
            )
        for c in cells:
            table.add_row(*(c[k] for k in keep))
        console.print(table)
    console.print(LEGEND, style="dim", width=min(console.width, 100))


@contextlib.contextmanager
def solver_output(verbose: bool) -> Iterator[TextIO]:
    """Yield a stream on the real standard output; unless ``verbose``, file descriptor 1 goes
    to /dev/null meanwhile, so what the solvers' C code prints (OSQP's "Polishing not
    needed", IPOPT's banner) does not reach the terminal."""
    if verbose:
        yield sys.stdout
        return
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no file descriptor 1 (an embedded interpreter): nothing to silence
        yield sys.stdout
        return
    # Python-level stdout replaced (a test, a notebook): keep writing there
    replaced = sys.stdout is not sys.__stdout__
    out = sys.stdout if replaced else os.fdopen(os.dup(saved), "w", encoding="utf-8")
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    try:
        yield out
    finally:
        sys.stdout.flush()
        _flush_c_stdout()
        os.dup2(saved, 1)
        os.close(saved)
        out.flush()
        if not replaced:
            out.close()


def _flush_c_stdout() -> None:
    """Flush C's stdio buffers, so that text the solvers buffered goes to /dev/null too."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - no libc (not Linux/macOS)
        pass


def run(args: argparse.Namespace) -> int:
    with solver_output(getattr(args, "verbose", False)) as out:
        return _run(args, out)


def _run(args: argparse.Namespace, out: TextIO) -> int:
    wide = getattr(args, "wide", False)
    # logs and pipes get the table's own width instead of rich's 80-column default
    full = wide or getattr(args, "physics", False)  # the physics table keeps its width
    console = Console(file=out, width=None if out.isatty() else (190 if full else 100))
    if args.list:
        return _list(console)
    robot = load_robot(args.robot)
    print_notes(robot, "bench")
    benchmark = "physics" if args.physics else "kinematic"
    stack = getattr(args, "stack", None)
    if args.physics:  # on a body: the robot folder's stack.toml when it has one
        from ..bench.physics import physics_stack

        stack = physics_stack(robot, stack)
    entries, notes = select(args.solvers, args.families, args.mode, benchmark, stack)
    if stack is not None:
        console.print(f"wqp-*/hqp-* load the stack {escape(str(stack))}")
    for note in notes:
        console.print(f"[yellow]note[/]: {escape(note)}")
    peers = [e.name for e in entries if e.family == "peer" or e.name == "nlp-ipopt"]
    if peers:  # the stack they take their tasks from, and what they leave out
        from ..bench.peers import peer_stack

        line = peer_stack(robot, stack).line()
        console.print(f"{', '.join(peers)}: {escape(line)}")
    if args.physics:
        return run_physics_command(args, console, robot, entries)
    walking = [t for t in args.trajectories if t != traj.STATIC_COM]
    for t in walking:  # fail fast on a bad name, before any run
        if t not in traj.TRAJECTORIES:
            traj.build(t, robot)
    records: list[dict[str, Any]] = []
    recordings = []  # kept for the figures only
    started = time.perf_counter()
    # a fresh install: the compiled ticks compile in background processes; meanwhile the
    # runs that do not use them print their errors (their times, taken beside the compiler,
    # would not compare: every run of the tables starts once the compilation is over)
    baselines = [e for e in entries if e.family in _WITHOUT_TICKS]
    building = bool(walking) and len(baselines) < len(entries) and _compile_in_background(console)
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    ) as bar:
        refs = {t: traj.build(t, robot) for t in walking}
        job = bar.add_task(
            "benchmark",
            total=len(entries) * len(refs) + (1 if traj.STATIC_COM in args.trajectories else 0),
        )
        from ..bench.runner import run_entry, save_recording, static_com_records

        if building:
            for name, ref in refs.items():
                for entry in baselines:
                    bar.update(job, description=f"{entry.name} on {name} (errors)")
                    record, _ = run_entry(
                        entry, robot, ref, args.mode, args.tol, args.max_iterations
                    )
                    console.print(_errors_line(record))
            bar.update(job, description="waiting for the compiled ticks")
            _wait_for_ticks()
        for name, ref in refs.items():
            for entry in entries:
                bar.update(job, description=f"{entry.name} on {name}")
                record, rec = run_entry(
                    entry, robot, ref, args.mode, args.tol, args.max_iterations, args.clock
                )
                records.append(record)
                if args.record:
                    save_recording(rec, args.record, entry.name, name)
                if args.plots:
                    recordings.append(rec)
                bar.advance(job)
        if traj.STATIC_COM in args.trajectories:
            families = {e.family for e in entries}
            records += static_com_records(
                robot, families, progress=lambda d: bar.update(job, description=d)
            )
            bar.advance(job)
    (_print_wide if wide else _print_tables)(console, records, args.mode)
    elapsed = time.perf_counter() - started
    console.print(
        f"{len(records)} runs in {elapsed:.1f} s on {platform.node()} "
        f"({platform.machine()}, Python {platform.python_version()})"
    )
    if args.plots and records:
        from ..bench.plots import quantity_figures, timing_figure

        paths = quantity_figures(recordings, args.plots)
        paths.append(timing_figure(records, args.plots / "time_per_tick.png"))
        console.print(
            f"{len(paths)} figures (PNG and SVG) in {args.plots}: <trajectory>__<quantity>, "
            "every solver per figure; time_per_tick"
        )
    if args.json:
        write_records(args.json, records)
        console.print(f"records in {args.json}")
    return 0


#: families whose runs do not use the compiled ticks (their errors show while those compile)
_WITHOUT_TICKS = ("pinv", "peer")


def _compile_in_background(console: Console) -> bool:
    """Start compiling the package's control ticks in background processes if they are not
    in the disk cache (:func:`wbc.solvers.plan.start_package_ticks`); True if started."""
    from ..solvers.plan import start_package_ticks

    if not start_package_ticks(announce=False):
        return False
    console.print(
        "[yellow]compiling the control ticks[/] (numba, once per installation, in background "
        "processes); meanwhile the errors of the runs without them, if any:"
    )
    return True


def _wait_for_ticks() -> None:
    from ..solvers.plan import wait_for_package_ticks

    wait_for_package_ticks()


def _errors_line(record: dict[str, Any]) -> str:
    """One run's tracking errors (printed while the ticks compile)."""

    def mm(key: str) -> str:
        value = record.get(key)
        return "–" if value is None else f"{value:.2g}"

    return (
        f"{record['solver']} on {record['trajectory']}: CoM err {mm('com_err_max_mm')} / "
        f"{mm('com_err_mean_mm')} mm, swing err {mm('foot_err_max_mm')} / "
        f"{mm('foot_err_mean_mm')} mm (max / mean)"
    )


def write_records(path: Path, records: list, **extra: Any) -> None:
    """``records`` as JSON at ``path``, with the date, machine, Python and command line
    (``extra`` keys, e.g. the elapsed time, go beside them)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.node()} {platform.machine()} {platform.processor()}".strip(),
        "python": sys.version.split()[0],
        "command": "wbc bench " + " ".join(sys.argv[2:]),
        **extra,
        "records": records,
    }
    path.write_text(json.dumps(payload, indent=1))


# ---------------------------------------------------------------------- --physics
def add_physics_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``wbc bench`` options of the physics benchmark (:mod:`wbc.bench.physics`)."""
    parser.add_argument(
        "--physics",
        action="store_true",
        help="play every run through the deploy path on the simulated robot (wbc[physics])",
    )
    parser.add_argument(
        "--robustness",
        type=number(0, 10000, integer=True),
        default=0,
        metavar="N",
        help="--physics: N randomised models",
    )
    parser.add_argument(
        "--seed", type=number(0, integer=True), default=0, help="--robustness: random seed"
    )
    parser.add_argument(
        "--push",
        action="store_true",
        help="--physics: largest survived torso impulse (N·s) forward, backward, toward and "
        "away from the swing foot, each beside its physical bound",
    )
    add_compensate_arguments(parser, "--physics: servo compliance feed-forward on the goals")
    parser.add_argument(
        "--closed-loop",
        action="store_true",
        help="--physics: the closed-loop rows (the default; kept for old command lines)",
    )
    parser.add_argument(
        "--open-loop",
        action="store_true",
        help="--physics: only the plans played open loop (by default each controller also "
        "runs live in the deployment's tick, closed through the torso IMU and the servos' "
        "present positions, with step adjustment: wbc.balance.live), no feed-forward unless "
        "--compensate",
    )
    add_encoders_only_argument(parser)
    add_stepping_arguments(parser)
    parser.add_argument(
        "--gyro",
        type=number(0, 10),
        default=0.0,
        metavar="SCALE",
        help="--physics: closed loop, torso gyro feedback on the leg goals (OP3 gains x SCALE; "
        "wbc.balance.feedback)",
    )


def run_physics_command(args: argparse.Namespace, console: Console, robot: Robot, entries) -> int:
    """``wbc bench --physics``: the table, and the records in ``--json``."""
    from ..bench.physics import PhysicsOptions, run_physics

    if args.robustness < 0:
        raise ConfigurationError(f"--robustness must be >= 0, got {args.robustness}")
    if args.open_loop and (args.closed_loop or args.encoders_only or args.stepping):
        raise ConfigurationError(
            "--open-loop: no --closed-loop, --encoders-only or --stepping with it"
        )
    resolve_compensate(args, robot, best=not args.open_loop)
    if not (math.isfinite(args.compensate) and args.compensate >= 0):
        raise ConfigurationError(
            f"--compensate GAIN must be a finite number >= 0, got {args.compensate}"
        )
    check_compensate_encoders(args)
    if not (math.isfinite(args.gyro) and args.gyro >= 0):
        raise ConfigurationError(f"--gyro SCALE must be a finite number >= 0, got {args.gyro}")
    if args.mode != "tick":
        raise ConfigurationError("--physics plays real-time plans: use --mode tick (the default)")
    names = [t for t in args.trajectories if t != traj.STATIC_COM]
    refs = {t: traj.build(t, robot, on_servos=True) for t in names}
    if not args.open_loop and _compile_in_background(console):
        _wait_for_ticks()  # the closed loop solves live: its share of the compiled tick
    started = time.perf_counter()
    options = PhysicsOptions(
        compensate=args.compensate,
        gyro=args.gyro,
        correct=args.compensate_encoders,
        closed_loop=not args.open_loop,
        use_imu=not args.encoders_only,
        stepping=not args.no_stepping,
        robustness=args.robustness,
        seed=args.seed,
        push=args.push,
        all_solvers=bool(args.solvers or args.families),
        record=args.record,
        plots=args.plots,
    )
    records = run_physics(options, console, robot, entries, refs)
    elapsed = time.perf_counter() - started
    console.print(f"{len(records)} simulated runs in {elapsed:.1f} s on {platform.node()}")
    if args.json:
        write_records(args.json, records, elapsed_s=elapsed)
        console.print(f"records in {args.json}")
    return 0
