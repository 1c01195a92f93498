"""The trajectories the benchmark runs every solver on."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields
from typing import Any

from ..exceptions import ConfigurationError, TrajectoryError
from ..model import Robot
from ..walking.gait import forward_walk, lateral_walk, turning_walk
from ..walking.geometry import Foot
from ..walking.keyposes import KeyPoseParams, keypose_walk
from ..walking.legs import LegGeometry
from ..walking.preview import PreviewParams
from ..walking.reference import StandingState, WalkingReference
from ..walking.schedule import GaitTiming, SwingParams
from ..walking.sizing import ACROSS, ALONG, PAIRS, TIMES, sized
from ..walking.static_walk import StaticWalkParams, static_walk
from ..walking.thesis_step import ThesisStepParams, thesis_step
from ..walking.window import MAX_LEAN, BalanceWindow


def _thesis_step(
    s: StandingState, foot=None, legs=None, min_clearance: float = 0.005, **params: Any
) -> WalkingReference:
    return thesis_step(s, ThesisStepParams(**params), foot, legs, min_clearance)


def _static_walk(
    s: StandingState, window: BalanceWindow, foot=None, legs=None, **params: Any
) -> WalkingReference:
    return static_walk(s, window, StaticWalkParams(**params), foot, legs)


def _keyposes(
    s: StandingState, foot=None, legs=None, min_clearance: float = 0.004, **params: Any
) -> WalkingReference:
    return keypose_walk(s, KeyPoseParams(**params), foot, legs, min_clearance)


#: the dynamic whole-body walks' ZMP: 18 mm in from each sole's centre, >= 10 mm inside
WHOLE_BODY_DYNAMIC: dict[str, Any] = {"zmp_offset": (0.0, 0.018), "margin": 0.010}
#: the whole-body walks' swing: a 12 mm apex
WHOLE_BODY_SWING = SwingParams(apex=0.012)
#: the new walks' timing: 0.5 s steps (0.4 s single support), 12 mm swing apex, so that the
#: reference asks no joint for more than PLANNING_SPEED_FRACTION of the servo's no-load
#: speed (walk10's 0.24 s swing with a 20 mm apex asks the swing knee for ~1.6x it)
WHOLE_BODY_TIMING: dict[str, Any] = {
    **WHOLE_BODY_DYNAMIC,
    "timing": GaitTiming(step_time=0.5, double_support_ratio=0.2),
    "swing": WHOLE_BODY_SWING,
}
#: walk10 with the whole-body window: walk10's footsteps and timing with the whole-body
#: walks' 12 mm apex. With walk10's 20 mm the swing knee is asked 1.63x the servo's no-load
#: speed (12 mm: 1.17x) and where the lagging swing foot lands depends on the lag: it landed
#: 6-9 mm beyond each footstep, 1.20 of the distance closed loop with the compliance
#: feed-forward x0.5; 12 mm: 1.04 (benchmarks/balance.md, "walk10_wb's travel")
WALK10_WB: dict[str, Any] = {"n_steps": 10, "swing": WHOLE_BODY_SWING}
#: the fast walk: 16 steps of 4 cm in 0.5 s (8 cm/s steady, 6.2 cm/s start to stop)
FAST: dict[str, Any] = {"n_steps": 16, "step_length": 0.04}
#: the turning walk: 8 steps of 2 cm turning 0.2 rad each (80 deg); the lateral walk: 8 steps
#: of 1.5 cm to the left; both with a 15 mm apex (the 12 mm one scuffs more in the simulator;
#: 2 cm lateral steps with it ask the knee for 0.77 of the no-load speed). With 1.8 cm lateral
#: steps the leading foot landed ~5 mm short and unloaded, the closed loop covering 0.89-0.90
#: of the plan at 2.9-3.1 deg (benchmarks/balance.md); 1.5 cm: 0.90-0.94, 2.8-2.9 deg
TURN: dict[str, Any] = {
    "n_steps": 8,
    "step_length": 0.02,
    "turn": 0.2,
    "swing": SwingParams(apex=0.015),
}
LATERAL: dict[str, Any] = {"n_steps": 8, "step_width": 0.015, "swing": SwingParams(apex=0.015)}

#: name -> (builder, description); a builder takes the start state and keyword overrides
TRAJECTORIES: dict[str, tuple[Callable[..., WalkingReference], str]] = {
    "thesis_step": (_thesis_step, "the thesis's one step: 100 poses, cubic splines"),
    "walk10": (lambda s, **kw: forward_walk(s, n_steps=10, **kw), "10 steps forward, ZMP preview"),
    "turn": (lambda s, **kw: turning_walk(s, **kw), "a turning walk, ZMP preview control"),
    "lateral": (lambda s, **kw: lateral_walk(s, **kw), "sideways steps, ZMP preview control"),
    "keyposes": (_keyposes, "the Kokone thesis's static key-pose walk: 12 poses, 0.8 s each"),
    # whole-body references: the torso leans over the stance foot (balance window)
    "static_walk": (_static_walk, "recommended static walk: whole body, CoM >= 15 mm in the sole"),
    "walk10_wb": (
        lambda s, **kw: forward_walk(s, **{**WHOLE_BODY_DYNAMIC, **WALK10_WB, **kw}),
        "walk10's steps with the whole-body window (ZMP >= 10 mm inside the soles), 12 mm apex",
    ),
    "fast_wb": (
        lambda s, **kw: forward_walk(s, **{**WHOLE_BODY_TIMING, **FAST, **kw}),
        "fast forward walk (6.2 cm/s), whole body, within the servos' speed",
    ),
    "turn_wb": (
        lambda s, **kw: turning_walk(s, **{**WHOLE_BODY_TIMING, **TURN, **kw}),
        "turning walk (80 deg), whole body, within the servos' speed",
    ),
    "lateral_wb": (
        lambda s, **kw: lateral_walk(s, **{**WHOLE_BODY_TIMING, **LATERAL, **kw}),
        "sideways walk (12 cm), whole body, within the servos' speed",
    ),
}
#: the trajectories that use the whole-body balance window (built per robot)
WHOLE_BODY = ("static_walk", "walk10_wb", "fast_wb", "turn_wb", "lateral_wb")
#: keyword overrides given as TOML tables, turned into their dataclasses
_TABLES = {"timing": GaitTiming, "swing": SwingParams}
#: the static CoM placement set of ch. 3 (not a walking reference: see wbc.bench.runner)
STATIC_COM = "static_com"
DEFAULT = ("thesis_step", "walk10")


#: the sized settings of each trajectory: the values its builder uses by default (what a
#: robot's dimensions scale, :func:`wbc.walking.sizing.sized`)
def default_options(name: str) -> dict[str, Any]:
    """The defaults of trajectory ``name`` that are sized to the robot (empty if none)."""
    walk = {
        "preview": PreviewParams(),
        "margin": 0.001,
        "zmp_offset": (0.0, 0.0285),
        "min_clearance": 0.005,
        "timing": GaitTiming(),
        "swing": SwingParams(),
    }
    table: dict[str, dict[str, Any]] = {
        "thesis_step": {**_params(ThesisStepParams()), "min_clearance": 0.005},
        "keyposes": {**_params(KeyPoseParams()), "min_clearance": 0.004},
        "static_walk": _params(StaticWalkParams()),
        "walk10": {**walk, "step_length": 0.035},
        "turn": {**walk, "step_length": 0.02, "turn": 0.2},
        "lateral": {**walk, "step_width": 0.02},
        "walk10_wb": {**walk, "step_length": 0.035, **WHOLE_BODY_DYNAMIC, **WALK10_WB},
        "fast_wb": {**walk, **WHOLE_BODY_TIMING, **FAST},
        "turn_wb": {**walk, **WHOLE_BODY_TIMING, **TURN},
        "lateral_wb": {**walk, **WHOLE_BODY_TIMING, **LATERAL},
    }
    return dict(table.get(name, {}))


def _params(p: Any) -> dict[str, Any]:
    keys = (*ALONG, *ACROSS, *PAIRS, *TIMES)
    return {f.name: getattr(p, f.name) for f in fields(p) if f.name in keys}


def names() -> list[str]:
    return [*TRAJECTORIES, STATIC_COM]


def robot_options(robot: Robot, name: str) -> dict[str, Any]:
    """The robot's walking data for trajectory ``name``: its feet, its legs, the whole-body
    balance window (:data:`WHOLE_BODY` trajectories; ``max_lean`` in rad may be set in
    ``[walking.<name>]``) and the keyword overrides of ``robot.toml``'s ``[walking.<name>]``.

    The legs are measured from the model at the standing pose (``robot.toml`` ``[legs]`` may
    state them: the Bioloid's states the rounded values its figures were recorded with)."""
    data = robot.robot_data
    legs = LegGeometry.from_robot(robot, robot.configuration("stand"))
    kw: dict[str, Any] = {"foot": Foot(*robot.foot_size), "legs": legs}
    table = dict(data.walking.get(name, {}))
    if name in WHOLE_BODY:
        max_lean = table.pop("max_lean", MAX_LEAN)
        try:
            kw["window"] = BalanceWindow.from_robot(
                robot, robot.configuration("stand"), max_lean=float(max_lean)
            )
        except (TypeError, ValueError, TrajectoryError) as exc:
            raise ConfigurationError(f"{data.source}: [walking.{name}] max_lean: {exc}") from None
    for key, value in table.items():
        if key in _TABLES:
            try:
                value = _TABLES[key](**value)
            except TypeError as exc:
                raise ConfigurationError(f"{data.source}: [walking.{name}.{key}]: {exc}") from None
        kw[key] = tuple(value) if isinstance(value, list) else value
    return kw


def build(
    name: str, robot: Robot, walking_only: bool = False, on_servos: bool = False
) -> WalkingReference:
    """A walking reference by name, starting from the robot's standing pose, its settings
    sized to the robot (:mod:`wbc.walking.sizing`; ``robot.toml`` ``[walking.<name>]`` on top).

    ``walking_only``: the caller cannot run :data:`STATIC_COM` (a benchmark set, not a
    walking reference); the message then lists only the walking references.

    ``on_servos``: the walk is played on servos (the simulator, the robot: ``wbc sim``,
    ``wbc bench --physics``, ``wbc deploy``, the closed loop, and ``wbc walk``, whose
    recording ``wbc deploy`` plays): its speed is always fitted
    (:data:`wbc.walking.sizing.SPEED_FRACTION` of the servos' no-load speed), whatever the
    robot's ``[walking] fit_speed``; only the walk's own ``[walking.<name>] fit_speed =
    false`` keeps it unfitted. False (the kinematic benchmark, ``wbc bench``): the robot's
    setting (the Bioloid's false: the thesis's walks as recorded).
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
    kw = robot_options(robot, name)
    flags = {}
    for key in ("fit_speed", "fit_torque"):
        robots = True if on_servos and key == "fit_speed" else getattr(robot.robot_data, key)
        flags[key] = kw.pop(key, robots)
        if not isinstance(flags[key], bool):
            raise ConfigurationError(
                f"{robot.robot_data.source}: [walking.{name}] {key} = {flags[key]!r}: true or false"
            )
    fixed = {k: kw.pop(k) for k in ("foot", "legs", "window") if k in kw}
    start = StandingState.from_robot(robot, robot.configuration("stand"))
    legs = fixed["legs"]

    def make(options: dict[str, Any]) -> WalkingReference:
        return builder(start, **fixed, **options)

    try:
        ref, _ = sized(
            robot,
            default_options(name),
            kw,
            legs.thigh + legs.shin,
            (fixed["foot"].length, fixed["foot"].width),
            make,
            **flags,
            gap=float(start.left.y - start.right.y) - fixed["foot"].width,
        )
    except TypeError as exc:  # an unknown key in [walking.<name>]
        raise ConfigurationError(f"{robot.robot_data.source}: [walking.{name}]: {exc}") from None
    ref.name = name
    return ref
