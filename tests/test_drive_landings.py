"""benchmarks/landings.py's bookkeeping: the landings' classes, the error along the step and
the placement errors chained into the world per run (the simulated runs are the benchmark's)."""

from __future__ import annotations

import math

import pytest

from wbc.walking.footsteps import Footstep

pytest.importorskip("mujoco")

WIDTH = 0.07


@pytest.fixture(scope="module")
def landings(benchmark_script):
    return benchmark_script("landings")


@pytest.mark.parametrize(
    ("side", "dx", "dout", "dyaw", "kind"),
    [
        ("left", 0.03, 0.0, 0.0, "fwd"),
        ("right", -0.02, 0.0, 0.0, "back"),
        ("left", 0.005, 0.015, 0.0, "side"),
        ("right", 0.0, -0.012, 0.0, "side"),
        ("left", 0.01, 0.0, math.radians(10), "turn"),
        ("right", 0.002, 0.001, math.radians(1), "spot"),
    ],
)
def test_a_landing_is_classed_by_its_planned_step_in_the_stance_soles_frame(
    landings, side, dx, dout, dyaw, kind
) -> None:
    """The stance sole turned 90°: the step's forward is the world's +y; ``out`` is away
    from the stance sole for either side."""
    sign = 1.0 if side == "left" else -1.0
    stance = Footstep("right" if side == "left" else "left", 1.0, 2.0, math.pi / 2)
    # the stance frame's x is the world's +y, its y (left) the world's −x
    local_x, local_y = dx, sign * (WIDTH + dout)
    step = Footstep(side, 1.0 - local_y, 2.0 + local_x, math.pi / 2 + dyaw)
    got, planned = landings.classify(step, stance, WIDTH)
    assert got == kind
    assert planned[0] == pytest.approx(dx)
    assert planned[1] == pytest.approx(WIDTH + dout)
    assert planned[2] == pytest.approx(dyaw)


def row(side: str, x: float, out: float, stance_yaw: float, planned=(0.0, 70.0, 0.0)) -> dict:
    """One landing's record with the same error for every reading but ``raw`` (none)."""
    errors = {k: [x, out, 0.0] for k in landings_readings()}
    errors["raw"] = [0.0, 0.0, 0.0]
    return {"sequence": 0, "model": 0, "side": side, "stance_yaw": stance_yaw,
            "errors": errors, "planned": list(planned), "slide": [0.0, 0.0, 0.0],
            "kind": "spot", "where": "mid"}  # fmt: skip


def landings_readings() -> tuple[str, ...]:
    return ("main", "raw", "mean", "raw_mean", "first", "hold10", "hold20", "hold30", "hold50",
            "stance_raw", "landed_raw", "side", "links", "truth_mean")  # fmt: skip


def test_the_placement_errors_add_up_in_the_world_by_the_stance_soles_headings(landings) -> None:
    """A landing of the left sole 1 mm behind (its stance heading 0: the world's −x) and one
    of the right sole 1 mm outward (its stance, the left sole, facing the world's +y:
    outward, to that sole's right, is the world's +x) cancel in the world; two left landings
    1 mm behind with the stance facing +x add up to 2 mm."""
    cancel = [row("left", -1.0, 0.0, 0.0), row("right", 0.0, 1.0, math.pi / 2)]
    lines = landings.run_sums(cancel)
    main = next(line for line in lines if line.strip().startswith("main"))
    assert main.split()[1] == "0.0"
    add = [row("left", -1.0, 0.0, 0.0), row("left", -1.0, 0.0, 0.0)]
    main = next(line for line in landings.run_sums(add) if line.strip().startswith("main"))
    assert main.split()[1] == "2.0"
    raw = next(line for line in landings.run_sums(add) if line.strip().startswith("raw "))
    assert raw.split()[1] == "0.0" and raw.split()[4] == "1;"  # below main's on the one run
    # the stance sole (right) slid 1 mm back unseen: the left sole's placement 1 mm behind
    # (stance heading 0) is then the odometry's truth but for the slide's −1 mm: 0 left
    slid = [row("left", -1.0, 0.0, 0.0)]
    slid[0]["slide"] = [-1.0, 0.0, 0.0]
    main = next(line for line in landings.run_sums(slid) if line.strip().startswith("main"))
    assert main.split()[1] == "1.0" and main.split()[5] == "0.0"


def test_the_error_along_the_step_is_positive_for_a_step_read_long(landings) -> None:
    r = row("left", 0.0, 0.0, 0.0, planned=(30.0, 70.0, 0.0))  # a 30 mm step forward
    assert landings.along(r, [0.5, 0.0, 0.0], 70.0) == pytest.approx(0.5)
    back = row("left", 0.0, 0.0, 0.0, planned=(-30.0, 70.0, 0.0))
    assert landings.along(back, [0.5, 0.0, 0.0], 70.0) == pytest.approx(-0.5)
    spot = row("left", 0.0, 0.0, 0.0, planned=(1.0, 71.0, 0.0))
    assert landings.along(spot, [0.5, 0.5, 0.0], 70.0) == 0.0
