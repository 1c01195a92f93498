"""A frame's tilt: its z axis projected on two directions (2-D), first-order at upright.

With k = R[:, 2] the frame's z axis (a torso's or a sole's up axis) and u, v two directions
(world; for a torso the heading's forward and left), the rows are ``x = [u·k, v·k]``: the
sines of the frame's pitch and (minus) its roll about those directions. Since
``dk = ω × k = −[k]ₓ ω``, ``J = [uᵀ; vᵀ] (−[k]ₓ J_ω)``, which does *not* vanish at upright
(u·k = 0): a lean limit ``|x| <= sin(max_lean)`` is a linear row there. (The thesis's
:class:`~wbc.tasks.TorsoOrientationTask`, ``1 − a·k``, is quadratic in the angle: its
Jacobian vanishes at alignment.) The balance window (:mod:`wbc.walking.window`) leans the
torso with it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import TaskError, check_vector


@njit(cache=True)
def tilt_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J) -> None:
    """e = x* − [u·k; v·k], J = [uᵀ; vᵀ] (−[k]ₓ J_ω) (target: x* (2), then u, v (3 each))."""
    f = slots[0]
    R, support = Rs[f], supports[f]
    k0, k1, k2 = R[0, 2], R[1, 2], R[2, 2]
    for i in range(2):
        a = 2 + 3 * i
        e[i] = target[i] - (k0 * target[a] + k1 * target[a + 1] + k2 * target[a + 2])
    for c in range(Jw.shape[1]):
        if support[c]:
            w0, w1, w2 = Jw[3, c], Jw[4, c], Jw[5, c]
            # −[k]ₓ ω = ω × k
            d0 = k2 * w1 - k1 * w2
            d1 = k0 * w2 - k2 * w0
            d2 = k1 * w0 - k0 * w1
            for i in range(2):
                a = 2 + 3 * i
                J[i, c] = target[a] * d0 + target[a + 1] * d1 + target[a + 2] * d2
        else:
            J[0, c] = 0.0
            J[1, c] = 0.0


class FrameTiltTask(FrameTask):
    """e = x* − [u·k; v·k] with k the frame's z axis, J = [uᵀ; vᵀ] (−[k]ₓ J_ω) (2 x nv).

    ``directions``: u and v (world, two rows of 3; default the world x and y axes),
    ``target``: x* (default 0, the frame upright: k normal to both).
    """

    dim = 2
    row_kernel = staticmethod(tilt_rows)
    target_fields = ("target", "directions")
    #: in a stack file: ``{ type = "frame_tilt", frame = "torso", target = [0.0, 0.0] }``
    stack_type = "frame_tilt"
    stack_keys = ("directions", "target")

    def __init__(
        self,
        robot: Robot,
        frame: str,
        directions: Sequence[Sequence[float]] | np.ndarray = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
        target: Sequence[float] | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name or f"tilt_{frame}", gain, weight, mask)
        self.target = np.zeros(2)
        self.directions = np.zeros(6)  # (u then v: the kernel's packed layout)
        self.set_directions(directions)
        if target is not None:
            self.set_target(target)

    def set_directions(self, directions: Sequence[Sequence[float]] | np.ndarray) -> None:
        """u and v (world): two rows of 3 finite numbers, copied in place."""
        try:
            d = np.asarray(directions, dtype=float)
        except (TypeError, ValueError):
            raise TaskError(
                f"task {self.name!r}: directions must be two rows of 3 numbers, got {directions!r}"
            ) from None
        if d.shape != (2, 3):
            raise TaskError(
                f"task {self.name!r}: directions must be two rows of 3 numbers, got shape {d.shape}"
            )
        check_vector(self, d.ravel(), 6, "directions", out=self.directions)

    def set_target(self, target: Sequence[float]) -> None:
        """x* = [u·k*, v·k*], copied in place."""
        check_vector(self, target, 2, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        """x* = the frame's current [u·k, v·k] (the kernel's own sums: the error is then
        exactly zero there)."""
        self.target[:] = 0.0
        self.target[:] = -self.compute_error(kin)
