"""Building the compiled ticks in worker processes (wbc.compiled.dispatch, wbc.warmup for the
package's, wbc.compiled.worker for another set of kernels)."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("numba")

from wbc.compiled import dispatch, workers


class FakeWorker:
    """A worker process that has finished with ``code``."""

    def __init__(self, cmd, env, stdout, stderr, code):
        self.cmd, self.env, self.code = cmd, env, code
        stdout.write("compiling...\nTypingError: no kernel\n" if code else "")

    def poll(self):
        return self.code

    def wait(self):
        return self.code


def _ticks(tmp_path, package=True):
    """Ticks over a stand-in module whose dispatchers have no disk cache."""
    tick = SimpleNamespace(overloads={}, _cache=None)
    module = SimpleNamespace(
        __file__=str(tmp_path / "wbc_tick_x.py"), weighted_tick=tick, cascade_tick=tick,
        weighted_rows=tick, cascade_rows=tick,
    )  # fmt: skip
    return dispatch.Ticks(module, package)


def test_start_build_runs_one_worker_per_solver_and_wait_reports_failures(
    tmp_path, monkeypatch, caplog
):
    started = []

    def popen(cmd, env, stdout, stderr, pass_fds=()):
        started.append(FakeWorker(cmd, env, stdout, stderr, code=1 if "hierarchical" in cmd else 0))
        return started[-1]

    monkeypatch.delenv(workers.WORKER_ENV, raising=False)
    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    ticks = _ticks(tmp_path)
    assert ticks.start_build(announce=False)
    assert [w.cmd[-1] for w in started] == list(workers.PARTS)
    assert all(w.cmd[:3] == [sys.executable, "-m", "wbc.warmup"] for w in started)
    assert all(w.env[workers.WORKER_ENV] == "1" for w in started)  # no workers of their own
    assert not ticks.start_build()  # already building
    with caplog.at_level(logging.WARNING, logger="wbc.compiled.dispatch"):
        ticks.wait("weighted_tick")
        assert not caplog.records  # finished, and well
        ticks.wait("cascade_tick")
    (failure,) = caplog.records
    assert "cascade_tick" in failure.message and "TypingError: no kernel" in failure.message
    assert ticks.builders == {}
    ticks.wait("cascade_tick")  # nothing left to wait for


@pytest.mark.skipif(workers.fcntl is None, reason="no flock on this platform")
def test_a_second_process_waits_for_the_first_ones_build(tmp_path, monkeypatch):
    """Two processes on one cold installation (here two Ticks over one module: the same lock
    files) compile each tick once: the second sees the first's workers hold the locks, starts
    none and waits for them (poll None while they run, then done)."""
    holders, real_popen = [], subprocess.Popen

    def popen(cmd, env, stdout, stderr, pass_fds=()):  # a worker that holds what it inherits
        holders.append(
            real_popen(
                [sys.executable, "-c", "import sys; sys.stdin.read()"],
                stdin=subprocess.PIPE,
                pass_fds=pass_fds,
            )
        )
        return holders[-1]

    monkeypatch.delenv(workers.WORKER_ENV, raising=False)
    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    first = _ticks(tmp_path)
    assert first.start_build(announce=False) and len(holders) == 2
    try:
        monkeypatch.setattr(dispatch.subprocess, "Popen", lambda *a, **k: pytest.fail("built"))
        second = _ticks(tmp_path)
        assert second.start_build(announce=False)  # waiting for the first's build
        assert all(isinstance(w, workers.BuildElsewhere) for w in second.builders.values())
        assert [w.poll() for w in second.builders.values()] == [None, None]
    finally:
        for holder in holders:
            holder.communicate(b"")  # the first's workers end: their locks are free
    assert [w.poll() for w in second.builders.values()] == [0, 0]
    second.wait_all()
    assert second.builders == {}
    third = _ticks(tmp_path)  # nobody building: this one builds
    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    assert third.start_build(announce=False) and len(holders) == 4
    for holder in holders[2:]:
        holder.communicate(b"")


def test_no_workers_for_other_kernel_sets_or_inside_a_worker(tmp_path, monkeypatch):
    def popen(*args, **kwargs):
        raise AssertionError("no worker expected")

    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    monkeypatch.delenv(workers.WORKER_ENV, raising=False)
    assert not _ticks(tmp_path, package=False).start_build()
    monkeypatch.setenv(workers.WORKER_ENV, "1")
    assert not _ticks(tmp_path).start_build()


def test_package_ticks_are_those_of_the_package_stacks(robot):
    from wbc.limits.collision_packed import ROW_PLACER
    from wbc.solvers.plan import (
        bound_set,
        box_limits,
        constraint_set,
        kernel_set,
        package_ticks,
    )
    from wbc.stacks import load_stack

    stack = load_stack("walk", robot).stack
    tasks = [t for lv in stack.levels for t in lv.active_tasks()]
    constraints = [c for lv in stack.levels for c in lv.constraints]
    kernels, bounds = kernel_set(tasks), bound_set(box_limits(stack))
    cons = constraint_set(constraints)
    # (the package's set: its fused ticks make the self-collision rows, ROW_PLACER)
    assert package_ticks() is dispatch.ticks(kernels, bounds, False, True, cons, ROW_PLACER)
    assert package_ticks().package and not package_ticks().split
    assert package_ticks().placer is ROW_PLACER[0] and package_ticks().buildable()


def test_a_bad_part_is_named():
    run = subprocess.run(
        [sys.executable, "-m", "wbc.warmup", "--part", "fast"], capture_output=True, text=True
    )
    assert run.returncode == 2
    assert "--part" in run.stderr and "weighted" in run.stderr and "hierarchical" in run.stderr


class RunningWorker(FakeWorker):
    """A worker process still compiling until ``finish`` is called."""

    def __init__(self, cmd, env, stdout, stderr):
        super().__init__(cmd, env, stdout, stderr, code=0)
        self.code = None

    def finish(self):
        self.code = 0


@pytest.fixture
def building(tmp_path, monkeypatch):
    """(Ticks over the stand-in module, the workers they start: :class:`RunningWorker`s, the
    ids of the dispatchers cached on disk), outside a worker and not waiting for builds."""
    started, cached = [], set()

    def popen(cmd, env, stdout, stderr, pass_fds=()):
        started.append(RunningWorker(cmd, env, stdout, stderr))
        return started[-1]

    monkeypatch.delenv(workers.WORKER_ENV, raising=False)
    monkeypatch.delenv(workers.WAIT_ENV, raising=False)
    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    monkeypatch.setattr(dispatch, "_on_disk", lambda d: id(d) in cached)
    return _ticks(tmp_path), started, cached


def test_a_tick_being_built_is_ready_once_cached_or_its_worker_is_done(
    building, tmp_path, monkeypatch, caplog
):
    ticks, started, cached = building
    ticks.cascade_tick = SimpleNamespace(overloads={}, _cache=None)  # (another dispatcher)
    with caplog.at_level(logging.WARNING, logger="wbc.compiled.dispatch"):
        assert not ticks.ready("weighted_tick")  # the first call starts both workers
        assert len(started) == 2 and "numpy path" in caplog.records[-1].message
        assert not ticks.ready("weighted_tick") and len(started) == 2  # no second build
        cached.add(id(ticks.weighted_tick))  # in the cache, its worker still running
        assert ticks.ready("weighted_tick")
        assert "weighted tick is ready" in caplog.records[-1].message
        assert "weighted_tick" in ticks.builders  # (not waited for)
        assert not ticks.ready("cascade_tick")
        started[1].finish()  # done, but nothing cached (a failure): compiles at the call
        assert ticks.ready("cascade_tick") and "cascade_tick" not in ticks.builders
    started[0].finish()
    ticks.wait_all()
    assert ticks.builders == {}
    fresh = _ticks(tmp_path)
    monkeypatch.setenv(workers.WAIT_ENV, "1")  # waiting instead: ready (the call waits)
    assert fresh.ready("weighted_tick") and not started[2:]


def test_a_set_worker_compiles_the_package_solve_first_unless_it_is_cached(
    building, tmp_path, monkeypatch
):
    """The split tick of another set calls the package's solve after its rows: a job names it
    when it is not cached (a fresh install on which nothing solved a split tick yet: the CI
    run where the worker finished and the solver then started the package's whole build),
    and the worker compiles it before the tick, so the tick on disk means both are ready."""
    from wbc.compiled import worker
    from wbc.compiled.ticks import weighted_solve

    _, started, cached = building
    ticks = _ticks(tmp_path, package=False)
    ticks.module.__name__ = "wbc_tick_x"
    ticks.cache, ticks.kernels = True, ()
    ticks.weighted_tick.py_func = SimpleNamespace(__name__="rows")  # (both ticks' stand-in)
    args, solve_args = (np.zeros(3),), (np.zeros((2, 2)), 1.0)
    assert not ticks.ready("weighted_tick", args, (weighted_solve, solve_args))
    job = json.loads(Path(started[-1].cmd[-1]).read_text())
    assert (job["solve"]["module"], job["solve"]["qualname"]) == (
        "wbc.compiled.ticks", "weighted_solve"
    )  # fmt: skip
    compiled = []  # (the signatures compiled, in order)
    recorder = SimpleNamespace(compile=compiled.append)
    monkeypatch.setattr(worker, "load_kernel", lambda entry: recorder)
    monkeypatch.setattr(dispatch, "load_generated", lambda *a: SimpleNamespace(rows=recorder))
    worker.run({**job, "tick": "rows"})
    assert [len(signature) for signature in compiled] == [2, 1]  # the solve's, then the tick's
    cached.add(id(weighted_solve))  # cached: the next job does not name it
    ticks.builders.clear()
    ticks.ready("cascade_tick", args, (weighted_solve, solve_args))
    assert "solve" not in json.loads(Path(started[-1].cmd[-1]).read_text())


FIRST_TICK = """
import json, time
from wbc import load_robot
from wbc.solvers.plan import package_ticks
from wbc.stacks import load_stack
robot = load_robot()
q = robot.configuration("walk_ready")
out = {}
try:
    for solver in ("weighted", "hierarchical"):
        s = load_stack("walk", robot, solver=solver).solver
        start = time.perf_counter()
        q_next = s.step(q, 0.01)
        out[solver] = dict(
            seconds=time.perf_counter() - start,
            ticks=[s.interim_ticks, s.compiled_ticks, s.handed_back_ticks],
            q=q_next.tolist(),
        )
    ticks = package_ticks()
    out["building"] = sorted(ticks.builders)
    out["compiled"] = bool(ticks.weighted_tick.overloads or ticks.cascade_tick.overloads)
finally:
    for worker in package_ticks().builders.values():  # (not waited for: stop them)
        worker.kill()
        worker.wait()
print(json.dumps(out))
"""


def test_the_first_tick_on_an_empty_cache_is_answered_while_the_tick_compiles(robot, tmp_path):
    """A fresh install (no compiled tick in the cache): the first tick of either solver is
    solved at once on the numpy path while worker processes compile the ticks, and agrees
    with the compiled tick (here: this process's). The row kernels' cache is kept: only the
    ticks are cold."""
    from wbc.stacks import load_stack

    env = {**os.environ, "WBC_CACHE_DIR": str(tmp_path / "wbc")}
    env.pop(workers.WAIT_ENV, None)
    env.pop(workers.WORKER_ENV, None)
    run = subprocess.run(
        [sys.executable, "-c", FIRST_TICK], env=env, capture_output=True, text=True,
        cwd=Path(__file__).resolve().parent.parent, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert "compiling the control ticks in 2 background processes" in run.stderr
    assert out["building"] == ["cascade_tick", "weighted_tick"]
    assert not out["compiled"]  # nothing compiled a tick in the process
    q = robot.configuration("walk_ready")
    # the weighted QP: one strictly convex problem (DAQP against the compiled least squares);
    # the hierarchy: the backend cascade against the compiled one
    for solver, tol in (("weighted", 1e-7), ("hierarchical", 1e-6)):
        assert out[solver]["ticks"] == [1, 0, 0], solver  # on the numpy path
        s = load_stack("walk", robot, solver=solver).solver
        q_next = s.step(q, 0.01)
        assert s.compiled_ticks == 1
        assert abs(q_next - out[solver]["q"]).max() < tol, solver


def test_only_the_default_solves_on_the_numpy_path_while_its_tick_compiles(robot, monkeypatch):
    from wbc.solvers.plan import _Plan
    from wbc.stacks import load_stack

    monkeypatch.setattr(_Plan, "ready", lambda self: False)  # as while the workers run
    q = robot.configuration("walk_ready")
    for solver in ("weighted", "hierarchical"):
        for compiled, counts in ((None, (1, 0)), (True, (0, 1))):  # True: waits for it
            s = load_stack("walk", robot, solver=solver).solver
            s.compiled = compiled
            s.step(q, 0.01)
            assert (s.interim_ticks, s.compiled_ticks) == counts, (solver, compiled)


def test_a_numpy_path_kernel_is_ready_once_compiled_or_its_worker_is_done(
    building, tmp_path, monkeypatch
):
    """The level cascade that the numpy path calls from Python (any backend): not ready while
    the hierarchical worker compiles it (the first call starts the workers), ready when that
    worker is done or it is compiled or cached (issue 28: the first HierarchicalQP tick on
    OSQP compiled it in the process for two minutes)."""
    ticks, started, cached = building
    kernel = SimpleNamespace(overloads={}, _cache=None)
    assert not ticks.kernel_ready(kernel, "cascade_tick")  # starts both workers
    assert len(started) == 2
    cached.add(id(kernel))  # its index is written while the worker goes on: not yet
    assert not ticks.kernel_ready(kernel, "cascade_tick")
    started[1].finish()
    assert ticks.kernel_ready(kernel, "cascade_tick") and "cascade_tick" not in ticks.builders
    assert len(started) == 2  # (no new workers: cached now)
    assert _ticks(tmp_path).kernel_ready(kernel, "cascade_tick")  # cached, no worker
    compiled_here = SimpleNamespace(overloads={"sig": 1}, _cache=None)
    assert _ticks(tmp_path).kernel_ready(compiled_here, "cascade_tick")
    monkeypatch.setenv(workers.WAIT_ENV, "1")  # waiting instead: ready (the call compiles)
    assert _ticks(tmp_path).kernel_ready(SimpleNamespace(overloads={}), "cascade_tick")
    assert len(started) == 2


@pytest.mark.parametrize("backend", ["osqp", "daqp"])
def test_the_hierarchy_on_any_backend_answers_while_its_level_kernel_compiles(
    robot, monkeypatch, backend
):
    """While the numpy path's level cascade is being compiled, a hierarchy on the numpy path
    (any backend, or compiled=False) solves by the backend cascade and counts an interim
    tick; the same answer as once it is ready (to the backends' accuracy)."""
    from wbc.solvers import HierarchicalQP
    from wbc.stacks import load_stack

    q = robot.configuration("walk_ready")
    ready = load_stack("walk", robot, backend=backend, solver="hierarchical", compiled=False)
    q_ready = ready.solver.step(q, 0.01)
    assert ready.solver.interim_ticks == 0
    monkeypatch.setattr(HierarchicalQP, "_level_solver_ready", staticmethod(lambda: False))
    control = load_stack("walk", robot, backend=backend, solver="hierarchical", compiled=False)
    q_interim = control.solver.step(q, 0.01)
    assert control.solver.interim_ticks == 1 and control.solver.compiled_ticks == 0
    assert abs(q_interim - q_ready).max() < 1e-5


def test_a_flushed_cache_index_is_not_a_cached_kernel(tmp_path, monkeypatch):
    """:func:`wbc.compiled._cache.refresh` flushes a kernel's cache, which leaves an empty
    index file: that is not a cached compilation (issue 28: the level cascade of ``ticks.py``
    counted as cached on a cold cache, and its first tick compiled it in the process)."""
    import importlib.util

    module_file = tmp_path / "flushed_kernel.py"
    module_file.write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef twice(x):\n    return 2.0 * x\n"
    )
    spec = importlib.util.spec_from_file_location("flushed_kernel", module_file)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "flushed_kernel", module)
    spec.loader.exec_module(module)
    kernel = module.twice
    kernel._cache.flush()  # (as refresh does: an index with no entry)
    assert Path(kernel._cache._cache_file._index_path).exists()
    assert not dispatch._on_disk(kernel)
    assert kernel(2.0) == 4.0  # compiled and saved
    assert dispatch._on_disk(kernel)


# ---------------------------------------------------------------------- another kernel set
USER_TASK = """
import numpy as np
from numba import njit

from wbc.tasks import Task


@njit(cache=True)
def height_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J):
    e[0] = target[0] - com[2]
    for k in range(Jcom.shape[1]):
        J[0, k] = Jcom[2, k]


class HeightTask(Task):
    dim = 1
    row_kernel = staticmethod(height_rows)
    target_fields = ("target",)

    def __init__(self, height):
        super().__init__("height", weight=10.0)
        self.target = np.array([height])
"""

NEW_SET = """
import json, sys
import numpy as np
from wbc import load_robot
from wbc.stacks import load_stack
from user_height import HeightTask
robot = load_robot()
q0 = robot.configuration("walk_ready")
out = {}
for compiled in (None, False):
    control = load_stack("walk", robot, solver=sys.argv[1], compiled=compiled)
    control.stack.add(HeightTask(robot.com(q0)[2] - 0.002), level=1)
    s = control.solver
    first = s.step(q0, 0.01)
    if compiled is None:
        (worker,) = s.fast.ticks.builders.values()
        building = worker.poll() is None  # the first tick answered while its worker compiles
        assert worker.wait() == 0
        out["first"] = [building, s.interim_ticks, s.compiled_ticks]
    q = s.step(first, 0.01)  # (compiled once its worker is done)
    out[str(compiled)] = [first.tolist(), q.tolist(), s.interim_ticks, s.compiled_ticks]
print(json.dumps(out))
"""


@pytest.mark.long(40)
@pytest.mark.parametrize("solver", ["weighted", "hierarchical"])
def test_a_new_kernel_set_compiles_in_a_worker_while_the_numpy_path_answers(tmp_path, solver):
    """A task type defined outside the package, on an empty cache: the first tick is solved
    at once on the numpy path while one worker compiles this set's tick (only its rows: the
    kernels and the solve are cached each on its own); the next tick runs it, and agrees
    with the numpy path to 1e-9."""
    (tmp_path / "user_height.py").write_text(USER_TASK)
    env = {**os.environ, "WBC_CACHE_DIR": str(tmp_path / "wbc")}
    env.pop(workers.WAIT_ENV, None)
    env.pop(workers.WORKER_ENV, None)
    run = subprocess.run(
        [sys.executable, "-c", NEW_SET, solver], env=env, capture_output=True, text=True,
        cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert "a new set of task types" in run.stderr
    building, interim, compiled = out["first"]
    assert (interim, compiled) == (1, 0)  # the first tick: the numpy path
    assert building  # it did not wait for the compile (the worker was still at it)
    first, q, interim, compiled = out["None"]
    assert (interim, compiled) == (1, 1)  # then the compiled tick
    numpy_first, numpy_q, _, numpy_compiled = out["False"]
    assert numpy_compiled == 0
    assert np.abs(np.array(first) - numpy_first).max() < 1e-9
    assert np.abs(np.array(q) - numpy_q).max() < 1e-9


def test_the_compiled_kernels_are_a_leaf():
    """wbc.compiled imports nothing above the kernels (imports inside functions counted):
    only wbc.exceptions and wbc.types of the package; the tasks, limits and solvers pass
    their kernels in, and the workers above it are started by module name."""
    import ast

    package = Path(dispatch.__file__).parent
    allowed = {"wbc.exceptions", "wbc.types"}
    above = []
    for path in sorted(package.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level == 1:
                    continue  # (wbc.compiled itself)
                name = ("wbc." + (node.module or "")) if node.level == 2 else node.module
            elif isinstance(node, ast.Import):
                name = node.names[0].name
            else:
                continue
            if name and name.startswith("wbc") and name not in allowed:
                above.append((path.name, name))
    assert above == []
