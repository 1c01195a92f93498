"""Multi-step walking: footsteps -> a checked, time-indexed :class:`WalkingReference`.

:func:`walk` builds the phases (:mod:`.schedule`), both soles' targets with swing
trajectories, the planned ZMP path, and the CoM from one of three ZMP-based generators:

* ``"preview"``: Kajita 2003 preview control of the cart-table model (:mod:`.preview`);
* ``"mpc"``: LIPM MPC over the CoM jerk with the ZMP-in-support-polygon inequalities,
  a casadi QP (:mod:`.mpc`);
* ``"lipm"``: the 3-D LIPM closed form (eqs. 1.65-1.68) around the moving ZMP, initial
  velocities solved per phase, starting from rest (:func:`.lipm.lipm_walk_com`).

The CoM height is constant (the standing CoM height by default). The torso heading is the
mean of the two soles' headings. The reference is checked (:func:`.checks.check_reference`)
before it is returned: bad input raises :class:`~wbc.exceptions.TrajectoryError`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from ..exceptions import TrajectoryError
from .checks import check_reference, lateral_offsets, sole_half_widths
from .footsteps import FootstepPlan, Side, plan_footsteps
from .geometry import Foot
from .legs import LegGeometry
from .lipm import GRAVITY, lipm_walk_com
from .mpc import LipmMpc, MpcParams
from .preview import PreviewController, PreviewParams
from .reference import StandingState, WalkingReference
from .schedule import GaitTiming, SwingParams, build_phases, sample_knots, sole_tracks, zmp_knots
from .spline import min_jerk
from .window import BalanceWindow

Generator = Literal["preview", "mpc", "lipm"]
GENERATORS: tuple[str, ...] = ("preview", "mpc", "lipm")
#: (m) soles within this of the balance window's half-width apart are at its stance
#: (:func:`lean_from_window`): a turning walk's soles sit within 0.9 mm of the standing
#: stance on the Bioloid and 1.0 mm on the OP3; a lateral walk's steps widen it by 12-22 mm
STANCE_TOLERANCE = 0.001
#: the share of a wider stance's extra half-width the whole-body lean is read without
#: (:func:`lean_from_window`; 0: from the soles' midpoint, as before)
LEAN_FROM_STANCE = 0.5


def walk(
    start: StandingState,
    plan: FootstepPlan,
    timing: GaitTiming | None = None,
    swing: SwingParams | None = None,
    generator: Generator = "preview",
    com_height: float | None = None,
    margin: float = 0.001,
    zmp_offset: tuple[float, float] = (0.0, 0.0285),
    min_clearance: float = 0.005,
    foot: Foot | None = None,
    legs: LegGeometry | None = None,
    preview: PreviewParams | None = None,
    mpc: MpcParams | None = None,
    check: bool = True,
    name: str | None = None,
    window: BalanceWindow | None = None,
    transfer: float = 1.0,
    lean_from_stance: float = LEAN_FROM_STANCE,
) -> WalkingReference:
    """A dynamic-gait reference for ``plan`` starting from ``start`` (at rest).

    ``margin`` (m) is the ZMP's required distance inside the support polygon (a constraint
    for the MPC, checked for all generators). ``zmp_offset`` places the planned ZMP in each
    stance sole's frame (x forward, y toward the other foot).

    The defaults fit the Bioloid's narrow lateral window: its hips roll only 5.6 deg inward
    (Annex A), so with the torso upright the CoM may move only ~11 mm sideways from the
    mid-stance (:class:`.legs.LegGeometry`), while the feet's inner edges are 11 mm from
    it. The ZMP path therefore runs 2 mm inside the inner edges (28.5 mm in from the sole
    centres), steps are short and quick (0.4 s, 40 % double support; :class:`GaitTiming`)
    and the margin is 1 mm. ``mpc`` takes :class:`.mpc.MpcParams`; the MPC also keeps the
    hips within their roll limits as constraints, so it copes with other settings too.

    ``window`` (a :class:`.window.BalanceWindow`) makes it a *whole-body* reference: the
    torso leans over the stance foot by the roll the window's solves need for the CoM's
    lateral offset (``torso_roll``), the arms are free, and the CoM is checked against the
    window instead of the legs-only hip roll model; the ZMP may then run well inside the
    soles (e.g. ``zmp_offset = (0, 0.018)``, ``margin = 0.01``).

    ``transfer`` (0–1]: the share of each double support within which the planned ZMP
    reaches the sole that just landed (:func:`.schedule.zmp_knots`; 1: over the whole
    double support). A shorter transfer shifts the lateral sway earlier: the DCM has crossed
    over the new stance sole while both soles are down (:func:`narrow_sway`).

    ``lean_from_stance`` (0–1): where the soles are wider apart than the window's stance,
    the share of the extra half-width the whole-body lean is read without
    (:func:`lean_from_window`; 0: from the soles' midpoint).
    """
    timing = timing or GaitTiming()
    swing = swing or SwingParams()
    foot = foot or start.foot
    legs = legs or start.legs
    if generator not in GENERATORS:
        raise TrajectoryError(f"unknown CoM generator {generator!r}; use one of {GENERATORS}")
    timing.validate()
    swing.validate()
    if not (np.isfinite(margin) and margin >= 0):
        raise TrajectoryError(f"walk: the margin must be >= 0, got {margin}")
    height = float(start.com[2]) if com_height is None else float(com_height)
    legs.check_com_height(height, "walk")
    for a, b in ((start.left, plan.start_left), (start.right, plan.start_right)):
        if np.linalg.norm(a.position - b.position) > 1e-6 or abs(a.yaw - b.yaw) > 1e-6:
            raise TrajectoryError(
                f"walk: the plan's start placement of the {a.side} sole differs from the start "
                "state's (the robot would have to jump)"
            )
    plan.validate(foot, legs, height, min_clearance)

    _check_double_support(generator, timing, mpc, len(plan.steps))

    phases = build_phases(plan, timing)
    dt = timing.dt
    soles = sole_tracks(plan, phases, dt, swing)
    t = soles.t
    kt, kp = zmp_knots(plan, phases, start.com[:2], zmp_offset, transfer=transfer)
    zref = sample_knots(kt, kp, t)
    # torso heading: the mean of the soles' headings
    torso_yaw = soles.torso_yaw()

    meta: dict[str, Any] = {
        "generator": generator,
        "timing": timing.__dict__,
        "swing": swing.__dict__,
        "zmp_offset": list(zmp_offset),
        "transfer": transfer,
    }
    if generator in ("preview", "lipm"):
        pos, vel, acc = _com_for_zmp(generator, kt, kp, zref, start.com[:2], height, t,
                                     phases[0].t1, preview, meta)  # fmt: skip
    else:
        params = mpc or MpcParams()
        solver = LipmMpc(height, params)
        hip_legs = legs if params.hip_roll and window is None else None
        result = solver.solve_walk(t, soles, foot, zref, start.com[:2], margin, hip_legs, torso_yaw)
        pos, vel, acc = result.pos, result.vel, result.acc
        meta["mpc"] = {
            **params.__dict__,
            "solve_time": result.solve_time,
            "build_time": result.build_time,
            "n_qp": result.n_qp,
            "n_variables": result.n_variables,
            "n_constraints": result.n_constraints,
            "status": result.status,
        }

    com = np.column_stack([pos, np.full(len(t), height)])
    com_vel = np.column_stack([vel, np.zeros(len(t))])
    com_acc = np.column_stack([acc, np.zeros(len(t))])
    if abs(height - start.com[2]) > 1e-9:  # move to the walking height during the start phase
        s = t / phases[0].t1
        f, df, ddf = min_jerk(s)
        com[:, 2] = start.com[2] + (height - start.com[2]) * f
        com_vel[:, 2] = (height - start.com[2]) * df / phases[0].t1
        com_acc[:, 2] = (height - start.com[2]) * ddf / phases[0].t1 ** 2
    ref = WalkingReference(
        t=t,
        com=com,
        com_vel=com_vel,
        com_acc=com_acc,
        **soles.reference_fields(),
        com_height=height,
        plan=plan,
        gait="dynamic",
        name=name or f"walk-{generator}",
        zmp_ref=zref,
        foot=foot,
        margin=margin,
        meta=meta,
    )
    if window is not None:
        lean_from_window(ref, window, lean_from_stance)
    if check:
        report = check_reference(
            ref, margin=margin, min_clearance=min_clearance, legs=legs, window=window
        )
        ref.meta["check"] = report.as_dict()
    return ref


def _com_for_zmp(
    generator: str,
    kt: np.ndarray,
    kp: np.ndarray,
    zref: np.ndarray,
    start_xy: np.ndarray,
    height: float,
    t: np.ndarray,
    t_start: float,
    preview: PreviewParams | None,
    meta: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CoM (pos, vel, acc, each (N, 2)) of the ``"preview"`` or ``"lipm"`` generator for
    the ZMP path (knots ``kt``, ``kp``; sampled ``zref``), from rest at ``start_xy``; records
    the generator's parameters in ``meta``."""
    if generator == "preview":
        ctrl = PreviewController(float(t[1] - t[0]), height, preview)
        x0 = np.zeros((3, 2))
        x0[0] = start_xy
        pos, vel, acc, _ = ctrl.run(zref, x0)
        meta["preview"] = ctrl.params.__dict__
        return pos, vel, acc
    tc = float(np.sqrt(height / GRAVITY))
    meta["lipm_tc"] = tc
    return lipm_walk_com(kt, kp, start_xy, tc, t, t_start)


def narrow_sway(
    ref: WalkingReference, transfer: float, inward: bool = True, longest: float = math.inf
) -> WalkingReference:
    """``ref`` re-planned by its own generator with a narrower, earlier lateral sway: the ZMP
    reaches each landed sole within the first ``transfer`` (0–1] of the double support
    (:func:`walk`'s ``transfer``) and, with ``inward``, runs in single support as far toward
    the other sole as the walk's margin allows (its ``zmp_offset`` widened until the ZMP is
    ``ref.margin`` from the sole's inner edge). Same soles, schedule and footsteps; the CoM
    is the generator's for the new ZMP path, so CoM and ZMP stay consistent and the ZMP keeps
    ``ref.margin`` inside the support polygon (:func:`.checks.check_reference`'s criterion;
    where ``ref`` itself keeps less, at least what it keeps). At mid single support the DCM
    is then further from the stance sole's outer edge: the closed loop walks this
    (:class:`wbc.balance.stabilizer.Gains` ``transfer``).

    Returns ``ref`` itself when it was not made by :func:`walk` with the ``"preview"`` or
    ``"lipm"`` generator (a static gait, the MPC, another source), has no double support,
    has single supports longer than ``longest`` (s), or cannot be re-planned within its
    margin."""
    if not (np.isfinite(transfer) and 0.0 < transfer <= 1.0):
        raise TrajectoryError(f"narrow_sway: transfer must be in (0, 1], got {transfer}")
    meta = ref.meta
    if ref.gait != "dynamic" or meta.get("generator") not in ("preview", "lipm"):
        return ref
    if "timing" not in meta or "zmp_offset" not in meta:
        return ref
    timing = GaitTiming(**meta["timing"])
    phases = build_phases(ref.plan, timing)
    if phases[-1].i1 != ref.n or not any(ph.kind == "double" for ph in phases):
        return ref
    if timing.single_support_time > longest + 1e-9:
        return ref
    floor = np.minimum(ref.zmp_margin(), ref.margin) - 1e-9
    x, y = (float(v) for v in meta["zmp_offset"])
    widest = 0.5 * ref.foot.width - ref.margin  # the ZMP ref.margin from the inner edge
    offset = (x, max(y, widest) if inward else y)
    for _ in range(4):  # the generator tracks its path within ~0.1 mm: correct the offset
        out = _replan(ref, phases, offset, transfer)
        short = float(np.max(floor - out.zmp_margin()))
        if short <= 0:
            return out
        if offset[1] - short < y - 1e-9:
            return ref
        offset = (x, offset[1] - short - 1e-6)
    return ref


def _replan(
    ref: WalkingReference, phases: list, offset: tuple[float, float], transfer: float
) -> WalkingReference:
    """``ref``'s CoM planned again by its generator along the ZMP path of ``offset`` and
    ``transfer`` (:func:`narrow_sway`); the torso roll of a whole-body reference with it."""
    meta = ref.meta
    generator = meta["generator"]
    t = ref.t - ref.t[0]
    kt, kp = zmp_knots(ref.plan, phases, ref.com[0, :2], offset, transfer=transfer)
    zref = sample_knots(kt, kp, t)
    new_meta = dict(meta, zmp_offset=list(offset), transfer=transfer)
    preview = PreviewParams(**meta["preview"]) if generator == "preview" else None
    pos, vel, acc = _com_for_zmp(generator, kt, kp, zref, ref.com[0, :2], ref.com_height, t,
                                 phases[0].t1, preview, new_meta)  # fmt: skip
    com, com_vel, com_acc = ref.com.copy(), ref.com_vel.copy(), ref.com_acc.copy()
    com[:, :2], com_vel[:, :2], com_acc[:, :2] = pos, vel, acc
    out = dataclasses.replace(
        ref, com=com, com_vel=com_vel, com_acc=com_acc, zmp_ref=zref, meta=new_meta
    )
    table = meta.get("window", {})
    if ref.torso_roll is not None and "offsets" in table:  # the torso leans for the new CoM
        lean_from_window(
            out, BalanceWindow.from_dict(table), float(table.get("lean_from_stance", 0.0))
        )
    return out


def lean_from_window(
    ref: WalkingReference, window: BalanceWindow, from_stance: float = LEAN_FROM_STANCE
) -> None:
    """Plan the torso roll of a whole-body reference (in place): the roll the balance
    window's solves use for the CoM's lateral offset from the soles' midpoint.

    ``from_stance`` (0–1): where the soles are further apart than at the window's stance (a
    lateral walk's steps), that share of the extra half-width, less :data:`STANCE_TOLERANCE`,
    is taken off the offset (0 when the CoM is nearer the midpoint than that).
    1 reads the offset at the window's stance: the CoM's distance to the nearer sole is
    the one the window's solve at that roll has; 0 reads it from the wider stance's midpoint,
    which overstates the lean and reverses it fast across each wide double support
    (``lateral_wb``: 5.6 deg at most, reversing at 53 deg/s; 1: 4.5 deg, 36 deg/s; 0.5:
    4.7 deg). The default, :data:`LEAN_FROM_STANCE`, is the measured one
    (benchmarks/physics.md, issue 30's eleventh pass)."""
    if not (np.isfinite(from_stance) and 0.0 <= from_stance <= 1.0):
        raise TrajectoryError(f"lean_from_window: from_stance must be in [0, 1], got {from_stance}")
    lateral = lateral_offsets(ref)
    if from_stance > 0.0:
        wider = sole_half_widths(ref) - window.half_width
        extra = np.maximum(from_stance * wider - STANCE_TOLERANCE, 0.0)
        lateral = np.sign(lateral) * np.maximum(np.abs(lateral) - extra, 0.0)
    ref.torso_roll = np.asarray(window.roll_for(lateral), dtype=float)
    ref.meta["window"] = {
        **window.as_dict(),  # (the whole table: narrow_sway plans the roll again)
        "max_roll": float(np.max(np.abs(ref.torso_roll))),
        "lean_from_stance": float(from_stance),
    }


def _check_double_support(
    generator: str, timing: GaitTiming, mpc: MpcParams | None, n_steps: int
) -> None:
    """The cart-table ZMP of a jerk-driven CoM is continuous: it cannot jump from foot to
    foot, so the preview and MPC generators need double-support phases (for the MPC, at
    least two samples long: a shorter transfer asks for extreme jerks)."""
    if generator == "lipm" or n_steps < 2:
        return
    ds = timing.double_support_time
    if generator == "mpc":
        sample = timing.dt * 2 if mpc is None or mpc.sample_time is None else mpc.sample_time
        need = 2 * sample
    else:
        need = timing.dt
    if ds < need - 1e-12:
        raise TrajectoryError(
            f"walk: the {generator!r} generator needs double support of at least "
            f"{need:.3f} s between steps (the ZMP of a jerk-driven CoM cannot jump between "
            f"feet), got {ds:.3f} s; raise double_support_ratio or use generator 'lipm'"
        )


def walk_steps(
    start: StandingState,
    n_steps: int = 10,
    stride: Sequence[float] = (0.035, 0.0, 0.0),
    first_side: Side | None = None,
    close: bool = True,
    **kwargs: Any,
) -> WalkingReference:
    """:func:`walk` along :func:`.footsteps.plan_footsteps` (``stride = (dx, dy, dyaw)``)."""
    plan = plan_footsteps(start.left, start.right, n_steps, stride, first_side, close)
    ref = walk(start, plan, **kwargs)
    ref.meta["stride"] = [float(v) for v in stride]
    return ref


def forward_walk(
    start: StandingState, n_steps: int = 10, step_length: float = 0.035, **kw: Any
) -> WalkingReference:
    """Straight walk (backward with a negative ``step_length``)."""
    kw.setdefault("name", f"forward-{n_steps}" if step_length >= 0 else f"backward-{n_steps}")
    return walk_steps(start, n_steps, (step_length, 0.0, 0.0), **kw)


def lateral_walk(
    start: StandingState, n_steps: int = 6, step_width: float = 0.02, **kw: Any
) -> WalkingReference:
    """Side-stepping (to the left for a positive ``step_width``)."""
    kw.setdefault("name", f"lateral-{n_steps}")
    return walk_steps(start, n_steps, (0.0, step_width, 0.0), **kw)


def turning_walk(
    start: StandingState, n_steps: int = 8, step_length: float = 0.02, turn: float = 0.2, **kw: Any
) -> WalkingReference:
    """Walking on an arc: ``turn`` rad per step (to the left if positive)."""
    kw.setdefault("name", f"turning-{n_steps}")
    return walk_steps(start, n_steps, (step_length, 0.0, turn), **kw)
