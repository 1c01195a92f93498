"""The controller's soles in contact during a driven walk (:meth:`wbc.drive.walker.Walker.
_contacts`): the planned placements, the stance sole's target slid toward the measured one."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..geometry import clip_norm, rot_z
from ..roles import SOLE_FRAMES
from ..walking.engine import WalkEngine
from ..walking.footsteps import Footstep, Side
from ..walking.loop import TickTargets

#: how far (m) the controller's stance contact moves toward a measured landing away from its plan,
#: at most (:func:`wbc.drive.contacts.move_contacts`), and how fast (m/s). A sole lands where the
#: commanded legs put it, its plan; the leg odometry measures it from the encoders at the end of
#: that double support (the compliant servos land a few millimetres short and narrow). Through the
#: single support that follows, the stance contact's target then slides toward the measured sole, so
#: the commanded body moves over the real stance sole as the plan has it over the planned one (the
#: stride the servos lost is given back at once, beyond the make-up's room at the limits). Only in
#: single support, where the stance contact is the one hard contact: moved within a double support,
#: or re-anchored there at the measured landing (the behaviour before 2026-12-05 08:35 UTC, an
#: unbounded reach: up to 29 mm off), the two contacts and the feet's self-collision rows were
#: infeasible together (290 failed solves in 100 random runs). Measured (benchmarks/drive.md,
#: "Contacts that move"): forward at the limit on the nominal model 7.99 -> 8.5 cm/s, over 20
#: randomised models a mean 7.56 -> 7.88 cm/s; 5 cm/s or an unbounded reach (3 cm) threw the
#: randomised models
DRIVE_CONTACT_REACH = 0.005
DRIVE_CONTACT_RATE = 0.02


def move_contacts(
    engine: WalkEngine,
    held: dict[Side, tuple[Footstep, np.ndarray]],
    targets: TickTargets,
    dt: float,
    reach: float,
    rate: float,
    keep_clear: bool,
) -> None:
    """The controller's soles in contact: each starts at its planned placement
    (:attr:`WalkEngine.feet`, where the commanded swing put it) and, in single support,
    the stance sole's target slides toward the measured one (:attr:`WalkEngine.contact`,
    leg odometry: what the state estimate stands on and the steps are aimed from), at
    most ``reach`` (m) from the plan, at ``rate`` (m/s; :data:`DRIVE_CONTACT_REACH`,
    :data:`DRIVE_CONTACT_RATE`) and, with
    ``keep_clear``, never closer to the swing's planned landing than the feet's
    clearance (:meth:`WalkEngine.clear_of_landing`: moved inward beside a landing at 7 mm,
    turning on the spot, the double support's two hard contacts held the feet inside
    their 5 mm self-collision margin and its solves failed). In double support the
    targets stay where they are: both contacts hard, with the feet's self-collision
    rows, could not follow a gap (benchmarks/drive.md, "Failed solves"). ``held``: per
    sole in contact its plan and target so far (updated). Written into the targets: the
    anchors of a phase's new contacts and, flagged :attr:`TickTargets.contacts_move`, the
    targets of the contacts already made."""
    double = targets.phase == "double"
    left = targets.support == SOLE_FRAMES["left"]
    supports: tuple[Side, ...] = ("left", "right") if double else ("left" if left else "right",)
    for side in ("left", "right"):
        if side not in supports:
            held.pop(side, None)  # lifted: its next contact starts afresh
    step = rate * dt
    for side in supports:
        plan = engine.feet[side]
        start, pos = held.get(side, (None, None))
        if start is not plan or pos is None:  # a new landing: where the swing put it
            pos = plan.position.copy()
        if not double and step > 0:
            gap = engine.contact[side].position - plan.position
            want = plan.position + clip_norm(gap, reach)
            moved = pos + clip_norm(want - pos, step)
            pos = engine.clear_of_landing(plan, pos, moved) if keep_clear else moved
        held[side] = (plan, pos)
        placement = pin.SE3(rot_z(plan.yaw), pos)
        if side == "left":
            targets.l_sole = placement
        else:
            targets.r_sole = placement
    targets.contacts_move = True
