"""What a run compiles: numba's compile events (``numba:compile``, one per new specialisation
of a dispatcher that was not in its disk cache) recorded in every Python process of a command
(the package's compile workers included), and a summary per kernel: how many specialisations,
the CPU seconds of each (its own, its nested callees' compilations taken out) and their
argument types.

    python tools/compile_trace.py run OUT.jsonl -- wbc bench --json /tmp/b.json   # records
    python tools/compile_trace.py show OUT.jsonl [--top 30] [--signatures]        # summary

``run`` puts a ``sitecustomize`` on ``PYTHONPATH`` that installs the listener in each process
started under it (:data:`ENV` names the file; JSON lines, appended). The CPU time is the
compiling thread's (``time.thread_time``: comparable across a loaded machine's runs); a
kernel's *own* time excludes the compilations it triggered (its callees typed and lowered
first), so the own times add up to the whole.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

#: the file a process appends its compile records to (unset: nothing recorded)
ENV = "WBC_COMPILE_TRACE"

_SITE = """\
import os
if os.environ.get({env!r}):
    import compile_trace
    compile_trace.install(os.environ[{env!r}])
"""


def install(path: str) -> None:
    """Record every ``numba:compile`` event of this process into ``path`` (JSON lines)."""
    from numba.core import event

    stack: list[list[float]] = []  # per open compilation: [cpu start, children's cpu]

    class _Recorder(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            stack.append([time.thread_time(), 0.0, time.time()])

        def on_end(self, ev: event.Event) -> None:
            start, children, wall = stack.pop()
            cpu = time.thread_time() - start
            if stack:
                stack[-1][1] += cpu
            d = ev.data["dispatcher"]
            f = d.py_func
            record = {
                "pid": os.getpid(),
                "kernel": f"{f.__module__}.{f.__qualname__}",
                "args": [str(a) for a in ev.data["args"]],
                "cpu": cpu,
                "own": cpu - children,
                "depth": len(stack),
                "start": wall,
            }
            with open(path, "a") as out:
                out.write(json.dumps(record) + "\n")

    event.register("numba:compile", _Recorder())


def run(out: str, command: list[str]) -> int:
    """Run ``command`` with the recorder installed in each of its Python processes."""
    site = tempfile.mkdtemp(prefix="compile_trace_")
    Path(site, "sitecustomize.py").write_text(_SITE.format(env=ENV))
    tools = str(Path(__file__).resolve().parent)
    path = os.pathsep.join(p for p in (site, tools, os.environ.get("PYTHONPATH", "")) if p)
    Path(out).unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": path, ENV: str(Path(out).resolve())}
    return subprocess.call(command, env=env)


def show(path: str, top: int, signatures: bool) -> None:
    """A markdown table per kernel: specialisations, own CPU s, and (``signatures``) their
    argument types where there are several."""
    records = [json.loads(line) for line in Path(path).read_text().splitlines() if line]
    by = defaultdict(list)
    for r in records:
        by[r["kernel"]].append(r)
    pids = sorted({r["pid"] for r in records})
    total = sum(r["own"] for r in records)
    print(f"{len(records)} compilations of {len(by)} kernels in {len(pids)} processes, "
          f"{total:.1f} CPU s")  # fmt: skip
    print("\n| kernel | compilations | processes | own CPU s |\n|---|---|---|---|")
    rows = sorted(by.items(), key=lambda kv: -sum(r["own"] for r in kv[1]))
    for kernel, rs in rows[:top]:
        n_pid = len({r["pid"] for r in rs})
        print(f"| `{kernel}` | {len(rs)} | {n_pid} | {sum(r['own'] for r in rs):.2f} |")
    repeated = sorted(
        ((k, rs) for k, rs in by.items() if len(rs) > len({r["pid"] for r in rs})),
        key=lambda kv: -len(kv[1]),
    )
    print(f"\n{len(repeated)} kernels compiled more than once in a process:")
    for kernel, rs in repeated:
        print(f"- `{kernel}`: {len(rs)} ({sum(r['own'] for r in rs):.2f} s)")
        if signatures:
            for r in rs:
                print(f"    pid {r['pid']}: ({', '.join(r['args'])})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    r = sub.add_parser("run", help="run a command with the recorder")
    r.add_argument("out")
    r.add_argument("command", nargs=argparse.REMAINDER)
    s = sub.add_parser("show", help="summarise a record file")
    s.add_argument("path")
    s.add_argument("--top", type=int, default=30)
    s.add_argument("--signatures", action="store_true")
    args = parser.parse_args(argv)
    if args.what == "run":
        command = args.command[1:] if args.command[:1] == ["--"] else args.command
        return run(args.out, command)
    show(args.path, args.top, args.signatures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
