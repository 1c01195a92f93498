"""The whole-body static walk (wbc.walking.static_walk)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.bench import trajectories as traj
from wbc.exceptions import TrajectoryError
from wbc.walking.feasibility import kinematic_feasibility
from wbc.walking.static_walk import StaticWalkParams, static_walk
from wbc.walking.window import BalanceWindow


def test_com_15mm_inside_the_stance_sole_in_single_support(robot, window, start):
    ref = static_walk(start, window, StaticWalkParams(n_steps=2))
    single = ref.support != 0
    assert single.any()
    assert ref.com_margin()[single].min() >= 0.015
    assert ref.gait == "static"
    # the CoM is at rest in single support (a static gait)
    assert np.abs(ref.com_vel[single]).max() < 1e-9
    rep = kinematic_feasibility(robot, ref, hold_arms=False)
    assert rep.feasible, rep


def test_the_legs_alone_cannot_do_it(start):
    """Without a torso lean (a zero-lean window) the CoM cannot reach 15 mm inside."""
    flat = BalanceWindow(
        offsets=np.array([0.0, 0.0115]),
        rolls=np.zeros(2),
        max_lateral=0.0115,
        upright=0.0115,
        max_lean=0.0,
        com_height=float(start.com[2]),
        half_width=0.0414,
    )
    with pytest.raises(TrajectoryError, match="balance window"):
        static_walk(start, flat, StaticWalkParams(n_steps=1))


def test_bad_parameters(start, window):
    with pytest.raises(TrajectoryError, match="n_steps"):
        static_walk(start, window, StaticWalkParams(n_steps=0))
    with pytest.raises(TrajectoryError, match="swing_time"):
        static_walk(start, window, StaticWalkParams(swing_time=-1.0))


def test_named_static_walk(robot):
    ref = traj.build("static_walk", robot)
    assert ref.name == "static_walk"
    assert ref.com_margin()[ref.support != 0].min() >= 0.015


@pytest.fixture(scope="module")
def longlegs(tmp_path_factory):
    """benchmarks/robots.py's long-legged robot (the Bioloid's URDF, legs 1.3x, body 0.8x,
    ROBOTIS OP3 joint names), made here; a two-step static walk."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parents[1] / "benchmarks" / "robots.py"
    spec = importlib.util.spec_from_file_location("bench_robots", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.make_robot(tmp_path_factory.mktemp("made") / "longlegs")


def _with_walk(folder, text):
    from wbc.model import load_robot

    (folder / "robot.toml").write_text("[walking.static_walk]\nn_steps = 2\n" + text)
    return load_robot(folder)


def test_a_long_legged_robots_static_walk_is_refused_beyond_its_reach(longlegs):
    """Over the front sole of its 39 mm step the whole body carries the CoM only 26 mm
    sideways (arms held, torso pitch and heading held), but 19.5 mm inside the sole is 29.9 mm
    out: one line naming step_length (it was built, and tracked with a -280 mm ZMP margin)."""
    robot = _with_walk(longlegs, "")
    with pytest.raises(TrajectoryError, match=r"unreachable.*front sole.*step_length") as err:
        traj.build("static_walk", robot)
    assert "\n" not in str(err.value)


def test_a_long_legged_robots_static_walk_at_the_step_it_fits_is_tracked(longlegs):
    """At the step it fits (21 mm: the refusal's), the CoM is kept within the reach at every
    stance: the walk stack tracks it with the ZMP inside the soles and the reference asks no
    joint for more than the sized share of its speed (on main: the CoM 34.5 mm out, beyond
    the 33 mm the front sole's stance reaches)."""
    from wbc.bench import metrics
    from wbc.stacks import load_stack, robot_stack
    from wbc.walking.loop import StackController, run
    from wbc.walking.sizing import SPEED_FRACTION

    robot = _with_walk(longlegs, "step_length = 0.021\n")
    ref = traj.build("static_walk", robot)
    rep = kinematic_feasibility(robot, ref, iterations=2)
    assert rep.speed_fraction < SPEED_FRACTION, rep
    assert rep.max_sole_error < 1e-3, rep
    rec = run(StackController(load_stack(robot_stack(robot)[0], robot)), robot, ref)
    m = metrics.compute(rec, robot)
    assert m["failures"] == 0
    assert m["zmp_margin_min_mm"] > 10.0, m["zmp_margin_min_mm"]
    assert m["foot_err_max_mm"] < 5.0 and m["com_err_max_mm"] < 2.5, m
    # the CoM pulled in from the sole's centre to stay within the reach
    assert ref.meta["com_offset_y"] > ref.meta["params"]["com_offset"][1]


def test_bad_reach_share_is_one_line(start, window):
    with pytest.raises(TrajectoryError, match="reach_share must be in"):
        static_walk(start, window, StaticWalkParams(reach_share=0.0))


def test_the_long_legged_robot_states_its_measured_dead_bands(benchmark_script, tmp_path):
    """Its robot.toml states the DCM error its unpushed walk10_wb shows on the nominal and 20
    randomised plants (benchmarks/robots.md, 2026-12-06 third round): the closed loop's step
    adjustment runs on its own bands, not the Bioloid's (which re-planned 12 of 20 into falls)."""
    from wbc.balance.stepping import SteppingParams
    from wbc.model import load_robot

    robot = load_robot(benchmark_script("robots").make_robot(tmp_path / "longlegs"))
    params = SteppingParams().for_robot(robot)
    assert SteppingParams().measured(robot)
    assert (params.band_x, params.band_y, params.trigger_jump) == (0.075, 0.09, 0.036)
