"""The figures of one simulated run against its plan (the physics benchmark's record):
:func:`physics_record` (see :mod:`wbc.bench.physics`), :func:`simulated_recording` (the
simulated run as a recording beside the plan), :func:`mid_single_support` (when pushes land).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..model import Robot
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_NAMES, SUPPORT_RIGHT, Recording
from ..sim.watch import FALL_HEIGHT, FALL_TILT_DEG

#: record key -> (description, unit)
PHYSICS_KEYS: dict[str, tuple[str, str]] = {
    "fell": ("fell", ""),
    "fall_time_s": ("fell at", "s"),
    "fall_phase": ("support phase at the fall", ""),
    "fall_joint": ("most loaded joint before the fall", ""),
    "orientation_dev_max_deg": ("max base orientation deviation from plan", "deg"),
    "torso_ref_dev_max_deg": ("max torso deviation from the reference's orientation", "deg"),
    "distance_ratio": ("travelled / planned distance", ""),
    "foot_slip_max_mm": ("max foot slip while in support", "mm"),
    "tracking_err_max_deg": ("max joint tracking error", "deg"),
    "tracking_joint": ("joint of the max tracking error", ""),
    "tracking_err_rms_deg": ("RMS joint tracking error over the playback", "deg"),
    "torque_peak_ratio": ("peak servo torque / stall", ""),
    "torque_joint": ("joint of the peak torque", ""),
    "cop_margin_min_mm": ("min real CoP margin in single support", "mm"),
    "swing_lift_max_mm": ("max lift of the planned swing sole in single support", "mm"),
    "swing_unloaded_share": ("share of single support with the swing sole unloaded", ""),
    "deploy_completed": ("deployment completed (no safe stop)", ""),
}


def _planned(rec: Recording, t: np.ndarray) -> np.ndarray:
    """Planned configurations at times ``t`` (s from the recording's start; clamped)."""
    t_rec = rec.t - rec.t[0]
    tc = np.clip(t, t_rec[0], t_rec[-1])
    q = np.stack([np.interp(tc, t_rec, rec.q[:, j]) for j in range(rec.q.shape[1])], axis=1)
    q[:, 3:7] /= np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    return q


def plan_time(result) -> np.ndarray:
    """The plan's time (s from its start) at each of ``result``'s log samples: the log's time
    since the playback start, or where a closed loop's walk ran off its reference's clock (a
    held lift-off, a slowed clock: :attr:`~wbc.sim.log.PlayResult.played`) the reference
    time it played there (past the walk's last tick: shifted by its last delay)."""
    t = result.log["t"] - result.playback_start
    played = getattr(result, "played", None)
    if played is None:
        return t
    tp = np.interp(t, played[0], played[1])
    return np.where(t > played[0, -1], t - (played[0, -1] - played[1, -1]), tp)


def _rotation(quat_xyzw: np.ndarray) -> np.ndarray:
    return pin.Quaternion(np.asarray(quat_xyzw)).toRotationMatrix()


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0))))


def physics_record(rec: Recording, result, robot: Robot, ref=None) -> dict[str, Any]:
    """The physics figures of one simulated run (see the module docstring); with the walking
    reference ``ref``, also ``torso_ref_dev_max_deg``: the largest angle between the real
    torso and the torso orientation the reference asks for (the plan may deviate from it)."""
    log = result.log
    t = log["t"] - result.playback_start
    q_real = log["q"]
    tp = plan_time(result)
    q_plan = _planned(rec, tp)
    n = len(t)
    dev = np.array([_angle(_rotation(q_plan[k, 3:7]), _rotation(q_real[k, 3:7])) for k in range(n)])
    low = q_real[:, 2] < FALL_HEIGHT * q_plan[:, 2]
    fallen = (dev > FALL_TILT_DEG) | low
    fall_k = int(np.argmax(fallen)) if np.any(fallen) else None
    upto = n if fall_k is None else fall_k
    rec_t = rec.t - rec.t[0]
    support = rec.channels.get("support")
    sup = (
        support[np.clip(np.searchsorted(rec_t, tp, side="right") - 1, 0, len(rec_t) - 1)]
        if support is not None
        else np.zeros(n, int)
    )
    names = robot.joint_names
    stall = result.sim.servo_params.stall_torque
    record: dict[str, Any] = {"fell": fall_k is not None}
    record["fall_time_s"] = float(t[fall_k]) if fall_k is not None else None
    if fall_k is not None:
        record["fall_phase"] = SUPPORT_NAMES.get(int(sup[fall_k]), "?")
        window = (t > t[fall_k] - 0.5) & (t <= t[fall_k])
        load = log["peak_torque"][window].max(axis=0) / stall
        j = int(np.argmax(load))
        record["fall_joint"] = f"{names[j]} ({load[j]:.2f} stall)"
    else:
        record["fall_phase"] = record["fall_joint"] = None
    record["orientation_dev_max_deg"] = float(dev[:upto].max()) if upto else 0.0
    if ref is not None:
        from ..geometry import heading_free

        start = pin.XYZQUATToSE3(rec.q[0, :7]).rotation  # the base is the torso
        wanted = ref.torso_rotations(heading_free(start))
        k_ref = np.clip(np.round((tp + rec.t[0] - ref.t[0]) / ref.dt).astype(int), 0, ref.n - 1)
        played = np.arange(n) < upto
        rdev = [_angle(wanted[k_ref[k]], _rotation(q_real[k, 3:7])) for k in np.flatnonzero(played)]
        record["torso_ref_dev_max_deg"] = float(max(rdev)) if rdev else 0.0
    # distance along the planned displacement of the base (playback part only)
    play_end = min(upto, int(np.searchsorted(tp, rec_t[-1], side="right")))
    d_plan = q_plan[play_end - 1, :2] - q_plan[0, :2] if play_end else np.zeros(2)
    planned = float(np.linalg.norm(d_plan))
    if planned > 0.01 and play_end and fall_k is None:  # none if it fell: not travel
        moved = (q_real[play_end - 1, :2] - q_real[0, :2]) @ d_plan / planned
        record["distance_ratio"] = float(moved / planned)
    else:
        record["distance_ratio"] = None
    record["planned_distance_mm"] = planned * 1e3
    # foot slip: a sole's horizontal travel while planned in support and carrying load
    weight = robot.total_mass * 9.81
    slip = 0.0
    for side, code in ((0, SUPPORT_LEFT), (1, SUPPORT_RIGHT)):
        planned_support = (sup == SUPPORT_DOUBLE) | (sup == code)
        loaded = log["sole_force"][:, side] > 0.05 * weight
        on = planned_support & loaded
        on[upto:] = False
        anchor = None
        for k in range(n):
            if on[k]:
                if anchor is None:
                    anchor = log["soles"][k, side, :2]
                slip = max(slip, float(np.linalg.norm(log["soles"][k, side, :2] - anchor)))
            else:
                anchor = None
    record["foot_slip_max_mm"] = slip * 1e3
    err = np.abs(q_real[:upto, 7:] - q_plan[:upto, 7:]) if upto else np.zeros((1, len(names)))
    j = int(np.argmax(err.max(axis=0)))
    record["tracking_err_max_deg"] = float(np.degrees(err.max()))
    record["tracking_joint"] = names[j]
    played = (t >= 0) & (t <= rec_t[-1]) & (np.arange(n) < upto)
    sq = (q_real[played, 7:] - q_plan[played, 7:]) ** 2
    record["tracking_err_rms_deg"] = float(np.degrees(np.sqrt(sq.mean()))) if sq.size else None
    peak = log["peak_torque"][:upto].max(axis=0) if upto else np.zeros(len(names))
    j = int(np.argmax(peak))
    record["torque_peak_ratio"] = float(peak[j] / stall)
    record["torque_joint"] = names[j]
    single = (sup != SUPPORT_DOUBLE) & (np.arange(n) < upto) & (t >= 0) & (t <= rec_t[-1])
    margins = log["cop_margin"][single]
    margins = margins[np.isfinite(margins)]
    record["cop_margin_min_mm"] = float(margins.min() * 1e3) if margins.size else None
    # the planned swing sole: how high it rises, how often it carries < 5 % of the weight
    swing = np.where(sup == SUPPORT_LEFT, 1, 0)  # right support: the left sole swings
    ks = np.flatnonzero(single)
    if ks.size:
        z = log["soles"][ks, swing[ks], 2] - log["soles"][0, swing[ks], 2]
        record["swing_lift_max_mm"] = float(z.max() * 1e3)
        force = log["sole_force"][ks, swing[ks]]
        record["swing_unloaded_share"] = float(np.mean(force < 0.05 * weight))
    else:
        record["swing_lift_max_mm"] = record["swing_unloaded_share"] = None
    record["deploy_completed"] = bool(result.deploy.completed)
    if not result.deploy.completed:
        record["deploy_trip"] = str(result.deploy.trip)
    record["sim_time_s"] = float(log["t"][-1]) if n else 0.0
    record["_series"] = {"t": t, "dev": dev}
    return record


def mid_single_support(rec: Recording) -> float | None:
    """Time (s from the start) of the middle of the recording's first single support."""
    support = rec.channels.get("support")
    if support is None:
        return None
    single = np.flatnonzero(np.asarray(support) != SUPPORT_DOUBLE)
    if not single.size:
        return None
    start = single[0]
    end = start
    while end + 1 < len(support) and support[end + 1] == support[start]:
        end += 1
    return float(0.5 * (rec.t[start] + rec.t[end]) - rec.t[0])


def simulated_recording(rec: Recording, result, robot: Robot) -> Recording:
    """The simulated run as a recording (real q, CoM and CoP beside the planned ones)."""
    log = result.log
    t = log["t"] - result.playback_start
    keep = np.r_[True, np.diff(t) > 1e-9]
    t, q = t[keep], log["q"][keep]
    rec_t = rec.t - rec.t[0]
    tc = np.clip(t, rec_t[0], rec_t[-1])
    channels = {"com": log["com"][keep], "zmp": log["cop"][keep]}
    for name, src in (("com_ref", "com"), ("zmp_ref", "zmp"), ("swing_ref", "swing")):
        if src in rec.channels:
            ref = np.asarray(rec.channels[src], dtype=float)
            channels[name] = np.stack(
                [np.interp(tc, rec_t, ref[:, j]) for j in range(ref.shape[1])], axis=1
            )
    if "swing_is_left" in rec.channels:  # the real sole of the planned swing side
        k = np.clip(np.searchsorted(rec_t, tc, side="right") - 1, 0, len(rec_t) - 1)
        left = np.asarray(rec["swing_is_left"], dtype=bool)[k]
        soles = log["soles"][keep]
        channels["swing"] = np.where(left[:, None], soles[:, 0], soles[:, 1])
    if "support" in rec.channels:
        k = np.clip(np.searchsorted(rec_t, tc, side="right") - 1, 0, len(rec_t) - 1)
        channels["support"] = np.asarray(rec["support"])[k]
    meta = dict(rec.meta, simulated=True)
    return Recording(t - t[0], q, robot.joint_names, channels, meta)
