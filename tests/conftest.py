"""Shared fixtures: one robot model per test session."""

from __future__ import annotations

import importlib.util
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from wbc.compiled.workers import LOCK_ENV, share_compilations

# numba's compilations of a kernel one at a time across the test workers and the package's
# compile workers they start (wbc.compiled.workers.share_compilations: they inherit the
# setting; WBC_COMPILE_LOCK=0: off); before wbc's kernels with signatures compile at import
os.environ.setdefault(LOCK_ENV, "1")
share_compilations()

from wbc import load_robot  # noqa: E402

# the tests count and compare compiled ticks: from a cold cache, a solver waits for its compiled
# tick rather than solving on the numpy path while it is built (wbc.compiled.workers.WAIT_ENV)
os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")

# derandomised and without the example database: every run checks the same examples
settings.register_profile("ci", max_examples=40, deadline=None, derandomize=True, database=None)
settings.register_profile("dev", max_examples=40, deadline=None)
settings.load_profile("ci")


def pytest_sessionstart(session: pytest.Session) -> None:
    """With test workers (``-n 2``, pyproject.toml's), the controller starts the package's
    compiled ticks' build (:func:`wbc.solvers.plan.start_package_ticks`: nothing if cached)
    before the workers collect: on a cold cache the build (one core's worth: the compile
    lock has its two workers take turns) then runs beside the long tests that need no
    package tick (the compile test, the dispatch and stabilizer tests), instead of starting
    when the first test needing it does while both workers wait for it. The workers' tests
    find its lock files held and wait for it (``BuildElsewhere``). ``-n 0``: nothing."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    from wbc.solvers.plan import start_package_ticks

    start_package_ticks(announce=False)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The tests marked ``long(seconds)`` first, the longest first (the others in their
    order): the workers take the tests in collection order (pyproject.toml's
    ``--no-loadscope-reorder``; xdist's default puts the groups first), and a long test taken
    last would run alone while the other worker idles."""

    def seconds(item: pytest.Item) -> float:
        mark = item.get_closest_marker("long")
        return -float(mark.args[0]) if mark is not None else 0.0

    items.sort(key=seconds)  # (stable: same order on every worker)
    _xdist_groups(config, items)


def _xdist_groups(config: pytest.Config, items: list[pytest.Item]) -> None:
    """``--dist loadgroup``'s suffix ``@group`` on the node ids of the tests marked
    ``xdist_group(group)``, where pytest-xdist's own did not take: it sets ``item._nodeid``,
    which pytest 9 no longer reads (a node keeps its id in ``_id``), so every such test was
    scheduled alone (pytest 9.2, pytest-xdist 3.8: the browser tests each worker's Chromium,
    ``bench_run`` set up on both workers)."""
    if not getattr(config.option, "loadgroup", False):  # (set in the workers only)
        return
    for item in items:
        names = {str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                 for m in item.iter_markers("xdist_group")}  # fmt: skip
        if not names or item.nodeid.rfind("@") > item.nodeid.rfind("]"):
            continue  # (no group, or xdist's suffix is there)
        grouped = f"{item.nodeid}@{'_'.join(sorted(names))}"
        node_id = getattr(item, "_id", None)
        if node_id is not None and hasattr(type(node_id), "parse"):
            item._id = type(node_id).parse(grouped)  # type: ignore[attr-defined]


@pytest.fixture(scope="session")
def robot():
    return load_robot("bioloid")


@pytest.fixture(scope="session")
def walk_ready_ticks(robot):
    """The Bioloid's Walk Ready pose as servo ticks by ID (the emulators' start)."""
    sm = robot.servo_map
    return sm.ticks_by_id(sm.pose_ticks("walk_ready"))


@pytest.fixture(scope="session")
def op3():
    return load_robot("op3")


@pytest.fixture(scope="session")
def pose_recording(tmp_path_factory):
    """A function writing a 50 Hz recording of ``seconds``: a robot's named pose plus
    ``k · 0.15 sin²(πt)`` rad (zero end speeds) on each ``(joint, k)`` of ``bends``;
    returns the file's path."""
    from wbc.recording import Recording

    def make(robot, pose: str, bends=(), seconds: float = 1.0, name: str = "motion") -> str:
        t = np.arange(0.0, seconds + 1e-9, 0.02)
        s = 0.15 * np.sin(np.pi * t) ** 2
        q = np.tile(robot.configuration(pose), (t.size, 1))
        for joint, k in bends:
            q[:, robot.q_index(joint)] += k * s
        path = tmp_path_factory.mktemp(name) / f"{name}.npz"
        Recording(t, q, robot.joint_names).save(path)
        return str(path)

    return make


class PacedClock:
    """A deployment's clock (``ServoBus.clock``) on which no tick is late: ``now`` advances by
    the sleeps only, and a sleep waits until the wall clock reaches the new time plus the
    lateness absorbed so far — or, when it is already past that, the whole interval asked
    for. A stall of the test machine delays the rest of the run instead of skipping ticks, and
    never causes a burst: ticks stay at least a period apart on the wall clock, so the goals'
    speed law holds on the servos' own receive times."""

    def __init__(self) -> None:
        self.t = time.perf_counter()
        self.behind = 0.0  # wall clock minus this clock, absorbed lateness (s)

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        seconds = max(seconds, 0.0)
        self.t += seconds
        wall = time.perf_counter()
        target = self.t + self.behind
        if wall >= target:
            # late (a stall, or the set-up before a run's first ticks, which no sleep paced):
            # the whole interval from now, not at once — returning at once would put this
            # tick right after the last one (the burst of a run's first two ticks)
            target = wall + seconds
            self.behind = target - self.t
        time.sleep(target - wall)


@pytest.fixture()
def device_time(monkeypatch):
    """Reply deadlines on the emulators' device clock (``wbc.servos.pty_runner.DeviceClock``,
    returned: a test has it watch the emulators it starts, ``device_time.watch(emu)``): a
    deadline is judged once those emulators have answered what they were sent, so a
    late-scheduled emulator is no servo timeout (as on real servos, whose replies do not wait
    for the host's scheduler); silence and late replies (injected faults) still time out.
    """
    from wbc.servos.bus import ServoBus
    from wbc.servos.pty_runner import DeviceClock

    clock = DeviceClock()
    monkeypatch.setattr(ServoBus, "reply_clock", clock)
    return clock


@pytest.fixture()
def paced_clock(monkeypatch):
    """The deployments' ticks on a :class:`PacedClock`: a stalled host plays every tick, later,
    so a test that counts goal writes (a fault injected after N) does not depend on the load.
    Not for tests of a time bound on the wall clock."""
    from wbc.servos.bus import ServoBus

    clock = PacedClock()
    monkeypatch.setattr(ServoBus, "clock", clock)
    return clock


@pytest.fixture()
def soft_plant_loop(robot):
    """A factory: ``closed_loop`` on the simulated Bioloid whose servos are ``stiffness`` ×
    servos.toml's, walk10_wb's first ``duration`` s after a 0.5 s rest (the stiffness identified
    there), wqp-daqp, no feed-forward; what the loop says goes to ``said``."""
    from wbc.balance.live import closed_loop
    from wbc.bench import trajectories as traj
    from wbc.bench.solvers import select
    from wbc.sim.actuator import nominal_servo
    from wbc.sim.bus import SimImu, sim_bus
    from wbc.sim.simulator import Simulation
    from wbc.walking.loop import start_configuration

    ref = traj.build("walk10_wb", robot)
    entry = select(["wqp-daqp"], None, "tick")[0][0]

    def make(stiffness: float, gains, said: list[str], duration: float = 1.2):
        sim = Simulation(robot, None, nominal_servo(robot).scaled(stiffness=stiffness))
        sim.reset(start_configuration(robot, ref))
        bus = sim_bus(sim, min(100.0, 1.0 / ref.dt))
        solver = entry.make(robot)
        return closed_loop(bus, robot, solver, ref, SimImu(sim), gains, compensate=0.0,
                           out=said.append, duration=duration, calibrate_s=0.5)  # fmt: skip

    return make


@pytest.fixture()
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="session")
def random_configuration(robot):
    """``make(seed)``: Walk Ready with every joint drawn inside its range (even seeds) or up to
    0.05 rad beyond it (odd), and one joint NaN when ``seed % 5 == 0``."""

    def make(seed: int) -> np.ndarray:
        rng = np.random.default_rng(seed)
        lo, hi = robot.q_min, robot.q_max
        q = robot.configuration("walk_ready").copy()
        q[7:] = rng.uniform(lo - 0.05, hi + 0.05) if seed % 2 else rng.uniform(lo, hi)
        if seed % 5 == 0:
            q[7 + seed % robot.n_joints] = np.nan  # numpy: a NaN joint is neither below nor above
        return q

    return make


@pytest.fixture(scope="session")
def window(robot):
    """The Bioloid's whole-body balance window (coarse: 6 samples), built once."""
    from wbc.walking.window import BalanceWindow

    return BalanceWindow.from_robot(robot, samples=6)


@pytest.fixture(scope="session")
def start(robot):
    """The Bioloid standing in its stand pose (the walks' start)."""
    from wbc.walking import StandingState

    return StandingState.from_robot(robot)


@pytest.fixture(scope="module")
def walk10(robot):
    """The Bioloid's ``walk10`` reference (one per test module)."""
    from wbc.bench.trajectories import build

    return build("walk10", robot)


@pytest.fixture(scope="module")
def legs(robot):
    """The Bioloid's leg geometry measured at its stand pose."""
    from wbc.walking.legs import LegGeometry

    return LegGeometry.from_robot(robot, robot.configuration("stand"))


@pytest.fixture(scope="session")
def benchmark_script():
    """``load(name)``: benchmarks/``name``.py as a module, loaded once per session (its
    folder on the import path, last, as for a script run there: the scripts import their
    siblings, e.g. ``_args``)."""
    folder = Path(__file__).resolve().parents[1] / "benchmarks"
    if str(folder) not in sys.path:
        sys.path.append(str(folder))

    def load(name: str):
        spec_name = f"wbc_{name}_benchmark"
        if spec_name not in sys.modules:
            path = folder / f"{name}.py"
            spec = importlib.util.spec_from_file_location(spec_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[spec_name] = module  # dataclasses look their module up
            spec.loader.exec_module(module)
        return sys.modules[spec_name]

    return load


@pytest.fixture(scope="session")
def stress_script(benchmark_script):
    """benchmarks/stress.py as a module (its draws and stacks replay the stress trials)."""
    return benchmark_script("stress")
