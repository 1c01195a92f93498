"""Swing-foot ground clearance: no sole corner below the ground."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..compiled.rows import frame_jacobian
from ..exceptions import ConfigurationError, TaskError
from ..geometry import sole_corners
from ..model import Kinematics, Robot
from .limit import Constraint, Inequality

#: defaults of the way back of a sole corner that starts below the clearance: a fraction
#: of its depth per step (the self-collision damper's), at most this many metres per step
#: (servo speed allows ~1 cm per 10 ms tick at the foot; 2 mm is 0.2 m/s)
DEFAULT_DAMPING = 0.4
DEFAULT_MAX_RISE = 0.002


@njit(cache=True)
def clearance_rows(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, h, G):
    """The constraint kernel of :class:`GroundClearanceConstraint` (one row per corner; the
    kernels' signature, :mod:`wbc.compiled.signature`): ``params`` = [clearance, damping ξ,
    max_rise, then the corners in the sole frame (x, y, z each)], the sole in slot 0. h is
    each corner's height above the clearance, or where negative (a corner below it) its way
    back −min(ξ δ, max_rise) (:func:`~wbc.limits.limit.way_back`)."""
    s = slots[0]
    R, p = Rs[s], ps[s]
    frame_jacobian(Jw, supports[s], p, Jf)
    clearance, damping, most = params[0], params[1], params[2]
    for c in range(h.shape[0]):
        x, y, z = params[3 + 3 * c], params[4 + 3 * c], params[5 + 3 * c]
        wx = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
        wy = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
        wz = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z
        for k in range(Jf.shape[1]):
            G[c, k] = wx * Jf[4, k] - wy * Jf[3, k] - Jf[2, k]
        h[c] = wz + p[2] - clearance
        if h[c] < 0.0:
            h[c] = -min(damping * -h[c], most)


class GroundClearanceConstraint(Constraint):
    """z of each sole corner after the step >= ``clearance`` (4 rows):

    z_c + J_c,z Δq >= clearance  ⇔  −J_c,z Δq <= z_c − clearance,
    with J_c = J_v − [R r_c]× J_ω for corner offset r_c in the sole frame.

    A corner that starts below the clearance (depth δ = clearance − z_c > 0: a start, a
    servo reading, a sole pushed into the floor) is not asked to jump back in one step, which
    the servos' speed and the hard contacts may not allow: its row is −J_c,z Δq <= −min(ξ δ,
    ``max_rise``) (:func:`~wbc.limits.limit.way_back`; ξ = ``damping``): no further down,
    then up a fraction ξ of the depth per step, at most ``max_rise`` m. Where even that is
    not possible with the hard tasks, the solvers rank those rows below them
    (:meth:`split`), as the joints' way back into their range.
    """

    held_rows_met = True  # the corners below the clearance are requests (:meth:`split`)
    row_kernel = staticmethod(clearance_rows)
    param_fields = ("settings", "corners")
    # (its rows: one per corner, a fixed count; its arrays written in place: its layout
    # changes with its frame alone, one token per frame)
    keeps_layout_token = True

    def __init__(
        self,
        robot: Robot,
        frame: str,
        clearance: float = 0.0,
        length: float | None = None,
        width: float | None = None,
        name: str | None = None,
        damping: float = DEFAULT_DAMPING,
        max_rise: float = DEFAULT_MAX_RISE,
    ) -> None:
        super().__init__(name or f"ground_clearance_{frame}")
        if not 0 < damping <= 1:
            raise ConfigurationError(f"ground_clearance damping must be in (0, 1], got {damping}")
        if not max_rise > 0:
            raise ConfigurationError(f"ground_clearance max_rise must be > 0 m, got {max_rise}")
        self.robot = robot
        #: [clearance, damping, max_rise] (the kernel's first parameters: :attr:`clearance`,
        #: :attr:`damping`, :attr:`max_rise` read and write it)
        self.settings = np.array([clearance, damping, max_rise], dtype=float)
        self._tokens: dict[int, object] = {}  # (:attr:`layout_token`, one per frame)
        self.set_frame(frame)
        # the foot rectangle: the robot's (robot.toml [feet]) unless given
        foot_length, foot_width = robot.foot_size
        self.corners = np.ascontiguousarray(
            sole_corners(
                foot_length if length is None else length, foot_width if width is None else width
            ),
            dtype=float,
        )

    clearance = property(
        lambda self: float(self.settings[0]),
        lambda self, value: self.settings.__setitem__(0, value),
        doc="The height (m) every sole corner keeps above the ground.",
    )
    damping = property(
        lambda self: float(self.settings[1]),
        lambda self, value: self.settings.__setitem__(1, value),
        doc="ξ: the fraction of a corner's depth below the clearance asked back per step.",
    )
    max_rise = property(
        lambda self: float(self.settings[2]),
        lambda self, value: self.settings.__setitem__(2, value),
        doc="The most (m) a corner below the clearance is asked to rise per step.",
    )

    def set_frame(self, frame: str) -> None:
        self.frame_id = self.robot.frame_id(frame)
        self.frame = frame
        self.layout_token = self._tokens.setdefault(self.frame_id, object())

    def frame_ids(self) -> tuple[int, ...]:
        return (self.frame_id,)

    @property
    def rows(self) -> int:
        return self.corners.shape[0]

    def split(self, kin: Kinematics, recovering: bool = False) -> tuple[Inequality, Inequality]:
        """(rows to hold, requests): the rows of the corners below the clearance (h < 0: Δq = 0
        does not meet them) are the requests (:meth:`Constraint.split`)."""
        G, h = self.compute(kin)
        ask = h < 0.0
        return Inequality(G[~ask], h[~ask]), Inequality(G[ask], h[ask])

    def lowest_point(self, kin: Kinematics) -> float:
        """Height (m) of the lowest sole corner."""
        R = kin.rotation(self.frame_id)
        return float(np.min(kin.translation(self.frame_id)[2] + self.corners @ R[2]))


class LinearInequality(Constraint):
    """A user-supplied G Δq <= h (fixed, or updated in place with :meth:`set`)."""

    def __init__(self, G: np.ndarray, h: np.ndarray, name: str = "linear_inequality") -> None:
        super().__init__(name)
        self.set(G, h)

    def set(self, G: np.ndarray, h: np.ndarray) -> None:
        G = np.atleast_2d(np.asarray(G, dtype=float))
        h = np.atleast_1d(np.asarray(h, dtype=float))
        if G.shape[0] != h.shape[0]:
            raise TaskError(f"constraint {self.name!r}: G has {G.shape[0]} rows, h {h.shape[0]}")
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(h))):
            raise TaskError(f"constraint {self.name!r}: non-finite values in G or h")
        self.G, self.h = G, h

    def compute(self, kin: Kinematics) -> Inequality:
        return Inequality(self.G, self.h)
