"""Errors and timings of one run, measured from forward kinematics of the recorded joints.

Nothing here reads a solver's own residuals: the CoM and soles are recomputed from the
configurations the solver returned (the control loop stores them), and compared with the
references.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..model import Robot
from ..recording import SUPPORT_DOUBLE, Recording

#: the keys every benchmark record has (more may follow)
KEYS = (
    "solver", "family", "trajectory", "mode", "com_err_max_mm", "com_err_mean_mm",
    "foot_err_max_mm", "foot_err_mean_mm", "limit_violations", "limit_violation_max_rad",
    "penetration_max_mm", "com_margin_min_mm", "time_median_us", "time_p99_us", "failures",
)  # fmt: skip
LIMIT_TOL = 1e-9  # rad: below this an excess is floating-point noise, not a violation


def _orientation_errors(sole: np.ndarray, ref: np.ndarray) -> np.ndarray:
    out = np.zeros(len(sole))
    for i, (a, b) in enumerate(zip(sole, ref, strict=True)):
        Ra = pin.Quaternion(a[6], a[3], a[4], a[5]).toRotationMatrix()
        Rb = pin.Quaternion(b[6], b[3], b[4], b[5]).toRotationMatrix()
        out[i] = np.linalg.norm(pin.log3(Rb @ Ra.T))
    return out


def compute(rec: Recording, robot: Robot) -> dict[str, Any]:
    """The benchmark record of one run (see :data:`KEYS`)."""
    com_err = np.linalg.norm(rec["com"] - rec["com_ref"], axis=1) * 1e3
    foot_err = np.linalg.norm(rec["swing"] - rec["swing_ref"], axis=1) * 1e3
    left = rec["swing_is_left"]
    swing = np.where(left[:, None], rec["l_sole"], rec["r_sole"])
    swing_ref = np.where(left[:, None], rec["l_sole_ref"], rec["r_sole_ref"])
    ori = np.degrees(_orientation_errors(swing, swing_ref))
    joints = rec.q[:, 7:]
    excess = np.maximum(robot.q_min - joints, 0.0) + np.maximum(joints - robot.q_max, 0.0)
    single = rec["support"] != SUPPORT_DOUBLE
    lowest = rec["swing_lowest"][single] if single.any() else np.zeros(1)
    times = rec["solve_time"] * 1e6
    record: dict[str, Any] = {
        "solver": rec.meta.get("controller", "?"),
        "family": rec.meta.get("family", "?"),
        "trajectory": rec.meta.get("trajectory", "?"),
        "mode": rec.meta.get("mode", "?"),
        "com_err_max_mm": float(com_err.max()),
        "com_err_mean_mm": float(com_err.mean()),
        "foot_err_max_mm": float(foot_err.max()),
        "foot_err_mean_mm": float(foot_err.mean()),
        "limit_violations": int(np.count_nonzero(excess > LIMIT_TOL)),
        "limit_violation_max_rad": float(excess.max()),
        "penetration_max_mm": float(max(0.0, -lowest.min()) * 1e3),
        "com_margin_min_mm": float(rec["com_margin"].min() * 1e3),
        "time_median_us": float(np.median(times)),
        "time_p99_us": float(np.percentile(times, 99)),
        "failures": int(np.count_nonzero(rec["failed"])),
        "foot_ori_err_max_deg": float(ori.max()),
        "foot_ori_err_mean_deg": float(ori.mean()),
        "zmp_margin_min_mm": float(rec["zmp_margin"].min() * 1e3),
        "iterations_mean": float(np.mean(rec["iterations"])),
        "ticks": len(rec),
    }
    return record
