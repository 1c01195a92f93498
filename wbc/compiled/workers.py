"""The processes that compile the package's ticks in background (:mod:`wbc.warmup`, one per
solver) and another kernel set's (:mod:`wbc.compiled.worker`): their command lines and
environment, and the lock file each holds while it compiles, so that processes started
together on a cold cache build each tick once (:class:`BuildElsewhere`); and a lock per
kernel (:func:`share_compilations`), so that they compile each kernel they share once."""

from __future__ import annotations

import os
import sys
from pathlib import Path

try:
    import fcntl
except ImportError:  # (no flock: each process builds its own ticks)
    fcntl = None  # type: ignore[assignment]


#: set in the environment (to anything but "" or "0"): a solver whose compiled tick is being
#: built in the background waits for it instead of solving on the numpy path meanwhile (the
#: tests, and anything that counts or times compiled ticks from a cold cache)
WAIT_ENV = "WBC_WAIT_FOR_COMPILE"


def waits() -> bool:
    """True if :data:`WAIT_ENV` asks solvers to wait for a build."""
    return os.environ.get(WAIT_ENV, "") not in ("", "0")


#: the worker processes that compile the package's ticks, one per solver (in parallel)
PARTS = ("weighted", "hierarchical")
#: the module a worker runs (``python -m``): it loads the package's ``walk`` stack, so it lives
#: above the stacks (:mod:`wbc.warmup`); started by name, never imported from here
WORKER_MODULE = "wbc.warmup"
#: set in a worker's environment: its own ticks compile in process (no workers of its own)
WORKER_ENV = "WBC_COMPILE_WORKER"


#: the module of the worker that builds a tick of another kernel set (:mod:`wbc.compiled.worker`)
SET_WORKER_MODULE = "wbc.compiled.worker"


def take_lock(path: Path, block: bool) -> int | None:
    """A file descriptor of ``path`` holding its exclusive lock (``flock``; waits for it if
    ``block``), or None if another process holds it. Closing the descriptor (in every process
    that inherited it) releases the lock; where ``flock`` is missing, never None."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    if fcntl is None:
        return fd
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | (0 if block else fcntl.LOCK_NB))
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


class BuildElsewhere:
    """A build of a tick by another process's worker (it holds the tick's lock file), seen
    as that worker: ``poll`` is None while it runs, ``wait`` returns once it has ended (0:
    whether it succeeded shows on disk; a tick not cached by then compiles in this process)."""

    def __init__(self, lock: Path) -> None:
        self.lock = lock

    def poll(self) -> int | None:
        fd = take_lock(self.lock, block=False)
        if fd is None:
            return None
        os.close(fd)
        return 0

    def wait(self) -> int:
        os.close(take_lock(self.lock, block=True))  # type: ignore[arg-type]
        return 0


def command(part: str) -> list[str]:
    """The command line of the worker that compiles ``part``."""
    return [sys.executable, "-m", WORKER_MODULE, "--part", part]


def worker_env() -> dict[str, str]:
    """A worker's environment: this one, marked as a worker's."""
    return {**os.environ, WORKER_ENV: "1"}


#: set to "1" (the tests set it): :func:`share_compilations` installs the lock; unset or
#: anything else, it does nothing (the package's workers compile as before: off by default,
#: benchmarks/test_suite.md)
LOCK_ENV = "WBC_COMPILE_LOCK"


def share_compilations() -> bool:
    """numba's compilations of a kernel with a disk cache made one at a time across the
    processes that call this (the package's workers, :mod:`wbc.warmup`; the test workers):
    numba's ``Dispatcher.compile`` wrapped so that a compilation of a kernel that numba
    caches on disk (``cache=True``, and the generated ticks) holds a lock file beside the
    kernel's cache index (``flock``); a second process asking for the same kernel waits,
    then loads the first one's from the disk cache (numba looks there before compiling).
    Nested compilations (a kernel's callees) take their locks in call order, so two
    processes cannot wait for each other; a lock this process holds is not taken again, and
    numba's own compiler lock is taken first, so two threads of a process cannot wait for
    each other either. Call it before the first compilation (kernels with a signature
    compile when their module is imported). Only with :data:`LOCK_ENV` "1" (a process's
    workers inherit it); True if installed (not without ``flock``, nor if installed
    already)."""
    try:
        from numba.core.compiler_lock import global_compiler_lock
        from numba.core.dispatcher import Dispatcher
    except ImportError:  # (no numba: nothing to share)
        return False
    if fcntl is None or os.environ.get(LOCK_ENV, "") != "1":
        return False
    if getattr(Dispatcher.compile, "locked", False):
        return False
    compile_ = Dispatcher.compile
    held: set[str] = set()

    def compile_once(self, sig):
        cache_file = getattr(getattr(self, "_cache", None), "_cache_file", None)
        index = getattr(cache_file, "_index_path", None)
        if not index:
            return compile_(self, sig)
        with global_compiler_lock:  # (numba's, re-entrant: one compilation a process)
            if index in held:
                return compile_(self, sig)
            try:
                fd = os.open(f"{index}.lock", os.O_RDWR | os.O_CREAT, 0o644)
            except OSError:  # (a cache directory that cannot be written: numba caches nothing)
                return compile_(self, sig)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX)
                held.add(index)
                return compile_(self, sig)
            finally:
                held.discard(index)
                os.close(fd)  # (releases the lock)

    compile_once.locked = True  # type: ignore[attr-defined]
    Dispatcher.compile = compile_once  # type: ignore[method-assign]
    return True
