"""Where the test suite's wall time goes: a pytest plugin that records, per test (set-up, call
and teardown), its worker, start, wall time and CPU time (the worker's own, and its reaped
children's: the package's compile workers a solver starts, the subprocesses a test runs), and
a summary of such records. A test whose wall time is far above its CPU time waited (for a
compile worker, a subprocess, or another process's compilation of a kernel it needs).

    PYTHONPATH=tools WBC_TEST_TIMELINE=/tmp/t.jsonl python -m pytest -p suite_timeline ...
    python tools/suite_timeline.py /tmp/t.jsonl [--top 20]
    python tools/suite_timeline.py --signatures CLONE CACHE   # kernels compiled more than once

``--signatures``: after a cold run, numba's cache indexes (``*.nbi``: ``__pycache__`` beside
the sources, the generated ticks' in the cache folder) list every signature a kernel was
compiled for; a kernel listed under several was compiled (with its callees) once each.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import resource
import time
from collections import defaultdict
from pathlib import Path

#: the file the plugin appends its records to (JSON lines; unset: nothing recorded)
ENV = "WBC_TEST_TIMELINE"


def _cpu() -> tuple[float, float]:
    """CPU seconds (user + system) of this process and of its reaped children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, kids.ru_utime + kids.ru_stime


try:
    import pytest

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):  # type: ignore[no-untyped-def]
        """One record per test (module docstring)."""
        path = os.environ.get(ENV)
        if not path:
            yield
            return
        start, (own, kids) = time.time(), _cpu()
        yield
        wall, (own2, kids2) = time.time() - start, _cpu()
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        record = {"worker": worker, "test": item.nodeid, "start": start, "wall": wall,
                  "cpu": own2 - own, "children": kids2 - kids}  # fmt: skip
        with open(path, "a") as f:
            f.write(json.dumps(record) + "\n")

except ImportError:  # (the summary needs no pytest)
    pass


def summary(records: list[dict], top: int = 20) -> list[str]:
    """Per worker its span, busy wall and CPU; the ``top`` tests that waited longest (wall −
    own CPU − children's CPU) with their start (s after the first test's)."""
    if not records:
        return ["no records"]
    t0 = min(r["start"] for r in records)
    end = max(r["start"] + r["wall"] for r in records)
    out = [f"{len(records)} tests, {end - t0:.1f} s from the first start to the last end"]
    per: dict[str, list[dict]] = defaultdict(list)
    for r in records:
        per[r["worker"]].append(r)
    for w, rs in sorted(per.items()):
        wall = sum(r["wall"] for r in rs)
        cpu = sum(r["cpu"] for r in rs)
        kids = sum(r["children"] for r in rs)
        waited = sum(max(r["wall"] - r["cpu"] - r["children"], 0.0) for r in rs)
        out.append(f"  {w}: {len(rs)} tests, wall {wall:.1f} s, CPU {cpu:.1f} s own + "
                   f"{kids:.1f} s children, waited {waited:.1f} s")  # fmt: skip
    out.append(f"the {top} longest waits (s: wait = wall − CPU − children's CPU; start):")
    for r in sorted(records, key=lambda r: r["cpu"] + r["children"] - r["wall"])[:top]:
        wait = r["wall"] - r["cpu"] - r["children"]
        out.append(f"  {wait:7.1f} wall {r['wall']:7.1f} cpu {r['cpu']:6.1f}+{r['children']:6.1f}"
                   f" at {r['start'] - t0:7.1f} {r['worker']} {r['test']}")  # fmt: skip
    return out


def signatures(folders: list[str]) -> list[tuple[str, list[str]]]:
    """(index file, its signatures) of every numba cache index below ``folders``, the most
    signatures first."""
    out = []
    for folder in folders:
        for path in Path(folder).rglob("*.nbi"):
            with open(path, "rb") as f:
                pickle.load(f)  # (numba's version)
                _, overloads = pickle.loads(f.read())
            out.append((str(path), [str(key[0]) for key in overloads]))
    return sorted(out, key=lambda r: (-len(r[1]), r[0]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", help="timeline files (folders with --signatures)")
    p.add_argument("--top", type=int, default=20)
    p.add_argument("--signatures", action="store_true", help="kernels cached more than once")
    args = p.parse_args(argv)
    if args.signatures:
        rows = signatures(args.files)
        print(f"{len(rows)} kernels, {sum(len(s) for _, s in rows)} compilations")
        for path, sigs in rows[: args.top]:
            if len(sigs) > 1:
                print(f"  {len(sigs)} {path}\n" + "\n".join(f"      {s[:200]}" for s in sigs))
        return 0
    records = [json.loads(line) for f in args.files for line in open(f) if line.strip()]
    print("\n".join(summary(records, args.top)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
