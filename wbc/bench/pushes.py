"""Pushes on the simulated robot (``wbc bench --physics --push``): a 10 ms force on the torso
at mid first single support, forward, backward, sideways toward and away from the swing foot
(:data:`PUSH_DIRECTIONS`), each beside its LIPM bound (:func:`push_bounds`); the largest
impulse survived (N·s) by bisection over 0–3 N·s (:func:`largest_push`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..exceptions import ConfigurationError, TrajectoryError, WbcError
from ..model import Robot
from ..recording import SUPPORT_LEFT, Recording
from .closed_loop import ClosedLoopSpec, simulate
from .sim_record import mid_single_support

PUSH_DURATION = 0.01
PUSH_MAX_NS = 3.0
PUSH_STEPS = 7
#: the directions of ``--push`` (``lateral`` is ``away``: the side no step can reach)
PUSH_DIRECTIONS = ("forward", "backward", "toward", "away")


def push_direction(rec: Recording, kind: str) -> np.ndarray:
    """``forward`` (+x), ``backward`` (−x), ``away`` (alias ``lateral``: sideways away from
    the swing foot, +y when standing on the left sole, −y on the right, the side where no
    step can catch the robot) or ``toward`` (sideways toward the swing foot)."""
    if kind == "forward":
        return np.array([1.0, 0.0, 0.0])
    if kind == "backward":
        return np.array([-1.0, 0.0, 0.0])
    if kind not in ("lateral", "away", "toward"):
        raise ConfigurationError(
            f"push direction must be one of {', '.join(PUSH_DIRECTIONS)} (or lateral), got {kind!r}"
        )
    t = mid_single_support(rec)
    support = rec.channels.get("support")
    if t is None or support is None:
        raise TrajectoryError("a sideways push needs a single-support phase in the recording")
    k = int(np.clip(np.searchsorted(rec.t - rec.t[0], t, side="right") - 1, 0, len(rec) - 1))
    away = 1.0 if support[k] == SUPPORT_LEFT else -1.0
    return np.array([0.0, away if kind != "toward" else -away, 0.0])


def push_bounds(ref, robot: Robot) -> dict[str, float] | None:
    """Each push direction's physical bound (N·s, LIPM, :func:`wbc.balance.stepping.
    capture_bounds`): ``away`` the CoP at the stance sole's edge; ``forward``, ``backward``,
    ``toward`` one step landing as far as the swing sole gets in the time left (None when
    ``ref`` is not a walk with a single support)."""
    from ..balance.capture import capture_bounds
    from ..walking.legs import LegGeometry

    try:
        b = capture_bounds(ref, robot.total_mass,
                           LegGeometry.from_robot(robot, robot.configuration("stand")))  # fmt: skip
    except (StopIteration, AttributeError, KeyError, WbcError):
        return None
    return {"away": float(b["away_ns"]), "forward": float(b["forward_in_time_ns"]),
            "backward": float(b["backward_in_time_ns"]),
            "toward": float(b["toward_in_time_ns"])}  # fmt: skip


def largest_push(
    rec: Recording,
    robot: Robot,
    direction: Sequence[float] | str,
    max_impulse: float = PUSH_MAX_NS,
    steps: int = PUSH_STEPS,
    settle: float = 1.0,
    compensate: float = 0.0,
    gyro: float = 0.0,
    closed: ClosedLoopSpec | None = None,
    correct: bool = False,
    offset: float = 0.0,
) -> float | None:
    """Largest impulse (N·s) along ``direction`` at mid single support (``offset`` s later)
    that the run survives (bisection over [0, max_impulse] in ``steps`` halvings); None if
    it falls unpushed."""
    t_push = mid_single_support(rec)
    if t_push is None:
        return None
    t_push += offset
    if isinstance(direction, str):
        direction = push_direction(rec, direction)
    u = np.asarray(direction, dtype=float) / np.linalg.norm(direction)

    def survives(impulse: float) -> bool:
        force = u * impulse / PUSH_DURATION
        push = (t_push, force, PUSH_DURATION)
        run = simulate(rec, robot, push=push, settle=settle, compensate=compensate, gyro=gyro,
                       closed=closed, correct=correct)  # fmt: skip
        return not run["fell"]

    if not survives(0.0):
        return None
    lo, hi = 0.0, max_impulse
    if survives(hi):
        return hi
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if survives(mid) else (lo, mid)
    return lo
