"""Numbers of the CoM-control thesis (2018): joint numbering, Annex B weights, tables.

The thesis numbers its joints j1..j18 (left leg from the ankle up, arms, right leg from the
hip down); bioloid-facts §8 identifies them with Robotis IDs. We map them onto the model's
joints through ``robot.servo_map.ids`` (the Robotis ID of each model joint), never by model
index.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ModelError
from ..model import Robot

#: thesis joint j -> Robotis ID (bioloid-facts §8)
THESIS_JOINT_IDS: dict[int, int] = {
    1: 18, 2: 16, 3: 14, 4: 10, 5: 12, 6: 8,  # left leg, ankle roll .. hip yaw
    7: 2, 8: 4, 9: 6,  # left arm
    10: 1, 11: 3, 12: 5,  # right arm
    13: 7, 14: 11, 15: 9, 16: 13, 17: 15, 18: 17,  # right leg, hip yaw .. ankle roll
}  # fmt: skip

#: Annex B, Table B.1: weights W used in ch. 3 (by thesis joint); a left-support posture
ANNEX_B_WEIGHTS: dict[int, float] = {
    1: 0.1, 2: 0.1, 3: 0.1, 4: 10.0, 5: 10.0, 6: 10.0,
    7: 0.1, 8: 10.0, 9: 10.0,
    10: 0.1, 11: 10.0, 12: 10.0,
    13: 10.0, 14: 0.1, 15: 10.0, 16: 0.1, 17: 10.0, 18: 10.0,
}  # fmt: skip

#: Table 3.3.1: (λ, α) of the six simulations
TABLE_3_3_1: dict[str, tuple[float, float]] = {
    "sim1": (0.1, 0.1),
    "sim2": (0.1, 0.5),
    "sim3": (0.1, 1.0),
    "sim4": (0.5, 1.0),
    "sim5": (0.5, 0.5),
    "sim6": (0.5, 0.1),
}

#: Table 3.3.2: CoM error (mm) per method and simulation
TABLE_3_3_2: dict[str, tuple[float, ...]] = {
    "DE": (0.0200, 0.0153, 0.0092, 0.0166, 0.0094, 0.1510),
    "DEAV": (0.2134, 0.0800, 0.1333, 0.0047, 0.1679, 0.2100),
    "MS": (0.1601, 0.1508, 0.0063, 0.0069, 0.0527, 0.1203),
    "MSAV": (0.1039, 0.1084, 0.1110, 0.1112, 0.1120, 0.1079),
    "MCMT": (0.0005, 3.0664, 4.4929, 4.3493, 2.6956, 0.0005),
}

#: Table 3.3.3: execution time (ms) per method and simulation (the thesis's implementation)
TABLE_3_3_3: dict[str, tuple[float, ...]] = {
    "DE": (21.3, 129.4, 50.1, 136.4, 105.5, 93.9),
    "DEAV": (86.3, 40.3, 73.9, 73.9, 83.1, 51.5),
    "MS": (141.5, 107.9, 376.1, 133.5, 146.3, 148.6),
    "MSAV": (105.8, 109.8, 90.7, 89.3, 115.8, 143.8),
    "MCMT": (31.6, 61.0, 70.4, 72.1, 61.6, 25.9),
}

#: Ch. 4 figures quoted in the text, per scheme: max CoM / swing-foot error (mm) and mean
#: time per pose (ms); None where the thesis gives no number ("hundredths of mm" for VAT).
THESIS_WALKING: dict[str, dict[str, float | None]] = {
    "vat": {"com_max_mm": None, "foot_max_mm": None, "ms_per_pose": 21.88},
    "vatl": {"com_max_mm": None, "foot_max_mm": None, "ms_per_pose": None},
    "cj_foot": {"com_max_mm": 5.3, "foot_max_mm": None, "ms_per_pose": 16.12},
    "cj_com": {"com_max_mm": 4.5e-4, "foot_max_mm": 2.3, "ms_per_pose": 189.6},
    "cjl_foot": {"com_max_mm": 10.0, "foot_max_mm": 0.009, "ms_per_pose": None},
    "cjl_com": {"com_max_mm": 7e-4, "foot_max_mm": 2.5, "ms_per_pose": None},
}


def _mirror_id(robotis_id: int) -> int:
    """The mirrored servo (left IDs are even, right IDs odd: 1<->2, 3<->4, ...)."""
    return robotis_id + 1 if robotis_id % 2 else robotis_id - 1


def thesis_joint_index(robot: Robot) -> dict[int, int]:
    """Thesis joint j -> index of that joint in the model's joint order."""
    if robot.servo_map is None:
        raise ModelError(f"robot {robot.name!r} has no servo map: thesis joints are Robotis IDs")
    by_id = {int(i): k for k, i in enumerate(robot.servo_map.ids)}
    missing = sorted(set(THESIS_JOINT_IDS.values()) - set(by_id))
    if missing:
        raise ModelError(f"robot {robot.name!r}: no joint with Robotis IDs {missing}")
    return {j: by_id[rid] for j, rid in THESIS_JOINT_IDS.items()}


def annex_b_weights(robot: Robot, support: str = "l_sole") -> np.ndarray:
    """Annex B weights in model joint order (n_joints,).

    Table B.1 is written for a left support foot (ankle and knee of the support leg mobile,
    its hip stiff; the swing leg's hip pitch and knee mobile). For ``support="r_sole"`` every
    joint takes the weight of its mirrored servo.
    """
    if support not in ("l_sole", "r_sole"):
        raise ModelError(f"support must be 'l_sole' or 'r_sole', got {support!r}")
    index = thesis_joint_index(robot)
    w = np.empty(robot.n_joints)
    for j, k in index.items():
        w[k] = ANNEX_B_WEIGHTS[j]
    if support == "r_sole":
        by_id = {int(i): k for k, i in enumerate(robot.servo_map.ids)}
        w = np.array([w[by_id[_mirror_id(int(i))]] for i in robot.servo_map.ids])
    return w
