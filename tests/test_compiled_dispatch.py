"""Building the package's compiled ticks in worker processes (wbc.compiled.dispatch,
wbc.compiled.__main__)."""

from __future__ import annotations

import logging
import subprocess
import sys
from types import SimpleNamespace

import pytest

pytest.importorskip("numba")

from wbc.compiled import __main__ as build
from wbc.compiled import dispatch


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
        __file__=str(tmp_path / "wbc_tick_x.py"), weighted_tick=tick, cascade_tick=tick
    )
    return dispatch.Ticks(module, package)


def test_start_build_runs_one_worker_per_solver_and_wait_reports_failures(
    tmp_path, monkeypatch, caplog
):
    started = []

    def popen(cmd, env, stdout, stderr):
        started.append(FakeWorker(cmd, env, stdout, stderr, code=1 if "hierarchical" in cmd else 0))
        return started[-1]

    monkeypatch.delenv(build.WORKER_ENV, raising=False)
    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    ticks = _ticks(tmp_path)
    assert ticks.start_build(announce=False)
    assert [w.cmd[-1] for w in started] == list(build.PARTS)
    assert all(w.cmd[:3] == [sys.executable, "-m", "wbc.compiled"] for w in started)
    assert all(w.env[build.WORKER_ENV] == "1" for w in started)  # no workers of their own
    assert not ticks.start_build()  # already building
    with caplog.at_level(logging.WARNING, logger="wbc.compiled.dispatch"):
        ticks.wait("weighted_tick")
        assert not caplog.records  # finished, and well
        ticks.wait("cascade_tick")
    (failure,) = caplog.records
    assert "cascade_tick" in failure.message and "TypingError: no kernel" in failure.message
    assert ticks.builders == {}
    ticks.wait("cascade_tick")  # nothing left to wait for


def test_no_workers_for_other_kernel_sets_or_inside_a_worker(tmp_path, monkeypatch):
    def popen(*args, **kwargs):
        raise AssertionError("no worker expected")

    monkeypatch.setattr(dispatch.subprocess, "Popen", popen)
    monkeypatch.delenv(build.WORKER_ENV, raising=False)
    assert not _ticks(tmp_path, package=False).start_build()
    monkeypatch.setenv(build.WORKER_ENV, "1")
    assert not _ticks(tmp_path).start_build()


def test_package_ticks_are_those_of_the_package_stacks(robot):
    from wbc.compiled.plan import kernel_set
    from wbc.stacks import load_stack

    tasks = [t for lv in load_stack("walk", robot).stack.levels for t in lv.active_tasks()]
    assert dispatch.package_ticks() is dispatch.ticks(kernel_set(tasks))
    assert dispatch.package_ticks().package


def test_a_bad_part_is_named():
    run = subprocess.run(
        [sys.executable, "-m", "wbc.compiled", "--part", "fast"], capture_output=True, text=True
    )
    assert run.returncode == 2
    assert "--part" in run.stderr and "weighted" in run.stderr and "hierarchical" in run.stderr
