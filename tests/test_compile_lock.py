"""The compile lock (:func:`wbc.compiled.workers.share_compilations`, in the test workers and
the package's compile workers): a process asking for a kernel that another process is
compiling waits for it, then loads it from the disk cache instead of compiling it too (on a
cold cache the two xdist workers each compiled the same kernels, and the two compile
workers the level solver's)."""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

KERNEL = """
from numba import njit


@njit(cache=True)
def twice(x):
    return 2.0 * x
"""

#: a process that imports the kernel (the lock installed unless told otherwise) and calls it:
#: its index file's path, or the call's answer, numba's cache hits and misses
CHILD = """
import sys
sys.path[:0] = [{folder!r}]
from wbc.compiled.workers import share_compilations
share_compilations()
import user_kernel
if sys.argv[1] == "index":
    print(user_kernel.twice._cache._cache_file._index_path)
else:
    print(user_kernel.twice(2.0), sum(user_kernel.twice._cache_hits.values()),
          sum(user_kernel.twice._cache_misses.values()))
"""


def _waiting(pid: int) -> bool:
    """True if process ``pid`` waits for a flock (a ``->`` line of /proc/locks)."""
    lines = Path("/proc/locks").read_text().splitlines()
    return any("-> FLOCK" in line and line.split()[-4] == str(pid) for line in lines)


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="reads /proc/locks (Linux)")
def test_a_process_waits_for_anothers_compilation_then_loads_it(tmp_path):
    (tmp_path / "user_kernel.py").write_text(KERNEL)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "WBC_COMPILE_LOCK": "1"}
    code = CHILD.format(folder=str(tmp_path))

    def child(what: str) -> list[str]:
        return [sys.executable, "-c", code, what]

    index = subprocess.run(child("index"), env=env, capture_output=True, text=True, check=True)
    lock_path = Path(index.stdout.strip() + ".lock")
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # (as a process compiling the kernel holds it)
        waiter = subprocess.Popen(child("call"), env=env, stdout=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 300.0
        while not _waiting(waiter.pid):
            assert waiter.poll() is None, "compiled without waiting for the lock"
            assert time.monotonic() < deadline, "never waited for the lock"
            time.sleep(0.05)
        # the kernel compiled and cached meanwhile by a process without the lock
        subprocess.run(child("call"), env={**env, "WBC_COMPILE_LOCK": "0"}, check=True,
                       capture_output=True)  # fmt: skip
    finally:
        os.close(fd)
    out, _ = waiter.communicate(timeout=300)
    assert waiter.returncode == 0
    value, hits, misses = out.split()
    assert (float(value), int(hits), int(misses)) == (4.0, 1, 0)  # loaded, not compiled


#: the package's compile worker (``python -m wbc.warmup``) with its compilation replaced:
#: whether numba's compile is wrapped by the time it would compile
WORKER = """
import sys
from numba.core.dispatcher import Dispatcher
import wbc.warmup as warmup
warmup.compile_part = lambda part: print(getattr(Dispatcher.compile, "locked", False), part)
warmup.main(["--part", "hierarchical"])
"""


@pytest.mark.parametrize("on", ["1", "0", None])
def test_the_package_compile_workers_take_the_lock_when_asked(on):
    """A compile worker (:mod:`wbc.warmup`) compiles with the lock with ``WBC_COMPILE_LOCK``
    "1" (as the tests set it: the two workers, started together on a cold cache, share the
    level solver's kernels, and the test workers theirs), else without it (the default)."""
    env = {k: v for k, v in os.environ.items() if k != "WBC_COMPILE_LOCK"}
    if on is not None:
        env["WBC_COMPILE_LOCK"] = on
    run = subprocess.run([sys.executable, "-c", WORKER], env=env, capture_output=True,
                         text=True, check=True)  # fmt: skip
    assert run.stdout.split() == [str(on == "1"), "hierarchical"]
