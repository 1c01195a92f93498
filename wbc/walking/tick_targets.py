"""What a controller is asked to track at one tick of a walk (:class:`TickTargets`), the
support roles of a reference's ticks and the soles' packed placements: the walking loop's
(:mod:`wbc.walking.loop`, which re-exports them) and the drive's targets."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..roles import SOLE_FRAMES as SOLES
from .reference import WalkingReference


def torso_target(yaw: float, pitch_roll: np.ndarray) -> np.ndarray:
    """The torso rotation every controller is asked for: Rz(yaw) · (start rotation with its
    heading removed), so the torso keeps its start lean and turns with the walk."""
    return pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ pitch_roll


@dataclass
class TickTargets:
    """What every controller is asked to track at one tick (world frame).

    The arrays are computed once per run (they are the reference, not part of a tick's cost)
    and shared by every controller: read them, never write them.
    """

    i: int
    t: float
    phase: str  # "double" or "single"
    support: str  # sole frame of the support foot (in double support: the stance foot of the
    swing: str  # neighbouring single-support phase) and of the other foot
    com: np.ndarray
    l_sole: pin.SE3
    r_sole: pin.SE3
    torso_yaw: float
    #: the torso rotation asked for: Rz(yaw) · the start rotation with its heading removed
    torso_rotation: np.ndarray
    #: the swing sole's target position and rotation (arrays of :attr:`swing_placement`)
    swing_position: np.ndarray
    swing_rotation: np.ndarray
    #: True when the soles in contact (:attr:`l_sole`, :attr:`r_sole`) move within a phase
    #: (a driven walk's stance contact sliding toward its measured landing): then a
    #: controller that holds contacts sets their targets at every tick, not only at the
    #: phase's start, where they are anchored
    contacts_move: bool = False
    #: m (≤ 0): the swing sole's ground clearance this tick relative to the stack's (a
    #: controller with a swing-bound ``ground_clearance`` lowers it by this much: the floor
    #: where the measured frame puts it; :attr:`~wbc.balance.stepping_params.SteppingParams.
    #: landing_floor`); 0: the stack's own
    swing_floor: float = 0.0
    #: m (> 0): the state estimator's landed-sole band this tick (a sole entering the support
    #: further than that from its plan is anchored where it landed:
    #: :class:`~wbc.balance.estimator.StateEstimator` ``anchor_band``;
    #: :attr:`~wbc.balance.stepping_params.SteppingParams.back_anchor`); None: its own
    anchor_band: float | None = None
    #: (l_sole, r_sole, :func:`sole_pack` of them), built once per walk by a
    #: :class:`Session`; a reader checks the two placements are still these (``is``)
    sole_pack: tuple | None = None

    def replace(self, **changes: Any) -> TickTargets:
        """A copy with these fields changed: a dict copy and the stores, for the feedback
        inside a tick (``dataclasses.replace`` costs ~10 µs there)."""
        out = object.__new__(type(self))
        values = self.__dict__.copy()
        values.update(changes)
        out.__dict__ = values
        return out

    def retarget(self, com: np.ndarray, torso_rotation: np.ndarray) -> TickTargets:
        """:meth:`replace` of the CoM and torso targets (the feedback's; half its cost)."""
        out = object.__new__(type(self))
        values = self.__dict__.copy()
        values["com"], values["torso_rotation"] = com, torso_rotation
        out.__dict__ = values
        return out

    def sole(self, frame: str) -> pin.SE3:
        """The reference placement of the sole ``frame`` ("l_sole" or "r_sole")."""
        return self.l_sole if frame == "l_sole" else self.r_sole

    @property
    def swing_placement(self) -> pin.SE3:
        return self.sole(self.swing)

    @property
    def support_placement(self) -> pin.SE3:
        return self.sole(self.support)


def sole_pack(l_sole: pin.SE3, r_sole: pin.SE3) -> np.ndarray:
    """(34,): both soles' homogeneous placements (row-major, left first) and the lengths of
    their lateral axes' horizontal part (``math.hypot`` of each ``y`` axis's x, y; at least
    1e-9): what the closed loop's tick reads of the soles (:mod:`wbc.balance.stabilizer`)."""
    out = np.empty(34)
    hl, hr = l_sole.homogeneous, r_sole.homogeneous
    out[:16], out[16:32] = hl.ravel(), hr.ravel()
    out[32] = max(math.hypot(hl[0, 1], hl[1, 1]), 1e-9)
    out[33] = max(math.hypot(hr[0, 1], hr[1, 1]), 1e-9)
    return out


def support_roles(ref: WalkingReference) -> tuple[list[str], list[str]]:
    """Support and swing sole per tick; double support takes the roles of the next single
    support phase (or of the previous one at the end of the walk)."""
    n = ref.n
    swing_side: list[str | None] = [ref.swing_side(i) for i in range(n)]
    nxt: str | None = None
    filled: list[str | None] = [None] * n
    for i in range(n - 1, -1, -1):
        if swing_side[i] is not None:
            nxt = swing_side[i]
        filled[i] = swing_side[i] or nxt
    prev: str | None = None
    for i in range(n):
        if swing_side[i] is not None:
            prev = swing_side[i]
        if filled[i] is None:
            filled[i] = prev or "right"
    swing = [SOLES[s] for s in filled]
    support = ["r_sole" if s == "l_sole" else "l_sole" for s in swing]
    return support, swing
