"""numba's compilations of a kernel with a disk cache made one at a time across the test
processes (installed by ``conftest.py`` in every worker, :func:`install`).

On a cold cache the two xdist workers asked for the same kernels at once and each compiled
them (``tests/test_compiled_lsq.py`` cold, ``-n 2``: 107 s of CPU, 62 s with this;
``benchmarks/test_suite.md``). With :func:`install`, a compilation of a kernel that numba caches
on disk (``cache=True``, and the generated ticks) holds a lock file beside the kernel's cache
index: a second process asking for the same kernel waits, then loads the first one's from
the disk cache (numba looks there before compiling). Nested compilations (a kernel's callees)
take their locks in call order, so two processes cannot wait for each other; a lock this
process holds is not taken again, and numba's own compiler lock is taken first, so two
threads of a process cannot wait for each other either. ``WBC_TEST_COMPILE_LOCK=0``: not
installed.
"""

from __future__ import annotations

import os

#: set to "0": :func:`install` does nothing
ENV = "WBC_TEST_COMPILE_LOCK"


def install() -> bool:
    """Wrap numba's ``Dispatcher.compile`` with the lock (module docstring); True if done."""
    try:
        import fcntl

        from numba.core.compiler_lock import global_compiler_lock
        from numba.core.dispatcher import Dispatcher
    except ImportError:  # (no flock, or no numba: nothing to share)
        return False
    if os.environ.get(ENV, "1") == "0" or getattr(Dispatcher.compile, "locked", False):
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
