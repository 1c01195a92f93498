"""The legs of a walking reference: what they can reach and where the hips are for a given
CoM (:class:`LegGeometry`), used by the footstep plans, the gaits, the MPC and the checks."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import ModelError, TrajectoryError
from ..geometry import yaw_of
from ..roles import SOLE_FRAMES, leg_segments
from .geometry import rot2


@dataclass(frozen=True)
class LegGeometry:
    """What the legs can reach, and where the hips are for a given CoM.

    Pelvis model: the hips' midpoint is ``mid + pelvis_gain (c - mid) + hip_offset`` with
    ``mid`` the soles' midpoint and ``c`` the CoM (horizontal), ``hip_offset`` = (forward,
    up) in the heading frame (up measured from the CoM height). The pelvis moves further than
    the CoM because the legs' mass lags behind it: ``pelvis_gain`` > 1, measured by
    :meth:`from_robot` with the arms held (1.33 on the Bioloid; arms swinging help lower it).
    Reach: hip-to-ankle within ``[min_reach, thigh + shin - reach_margin]``.

    With the torso upright a leg's hip roll equals its lean in the frontal plane,
    ``atan2(lateral ankle-from-hip offset, hip height above the ankle)``. The Bioloid's hip
    roll allows only ``max_adduction`` = 5.57 deg toward the other leg (Annex A), so the
    pelvis can move only ~15 mm sideways from the mid-stance and the CoM ~11 mm: this, not
    the foot (whose inner edge is 11 mm from the mid-stance), bounds the lateral CoM motion.
    ``roll_margin`` is kept as a safety on the estimate.
    """

    #: measured on the robot (:meth:`from_robot`; ``robot.toml`` ``[legs]`` may state them):
    #: the thigh and shin (m), the hips' half spacing (m), the ankle axes' height above the
    #: sole (m), the hip offset (m), the pelvis gain, the shortest hip-to-ankle distance (m),
    #: the hip roll's range toward the other leg and away from it (rad)
    thigh: float
    shin: float
    hip_half_width: float
    ankle_height: float
    hip_offset: tuple[float, float]
    pelvis_gain: float
    min_reach: float
    max_adduction: float
    max_abduction: float
    #: safety margins on the reach (m) and on the hip roll (rad)
    reach_margin: float = 0.003
    roll_margin: float = 0.005

    @property
    def max_reach(self) -> float:
        return self.thigh + self.shin - self.reach_margin

    @classmethod
    def from_robot(cls, robot: Any, q: np.ndarray | None = None, **overrides: Any) -> LegGeometry:
        """Measure the leg from the model: link lengths at q = 0; hip roll limits; the pelvis
        gain and hip offset at ``q`` (default the standing pose; the pelvis is moved sideways
        with the soles fixed, torso and arms held); minimum reach at the knee's flexion limit.
        The joints are found by role (:attr:`wbc.model.Robot.roles`); ``robot.toml`` ``[legs]``
        states any field by hand, ``overrides`` replace both."""
        import pinocchio as pin

        model, data = robot.model, robot.data

        roles = robot.roles
        names = {
            "hip": roles.joint("left", "hip_pitch"),
            "knee": roles.joint("left", "knee"),
            "ankle": roles.joint("left", "ankle_pitch"),
            "right_hip": roles.joint("right", "hip_pitch"),
        }

        def joint_origins(qq: np.ndarray) -> dict[str, np.ndarray]:
            pin.forwardKinematics(model, data, qq)
            return {k: data.oMi[model.getJointId(n)].translation.copy() for k, n in names.items()}

        o = joint_origins(robot.neutral())
        thigh, shin = leg_segments(robot)
        half_width = 0.5 * float(abs(o["hip"][1] - o["right_hip"][1]))
        sole = robot.frame_placement(robot.neutral(), "l_sole").translation
        ankle_h = float(o["ankle"][2] - sole[2])
        # knee: interior angle at q = 0 plus the flexion range gives the closest hip-ankle
        # (the knee bends the way it is bent at the standing pose, else toward +)
        straight = np.linalg.norm(o["ankle"] - o["hip"])
        interior0 = np.arccos(
            np.clip((thigh**2 + shin**2 - straight**2) / (2 * thigh * shin), -1.0, 1.0)
        )
        k = robot.joint_index(names["knee"])
        qq = robot.configuration("stand") if q is None else q
        flex = float(robot.q_max[k] if qq[7 + k] >= 0 else -robot.q_min[k])
        interior = max(interior0 - flex, 0.0)
        min_reach = float(np.sqrt(thigh**2 + shin**2 - 2 * thigh * shin * np.cos(interior)))
        roll = {s: robot.joint_index(roles.joint(s, "hip_roll")) for s in ("left", "right")}
        # left: positive roll moves the foot outward (+y); right: inward
        max_add = min(-robot.q_min[roll["left"]], robot.q_max[roll["right"]])
        max_abd = min(robot.q_max[roll["left"]], -robot.q_min[roll["right"]])
        gain = _pelvis_gain(robot, qq)
        oq = joint_origins(qq)
        com = robot.com(qq)
        torso = robot.frame_placement(qq, "torso").rotation
        heading = yaw_of(torso)
        mid_soles = 0.5 * (
            robot.frame_placement(qq, "l_sole").translation[:2]
            + robot.frame_placement(qq, "r_sole").translation[:2]
        )
        pelvis = 0.5 * (oq["hip"] + oq["right_hip"])
        resid = pelvis[:2] - (mid_soles + gain * (com[:2] - mid_soles))
        fwd = float((rot2(heading).T @ resid)[0])
        kw: dict[str, Any] = dict(
            thigh=thigh,
            shin=shin,
            hip_half_width=half_width,
            ankle_height=ankle_h,
            hip_offset=(fwd, float(pelvis[2] - com[2])),
            pelvis_gain=gain,
            min_reach=min_reach,
            max_adduction=float(max_add),
            max_abduction=float(max_abd),
        )
        stated = dict(getattr(robot.robot_data, "legs", {}))
        fields = set(cls.__dataclass_fields__)
        unknown = sorted(set(stated) - fields)
        if unknown:
            raise ModelError(
                f"{robot.robot_data.source}/robot.toml [legs]: unknown keys {unknown}; "
                f"allowed: {', '.join(sorted(fields))}"
            )
        for key, value in stated.items():
            ok = all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                for v in (value if isinstance(value, list) else [value])
            )
            if not ok or (key == "hip_offset" and len(value) != 2):
                raise ModelError(
                    f"{robot.robot_data.source}/robot.toml [legs] {key} = {value!r}: must be "
                    f"{'two numbers (m)' if key == 'hip_offset' else 'a number (m or rad)'}"
                )
            kw[key] = tuple(float(v) for v in value) if isinstance(value, list) else float(value)
        kw.update(overrides)
        return cls(**kw)

    def hips(
        self, com: np.ndarray, heading: np.ndarray, l_sole: np.ndarray, r_sole: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Estimated (left, right) hip centres (N, 3) for CoM positions (N, 3), headings (N,)
        and sole positions (N, 3) (see the pelvis model in the class docstring)."""
        com = np.atleast_2d(com)
        heading = np.atleast_1d(heading)
        mid = 0.5 * (np.atleast_2d(l_sole)[:, :2] + np.atleast_2d(r_sole)[:, :2])
        c, s = np.cos(heading), np.sin(heading)
        fwd = np.column_stack([c, s])
        left = np.column_stack([-s, c])
        pelvis = np.empty_like(com, dtype=float)
        pelvis[:, :2] = mid + self.pelvis_gain * (com[:, :2] - mid) + self.hip_offset[0] * fwd
        pelvis[:, 2] = com[:, 2] + self.hip_offset[1]
        lh, rh = pelvis.copy(), pelvis.copy()
        lh[:, :2] += self.hip_half_width * left
        rh[:, :2] -= self.hip_half_width * left
        return lh, rh

    def leg_lengths(
        self, com: np.ndarray, heading: np.ndarray, l_sole: np.ndarray, r_sole: np.ndarray
    ) -> np.ndarray:
        """(N, 2) hip-to-ankle distances of the left and right legs."""
        lh, rh = self.hips(com, heading, l_sole, r_sole)
        up = np.array([0.0, 0.0, self.ankle_height])
        return np.column_stack(
            [
                np.linalg.norm(lh - (np.atleast_2d(l_sole) + up), axis=1),
                np.linalg.norm(rh - (np.atleast_2d(r_sole) + up), axis=1),
            ]
        )

    def leg_rolls(
        self, com: np.ndarray, heading: np.ndarray, l_sole: np.ndarray, r_sole: np.ndarray
    ) -> np.ndarray:
        """(N, 2) frontal lean (rad) of the left and right legs, positive = abduction (the
        foot further out than its hip); with an upright torso this is the hip roll."""
        heading = np.atleast_1d(heading)
        n = np.column_stack([-np.sin(heading), np.cos(heading)])  # heading-frame left
        lh, rh = self.hips(com, heading, l_sole, r_sole)
        out = []
        for s, hip, sole in ((1.0, lh, l_sole), (-1.0, rh, r_sole)):
            sole = np.atleast_2d(sole)
            lateral = s * np.einsum("ij,ij->i", sole[:, :2] - hip[:, :2], n)
            height = hip[:, 2] - (sole[:, 2] + self.ankle_height)
            out.append(np.arctan2(lateral, height))
        return np.column_stack(out)

    def max_com_lateral(self, com_height: float, half_width: float, sole_z: float = 0.0) -> float:
        """Largest lateral CoM distance (m) from the mid-stance toward a stance sole that the
        sole's hip roll allows (adduction limit less the margin), soles ``half_width`` each
        side of the mid-stance, torso upright: ``(half_width - hip_half_width + tan(a) H) /
        pelvis_gain``."""
        height = com_height + self.hip_offset[1] - (sole_z + self.ankle_height)
        pelvis = (
            half_width
            - self.hip_half_width
            + np.tan(self.max_adduction - self.roll_margin) * height
        )
        return float(pelvis / self.pelvis_gain)

    def lateral_com_bounds(
        self,
        heading: float,
        left_ankle_xy: np.ndarray,
        right_ankle_xy: np.ndarray,
        height: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Linear form ``G c_xy <= h`` (4 rows: adduction and abduction of each leg, with the
        roll margin) of the hip roll limits for a CoM ``c_xy``, the soles at ``*_ankle_xy``
        and the hip-above-ankle ``height`` (per leg, (2,))."""
        n = np.array([-np.sin(heading), np.cos(heading)])
        t_add = np.tan(self.max_adduction - self.roll_margin)
        t_abd = np.tan(self.max_abduction - self.roll_margin)
        k = self.pelvis_gain
        mid = 0.5 * float(np.dot(np.asarray(left_ankle_xy) + np.asarray(right_ankle_xy), n))
        rows, rhs = [], []
        for i, (s, a) in enumerate(((1.0, left_ankle_xy), (-1.0, right_ankle_xy))):
            # pelvis (lateral) = mid + k (c.n - mid); abduction angle of leg s is
            # atan((s (a.n - pelvis) - w) / H), kept within [-t_add, t_abd]
            base = s * float(np.dot(a, n)) - self.hip_half_width - s * (1.0 - k) * mid
            rows.append(s * k * n)  # adduction: s k c.n <= base + t_add H
            rhs.append(base + t_add * height[i])
            rows.append(-s * k * n)  # abduction: -s k c.n <= t_abd H - base
            rhs.append(t_abd * height[i] - base)
        return np.array(rows), np.array(rhs)

    def check_com_height(self, com_height: float, what: str = "the walk") -> None:
        """Raise if the legs cannot hold the CoM at ``com_height`` over flat feet."""
        if not (np.isfinite(com_height) and com_height > 0):
            raise TrajectoryError(f"{what}: the CoM height must be positive, got {com_height}")
        vertical = com_height + self.hip_offset[1] - self.ankle_height
        if not (self.min_reach <= vertical <= self.max_reach):
            lo = self.min_reach - self.hip_offset[1] + self.ankle_height
            hi = self.max_reach - self.hip_offset[1] + self.ankle_height
            raise TrajectoryError(
                f"{what}: a CoM height of {com_height * 1000:.1f} mm is out of the legs' reach "
                f"(hip-to-ankle {vertical * 1000:.1f} mm; feasible CoM heights "
                f"{lo * 1000:.1f}-{hi * 1000:.1f} mm)"
            )


def _pelvis_gain(robot: Any, q: np.ndarray, step: float = 1e-3) -> float:
    """Pelvis displacement per CoM displacement, sideways: move the floating base by
    ``step`` along y with the torso orientation and the arms held, solve each leg's six
    joints so its sole stays put (Newton on the 6x6 leg Jacobian), and compare CoM shifts."""
    import pinocchio as pin

    model, data = robot.model, robot.data
    q1 = q.copy()
    q1[1] += step
    for side, sole in SOLE_FRAMES.items():
        fid = robot.frame_id(sole)
        target = robot.frame_placement(q, sole)
        cols = [robot.v_index(j) for j in robot.roles.leg(side)]
        for _ in range(20):
            pin.framesForwardKinematics(model, data, q1)
            err = pin.log6(data.oMf[fid].inverse() * target).vector
            if np.linalg.norm(err) < 1e-12:
                break
            J = pin.computeFrameJacobian(model, data, q1, fid, pin.LOCAL)[:, cols]
            dq = np.zeros(model.nv)
            dq[cols] = np.linalg.solve(J, err)
            q1 = pin.integrate(model, q1, dq)
    shift = robot.com(q1)[1] - robot.com(q)[1]
    return float(step / shift)
