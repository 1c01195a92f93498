"""The compiled tick of a set of kernels, generated.

A plan's tasks and box limits bring their own kernels (:attr:`wbc.tasks.Task.row_kernel`,
:attr:`wbc.limits.BoxLimit.bound_kernel`; every one takes the inputs of
:mod:`wbc.compiled.signature`), wherever their classes are defined; the solvers' plans
(:mod:`wbc.solvers.plan`) pass them in: this module knows no task. For each set of kernels
it writes a small Python module (one ``if kind == i`` branch per kernel around the shared row
bookkeeping, the box limits' bounds folded into one box, then the weighted or the cascade
solve of :mod:`wbc.compiled.ticks`; the tick itself takes q, its plan's buffers by address
and the views of Pinocchio's data, gathers the targets and calls that body), imports it and
returns its functions.
The file is written once into the cache directory (``$WBC_CACHE_DIR``, else
``$XDG_CACHE_HOME/wbc``, else ``~/.cache/wbc``) under a name that digests the kernels' source
files and the compiled modules they call, so numba's on-disk cache of the generated functions
never serves stale code; a kernel whose source cannot be read (defined in an interactive
session) is compiled without the disk cache.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import inspect
import json
import logging
import os
import pickle
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from ._cache import refresh
from .entry import entry_point
from .template import (  # noqa: F401 (the tick's columns and arguments: defined there)
    BOUND_COLUMNS,
    C_KIND,
    C_PARAM,
    C_PARAM_SIZE,
    C_ROW,
    C_ROWS,
    C_SLOT,
    C_SLOTS,
    CASCADE_ARGS,
    CONSTRAINT_COLUMNS,
    DIRECT,
    KIND,
    NO_ROOM,
    PLACED_ARGS,
    ROW,
    ROWS,
    SEL,
    SLOT,
    SLOTS,
    SPEC_COLUMNS,
    TARGET,
    TARGET_SIZE,
    TICK_ARGS,
    WEIGHTED_ARGS,
    source,
)
from .workers import (
    PARTS,
    SET_WORKER_MODULE,
    WORKER_ENV,
    BuildElsewhere,
    command,
    take_lock,
    waits,
    worker_env,
)

log = logging.getLogger(__name__)

_HERE = Path(__file__).parent


def _on_disk(dispatcher) -> bool:
    """True if numba holds a cached compilation of ``dispatcher``: its index file lists one,
    for the current source (an index that :func:`wbc.compiled._cache.refresh` flushed is
    empty: a kernel of ``ticks.py`` on a cold cache had one from the import on, and the first
    ``HierarchicalQP(..., "osqp")`` tick compiled it in the process, issue 28)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    index = getattr(cache_file, "_index_path", None)
    if not index or not os.path.exists(index):
        return False
    load = getattr(cache_file, "_load_index", None)
    if load is None:  # another numba: the file's existence
        return True
    try:
        return bool(load())
    except Exception:  # (an unreadable index: numba recompiles, so not cached)
        return False


def cache_dir() -> Path:
    """Where generated modules (and numba's cache of them) live."""
    env = os.environ.get("WBC_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "wbc"


def _source_file(kernel) -> Path | None:
    try:
        path = inspect.getsourcefile(kernel.py_func)
    except (TypeError, OSError):
        return None
    return Path(path) if path and Path(path).is_file() else None


class Ticks:
    """The generated tick functions of one set of kernels, called through their entry points
    (skipping numba's per-call type dispatch).

    For the package's own kernels (the tick of every package stack), a tick not yet in the
    disk cache is compiled by worker processes (:data:`~wbc.compiled.workers.WORKER_MODULE`),
    both solvers' in parallel (:meth:`start_build`), and loaded from the cache when its worker
    is done (:meth:`ready`: meanwhile the solvers solve on the numpy path, the same problem by
    the backend). Another set (a task or limit type defined elsewhere) is split in two calls
    (:attr:`split`): its rows compile in one worker
    (:data:`~wbc.compiled.workers.SET_WORKER_MODULE`, the tick a solver asks for), the solve is
    the package's. A set whose kernels a worker cannot import (defined in ``__main__`` or
    interactively), or a failed worker, compiles in this process."""

    def __init__(
        self,
        module,
        package: bool = False,
        kernels: Sequence = (),
        bounds: Sequence = (),
        cache: bool = False,
        constraints: Sequence = (),
        placer: object = None,
    ) -> None:
        self.module = module
        #: the kernel the fused ticks call first (a constraint's rows made in the tick: the
        #: package's set; None: a split set, whose ``*_rows`` do not call it)
        self.placer = placer
        #: True for a set other than the package's: its ticks are split in two calls, the
        #: rows (``weighted_rows``, ``cascade_rows``: generated, small, so that a new set
        #: compiles in seconds, only what is new, each kernel cached on its own) and the
        #: package's solve (:func:`wbc.compiled.ticks.weighted_solve`, ``cascade_solve``:
        #: compiled once, cached); the package's set is one fused call (~1 µs less a tick)
        self.split = not package
        #: the row and bound kernels of the set (a worker imports them again)
        self.kernels, self.bounds = tuple(kernels), tuple(bounds)
        self.constraints = tuple(constraints)
        #: True if numba caches the ticks on disk (every kernel's source file is known):
        #: then a worker can build them
        self.weighted_tick = module.weighted_rows if not package else module.weighted_tick
        self.cascade_tick = module.cascade_rows if not package else module.cascade_tick
        self._entries: dict[tuple[str, int], object] = {}
        self.package = package
        self.cache = cache
        #: the worker compiling each tick (by tick name), while it runs or until waited for
        self.builders: dict[str, subprocess.Popen] = {}
        self.build_started = 0.0
        #: the ticks known to run without compiling in this process or waiting (see ready)
        self._ready: set[str] = set()

    def cached(self) -> bool:
        """True if both ticks are in numba's disk cache."""
        return _on_disk(self.weighted_tick) and _on_disk(self.cascade_tick)

    def start_build(
        self, announce: bool = True, name: str = "", args: tuple = (), solve: tuple = ()
    ) -> bool:
        """Start compiling ticks in worker processes, unless they are cached or being built;
        True if started. The package's set: both ticks (``python -m wbc.warmup --part ...``,
        which compile the numpy path's kernels too), each unless another process's worker
        builds it already (its lock file held): that build is waited for as this one's
        (:class:`BuildElsewhere`), so that processes started together on a cold cache compile
        each tick once; another set (a task or limit type
        defined elsewhere) whose kernels' source files are known: the tick ``name`` for the
        types of ``args`` (``python -m wbc.compiled.worker``: the kernels are cached each on
        its own, the worker links them into this set's tick; ``solve``, ``(kernel, args)``:
        the package's solve that the split tick calls next, compiled first if it is not cached
        yet, so that the tick on disk means both are ready). A caller can do other work
        meanwhile (``wbc bench`` runs the baselines); ``announce``: log a line saying so."""
        if self.builders.get(name) or os.environ.get(WORKER_ENV):
            return False
        if not self.package:
            if not (self.buildable() and name and args) or _on_disk(getattr(self, name)):
                return False
            return self._start_set_worker(name, args, announce, solve)
        if self.builders or self.cached():
            return False
        elsewhere = []
        for part, tick in zip(PARTS, ("weighted_tick", "cascade_tick"), strict=True):
            lock = take_lock(self._lock(tick), block=False)
            if lock is None:  # another process's worker builds it: wait for that one
                self.builders[tick] = BuildElsewhere(self._lock(tick))
                elsewhere.append(tick)
                continue
            try:
                with open(self._log(tick), "w") as log_file:  # the worker's messages
                    self.builders[tick] = subprocess.Popen(
                        command(part),
                        env=worker_env(),
                        stdout=log_file,
                        stderr=subprocess.STDOUT,
                        pass_fds=(lock,),  # the worker holds the lock until it exits
                    )
            finally:
                os.close(lock)
        if not self.builders:
            return False
        self.build_started = time.perf_counter()
        if announce:
            log.warning(
                "wbc: compiling the control ticks in %d background processes (numba; once per "
                "installation, about a minute; cached in %s%s); until they are ready the "
                "solvers solve on the numpy path (the same QP by the backend, slower ticks)",
                len(self.builders),
                Path(self.module.__file__).parent,
                f"; {' and '.join(elsewhere)} by another process" if elsewhere else "",
            )
        return True

    def _start_set_worker(self, name: str, args: tuple, announce: bool, solve: tuple = ()) -> bool:
        """Start the worker of tick ``name`` of this (non-package) kernel set (and of the
        package's ``solve``, ``(kernel, args)``, unless it is cached)."""
        from numba import typeof

        def entry(kernel) -> dict:
            return {
                "module": kernel.py_func.__module__,
                "file": str(_source_file(kernel)),
                "qualname": kernel.py_func.__qualname__,
            }

        signature = tuple(typeof(a) for a in args)
        job = {
            "name": self.module.__name__,
            "path": self.module.__file__,
            "kernels": [entry(k) for k in self.kernels],
            "bounds": [entry(k) for k in self.bounds],
            "constraints": [entry(k) for k in self.constraints],
            "tick": getattr(self, name).py_func.__name__,
            "signature": pickle.dumps(signature).hex(),
        }
        if solve and not _on_disk(solve[0]):
            kernel, solve_args = solve
            job["solve"] = entry(kernel)
            job["solve_signature"] = pickle.dumps(tuple(typeof(a) for a in solve_args)).hex()
        job_file = Path(self.module.__file__).with_suffix(f".{name}.job.json")
        try:
            job_file.write_text(json.dumps(job))
        except OSError:
            return False
        if announce:
            log.warning(
                "wbc: compiling the control tick of a new set of task types (%s) in a "
                "background process (numba; once; cached in %s); until it is ready the "
                "solver solves on the numpy path",
                ", ".join(k.py_func.__qualname__ for k in self.kernels[-3:]),
                job_file.parent,
            )
        self.build_started = time.perf_counter()
        with open(self._log(name), "w") as log_file:
            self.builders[name] = subprocess.Popen(
                [sys.executable, "-m", SET_WORKER_MODULE, str(job_file)],
                env=worker_env(),
                stdout=log_file,
                stderr=subprocess.STDOUT,
            )
        return True

    def _log(self, name: str) -> Path:
        return Path(self.module.__file__).with_suffix(f".{name}.log")

    def _lock(self, name: str) -> Path:
        """The lock file of tick ``name``'s build: held by its worker while it compiles, so
        that another process on the same installation waits for that build instead of
        starting its own (:class:`BuildElsewhere`)."""
        return Path(self.module.__file__).with_suffix(f".{name}.lock")

    def wait(self, name: str) -> None:
        """Wait for the worker building tick ``name`` (if any); a failure is logged, and the
        tick then compiles in this process."""
        worker = self.builders.pop(name, None)
        if worker is None:
            return
        if worker.poll() is None:
            log.warning(
                "wbc: waiting for the background compilation of %s (%.0f s so far)",
                name,
                time.perf_counter() - self.build_started,
            )
        if worker.wait() != 0:
            try:
                tail = self._log(name).read_text().strip().splitlines()[-1:]
            except OSError:
                tail = []
            log.warning(
                "wbc: compiling %s in a worker failed (%s; log: %s)",
                name,
                tail[0] if tail else "no message",
                self._log(name),
            )

    def buildable(self) -> bool:
        """True if workers can build this set's ticks: the package's, or a set whose kernels
        numba caches on disk and a worker can import (not defined in ``__main__``)."""
        return self.package or (
            self.cache
            and all(
                k.py_func.__module__ != "__main__"
                for k in (*self.kernels, *self.bounds, *self.constraints)
            )
        )

    def ready(self, name: str, args: tuple = (), solve: tuple = ()) -> bool:
        """True if tick ``name`` runs at once at its next :meth:`call` (compiled in this
        process or cached on disk, its worker done), or must compile here anyway (no worker
        can build it, inside a worker, ``$WBC_WAIT_FOR_COMPILE`` set: :meth:`call` then waits
        or compiles). False while a worker builds it (started here if the cache is empty; a
        set other than the package's: for the types of ``args``, the tick's arguments, with
        the package's ``solve`` that follows it, ``(kernel, args)``): the caller solves this
        tick another way. Says once when it becomes ready."""
        if name in self._ready:
            return True
        dispatcher = getattr(self, name)
        building = name in self.builders
        if (
            not self.buildable()
            or (not self.package and not args)
            or os.environ.get(WORKER_ENV)
            or waits()
            or dispatcher.overloads
            or (not building and _on_disk(dispatcher))
        ):
            self._ready.add(name)
            return True
        if not building:
            self.start_build(name=name, args=args, solve=solve)
        worker = self.builders.get(name)
        if worker is not None and worker.poll() is None and not _on_disk(dispatcher):
            return False  # (its worker may go on with other kernels once the tick is cached)
        if not _on_disk(dispatcher):
            self.wait(name)  # (a failure is logged: the tick then compiles at the call)
        else:
            log.warning(
                "wbc: the compiled %s is ready (%.0f s after the build started); the solvers "
                "switch to it",
                name.replace("_", " "),
                time.perf_counter() - self.build_started,
            )
        self._ready.add(name)
        return True

    def kernel_ready(self, dispatcher, tick: str) -> bool:
        """True if ``dispatcher`` (a kernel that the numpy path calls from Python, e.g. the
        level cascade :func:`wbc.compiled.ticks.cascade_solve`) runs at its next call without
        compiling here: compiled in this process, or cached on disk and the worker of
        ``tick``'s part done (it compiles the numpy path's kernels after its tick); also True
        where the call must compile anyway (inside a worker, ``$WBC_WAIT_FOR_COMPILE`` set, no
        worker could start). False while the worker builds it (started here if it is not
        cached): the caller solves another way meanwhile (the backend cascade), on every
        backend — the first ``HierarchicalQP(..., "osqp")`` tick of a cold cache compiled the
        cascade in the process for two minutes (issue 28)."""
        if dispatcher.overloads or os.environ.get(WORKER_ENV) or waits():
            return True
        worker = self.builders.get(tick)
        if worker is None:
            if _on_disk(dispatcher) or not self.start_build():
                return True
            worker = self.builders[tick]
        if worker.poll() is None:
            return False
        self.wait(tick)  # (done; a failure is logged, and the kernel compiles at the call)
        return True

    def wait_all(self) -> None:
        """Wait for every worker (so that nothing compiles beside what comes next)."""
        for name in list(self.builders):
            self.wait(name)

    def entry(self, name: str, variant: int):
        """The entry point of tick ``name`` that :meth:`call` found (after a first call)."""
        return self._entries[(name, variant)]

    def call(self, name: str, variant: int, args: tuple) -> int:
        """Call tick ``name`` with ``args``; ``variant`` tells apart the argument types a
        tick gets (the number of frame slots)."""
        entry = self._entries.get((name, variant))
        if entry is not None:
            return entry(*args)
        dispatcher = getattr(self, name)
        if not dispatcher.overloads and not _on_disk(dispatcher):
            self.start_build()
        if not _on_disk(dispatcher):  # (else cached: its worker may go on with other kernels)
            self.wait(name)
        if not dispatcher.overloads and not _on_disk(dispatcher):
            log.warning(
                "wbc: compiling the control tick (numba; once per installation and set of "
                "task types, up to a minute; cached in %s)",
                Path(self.module.__file__).parent,
            )
        result = dispatcher(*args)
        self._entries[(name, variant)] = entry_point(dispatcher, args)
        return result


def ticks(
    kernels: tuple,
    bounds: tuple = (),
    velocities: bool = False,
    package: bool = False,
    constraints: tuple = (),
    placer: tuple = (),
) -> Ticks:
    """The compiled tick of these row kernels, bound kernels and constraint kernels
    (generated, imported and kept
    for the process); ``velocities``: it computes the frames' velocities; ``package``: the
    package's own set (the tick of every package stack: :meth:`Ticks.start_build` compiles it
    in worker processes); ``placer``: (kernel, source files it calls...) — the kernel the
    fused ticks call first (:data:`PLACED_ARGS`; the package's set has it). The caller
    (:mod:`wbc.solvers.plan`) knows the tasks and limits."""
    # (one object per set however the call spells it: its workers are in its builders)
    return _ticks(tuple(kernels), tuple(bounds), velocities, package, tuple(constraints), placer)


@functools.lru_cache(maxsize=32)
def _ticks(
    kernels: tuple,
    bounds: tuple,
    velocities: bool,
    package: bool,
    constraints: tuple,
    placer: tuple,
) -> Ticks:
    """:func:`ticks`, kept for the process."""
    files = [_source_file(k) for k in (*kernels, *bounds, *constraints, *placer[:1])]
    files += [Path(f) for f in placer[1:]]
    cache = all(f is not None for f in files)
    text = source(kernels, cache, bounds, velocities, constraints)
    h = hashlib.sha256(text.encode())
    lsq = [
        _HERE / f
        for f in (
            "lsq.py lsq_subproblem.py lsq_update.py lsq_linalg.py lsq_multipliers.py proximal.py "
            "space.py"
        ).split()
    ]
    own = [_HERE / f for f in ("rows.py", "ticks.py", "boxes.py", "checks.py")]
    for f in [*files, *own, *lsq]:
        if f is not None:
            h.update(f.read_bytes())
    name = f"wbc_tick_{h.hexdigest()[:20]}"
    if name in sys.modules:
        module = sys.modules[name]
    else:
        module = load_generated(name, _write(name, text), kernels, bounds, constraints)
        if placer:
            module.placer = placer[0]
    return Ticks(
        module, package, kernels, bounds, cache, constraints, placer[0] if placer else None
    )


def load_generated(
    name: str, path: Path, kernels: Sequence, bounds: Sequence, constraints: Sequence = ()
):
    """Import the generated module ``name`` from ``path`` with its kernels bound (``k0``...,
    ``b0``...), registered in ``sys.modules`` (numba's cache finds a function's module by
    name)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    for i, k in enumerate(kernels):
        setattr(module, f"k{i}", k)
    for i, k in enumerate(bounds):
        setattr(module, f"b{i}", k)
    for i, k in enumerate(constraints):
        setattr(module, f"c{i}", k)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def refresh_kernel(kernel) -> None:
    """numba caches a kernel on its own file only: flush it when the helpers it calls
    (:mod:`wbc.compiled.rows`) changed (a task's or a limit's class calls this when it is
    defined)."""
    refresh([kernel], [_HERE / "rows.py"])


def _write(name: str, text: str) -> Path:
    """The module file (written once; never rewritten, so numba's cache index stays valid)."""
    for directory in (cache_dir(), Path(tempfile.gettempdir()) / "wbc-cache"):
        path = directory / f"{name}.py"
        try:
            if path.is_file() and path.read_text() == text:
                return path
            directory.mkdir(parents=True, exist_ok=True)
            tmp = directory / f"{name}.{os.getpid()}.tmp"
            tmp.write_text(text)
            os.replace(tmp, path)
            return path
        except OSError:
            continue
    raise OSError(f"cannot write the compiled tick module {name}.py to {cache_dir()}")
