"""Reproduce the structure of the CoM-control thesis's Tables 3.3.2 / 3.3.3 and its ch. 4 walking
figures on our Bioloid model, next to the thesis's numbers.

    python benchmarks/thesis_tables.py                 # both, printed
    python benchmarks/thesis_tables.py --markdown out.md
    python benchmarks/thesis_tables.py --only placement --repeats 5

The work is done by :func:`wbc.pinv.run_com_placement_benchmark` and
:func:`wbc.pinv.run_walking_benchmark` (also callable from the benchmark CLI).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wbc import load_robot
from wbc.pinv import (
    METHODS,
    SCHEME_NAMES,
    TABLE_3_3_1,
    THESIS_COM_TOLERANCE,
    run_com_placement_benchmark,
    run_walking_benchmark,
)


def _fmt(x: float | None, digits: int = 4) -> str:
    if x is None:
        return "–"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e5):
        return f"{x:.1e}"
    return f"{x:.{digits}f}"


def placement_markdown(rows: list[dict]) -> str:
    settings = list(dict.fromkeys(r["setting"] for r in rows))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    by = {(r["method"], r["setting"]): r for r in rows}
    head = (
        "| method | "
        + " | ".join(f"{s} (λ={TABLE_3_3_1[s][0]:g}, α={TABLE_3_3_1[s][1]:g})" for s in settings)
        + " |"
    )
    sep = "|---" * (len(settings) + 1) + "|"
    out = ["CoM error (mm), ours / thesis (Table 3.3.2); * = not converged (iteration cap):", "",
           head, sep]  # fmt: skip
    for m in methods:
        cells = []
        for s in settings:
            r = by[(m, s)]
            star = "" if r["converged"] else "*"
            cells.append(f"{_fmt(r['com_error_mm'])}{star} / {_fmt(r['thesis_com_error_mm'])}")
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    out += ["", "Time (ms), ours / thesis (Table 3.3.3):", "", head, sep]
    for m in methods:
        cells = [f"{by[(m, s)]['time_ms']:.1f} / {by[(m, s)]['thesis_time_ms']:.1f}"
                 for s in settings]  # fmt: skip
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    out += ["", "Iterations (pseudo-inverse updates) / largest joint-limit excursion (deg) / "
            "swing-sole height at the end (mm):", "", head, sep]  # fmt: skip
    for m in methods:
        cells = [f"{by[(m, s)]['iterations']} / {by[(m, s)]['joint_limit_excess_deg']:.0f} / "
                 f"{by[(m, s)]['swing_sole_height_mm']:.0f}" for s in settings]  # fmt: skip
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def walking_markdown(rows: list[dict]) -> str:
    out = [
        "| scheme | CoM max (mm) | thesis | foot max (mm) | thesis | ms/pose | thesis | "
        "iter/pose | unconverged poses | min swing height (mm) | joint-limit excess (deg) |",
        "|---" * 11 + "|",
    ]
    for r in rows:
        out.append(
            f"| {r['scheme']} | {_fmt(r['com_max_mm'])} | {_fmt(r['thesis_com_max_mm'])} | "
            f"{_fmt(r['foot_max_mm'])} | {_fmt(r['thesis_foot_max_mm'])} | "
            f"{r['ms_per_pose']:.1f} | {_fmt(r['thesis_ms_per_pose'], 2)} | "
            f"{r['iterations_mean']:.0f} | {r['unconverged_poses']} | "
            f"{r['swing_min_height_mm']:.2f} | {r['joint_limit_excess_deg']:.1f} |"
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", choices=["placement", "walking"], default=None)
    p.add_argument("--repeats", type=int, default=3, help="runs per placement cell (best time)")
    p.add_argument("--poses", type=int, default=100, help="poses of the walking step")
    p.add_argument("--max-iterations", type=int, default=200, help="per walking pose")
    p.add_argument(
        "--length-scale",
        type=float,
        default=1000.0,
        help="1000: lengths in mm as in the thesis (default); 1: metres",
    )
    p.add_argument("--damping", type=float, default=0.1, help="λ of the walking schemes")
    p.add_argument("--gain", type=float, default=0.1, help="α of the walking schemes")
    p.add_argument(
        "--weights",
        choices=["identity", "annex_b"],
        default="identity",
        help="base W of the walking schemes (default identity, see wbc.pinv.schemes)",
    )
    p.add_argument("--markdown", type=Path, default=None, help="also write the tables here")
    args = p.parse_args(argv)
    robot = load_robot("bioloid")
    parts = [f"Machine: {platform.processor() or platform.machine()}, Python "
             f"{platform.python_version()}; length scale {args.length_scale:g}."]  # fmt: skip
    if args.only in (None, "placement"):
        start = time.perf_counter()
        rows = run_com_placement_benchmark(robot, methods=METHODS, repeats=args.repeats,
                                           length_scale=args.length_scale)  # fmt: skip
        parts += [
            f"## Static CoM placement (ch. 3), walk_ready -> CoM over the left sole, "
            f"tolerance {THESIS_COM_TOLERANCE * 1e3:g} mm, best of {args.repeats} runs "
            f"({time.perf_counter() - start:.0f} s)",
            "",
            placement_markdown(rows),
        ]
    if args.only in (None, "walking"):
        start = time.perf_counter()
        base_w = None if args.weights == "identity" else "annex_b"
        rows = run_walking_benchmark(robot, SCHEME_NAMES, n_poses=args.poses,
                                     max_iterations=args.max_iterations,
                                     length_scale=args.length_scale, damping=args.damping,
                                     gain=args.gain,
                                     weights=base_w)  # fmt: skip
        parts += [
            "",
            f"## Walking schemes (ch. 4), {args.poses}-pose step, λ = {args.damping:g}, "
            f"α = {args.gain:g}, W = {args.weights}, "
            f"tol 0.01 mm, ≤ {args.max_iterations} iterations per pose "
            f"({time.perf_counter() - start:.0f} s)",
            "",
            walking_markdown(rows),
        ]
    text = "\n".join(parts)
    print(text)
    if args.markdown is not None:
        args.markdown.write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
