"""The rows of the pre-motion solves: the balance window's (:mod:`.window`) and the
feasibility IK's (:mod:`.feasibility`), written once.

At ``q``: the CoM ``c`` and its Jacobian ``J_c`` (world), and for each sole held at a target
placement ``M*`` its error in the sole's own frame, ``e = log6(M⁻¹ M*)``, with the frame's
local Jacobian ``J`` (``J dq = e`` moves the sole onto its target to first order).

These are not the control tasks' rows (:class:`~wbc.tasks.ContactTask`: world-aligned
``[p* − p; log(R* Rᵀ)]``; :class:`~wbc.tasks.ComTask` reads the CoM of
``pinocchio.jacobianCenterOfMass(..., False)``, which differs from ``centerOfMass``'s in the
last bit for most configurations). Both solves feed the sized references (the window their
torso roll, the feasibility IK the speed fit of :mod:`wbc.walking.sizing`), so a switch moves
recorded references (2026-12-05): in the feasibility IK the task classes' rows changed 24
reference arrays of Kokone and the OP3 (up to 2e-9 in a CoM acceleration), its CoM row alone
27; in the window the Bioloid's reach by 3.9 µm and its roll table by up to 1.9e-5 rad.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin


def sole_rows(
    model: pin.Model, data: pin.Data, q: np.ndarray, frame_ids: Sequence[int], targets: Sequence
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Kinematics at ``q`` (frames, CoM) and the rows of the soles ``frame_ids`` held at the
    placements ``targets`` (``pinocchio.SE3``): ``(c, J_c, J, e)`` with ``J`` (6k x nv) the
    soles' local Jacobians stacked and ``e`` (6k) their errors ``log6(M⁻¹ M*)``."""
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    com = pin.centerOfMass(model, data, q)
    Jc = pin.jacobianCenterOfMass(model, data, q)
    Js, es = [], []
    for fid, target in zip(frame_ids, targets, strict=True):
        Js.append(pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL))
        es.append(pin.log6(data.oMf[fid].inverse() * target).vector)
    return com, Jc, np.vstack(Js), np.concatenate(es)
