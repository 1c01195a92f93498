"""The five principal masses and their targets (com-control-thesis sec. 3.1, eqs. 3.1-3.11).

The body is five chains — two legs, two arms and the torso — each with a principal mass m_k
at its centre of mass x_k, so that x = Σ m_k x_k / M (3.1). We compute them from Pinocchio's
subtree centres of mass: a limb is the subtree of the joint that attaches it to the torso;
the torso is the root body alone, ``m_5 x_5 = M x − Σ_limbs m_k x_k`` (and the same for the
Jacobians, J_5 = (M J − Σ m_k J_k)/m_5).

Order (k = 1..5) follows the thesis's DE partition (3.12): 1 support leg (q_a), 2 right arm
(q_b), 3 left arm (q_c), 4 swing leg (q_d), 5 torso.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ModelError
from ..model import Kinematics, Robot
from .pseudoinverse import moore_penrose

__all__ = ["Chain", "PrincipalMasses", "com_mass_matrix", "principal_mass_targets"]


@dataclass(frozen=True)
class Chain:
    """A limb: its name, the Pinocchio id of the joint attaching it, its model joint indices."""

    name: str
    root_joint: int
    joints: np.ndarray


class PrincipalMasses:
    """Positions and Jacobians of the five principal masses of a humanoid.

    Args:
        robot: the model (its root body is the torso).
        support, swing: sole frames of the support and swing legs.
        left_hand, right_hand: frames identifying the arms.
    """

    NAMES = ("support_leg", "right_arm", "left_arm", "swing_leg", "torso")

    def __init__(
        self,
        robot: Robot,
        support: str = "l_sole",
        swing: str = "r_sole",
        left_hand: str = "l_hand",
        right_hand: str = "r_hand",
    ) -> None:
        model = robot.model
        self.robot = robot
        frames = {"support_leg": support, "right_arm": right_hand, "left_arm": left_hand,
                  "swing_leg": swing}  # fmt: skip
        chains = []
        for name, frame in frames.items():
            parent = model.frames[robot.frame_id(frame)].parentJoint
            path = list(model.supports[parent])
            if len(path) < 3 or path[1] != 1:
                raise ModelError(f"frame {frame!r} is not on a limb attached to the root body")
            root = path[2]
            joints = np.array(
                [robot.joint_index(model.names[j]) for j in model.subtrees[root]], dtype=int
            )
            chains.append(Chain(name, int(root), joints))
        roots = [c.root_joint for c in chains]
        if len(set(roots)) != 4:
            raise ModelError(
                f"support, swing and hand frames must be on four distinct limbs: {frames}"
            )
        self.chains: tuple[Chain, ...] = tuple(chains)
        self.total_mass = robot.total_mass
        limb_masses = []
        for c in chains:
            limb_masses.append(sum(model.inertias[j].mass for j in model.subtrees[c.root_joint]))
        torso = self.total_mass - sum(limb_masses)
        if torso <= 0.0:
            raise ModelError("the root body (torso) has no mass")
        self.masses = np.array([*limb_masses, torso])
        self.positions = np.zeros((5, 3))
        self.jacobians = np.zeros((5, 3, robot.nv))

    def compute(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Positions (5, 3) and Jacobians (5, 3, nv) of the principal masses at ``kin``'s q.

        Runs ``pinocchio.jacobianCenterOfMass(..., computeSubtreeComs=True)`` on ``kin``'s
        data (already holding the forward kinematics of ``kin.update``).
        """
        model, data = self.robot.model, kin.data
        pin.jacobianCenterOfMass(model, data, True)
        M = self.total_mass
        mx = M * data.com[0]
        mJ = M * data.Jcom
        for k, c in enumerate(self.chains):
            self.positions[k] = data.com[c.root_joint]
            self.jacobians[k] = pin.getJacobianSubtreeCenterOfMass(model, data, c.root_joint)
            mx = mx - self.masses[k] * self.positions[k]
            mJ = mJ - self.masses[k] * self.jacobians[k]
        self.positions[4] = mx / self.masses[4]
        self.jacobians[4] = mJ / self.masses[4]
        return self.positions, self.jacobians

    def com(self, positions: np.ndarray | None = None) -> np.ndarray:
        """x = Σ m_k x_k / M (eq. 3.1)."""
        p = self.positions if positions is None else positions
        return self.masses @ p / self.masses.sum()


def com_mass_matrix(masses: np.ndarray) -> np.ndarray:
    """J_c (3 x 15) of Δx = J_c Δx_K (eqs. 3.3-3.7): J_c = [m_1 I … m_5 I] / M.

    Eq. 3.6 prints J_c as a block diagonal of rows n_i = [m_i m_i m_i], which is 5 x 15 and
    cannot map Δx_K (15) to Δx (3); the matrix above is the one eq. 3.3 defines.
    """
    m = np.asarray(masses, dtype=float)
    return np.kron(m[None, :], np.eye(3)) / m.sum()


def principal_mass_targets(
    masses: np.ndarray,
    positions: np.ndarray,
    com_target: np.ndarray,
    tol: float = 1e-12,
    max_iterations: int = 100,
) -> tuple[np.ndarray, int]:
    """Targets x_k* of the principal masses for a CoM target x* (sec. 3.1.1, eqs. 3.8-3.11).

    Iterates Δx_K = J_c† Δx (Moore–Penrose), x̂_k = x_k + Δx_k, recomputes x with (3.1) until
    ‖Δx‖ <= tol. J_c is linear and constant, so one iteration is exact (the loop is kept as
    the thesis writes it). As the thesis notes, nothing here knows about joint limits or
    reachability. Returns (targets (5, 3), iterations).
    """
    m = np.asarray(masses, dtype=float)
    x_k = np.array(positions, dtype=float).reshape(-1)
    if x_k.size != 3 * m.size:
        raise ConfigurationError(f"positions must be ({m.size}, 3), got {np.shape(positions)}")
    Jc = com_mass_matrix(m)
    Jc_pinv = moore_penrose(Jc)
    target = np.asarray(com_target, dtype=float)
    for it in range(1, max_iterations + 1):
        dx = target - Jc @ x_k
        if np.linalg.norm(dx) <= tol:
            return x_k.reshape(-1, 3), it - 1
        x_k = x_k + Jc_pinv @ dx
    return x_k.reshape(-1, 3), max_iterations
