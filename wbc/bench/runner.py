"""Run solvers on trajectories and collect benchmark records."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..model import Kinematics, Robot
from ..recording import Recording
from ..solvers import HierarchicalQP, TaskStack, WeightedQP
from ..solvers.backends import BACKENDS
from ..tasks import ComTask, ContactTask, DampingTask
from ..walking.loop import RunOptions, run
from ..walking.reference import WalkingReference
from . import metrics
from .solvers import SolverEntry


def run_entry(
    entry: SolverEntry,
    robot: Robot,
    ref: WalkingReference,
    mode: str,
    tol: float = 1e-6,
    max_iterations: int = 100,
    clock: str = "wall",
) -> tuple[dict[str, Any], Recording]:
    """One solver on one trajectory: its record (:data:`metrics.KEYS`) and recording; its
    ticks timed by ``clock`` (:data:`wbc.walking.clock.CLOCKS`), named in ``time_clock``."""
    controller = entry.make(robot)
    options = RunOptions(mode=mode, tol=tol, max_iterations=max_iterations, clock=clock)
    rec = run(controller, robot, ref, options=options)
    record = metrics.compute(rec, robot)
    record["time_clock"] = clock
    record["solver"], record["family"] = entry.name, entry.family
    # the task stack file (a peer's and the NLP's: the stack they read; None: a pinv scheme)
    record["stack"] = entry.stack if entry.stack is not None else getattr(controller, "stack", None)
    record["gait"] = ref.gait  # static: the CoM margin is the balance figure; dynamic: the ZMP's
    rec.meta.update(solver=entry.name, family=entry.family)
    return record, rec


def save_recording(rec: Recording, folder: Path, solver: str, trajectory: str) -> Path:
    """``<folder>/<solver>__<trajectory>.npz``."""
    return rec.save(Path(folder) / f"{solver}__{trajectory}.npz")


# ---------------------------------------------------------------------------- ch. 3 set
def static_com_records(
    robot: Robot,
    families: set[str],
    repeats: int = 3,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """The static CoM placement set of ch. 3: from Walk Ready, put the CoM over the left sole.

    The thesis's five methods run on its six (λ, α) settings; the QP families solve the same
    placement to convergence (left sole held by a hard contact, the CoM task, light damping).
    Errors are measured from forward kinematics; times are the best of ``repeats`` on the wall
    clock (``time_clock``: the best of several leaves the preemptions out).
    """
    from ..pinv import default_com_target, run_com_placement_benchmark

    q0 = robot.configuration("stand")
    target = default_com_target(robot, q0, "l_sole")
    rows: list[dict[str, Any]] = []
    if "pinv" in families:
        if progress:
            progress("pinv CoM placement (5 methods x 6 settings)")
        for r in run_com_placement_benchmark(robot, q0, target, repeats=repeats):
            rows.append({
                "solver": f"pinv-{r['method'].lower()}-{r['setting']}", "family": "pinv",
                "trajectory": "static_com", "mode": "converge",
                "com_err_max_mm": r["com_error_mm"], "com_err_mean_mm": r["com_error_mm"],
                "time_median_us": r["time_ms"] * 1e3, "time_clock": "wall",
                "iterations_mean": r["iterations"],
                "limit_violation_max_rad": float(np.radians(r["joint_limit_excess_deg"])),
                "converged": bool(r["converged"]),
                "thesis_com_err_mm": r["thesis_com_error_mm"],
                "thesis_time_ms": r["thesis_time_ms"],
            })  # fmt: skip
    qp_families = {"qp-weighted": WeightedQP, "qp-hierarchical": HierarchicalQP}
    for family, cls in qp_families.items():
        if family not in families:
            continue
        for backend in BACKENDS:
            if progress:
                progress(f"{family} {backend} CoM placement")
            best = None
            for _ in range(max(1, repeats)):
                stack = TaskStack(robot, velocity_limits=False)
                kin = Kinematics(robot, q0)
                stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
                stack.add(ComTask(robot, target), level=1)
                # damping (not a posture target): it vanishes at the fixed point, no bias
                stack.add(DampingTask(robot, weight=1e-4), level=2)
                start = time.perf_counter()
                result = cls(stack, backend).solve_pose(q0, tol=5e-7, max_iterations=200)
                elapsed = time.perf_counter() - start
                if best is None or elapsed < best[1]:
                    best = (result, elapsed)
            result, elapsed = best
            err = float(np.linalg.norm(robot.com(result.q) - target) * 1e3)
            excess = np.maximum(robot.q_min - result.q[7:], 0) + np.maximum(
                result.q[7:] - robot.q_max, 0
            )
            prefix = "wqp" if family == "qp-weighted" else "hqp"
            rows.append({
                "solver": f"{prefix}-{backend}", "family": family, "trajectory": "static_com",
                "mode": "converge", "com_err_max_mm": err, "com_err_mean_mm": err,
                "time_median_us": elapsed * 1e6, "time_clock": "wall",
                "iterations_mean": result.iterations,
                "limit_violation_max_rad": float(excess.max()), "converged": result.converged,
            })  # fmt: skip
    return rows
