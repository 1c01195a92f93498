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
import json
import platform
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from ..model import load_robot
from . import trajectories as traj
from .solvers import FAMILIES, registry, select


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="bioloid", help="robot name or URDF path")
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
        "--mode",
        choices=("tick", "converge"),
        default="tick",
        help="one QP/iteration per control tick (real time), or iterate every pose to convergence",
    )
    parser.add_argument(
        "--tol", type=float, default=1e-6, help="converged mode: task error tolerance (m / rad)"
    )
    parser.add_argument(
        "--max-iterations", type=int, default=100, help="converged mode: iteration cap per pose"
    )
    parser.add_argument("--json", type=Path, metavar="FILE", help="write one record per run")
    parser.add_argument(
        "--record", type=Path, metavar="DIR", help="save each run as <solver>__<trajectory>.npz"
    )
    parser.add_argument("--plots", type=Path, metavar="DIR", help="write figures")
    parser.add_argument("--list", action="store_true", help="list solvers and trajectories")
    from .physics import add_physics_arguments  # --physics, --robustness, --seed, --push

    add_physics_arguments(parser)


def _list(console: Console) -> int:
    table = Table(title="solvers")
    table.add_column("name")
    table.add_column("family")
    for e in registry().values():
        table.add_row(e.name, e.family + ("" if e.real_time else " (converged mode only)"))
    console.print(table)
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


def _thesis_columns(record: dict[str, Any]) -> tuple[str, str, str]:
    """The thesis's own figures for the rows that correspond to its experiments."""
    if record["trajectory"] == "static_com":
        return (
            _fmt(record.get("thesis_com_err_mm")),
            "-",
            _fmt(record.get("thesis_time_ms")) + " ms" if "thesis_time_ms" in record else "-",
        )
    if record["trajectory"] != "thesis_step":
        return "-", "-", "-"
    from ..pinv.thesis_data import THESIS_WALKING

    scheme = record["solver"].split("-", 1)[-1]
    row = THESIS_WALKING.get(scheme) if record["solver"].startswith(("pinv-", "qp-")) else None
    if row is None:
        return "-", "-", "-"
    ms = row["ms_per_pose"]
    return (_fmt(row["com_max_mm"]), _fmt(row["foot_max_mm"]), "-" if ms is None else f"{ms} ms")


def _print_tables(console: Console, records: list[dict[str, Any]], mode: str) -> None:
    for name in dict.fromkeys(r["trajectory"] for r in records):
        rows = [r for r in records if r["trajectory"] == name]
        table = Table(
            title=f"{name} ({mode} mode)"
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
            "µs median / p99",
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
                f"{_fmt(r['time_median_us'], 4)} / {_fmt(r.get('time_p99_us'), 4)}",
                _fmt(r.get("iterations_mean")),
                _fmt(r.get("failures")),
                f"{t_com} / {t_foot}",
                t_time,
            )
        console.print(table)


def run(args: argparse.Namespace) -> int:
    # logs and pipes get a wide table instead of rich's 80-column default
    console = Console(width=None if sys.stdout.isatty() else 190)
    if args.list:
        return _list(console)
    robot = load_robot(args.robot)
    entries, notes = select(args.solvers, args.families, args.mode)
    for note in notes:
        console.print(f"[yellow]note[/]: {escape(note)}")
    if args.physics:
        from .physics import run_physics_command

        return run_physics_command(args, console, robot, entries)
    walking = [t for t in args.trajectories if t != traj.STATIC_COM]
    for t in walking:  # fail fast on a bad name, before any run
        if t not in traj.TRAJECTORIES:
            traj.build(t, robot)
    records: list[dict[str, Any]] = []
    started = time.perf_counter()
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
        from .runner import run_entry, save_recording, static_com_records

        for name, ref in refs.items():
            for entry in entries:
                bar.update(job, description=f"{entry.name} on {name}")
                record, rec = run_entry(entry, robot, ref, args.mode, args.tol, args.max_iterations)
                records.append(record)
                if args.record:
                    save_recording(rec, args.record, entry.name, name)
                if args.plots:
                    from .plots import run_figure

                    run_figure(rec, args.plots / f"{entry.name}__{name}.png")
                bar.advance(job)
        if traj.STATIC_COM in args.trajectories:
            families = {e.family for e in entries}
            records += static_com_records(
                robot, families, progress=lambda d: bar.update(job, description=d)
            )
            bar.advance(job)
    _print_tables(console, records, args.mode)
    elapsed = time.perf_counter() - started
    console.print(
        f"{len(records)} runs in {elapsed:.1f} s on {platform.node()} "
        f"({platform.machine()}, Python {platform.python_version()})"
    )
    if args.plots and records:
        from .plots import timing_figure

        path = timing_figure(records, args.plots / "time_per_tick.png")
        console.print(f"figures in {args.plots} (time comparison: {path.name})")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            "date": datetime.now(UTC).isoformat(timespec="seconds"),
            "machine": f"{platform.node()} {platform.machine()} {platform.processor()}".strip(),
            "python": sys.version.split()[0],
            "command": "wbc bench " + " ".join(sys.argv[2:]),
            "records": records,
        }
        args.json.write_text(json.dumps(payload, indent=1))
        console.print(f"records in {args.json}")
    return 0
