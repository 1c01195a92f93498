"""Support-sole-rooted coordinates: the thesis's kinematics on our floating-base model.

The thesis roots its kinematics at the sole of the support foot: 18 joint coordinates, no
floating base, every Jacobian relative to that sole (sec. 2.2). Our model has a free-flyer
base (nv = 24). We get exactly the thesis's behaviour by **eliminating the base through the
support contact**, i.e. by working in the contact's null space parametrised by the joints:

    contact (6 rows, a :class:`~wbc.tasks.ContactTask` on the support sole):
        J_cb Δq_b + J_cj Δq_j = e_c
    J_cb (6 x 6) maps the base twist to the sole twist; it is an adjoint, always invertible, so
        Δq_b = J_cb⁻¹ (e_c − J_cj Δq_j)
    and any task J = [J_b  J_j] becomes, on the joints alone,
        J_r = J_j − J_b J_cb⁻¹ J_cj,      e_r = e − J_b J_cb⁻¹ e_c.

J_r is the thesis's sole-rooted Jacobian (the task's motion relative to the support sole
caused by the 18 joints), expressed in world axes — the support sole is flat and fixed, so
world and sole axes differ by a constant heading. This is the same as putting the contact
first in a hierarchy and projecting everything into its null space, but keeps the thesis's
18-column matrices, so W (Annex B) and the Chan–Dubey weights act on the 18 joints directly,
exactly as in the thesis, with nothing to choose for the base. The e_c terms correct any
drift of the support sole (Newton step with gain 1), and :meth:`SoleRooted.integrate`
then places the base so that the sole is exactly at its anchor: the root never moves.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, SolverError
from ..model import Kinematics, Robot
from ..tasks import ContactTask


class SoleRooted:
    """Kinematics of one configuration in support-sole-rooted (joint-only) coordinates."""

    def __init__(self, robot: Robot, support: str = "l_sole") -> None:
        self.robot = robot
        self.kin = Kinematics(robot)
        self.contact = ContactTask(robot, support, name=f"support_{support}")
        self.support = support
        self.anchored = False
        self._A = np.zeros((6, robot.n_joints))  # J_cb⁻¹ J_cj
        self._b = np.zeros(6)  # J_cb⁻¹ e_c
        self._data = robot.model.createData()

    @property
    def q(self) -> np.ndarray:
        return self.kin.q

    def anchor(self, q: np.ndarray) -> None:
        """Fix the support sole where it is at q (the root of the kinematics)."""
        self.kin.update(q)
        self.contact.make_contact(self.kin)
        self.anchored = True
        self._reduce_contact()

    def update(self, q: np.ndarray) -> None:
        """Recompute the kinematics and the base elimination at q."""
        if not self.anchored:
            raise ConfigurationError(
                "SoleRooted.update before anchor(q): the support sole is not fixed"
            )
        self.kin.update(q)
        self._reduce_contact()

    def _reduce_contact(self) -> None:
        Jc, ec = self.contact.compute(self.kin)
        try:
            X = np.linalg.solve(Jc[:, :6], np.column_stack([Jc[:, 6:], ec]))
        except np.linalg.LinAlgError:
            raise SolverError("support contact Jacobian w.r.t. the base is singular") from None
        self._A[:] = X[:, :-1]
        self._b[:] = X[:, -1]

    def reduce(self, J: np.ndarray, e: np.ndarray | None = None):
        """Sole-rooted (J_r, e_r) of a task given its (J, e) in nv coordinates."""
        Jb = J[:, :6]
        Jr = J[:, 6:] - Jb @ self._A
        if e is None:
            return Jr
        return Jr, e - Jb @ self._b

    def lift(self, dq_joints: np.ndarray) -> np.ndarray:
        """The nv increment [Δq_b; Δq_j] that keeps the support sole anchored."""
        dq = np.empty(self.robot.nv)
        dq[6:] = dq_joints
        dq[:6] = self._b - self._A @ dq_joints
        return dq

    def integrate(self, dq_joints: np.ndarray) -> np.ndarray:
        """q ⊕ lift(Δq_j) from the configuration of the last update, with the base then
        placed so that the support sole is exactly at its anchor (the thesis's fixed root;
        the first-order lift alone would let it drift by O(‖Δq‖²))."""
        q = self.robot.integrate(self.kin.q, self.lift(dq_joints))
        return self.reanchor(q)

    def reanchor(self, q: np.ndarray) -> np.ndarray:
        """q with its base moved so that the support sole is at its anchor (joints kept)."""
        model, data = self.robot.model, self._data
        pin.framesForwardKinematics(model, data, q)
        oMb = pin.XYZQUATToSE3(q[:7])
        sMb = data.oMf[self.contact.frame_id].actInv(oMb)
        q[:7] = pin.SE3ToXYZQUAT(self.contact.target * sMb)
        return q

    def contact_error(self) -> float:
        """‖e_c‖ of the support sole at the last update (m and rad mixed; ~0 when anchored)."""
        return float(np.linalg.norm(self.contact.last_error))
