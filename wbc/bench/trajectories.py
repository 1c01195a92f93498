"""The trajectories the benchmark runs every solver on."""

from __future__ import annotations

from collections.abc import Callable

from ..exceptions import ConfigurationError
from ..model import Robot
from ..walking.gait import forward_walk, lateral_walk, turning_walk
from ..walking.reference import StandingState, WalkingReference
from ..walking.thesis_step import thesis_step

#: name -> (builder, description)
TRAJECTORIES: dict[str, tuple[Callable[[StandingState], WalkingReference], str]] = {
    "thesis_step": (lambda s: thesis_step(s), "the thesis's one step: 100 poses, cubic splines"),
    "walk10": (lambda s: forward_walk(s, n_steps=10), "10 steps forward, ZMP preview control"),
    "turn": (lambda s: turning_walk(s), "a turning walk, ZMP preview control"),
    "lateral": (lambda s: lateral_walk(s), "sideways steps, ZMP preview control"),
}
#: the static CoM placement set of ch. 3 (not a walking reference: see wbc.bench.runner)
STATIC_COM = "static_com"
DEFAULT = ("thesis_step", "walk10")


def names() -> list[str]:
    return [*TRAJECTORIES, STATIC_COM]


def build(name: str, robot: Robot, walking_only: bool = False) -> WalkingReference:
    """A walking reference by name, starting from the robot's Walk Ready stance.

    ``walking_only``: the caller cannot run :data:`STATIC_COM` (a benchmark set, not a
    walking reference); the message then lists only the walking references.
    """
    if name == STATIC_COM:
        raise ConfigurationError(
            f"trajectory {STATIC_COM!r} is the static CoM placement set (wbc bench "
            f"--trajectories {STATIC_COM}), not a walking reference; walk one of "
            f"{list(TRAJECTORIES)}"
        )
    try:
        builder, _ = TRAJECTORIES[name]
    except KeyError:
        allowed = list(TRAJECTORIES) if walking_only else names()
        raise ConfigurationError(f"unknown trajectory {name!r}; choose from {allowed}") from None
    ref = builder(StandingState.from_robot(robot))
    ref.name = name
    return ref
