"""Benchmarks of the thesis's baselines: Tables 3.3.2/3.3.3 and the ch. 4 walking step.

Both return plain rows (``list[dict]``) so that a CLI or a report can print them:

* :func:`run_com_placement_benchmark` — CoM error (mm) and time (ms) for each method of ch. 3
  and each (λ, α) of Table 3.3.1, next to the thesis's numbers;
* :func:`run_walking_benchmark` — the six schemes of ch. 4 on a 100-pose step
  (:func:`thesis_like_step`): CoM / swing-foot error maxima and time per pose.

The thesis does not give its CoM target nor its step's numbers; ours are documented in
:func:`~wbc.pinv.com_placement.default_com_target` and :func:`thesis_like_step`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from ..exceptions import SolverError, TrajectoryError
from ..model import Robot
from .com_placement import METHODS, ComPlacement, default_com_target
from .schemes import SCHEME_NAMES, ThesisScheme
from .thesis_data import TABLE_3_3_1, TABLE_3_3_2, TABLE_3_3_3, THESIS_WALKING

__all__ = [
    "StepReference",
    "run_com_placement_benchmark",
    "run_walking_benchmark",
    "settled_start",
    "thesis_like_step",
    "track_step",
]


# ---------------------------------------------------------------------------- ch. 3
def run_com_placement_benchmark(
    robot: Robot,
    q0: np.ndarray | None = None,
    com_target: np.ndarray | None = None,
    methods: Sequence[str] = METHODS,
    settings: Sequence[str] = tuple(TABLE_3_3_1),
    repeats: int = 3,
    support: str = "l_sole",
    swing: str = "r_sole",
    **options,
) -> list[dict]:
    """Every method x setting from ``q0`` (default walk_ready) to ``com_target`` (default:
    over the support sole). Time is the best of ``repeats`` runs (ms); ``options`` go to
    :class:`~wbc.pinv.com_placement.ComPlacement` (tol, max_iterations, length_scale, ...).
    """
    q0 = robot.configuration("stand") if q0 is None else q0
    target = default_com_target(robot, q0, support) if com_target is None else com_target
    placement = ComPlacement(robot, support, swing, **options)
    rows = []
    for method in methods:
        for setting in settings:
            lam, alpha = TABLE_3_3_1[setting]
            best = None
            for _ in range(max(1, repeats)):
                res = placement.solve(q0, target, method, lam, alpha)
                best = res if best is None or res.time < best.time else best
            col = int(setting.removeprefix("sim")) - 1
            rows.append({
                "method": method.upper(), "setting": setting, "damping": lam, "gain": alpha,
                "com_error_mm": best.com_error * 1e3, "time_ms": best.time * 1e3,
                "iterations": best.iterations, "outer_iterations": best.outer_iterations,
                "converged": best.converged,
                "joint_limit_excess_deg": float(np.degrees(best.joint_limit_excess)),
                "swing_sole_height_mm": best.swing_sole_height * 1e3,
                "thesis_com_error_mm": TABLE_3_3_2[method.upper()][col],
                "thesis_time_ms": TABLE_3_3_3[method.upper()][col],
            })  # fmt: skip
    return rows


# ---------------------------------------------------------------------------- ch. 4
@dataclass(frozen=True)
class StepReference:
    """Per-pose targets of one step: CoM (N, 3), swing sole (N, 3), phase (N,) bool swing."""

    com: np.ndarray
    swing: np.ndarray
    swinging: np.ndarray

    def __len__(self) -> int:
        return len(self.com)


def thesis_like_step(
    robot: Robot,
    q0: np.ndarray,
    support: str = "l_sole",
    swing: str = "r_sole",
    n_poses: int = 100,
    step_length: float = 0.04,
    step_height: float = 0.02,
    shift_poses: int | None = None,
    lift_pose: int | None = None,
) -> StepReference:
    """A step shaped like the thesis's (sec. 4.3.1), with clamped cubic splines (sec. 4.1.1).

    Poses 1..``shift_poses``: double support, the CoM moves (height constant) from its start
    to over the support sole's origin; it then stays there (statically stable). From pose
    ``lift_pose`` the swing sole follows a spline through its start, an apex ``step_height``
    above the midpoint and the end ``step_length`` ahead (+x), which it reaches at the last
    pose. The thesis gives no lengths; 40 mm x 20 mm is a small Bioloid step. By default
    ``shift_poses`` = 30 % and ``lift_pose`` = 40 % of ``n_poses`` (30 and 40 of 100).
    """
    shift_poses = round(0.3 * n_poses) if shift_poses is None else shift_poses
    lift_pose = round(0.4 * n_poses) if lift_pose is None else lift_pose
    if not (2 <= shift_poses < lift_pose < n_poses - 2):
        raise TrajectoryError(
            f"need 2 <= shift_poses < lift_pose < n_poses - 2, got {shift_poses}, {lift_pose}, "
            f"{n_poses}"
        )
    c0 = robot.com(q0)
    s0 = robot.frame_placement(q0, support).translation
    f0 = robot.frame_placement(q0, swing).translation.copy()
    c1 = np.array([s0[0], s0[1], c0[2]])
    i = np.arange(n_poses, dtype=float)
    com = np.tile(c1, (n_poses, 1))
    shift = CubicSpline([0.0, shift_poses - 1.0], np.vstack([c0, c1]), bc_type="clamped")
    com[:shift_poses] = shift(i[:shift_poses])
    apex = f0 + np.array([step_length / 2, 0.0, step_height])
    end = f0 + np.array([step_length, 0.0, 0.0])
    t0, t1 = lift_pose - 1.0, n_poses - 1.0
    foot_spline = CubicSpline(
        [t0, 0.5 * (t0 + t1), t1], np.vstack([f0, apex, end]), bc_type="clamped"
    )
    foot = np.tile(f0, (n_poses, 1))
    foot[lift_pose - 1 :] = foot_spline(i[lift_pose - 1 :])
    return StepReference(com, foot, i >= lift_pose - 1)


def track_step(
    scheme: ThesisScheme,
    q0: np.ndarray,
    reference: StepReference,
    tol: float = 1e-5,
    max_iterations: int = 200,
) -> dict[str, np.ndarray]:
    """Solve every pose of ``reference`` in turn from ``q0``; per-pose arrays of the results."""
    robot = scheme.robot
    scheme.reset(q0)
    q = q0.copy()
    n = len(reference)
    out = {
        k: np.zeros(n)
        for k in (
            "com_error",
            "foot_error",
            "primary_error",
            "time",
            "iterations",
            "converged",
            "swing_height",
            "limit_excess",
        )
    }
    out["q"] = np.zeros((n, robot.nq))
    sw, sp = robot.frame_id(scheme.swing), robot.frame_id(scheme.support)
    for k in range(n):
        scheme.set_targets(reference.com[k], reference.swing[k])
        q, info = scheme.solve_pose(q, tol, max_iterations)
        kin = scheme.root.kin
        out["q"][k] = q
        out["com_error"][k] = info.com_error
        out["foot_error"][k] = info.foot_error
        # largest |error| of the primary tasks (m for positions, 1 − cos for orientations)
        out["primary_error"][k] = max(
            float(np.max(np.abs(info.errors[name]))) for name in scheme.primary
        )
        out["time"][k] = info.time
        out["iterations"][k] = info.iterations
        out["converged"][k] = info.converged
        out["swing_height"][k] = kin.placement(sw).translation[2] - kin.placement(sp).translation[2]
        out["limit_excess"][k] = info.joint_limit_excess
    return out


def settled_start(
    robot: Robot, q: np.ndarray, support: str = "l_sole", swing: str = "r_sole"
) -> np.ndarray:
    """A start pose that satisfies every walking task: q with the torso made upright and the
    swing sole flat, CoM and swing sole kept where they are.

    Walk Ready leans the torso ~10° forward, so the thesis's torso task (4.4) is far from
    zero at pose 1 on our model. This runs VAT almost undamped (λ = 1e-9, α = 1: Newton
    steps, not the thesis's setting) until every error is below 1e-9.
    """
    vat = ThesisScheme(robot, "vat", support, swing, damping=1e-9, gain=1.0)
    vat.reset(q)
    q_settled, info = vat.solve_pose(q, 1e-9, 500, orientation_tol=1e-9)
    if not info.converged:
        raise SolverError(f"could not settle the start pose (errors {info.errors})")
    return q_settled


def run_walking_benchmark(
    robot: Robot,
    schemes: Sequence[str] = SCHEME_NAMES,
    q0: np.ndarray | None = None,
    n_poses: int = 100,
    tol: float = 1e-5,
    max_iterations: int = 200,
    settle: bool = True,
    **scheme_options,
) -> list[dict]:
    """Each scheme on :func:`thesis_like_step` from ``q0`` (default walk_ready, made to
    satisfy every task first by :func:`settled_start` unless ``settle`` is False)."""
    q0 = robot.configuration("stand") if q0 is None else q0
    if settle:
        q0 = settled_start(robot, q0)
    reference = thesis_like_step(robot, q0, n_poses=n_poses)
    rows = []
    for name in schemes:
        scheme = ThesisScheme.make(name, robot, **scheme_options)
        start = time.perf_counter()
        r = track_step(scheme, q0, reference, tol, max_iterations)
        total = time.perf_counter() - start
        thesis = THESIS_WALKING[name]
        rows.append({
            "scheme": name, "poses": n_poses,
            "com_max_mm": 1e3 * r["com_error"].max(), "com_mean_mm": 1e3 * r["com_error"].mean(),
            "foot_max_mm": 1e3 * r["foot_error"].max(),
            "foot_mean_mm": 1e3 * r["foot_error"].mean(),
            "primary_max": float(r["primary_error"].max()),
            "ms_per_pose": 1e3 * r["time"].mean(), "ms_per_pose_max": 1e3 * r["time"].max(),
            "iterations_mean": float(r["iterations"].mean()),
            "unconverged_poses": int(n_poses - r["converged"].sum()),
            "swing_min_height_mm": 1e3 * r["swing_height"].min(),
            "joint_limit_excess_deg": float(np.degrees(r["limit_excess"].max())),
            "total_s": total,
            "thesis_com_max_mm": thesis["com_max_mm"],
            "thesis_foot_max_mm": thesis["foot_max_mm"],
            "thesis_ms_per_pose": thesis["ms_per_pose"],
        })  # fmt: skip
    return rows
