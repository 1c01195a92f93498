"""The behaviour gate: fixed, deterministic commands run on a tree, and every number they record
that is not a timing compared with a reference tree's records.

    python tools/behaviour_gate.py record REF_DIR [--tree DIR]
    python tools/behaviour_gate.py check REF_DIR OUT_DIR [--tree DIR]

``record`` runs the commands on ``--tree`` (default: this repository) into ``REF_DIR``;
``check`` runs them into ``OUT_DIR`` and prints each difference and ``GATE: N differences``
(exit 1 if any). A refactoring should give 0; a change of default names its differences. The
commands (two in parallel, ~1 min with warm kernels on an idle 2-core machine, several minutes
cold): the kinematic benchmark on the recommended and the strict stack, Kokone, a short
``wbc drive --sim`` script, the closed-loop physics benchmark, four randomised plants, the OP3.
Set ``XDG_CACHE_HOME`` per tree (the kernels' cache) and ``PYTHONPATH`` to the tree.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

COMMANDS_TOML = """[[command]]
duration = 3.0
vx = 0.06
[[command]]
duration = 3.0
vx = 0.03
vy = 0.02
wz = 0.3
[[command]]
duration = 1.0
"""

#: two chains of commands run in parallel: (record name, arguments after ``wbc``)
CHAINS: list[list[tuple[str, list[str]]]] = [
    [
        ("walk", ["bench", "--trajectories", "walk10", "walk10_wb", "turn",
                  "--solvers", "hqp-daqp", "wqp-daqp", "--stack", "walk"]),
        ("strict", ["bench", "--trajectories", "walk10", "lateral",
                    "--solvers", "hqp-daqp", "wqp-daqp"]),
        ("kokone", ["bench", "--robot", "kokone", "--trajectories", "keyposes", "walk10",
                    "--solvers", "wqp-daqp", "hqp-daqp"]),
        ("drive", ["drive", "--sim", "--commands", "{commands}"]),
    ],
    [
        ("physics", ["bench", "--physics", "--trajectories", "walk10_wb", "turn_wb",
                     "lateral_wb", "--solvers", "wqp-daqp", "hqp-daqp"]),
        ("robust", ["bench", "--physics", "--robustness", "4", "--seed", "3",
                    "--trajectories", "walk10_wb", "--solvers", "wqp-daqp"]),
        ("op3", ["bench", "--robot", "op3", "--physics", "--trajectories", "walk10",
                 "--solvers", "hqp-daqp"]),
    ],
]  # fmt: skip

#: keys holding timings, machine facts or paths (not behaviour), matched as substrings
SKIP = ("date", "machine", "python", "command", "time_", "wall", "cpu", "compile", "elapsed",
        "_us", "_ms", "seconds", "path", "file", "realtime_factor", "steps_per_s",
        "feedback_share", "stack")  # fmt: skip
#: behaviour keys that contain a SKIP substring
KEEP = ("fall_time_s", "sim_time_s")


def run(tree: Path, out: Path) -> None:
    """Every command of :data:`CHAINS` on ``tree``, its record ``out/NAME.json``."""
    out.mkdir(parents=True, exist_ok=True)
    commands = out / "commands.toml"
    commands.write_text(COMMANDS_TOML)

    def chain(steps: list[tuple[str, list[str]]]) -> None:
        for name, args in steps:
            args = [a.format(commands=commands) for a in args]
            cmd = [sys.executable, "-m", "wbc.cli", *args, "--json", str(out / f"{name}.json")]
            with open(out / f"{name}.log", "w") as log:
                subprocess.run(cmd, cwd=tree, stdout=log, stderr=subprocess.STDOUT, check=False)

    with ThreadPoolExecutor(len(CHAINS)) as pool:
        list(pool.map(chain, CHAINS))


def differences(prefix: str, a: object, b: object, out: list[str]) -> None:
    """Append to ``out`` every difference between records ``a`` and ``b`` (numbers beyond
    1e-9 relative; keys in one only; other values unequal), timing keys left out."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if any(s in k for s in SKIP) and k not in KEEP:
                continue
            if k not in a or k not in b:
                out.append(f"{prefix}.{k}: only in {'reference' if k in a else 'new'}")
            else:
                differences(f"{prefix}.{k}", a[k], b[k], out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{prefix}: length {len(a)} vs {len(b)}")
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            differences(f"{prefix}[{i}]", x, y, out)
    elif (
        isinstance(a, int | float)
        and isinstance(b, int | float)
        and not isinstance(a, bool)
        and not isinstance(b, bool)
    ):
        both_nan = math.isnan(a) and math.isnan(b)
        if not both_nan and abs(a - b) > 1e-9 * max(1.0, abs(a), abs(b)):
            out.append(f"{prefix}: {a!r} vs {b!r}")
    elif a != b:
        out.append(f"{prefix}: {str(a)[:80]!r} vs {str(b)[:80]!r}")


def compare(reference: Path, new: Path) -> int:
    """Print the differences between the two folders' records; their number."""
    total = 0
    for path in sorted(reference.glob("*.json")):
        other = new / path.name
        if not other.exists():
            print(f"{path.name}: no record (see {other.with_suffix('.log')})")
            total += 1
            continue
        found: list[str] = []
        differences(path.stem, json.loads(path.read_text()), json.loads(other.read_text()), found)
        for line in found[:40]:
            print(line)
        if len(found) > 40:
            print(f"... {len(found) - 40} more in {path.name}")
        total += len(found)
    print(f"GATE: {total} differences")
    return total


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("action", choices=["record", "check"])
    ap.add_argument("reference", type=Path, help="the reference records' folder")
    ap.add_argument("out", type=Path, nargs="?", help="check: the new records' folder")
    ap.add_argument("--tree", type=Path, default=Path(__file__).resolve().parent.parent)
    args = ap.parse_args()
    if args.action == "record":
        run(args.tree, args.reference)
        return 0
    if args.out is None:
        ap.error("check needs OUT (the new records' folder)")
    run(args.tree, args.out)
    return 1 if compare(args.reference, args.out) else 0


if __name__ == "__main__":
    sys.exit(main())
