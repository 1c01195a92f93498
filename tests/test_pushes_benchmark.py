"""benchmarks/pushes.py: the loops' specs (``--gains sized``: the closed loop's default)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest


@pytest.fixture(scope="module")
def pushes(benchmark_script):
    return benchmark_script("pushes")


def test_gains_sized_leaves_the_gains_to_the_closed_loop(pushes):
    from wbc.balance.stabilizer import Gains

    entry = SimpleNamespace(make=lambda robot: None)
    assert pushes.gains_arg("sized") == "sized"
    assert pushes.gains_arg('{"k_p": 2.0}') == {"k_p": 2.0}
    sized, comp = pushes.loop_spec("step", entry, None, {}, "sized", {}, 1.0, {})
    assert sized.gains is None and sized.stepping is not None and comp == 1.0
    given, _ = pushes.loop_spec("step", entry, None, {}, {"k_p": 2.0}, {}, 1.0, {})
    assert given.gains == Gains(k_p=2.0)
    plain, _ = pushes.loop_spec("closed", entry, None, {}, None, {}, 1.0, {})
    assert plain.gains == Gains() and plain.stepping is None
    nohip, _ = pushes.loop_spec("nohip", entry, None, {}, "sized", {}, 1.0, {})
    assert nohip.gains == Gains(k_hip=0.0)


def test_the_closed_loops_gains_start_from_the_robots_sized_default(pushes):
    """Given a robot, --gains keywords go over the closed loop's default on it
    (default_sized_gains): Kokone's torso terms scaled to its servos — the design robot's
    gains as they are tipped it over unpushed (walk10_wb at 3.29 s, walk10 at 2.1 s:
    benchmarks/pushes.md) — in every closed loop (nohip, before too); the Bioloid's Gains()."""
    from dataclasses import replace

    from wbc.balance.margin import default_sized_gains
    from wbc.balance.stabilizer import Gains
    from wbc.model import load_robot

    entry = SimpleNamespace(make=lambda robot: None)
    ref = SimpleNamespace(dt=0.01)
    kokone, bioloid = load_robot("kokone"), load_robot("bioloid")
    sized, scale = default_sized_gains(kokone, 1.0, 0.01)
    assert scale < 0.1 and sized != Gains()
    spec, _ = pushes.loop_spec("step", entry, ref, {}, {}, {}, 1.0, {}, kokone)
    assert spec.gains == sized and spec.stepping is not None
    spec, _ = pushes.loop_spec("closed", entry, ref, {}, {"real_step": 0}, {}, 1.0, {}, kokone)
    assert spec.gains == replace(sized, real_step=0)
    spec, _ = pushes.loop_spec("nohip", entry, ref, {}, {}, {}, 1.0, {}, kokone)
    assert spec.gains == replace(sized, k_hip=0.0)
    spec, _ = pushes.loop_spec("before", entry, ref, {}, {}, {}, 1.0, {}, kokone)
    assert spec.gains == replace(sized, transfer=0.0)
    spec, _ = pushes.loop_spec("step", entry, ref, {}, {"k_p": 2.0}, {}, 0.5, {}, bioloid)
    assert spec.gains == Gains(k_p=2.0)
    spec, _ = pushes.loop_spec("step", entry, ref, {}, "sized", {}, 1.0, {}, kokone)
    assert spec.gains is None  # (closed_loop sizes it: the same gains)


def test_step_on_commands_reaches_the_closed_loop():
    """ClosedLoopSpec.step_on_commands (pushes.py --step-on-commands): Kokone's SSC-32 reads no
    positions, so its closed loop drops step adjustment unless asked (with dead bands given:
    it states none); asked, the step adjuster runs."""
    pytest.importorskip("mujoco")
    from dataclasses import replace

    from wbc.balance.stepping import SteppingParams
    from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build
    from wbc.model import load_robot

    kokone = load_robot("kokone")
    ref = build("walk10", kokone)  # (a dynamic walk: the adjuster re-plans those)
    bands = SteppingParams(band_x=0.04, band_y=0.026)
    spec = ClosedLoopSpec(registry()["hqp-daqp"].make, ref, None, stepping=bands, calibrate_s=0.0)
    stepping = {}
    for on in (False, True):
        _, loop = play_closed_loop(replace(spec, step_on_commands=on), kokone, compensate=1.0,
                                   duration=0.1, settle=0.0)  # fmt: skip
        stepping[on] = loop.stepping
    assert stepping[False] is None and stepping[True] is not None
    assert stepping[True].bands == (0.04, 0.026)
