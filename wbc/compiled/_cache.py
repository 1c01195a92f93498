"""Keep numba's on-disk cache honest across modules.

numba keys a cached function on its own source file only: a kernel that calls functions of
another module (a tick calling the row and QP kernels, the rows reading the layout constants)
would keep running the *old* code of those after they change (an upgrade, an edit in a
development checkout). :func:`refresh` stamps each kernel's cache with a digest of the files
it depends on and flushes the cache when they changed.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
from collections.abc import Iterator, Sequence
from pathlib import Path


def digest(files: Sequence[str | os.PathLike]) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(Path(f).read_bytes())
    return h.hexdigest()


def refresh(dispatchers: Sequence[object], depends_on: Sequence[str | os.PathLike]) -> None:
    """Flush the on-disk cache of every dispatcher whose dependencies changed since it was
    cached (best effort: a cache directory that cannot be written is left alone)."""
    stamp_value = digest(depends_on)
    for d in dispatchers:
        cache = getattr(d, "_cache", None)
        path = getattr(cache, "cache_path", None)
        if not path:
            continue
        name = f"{d.py_func.__module__}.{d.py_func.__qualname__}.deps"
        stamp = Path(path) / name
        try:
            if stamp.exists() and stamp.read_text() == stamp_value:
                continue
            cache.flush()
            os.makedirs(path, exist_ok=True)
            stamp.write_text(stamp_value)
        except OSError:
            continue


class _Depth:
    """numba's compile events, counted per thread (how deep in nested compiles we are)."""

    def __init__(self) -> None:
        import threading

        from numba.core import event

        self.local = threading.local()

        class Listener(event.Listener):
            def on_start(_, e) -> None:
                self.local.n = self.now() + 1

            def on_end(_, e) -> None:
                self.local.n = self.now() - 1

        self.listener = Listener()

    def now(self) -> int:
        return getattr(self.local, "n", 0)


@contextlib.contextmanager
def lean_linking() -> Iterator[bool]:
    """Compile entry points without optimising their callees twice (yields False, changing
    nothing, where this numba lacks the hooks).

    numba compiles a function called from compiled code as a library of its own: LLVM
    optimises it with everything it calls, then the caller links that in and LLVM optimises
    the whole again — at every level of the call tree (tick → solve → level solver → active
    set → subproblem), ~45% of a cold compile. Inside this context a function compiled only
    to be linked into its caller skips that optimisation, and is not written to the disk
    cache (its unoptimised code would be reused there); the function compiled for a call
    from Python — the entry point, what the disk cache keeps — is optimised in full with
    its callees linked in, as always. Meant for a process that only fills the cache
    (``python -m wbc.compiled``): in it, a function first compiled as a callee runs
    unoptimised when Python calls it later.
    """
    try:
        from numba.core import caching, codegen, event

        optimize = codegen.CPUCodeLibrary._optimize_final_module
        save = caching.Cache.save_overload
    except (ImportError, AttributeError):  # another numba: compile as usual
        yield False
        return
    depth = _Depth()

    def lean_optimize(library) -> None:
        if depth.now() <= 1:  # the entry point being compiled (depth 1), or a lazy finalize
            optimize(library)

    def lean_save(cache, sig, data) -> None:
        if depth.now() == 0:  # saved after its own compile event: 0 for an entry point
            save(cache, sig, data)

    event.register("numba:compile", depth.listener)
    codegen.CPUCodeLibrary._optimize_final_module = lean_optimize
    caching.Cache.save_overload = lean_save
    try:
        yield True
    finally:
        codegen.CPUCodeLibrary._optimize_final_module = optimize
        caching.Cache.save_overload = save
        event.unregister("numba:compile", depth.listener)
