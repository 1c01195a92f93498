"""The whole-body balance window: how far sideways the *whole body* can carry its CoM.

:class:`~wbc.walking.legs.LegGeometry` models the legs alone with the torso upright and the
arms idle: on the Bioloid the stance hip's 5.57 deg adduction limit then holds the CoM within
~11 mm of the mid-stance, while the stance sole's centre is 41.4 mm out. Leaning the torso
over the stance foot uses the stance hip's abduction range instead, and the arms (a large
share of the mass) can follow: the reachable CoM window is several times wider.

:class:`BalanceWindow` measures it on the model, both soles flat and fixed at a stance (the
standing stance by default), the CoM at a fixed height, every joint within its limits:

* ``max_lateral``: the largest lateral CoM offset from the mid-stance with the torso's roll
  within ``max_lean`` and its pitch and heading held at the start's, as every reference asks
  them (sequential linear programming: maximise ``n . c(q)`` over a linearised step with the
  soles' 6-D placements, the CoM height, the torso's pitch and heading as linear rows, its
  roll as a bound, the joint limits and a trust region as bounds, until the step vanishes);
* ``upright``: the same with the torso held upright (legs and arms only);
* a table of torso rolls over lateral offsets ``0 ..`` the lean solve's reach (its torso may
  also pitch and turn, within ``max_lean``; at least ``max_lateral``): at each offset a
  prioritised solve (soles and CoM exact, then the torso as upright as possible, then a light
  posture toward the standing pose), so the generators can ask the torso for the roll the
  body needs (:meth:`roll_for`). The roll is about the heading axis: positive tilts the
  torso's top toward -y (to the right), i.e. a CoM to the right asks for a positive roll.

:func:`lateral_reach` is the bound at another stance: the soles a step apart along the
heading, the CoM over the front (or back) sole, as a static walk's double supports have them.

Everything here is a pre-motion computation (a fraction of a second), not a control tick.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import TrajectoryError
from ..geometry import yaw_of
from ..model import Kinematics
from ..tasks import ComTask, FrameTiltTask, LocalFramePoseTask

#: default largest torso tilt from upright the window may use (rad; 15 deg)
MAX_LEAN = float(np.deg2rad(15.0))
#: weights of the lean solve: the torso's pitch (kept), its roll, every joint's posture.
#: Comparable roll and posture weights share the work between a torso lean and the limbs,
#: rather than flinging the arms to their limits before the torso leans at all.
W_PITCH, W_ROLL, W_POSTURE = 1e4, 1.0, 1.0
#: the frames held
SOLES = ("l_sole", "r_sole")


@dataclass(frozen=True)
class BalanceWindow:
    """Lateral CoM window of the whole body at a stance (lengths in m, angles in rad).

    ``offsets`` (K,) ascending lateral CoM offsets from the mid-stance toward the *left*
    sole (the window is mirror-symmetric: a right offset takes the opposite roll),
    ``rolls`` (K,) the torso roll the whole body uses at each (negative: leaning left).
    """

    offsets: np.ndarray
    rolls: np.ndarray
    max_lateral: float
    upright: float
    max_lean: float
    com_height: float
    half_width: float

    def roll_for(self, lateral: np.ndarray | float) -> np.ndarray:
        """Torso roll (rad) for lateral CoM offsets (m, + = left) from the mid-stance:
        zero within the upright window would be ideal, the table's solves give the
        smallest tilt the body needs (linear interpolation, odd in the offset)."""
        y = np.asarray(lateral, dtype=float)
        return np.sign(y) * np.interp(np.abs(y), self.offsets, self.rolls)

    def inside(self, lateral: np.ndarray | float, margin: float = 0.0) -> np.ndarray:
        """Whether lateral offsets lie within the window less ``margin``."""
        return np.abs(np.asarray(lateral, dtype=float)) <= self.max_lateral - margin

    def as_dict(self) -> dict[str, Any]:
        return {
            "max_lateral": self.max_lateral,
            "upright": self.upright,
            "max_lean": self.max_lean,
            "com_height": self.com_height,
            "half_width": self.half_width,
            "offsets": self.offsets.tolist(),
            "rolls": self.rolls.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BalanceWindow:
        """The window :meth:`as_dict` gave (other keys ignored)."""
        return cls(
            offsets=np.asarray(data["offsets"], dtype=float),
            rolls=np.asarray(data["rolls"], dtype=float),
            **{k: float(data[k]) for k in ("max_lateral", "upright", "max_lean", "com_height",
                                           "half_width")},
        )  # fmt: skip

    @classmethod
    def from_robot(
        cls,
        robot: Any,
        q: np.ndarray | None = None,
        max_lean: float = MAX_LEAN,
        com_height: float | None = None,
        samples: int = 9,
        hold_arms: bool = False,
    ) -> BalanceWindow:
        """Measure the window at the stance of ``q`` (default: the standing pose).

        ``max_lean``: the torso tilt allowed (rad, >= 0); ``com_height``: the CoM height
        (default: the one of ``q``); ``hold_arms``: keep the arms at their angles in ``q``
        (the legs-and-torso window). Raises :class:`TrajectoryError` on bad input.
        """
        if not (np.isfinite(max_lean) and 0.0 <= max_lean < 0.8):
            raise TrajectoryError(
                f"balance window: max_lean must be in [0, 0.8) rad, got {max_lean}"
            )
        if int(samples) != samples or samples < 2:
            raise TrajectoryError(f"balance window: samples must be an integer >= 2, got {samples}")
        q = robot.configuration("stand") if q is None else robot.check_configuration(q).copy()
        prob = _Problem(robot, q, com_height, hold_arms)
        upright = prob.extreme(0.0, held=True)
        # the range of the roll table: the lean solve's (torso pitch and yaw free)
        reach = prob.extreme(max_lean)
        # the bound: only the torso's roll leans, its pitch and heading held as every
        # reference asks them (Rz(yaw) Rx(roll) L) and the stacks track them
        bound = min(reach, prob.extreme(max_lean, held=True))
        offsets = np.linspace(0.0, reach, int(samples))
        rolls = np.zeros_like(offsets)
        qq = prob.q0.copy()
        for k, d in enumerate(offsets):
            qq = prob.lean_solve(qq, d, max_lean)
            rolls[k] = prob.roll(qq)
            # the offset reached (near the edge the lean bound may stop short of the ask)
            offsets[k] = float((robot.com(qq) - prob.mid) @ prob.left)
        offsets = np.maximum.accumulate(offsets)
        # zero at the mid-stance (odd in the offset), within the lean allowed
        rolls = np.clip(rolls - rolls[0], -max_lean, max_lean)
        return cls(
            offsets=offsets,
            rolls=rolls,
            max_lateral=float(bound),
            upright=float(upright),
            max_lean=float(max_lean),
            com_height=float(prob.height),
            half_width=float(prob.half_width),
        )


def lateral_reach(
    robot: Any,
    q: np.ndarray | None = None,
    stagger: float = 0.0,
    forward: float | None = None,
    max_lean: float = MAX_LEAN,
    com_height: float | None = None,
    hold_arms: bool = True,
) -> float:
    """The largest lateral CoM offset (m) from the soles' midpoint toward the left sole that
    the whole body reaches with both soles flat at the stance of ``q`` (default: the standing
    pose) moved ``stagger`` apart along the heading (the left sole ``stagger / 2`` ahead, the
    right behind), the CoM ``forward`` of their midpoint (default: as in ``q``) at
    ``com_height``, the torso's pitch and heading held at ``q``'s and its roll within
    ``max_lean``, every joint within its limits, the arms held if ``hold_arms`` (as
    :func:`~wbc.walking.feasibility.kinematic_feasibility` holds them).

    A static walk's double supports stand a step long, its CoM over the back sole and then
    over the one that just landed (the left sole behind: ``stagger < 0, forward = stagger /
    2``; ahead: ``stagger > 0``): both reach less than the standing stance. Raises
    :class:`TrajectoryError` if the legs cannot stand so."""
    if not (np.isfinite(max_lean) and 0.0 <= max_lean < 0.8):
        raise TrajectoryError(f"balance window: max_lean must be in [0, 0.8) rad, got {max_lean}")
    if not np.isfinite(stagger) or (forward is not None and not np.isfinite(forward)):
        raise TrajectoryError(
            f"balance window: stagger and forward must be finite, got {stagger}, {forward}"
        )
    q = robot.configuration("stand") if q is None else robot.check_configuration(q).copy()
    prob = _Problem(robot, q, com_height, hold_arms, float(stagger), forward)
    return prob.extreme(max_lean, held=True)


class _Problem:
    """Both soles fixed at their placements in ``q``, the CoM at ``height``."""

    def __init__(
        self,
        robot: Any,
        q: np.ndarray,
        height: float | None,
        hold_arms: bool,
        stagger: float = 0.0,
        forward: float | None = None,
    ) -> None:
        self.robot = robot
        self.model, self.data = robot.model, robot.data
        self.q0 = q
        self.soles = [robot.frame_placement(q, f) for f in SOLES]
        self.fid_torso = robot.frame_id("torso")
        self.height = float(robot.com(q)[2]) if height is None else float(height)
        R = self.soles[0].rotation
        heading = yaw_of(R)
        self.fwd = np.array([np.cos(heading), np.sin(heading), 0.0])
        self.left = np.array([-np.sin(heading), np.cos(heading), 0.0])
        # a staggered stance: the left sole stagger/2 ahead, the right one behind (same mid)
        for k, sign in enumerate((0.5, -0.5)):
            self.soles[k] = pin.SE3(
                self.soles[k].rotation, self.soles[k].translation + sign * stagger * self.fwd
            )
        mid = 0.5 * (self.soles[0].translation + self.soles[1].translation)
        self.mid = mid
        self.half_width = 0.5 * float(
            (self.soles[0].translation - self.soles[1].translation) @ self.left
        )
        self.com_x = float((robot.com(q) - mid) @ self.fwd) if forward is None else float(forward)
        nv = self.model.nv
        self.free = np.ones(nv, dtype=bool)
        if hold_arms:
            for side in ("left", "right"):
                for name in robot.roles.arm(side):
                    self.free[robot.v_index(name)] = False
        # the rows (wbc.tasks): the soles held at their placements, the CoM (its target set
        # per solve), the torso's tilt about the heading; "upright" is the start pose's own lean
        self.kin = Kinematics(robot, q)
        self.soles_task = [
            LocalFramePoseTask(robot, f, target=m) for f, m in zip(SOLES, self.soles, strict=True)
        ]
        self.com_task = ComTask(robot)
        self.tilt_task = FrameTiltTask(robot, "torso", np.array([self.fwd, self.left]))
        self.tilt_task.set_target_from(self.kin)
        self._J = np.zeros((12, nv))
        self._e = np.zeros(12)
        #: the CoM held at its start's forward offset and height (the extreme's, the projection's)
        self.com_hold = mid + self.com_x * self.fwd
        self.com_hold[2] = self.height
        #: the torso's forward axis across the heading at the start (its yaw, held by
        #: :meth:`extreme` with ``held``)
        self.yaw0 = self._yaw(q)[0]
        if stagger != 0.0 or forward is not None:
            self.q0 = self._project(q, stance=True, steps=30)
            if np.linalg.norm(self._rows(self.q0, self.com_hold)[3]) > 1e-6:
                raise TrajectoryError(
                    f"balance window: the soles cannot stand {stagger * 1e3:.1f} mm apart "
                    "along the heading (the legs do not reach)"
                )

    def _yaw(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """The torso's yaw row: ``x·left`` (x its forward axis; sin of its yaw from the
        heading) and its Jacobian ``(x × left)ᵀ J_ω`` (``dx = ω × x``)."""
        J = pin.computeFrameJacobian(
            self.model, self.data, q, self.fid_torso, pin.LOCAL_WORLD_ALIGNED
        )[3:]
        x = self.data.oMf[self.fid_torso].rotation[:, 0]
        return float(x @ self.left), np.cross(x, self.left) @ J

    # ------------------------------------------------------------------ linearisation
    def _rows(self, q: np.ndarray, com_target: np.ndarray):
        """The rows at ``q`` (as ``J dq = e``): the CoM's toward ``com_target``, the soles'
        stacked, and the torso's tilt ``x`` (sin pitch, −sin roll about the heading, relative
        to the start pose's: ``−e`` of :attr:`tilt_task`) with its Jacobian. Returns
        ``(J_c, e_c, J_s, e_s, x, J_x)``."""
        kin = self.kin
        kin.update(q)
        for k, task in enumerate(self.soles_task):
            task.fill(kin, self._J[6 * k : 6 * k + 6], self._e[6 * k : 6 * k + 6])
        self.com_task.set_target(com_target)
        Jc, ec = self.com_task.compute(kin)
        Jt, e_tilt = self.tilt_task.compute(kin)
        return Jc, ec, self._J.copy(), self._e.copy(), -e_tilt, Jt

    def _bounds(self, q: np.ndarray, trust: float) -> tuple[np.ndarray, np.ndarray]:
        nv = self.model.nv
        lb = np.full(nv, -trust)
        ub = np.full(nv, trust)
        j = q[7:]
        lb[6:] = np.maximum(lb[6:], self.robot.q_min - j)
        ub[6:] = np.minimum(ub[6:], self.robot.q_max - j)
        lb = np.minimum(lb, 0.0)
        ub = np.maximum(ub, 0.0)
        lb[~self.free] = 0.0
        ub[~self.free] = 0.0
        return lb, ub

    def _qp(
        self,
        q: np.ndarray,
        H: np.ndarray,
        g: np.ndarray,
        trust: float,
        G: np.ndarray | None = None,
        h: np.ndarray | None = None,
    ) -> np.ndarray | None:
        """min 1/2 dq' H dq + g' dq s.t. G dq <= h, within the bounds, held joints fixed
        (None if the solver failed)."""
        from qpsolvers import solve_qp

        f = self.free
        lb, ub = self._bounds(q, trust)
        Gf = None if G is None else G[:, f]
        sol = solve_qp(H[np.ix_(f, f)], g[f], G=Gf, h=h, lb=lb[f], ub=ub[f], solver="quadprog")
        if sol is None:
            return None
        dq = np.zeros(self.model.nv)
        dq[f] = sol
        return dq

    def roll(self, q: np.ndarray) -> float:
        """Torso roll about the heading axis (rad): positive tilts its top to the right."""
        pin.framesForwardKinematics(self.model, self.data, q)
        z = self.data.oMf[self.fid_torso].rotation[:, 2]
        return float(-np.arcsin(np.clip(z @ self.left, -1.0, 1.0)))

    # ------------------------------------------------------------------ the two solves
    def extreme(self, max_lean: float, iterations: int = 60, held: bool = False) -> float:
        """Largest lateral CoM offset toward the left sole (SLP with a shrinking trust
        region), torso tilt within ``max_lean``; ``held``: the torso's pitch and yaw held
        at the start's (only its roll leans), as a reference asks of the torso."""
        from scipy.optimize import linprog

        q = self.q0.copy()
        trust = 0.05
        s = np.sin(max_lean)
        best = -np.inf
        for _ in range(iterations):
            Jc, ec, Js, es, tilt, Jt = self._rows(q, self.com_hold)
            lb, ub = self._bounds(q, trust)
            A_eq = np.vstack([Js, Jc[2:3], self.fwd @ Jc])
            b_eq = np.concatenate([es, ec[2:3], [self.fwd @ ec]])
            if held:
                yaw, Jy = self._yaw(q)
                A_eq = np.vstack([A_eq, Jt[0:1], Jy[None]])
                b_eq = np.concatenate([b_eq, [-tilt[0], self.yaw0 - yaw]])
            # |tilt + Jt dq| <= sin(max_lean), per component
            A_ub = np.vstack([Jt, -Jt])
            b_ub = np.concatenate([s - tilt, s + tilt])
            res = linprog(
                -(self.left @ Jc),
                A_ub=A_ub,
                b_ub=np.maximum(b_ub, 0.0),
                A_eq=A_eq,
                b_eq=b_eq,
                bounds=list(zip(lb, ub, strict=True)),
                method="highs",
            )
            if res.status != 0:
                trust *= 0.5
                if trust < 1e-5:
                    break
                continue
            q_new = pin.integrate(self.model, q, res.x)
            com_new = self.robot.com(q_new)
            y_new = float((com_new - self.mid) @ self.left)
            _, _, _, es_new, tilt_new, _ = self._rows(q_new, self.com_hold)
            ok = np.linalg.norm(es_new) < 1e-3 and np.max(np.abs(tilt_new)) <= s + 1e-3
            if ok and y_new >= best - 1e-6:
                q = q_new
                step = float(np.max(np.abs(res.x)))
                best = max(best, y_new)
                if step < 1e-4:
                    break
            else:
                trust *= 0.5
                if trust < 1e-5:
                    break
        # a few corrections onto the constraints, then measure
        q = self._project(q, held=held)
        return float((self.robot.com(q) - self.mid) @ self.left)

    def _project(
        self, q: np.ndarray, held: bool = False, stance: bool = False, steps: int = 10
    ) -> np.ndarray:
        """Newton steps onto the soles and the CoM height (least norm, bounded); ``held``:
        also the torso's pitch and yaw at the start's; ``stance``: the torso upright as at
        the start and the whole CoM at :attr:`com_hold` (a staggered stance's start)."""

        for _ in range(steps):
            Jc, ec, Js, es, tilt, Jt = self._rows(q, self.com_hold)
            rows, errs = [Js, Jc if stance else Jc[2:3]], [es, ec if stance else ec[2:3]]
            if held or stance:
                yaw, Jy = self._yaw(q)
                rows += [Jt if stance else Jt[0:1], Jy[None]]
                errs += [-tilt if stance else -tilt[0:1], [self.yaw0 - yaw]]
            A = np.vstack(rows)
            b = np.concatenate(errs)
            if np.linalg.norm(b) < 1e-10:
                break
            nv = self.model.nv
            sol = self._qp(q, A.T @ A * 1e4 + 1e-6 * np.eye(nv), -1e4 * A.T @ b, 0.1)
            if sol is None:
                break
            q = pin.integrate(self.model, q, sol)
        return q

    def lean_solve(
        self, q: np.ndarray, lateral: float, max_lean: float, iterations: int = 40
    ) -> np.ndarray:
        """Soles and CoM (at ``lateral`` toward the left) first (weight 1e6), then the
        torso's pitch at the start's (:data:`W_PITCH`), its roll upright (:data:`W_ROLL`)
        and a posture toward the start pose (:data:`W_POSTURE`); joint limits hard."""

        target = self.mid + self.com_x * self.fwd + lateral * self.left
        target[2] = self.height
        nv = self.model.nv
        for _ in range(iterations):
            Jc, ec, Js, es, tilt, Jt = self._rows(q, target)
            A1 = np.vstack([Js, Jc])
            b1 = np.concatenate([es, ec])
            dpost = np.zeros(nv)
            dpost[6:] = self.q0[7:] - q[7:]
            Wt = np.array([W_PITCH, W_ROLL])[:, None]
            H = 1e6 * A1.T @ A1 + Jt.T @ (Wt * Jt) + W_POSTURE * np.eye(nv)
            g = -(1e6 * A1.T @ b1 - Jt.T @ (Wt[:, 0] * tilt) + W_POSTURE * dpost)
            # the torso tilt within max_lean (linearised): |tilt + Jt dq| <= sin(max_lean)
            lim = np.sin(max_lean)
            G = np.vstack([Jt, -Jt])
            h = np.maximum(np.concatenate([lim - tilt, lim + tilt]), 0.0)
            sol = self._qp(q, H, g, 0.1, G, h)
            if sol is None:
                raise TrajectoryError("balance window: the lean solve failed (quadprog)")
            q = pin.integrate(self.model, q, sol)
            if np.max(np.abs(sol)) < 1e-9:
                break
        return q


def main(argv: list[str] | None = None) -> int:
    """Print the Bioloid's balance windows: ``python -m wbc.walking.window``."""
    from ..model import load_robot
    from .legs import LegGeometry
    from .reference import StandingState

    robot = load_robot("bioloid")
    start = StandingState.from_robot(robot)
    half = 0.5 * float(start.left.y - start.right.y)
    legs = LegGeometry.from_robot(robot).max_com_lateral(float(start.com[2]), half)
    inner = half - robot.foot_size[1] / 2
    print(f"sole centre {half * 1e3:.1f} mm, inner edge {inner * 1e3:.1f} mm from mid")
    print(f"legs-only model (LegGeometry, torso upright, arms idle): {legs * 1e3:.1f} mm")
    for arms in (True, False):
        for lean in (0.0, 5.0, 10.0, 15.0, 20.0):
            w = BalanceWindow.from_robot(robot, max_lean=np.deg2rad(lean), hold_arms=arms)
            table = ", ".join(
                f"{o * 1e3:.0f} mm {np.rad2deg(r):+.1f}°"
                for o, r in zip(w.offsets[::2], w.rolls[::2], strict=True)
            )
            print(
                f"arms {'held' if arms else 'free'}, lean <= {lean:4.1f}°: max lateral "
                f"{w.max_lateral * 1e3:5.1f} mm (upright {w.upright * 1e3:.1f} mm); roll: {table}"
            )
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
