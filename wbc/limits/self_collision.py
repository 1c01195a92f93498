"""Self-collision avoidance: distance rows between link pairs, in velocity-damper form.

The collision math is kept apart from the :class:`Constraint` glue at the bottom:

* :func:`candidate_pairs` / :func:`choose_pairs` — which geometry pairs can meet: not on the
  same joint, not on adjacent joints, and closer than a threshold in at least one of
  ``samples`` random configurations within the joint limits (computed once, seeded);
* :mod:`wbc.limits.collision_boxes` — the robot's collision boxes, their frames and the
  Lipschitz bounds of the pairs' distances (the broad phase);
* :class:`PairDistances` — signed distance d, witness points p1, p2 and normal n (p1 → p2)
  of the pairs, compiled (:mod:`wbc.limits.collision_kernels`, one call per tick with the rows);
* :func:`~wbc.limits.collision_reference.distance_jacobian`,
  :func:`~wbc.limits.collision_reference.separating_plane_rows` — the rows' numpy forms (the
  tests compare the kernels to them): J_d = nᵀ (J_b − J_a) for the box corners near the
  separating plane, each paired with its projection on the other box, and the witness pair
  where it stands for itself (parallel features: the witness is any point of their overlap,
  picked by rounding; the corners' rows do not depend on it, so the rows are continuous in q);
* :func:`damper_bound` — h(d) of the rows −J_d Δq <= h(d): the velocity damper
  d + J_d Δq >= margin + (1 − ξ)(d − margin), i.e. at most a fraction ξ of the gap to the
  margin closes in one tick, relaxed smoothly towards the trigger, never past a fraction
  c = :data:`~wbc.limits.collision_kernels.MAX_CLOSURE` of that gap.

Activation: with m = margin, T = trigger, ξ = damping and c = MAX_CLOSURE (0.9),

    h(d) = min(ξ (d − m) · (T − m) / (T − d), c (d − m))   for m <= d < T,
    h(d) = −ξ · min(m − d, m)                               for d < m (the pair moves back out),

and no row for d >= T. Inside the margin (h < 0: Δq = 0 does not meet the row, which asks the
pair to separate) the rate is a fraction ξ of the gap to the margin per tick, capped at ξ m: a
start deep inside (boxes overlapping, e.g. joints outside their limits) is never asked to jump
out in one tick (:func:`~wbc.limits.limit.way_back`). Where the hard tasks and the way back of
joints outside their limits leave no room even for that, the solver ranks these rows below
both, as the best achievable separation (:meth:`SelfCollisionConstraint.split`,
:meth:`wbc.solvers.base.StackSolver.solve`); the rows of the pairs outside the margin are
never relaxed.

h is continuous and increasing below T, C¹ at d = m (for ξ <= c), Lipschitz with constant
max(ξ, c²/ξ) (the relaxed branch binds below T − ξ (T − m)/c = 13.3 mm with the defaults, the
cap above), and h(d) <= c (d − m) for every d < T: a tick whose rows hold to first order
closes at most 90 % of the gap to the margin, wherever it starts (stress trial 5101 with
``common_frame``: 15.56 mm, uncapped h = 1.35 (d − m), crossed to 2.97 mm). The price: at
T the row appears with h = c (T − m) (13.5 mm), not +∞, so the QP's solution jumps there
when a tick would close more than that — the ticks that would otherwise cross the margin.
The linearised tick's second order remains (the tests pull links together at <= 0.1 m/s and
stay within 0.5 mm of the margin). ``UNREACHABLE`` drops no row with the defaults (h <= c (T
− m)).

Never a silent result: at a hard level, a pair more than :data:`RECOVERY_TOL` inside its
margin for more than :data:`RECOVERY_TICKS` control ticks in a row (the hard tasks hold it:
both soles pinning crossed legs) raises :class:`~wbc.exceptions.InfeasibleError` naming the
pair (:meth:`SelfCollisionConstraint.solved`, called by the solvers after each solve).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..compiled.entry import entry_point
from ..exceptions import ConfigurationError, InfeasibleError
from ..model import Kinematics, Robot
from .collision_boxes import CollisionModel, collision_model
from .collision_distances import PairDistances, Witness
from .collision_kernels import MAX_CLOSURE
from .collision_packed import ROW_PLACER, pack, packed_rows
from .limit import Constraint, Inequality, way_back

#: defaults: 5 mm kept between any two links (placo's default), rows below 20 mm, and at most
#: 40 % of the gap to the margin closed per tick near it
DEFAULT_MARGIN = 0.005
DEFAULT_TRIGGER = 0.02
DEFAULT_DAMPING = 0.4
#: a bound past which a row is left out (m of closure in one tick: no two links of a small
#: humanoid can approach by 1 m; h <= MAX_CLOSURE (trigger − margin) keeps every row below it)
UNREACHABLE = 1.0
#: random configurations used to find the pairs that can meet
DEFAULT_SAMPLES = 600
#: a pair more than RECOVERY_TOL (m: a linearised tick's second order, as the damper's tests
#: allow) inside its margin must be back in at most RECOVERY_TICKS ticks in a row (from 4 mm
#: inside, the damper's way back leaves 4 mm · 0.6²⁵ ≈ 1e-8 m), else InfeasibleError
#: naming it (the hard tasks hold it inside: a hard level that cannot be met)
RECOVERY_TICKS = 25
RECOVERY_TOL = 5e-4
KEPT_ENTRIES = 8  # (the kernel's entry points kept: one per G, h written, a plan's a phase)


def _link_pairs(pairs: Iterable[Sequence[str]], links: set[str], what: str) -> set[frozenset]:
    out = set()
    for pair in pairs:
        if len(pair) != 2 or not all(isinstance(n, str) for n in pair):
            raise ConfigurationError(f"self_collision {what}: expected [link, link], got {pair!r}")
        unknown = [n for n in pair if n not in links]
        if unknown:
            raise ConfigurationError(
                f"self_collision {what}: unknown link(s) {unknown}; links with collision "
                f"geometry: {sorted(links)}"
            )
        out.add(frozenset(pair))
    return out


#: a joint offset shorter than this (m) makes its parent's link zero-length
ZERO_LENGTH = 1e-6


def adjacency(model: pin.Model, a: int, b: int) -> str | None:
    """Why two bodies (joints a, b) are left out by their kinematics alone, or None: the same
    body (rigidly attached), parent and child, or parent and child through links of zero
    length (a joint offset below :data:`ZERO_LENGTH`: a hip or an ankle whose two or three
    axes cross — the bodies touch at the joint whatever the angles)."""
    if a == b:
        return "on one body"
    parents = model.parents
    if parents[a] == b or parents[b] == a:
        return "adjacent joints"
    for top, low in ((a, b), (b, a)):
        x, through = low, []
        while parents[x] > 0 and parents[x] != top:
            if np.linalg.norm(model.jointPlacements[x].translation) > ZERO_LENGTH:
                break
            x = parents[x]
            through.append(model.names[x])
        else:
            if parents[x] == top and through:
                return f"adjacent through the zero-length link of {', '.join(through)}"
    return None


def candidate_pairs(
    robot: Robot,
    cm: CollisionModel,
    include: Iterable[Sequence[str]] = (),
    exclude: Iterable[Sequence[str]] = (),
) -> list[tuple[int, int]]:
    """Geometry pairs (i < j) that :func:`adjacency` keeps and whose links are not in
    ``exclude``; ``include`` forces link pairs in (any but two geometries of one body)."""
    return _candidates(robot, cm, include, exclude)[0]


def _candidates(
    robot: Robot,
    cm: CollisionModel,
    include: Iterable[Sequence[str]] = (),
    exclude: Iterable[Sequence[str]] = (),
) -> tuple[list[tuple[int, int]], list[tuple[int, int, str]]]:
    """(candidate pairs, pairs left out with the reason)."""
    links = set(cm.links)
    inc = _link_pairs(include, links, "include")
    exc = _link_pairs(exclude, links, "exclude")
    out, left = [], []
    n = len(cm.links)
    for i in range(n):
        for j in range(i + 1, n):
            key = frozenset((cm.links[i], cm.links[j]))
            a, b = int(cm.joints[i]), int(cm.joints[j])
            why = adjacency(robot.model, a, b)
            if key in inc and a != b:
                out.append((i, j))
            elif why is not None:
                left.append((i, j, why))
            elif key in exc:
                left.append((i, j, "excluded by the stack"))
            else:
                out.append((i, j))
    return out, left


def sampled_min_distances(
    robot: Robot,
    cm: CollisionModel,
    pairs: Sequence[tuple[int, int]],
    samples: int,
    seed: int,
    poses: Sequence[np.ndarray] | None = None,
) -> np.ndarray:
    """Smallest signed distance of each pair over ``samples`` configurations drawn uniformly
    within the joint limits and ``poses`` (default: q = 0 and the robot's named poses)."""
    geometry = cm.geometry.copy()
    geometry.removeAllCollisionPairs()
    for i, j in pairs:
        geometry.addCollisionPair(pin.CollisionPair(i, j))
    gdata = pin.GeometryData(geometry)
    data = robot.model.createData()
    rng = np.random.default_rng(seed)
    if poses is None:
        poses = [robot.neutral()]
        if robot.servo_map is not None:
            poses += [robot.configuration(name) for name in sorted(robot.servo_map.poses)]
    best = np.full(len(pairs), np.inf)
    for k in range(samples + len(poses)):
        q = poses[k] if k < len(poses) else robot.random_configuration(rng)
        pin.computeDistances(robot.model, data, geometry, gdata, q)
        d = np.fromiter((r.min_distance for r in gdata.distanceResults), float, len(pairs))
        np.minimum(best, d, out=best)
    return best


class PairChoice(NamedTuple):
    """Which geometry pairs a robot's self-collision limit checks, and why the others are
    left out (:func:`choose_pairs`)."""

    included: list[tuple[int, int]]
    excluded: list[tuple[int, int, str]]  # (geometry, geometry, reason)
    links: tuple[str, ...]  # link of each geometry
    names: tuple[str, ...]  # name of each geometry

    def excluded_links(self, kinds: tuple[str, ...] = ()) -> list[tuple[str, str, str]]:
        """(link, link, reason) of each link pair with a pair left out (its first reason),
        only those whose reason contains one of ``kinds`` if given."""
        out: dict[frozenset, tuple[str, str, str]] = {}
        for i, j, why in self.excluded:
            if kinds and not any(k in why for k in kinds):
                continue
            key = frozenset((self.links[i], self.links[j]))
            out.setdefault(key, (self.links[i], self.links[j], why))
        return list(out.values())


#: the reasons of :func:`choose_pairs` that ``wbc robot check`` lists
LISTED_REASONS = ("adjacent through", "boxes overlap", "within the margin")


def choose_pairs(
    robot: Robot,
    margin: float = DEFAULT_MARGIN,
    trigger: float = DEFAULT_TRIGGER,
    include: Iterable[Sequence[str]] = (),
    exclude: Iterable[Sequence[str]] = (),
    samples: int = DEFAULT_SAMPLES,
    seed: int = 0,
) -> PairChoice:
    """The geometry pairs of ``robot`` that its self-collision limit checks: every pair but

    * two geometries of one body, or of a parent and a child joint, also through links of
      zero length (:func:`adjacency`: the bodies meet at the joint by construction);
    * pairs closer than ``margin`` at the robot's standing pose (``robot.configuration
      ("stand")``): boxes drawn touching or overlapping there, which hard rows would have
      to push apart before the robot could stand;
    * pairs never closer than ``trigger`` in ``samples`` random configurations within the
      joint limits (seeded; plus q = 0 and the named poses: a heuristic, a pair that meets
      only in a tiny corner of the joint space can be missed — name it in ``include``);
    * link pairs in ``exclude``;

    ``include`` forces link pairs in. Each pair left out comes with its reason."""
    if samples < 0:
        raise ConfigurationError(f"self_collision samples must be >= 0, got {samples}")
    cm = _cached_collision_model(robot)
    include = [tuple(p) for p in include]
    pairs, left = _candidates(robot, cm, include, exclude)
    forced = _link_pairs(include, set(cm.links), "include")
    names = tuple(g.name for g in cm.geometry.geometryObjects)
    if pairs:
        stand = robot.configuration("stand")
        standing = sampled_min_distances(robot, cm, pairs, 0, seed, poses=[stand])
        best = sampled_min_distances(robot, cm, pairs, samples, seed) if samples else None
        kept = []
        for k, p in enumerate(pairs):
            d = standing[k]
            if frozenset((cm.links[p[0]], cm.links[p[1]])) in forced:
                kept.append(p)
            elif d < 0:
                why = f"boxes overlap by {-d * 1e3:.1f} mm at the standing pose"
                left.append((*p, why))
            elif d < margin:
                why = f"{d * 1e3:.1f} mm apart at the standing pose: within the margin"
                left.append((*p, f"{why} ({margin * 1e3:g} mm)"))
            elif best is not None and best[k] >= trigger:
                why = f"never closer than {trigger * 1e3:g} mm in {samples} sampled poses"
                left.append((*p, why))
            else:
                kept.append(p)
        pairs = kept
    return PairChoice(pairs, left, cm.links, names)


def pair_report(robot: Robot, margin: float = DEFAULT_MARGIN) -> list[tuple[str, str]]:
    """``wbc robot check``'s lines about self-collision, as (level, message): how many pairs
    the default limit checks, each link pair left out because it is adjacent through a
    zero-length link or within the margin at the standing pose (note), and a warning for
    each pair of boxes that overlap at the standing pose."""
    choice = choose_pairs(robot, margin)
    out = [
        (
            "ok",
            f"self-collision: {len(choice.included)} pairs of collision boxes checked "
            f"(margin {margin * 1e3:g} mm), {len(choice.excluded)} left out",
        )
    ]
    for a, b, why in choice.excluded_links(LISTED_REASONS):
        level = "warning" if "overlap" in why else "note"
        out.append((level, f"self-collision: {a} / {b} not checked: {why}"))
    return out


def damper_bound(distance: np.ndarray, margin: float, trigger: float, damping: float):
    """h(d) of the rows −J_d Δq <= h(d) (see the module docstring); +inf for d >= trigger."""
    d = np.asarray(distance, dtype=float)
    gap = d - margin
    with np.errstate(divide="ignore", invalid="ignore"):  # (d >= trigger: replaced below)
        relaxed = damping * gap * (trigger - margin) / np.maximum(trigger - d, 0.0)
    # outside: at most MAX_CLOSURE of the gap; inside: separate at rate ξ, at most ξ m per tick
    outside = np.minimum(relaxed, MAX_CLOSURE * gap)
    h = np.where(gap > 0, outside, way_back(-gap, damping, damping * margin))
    return np.where(d < trigger, h, np.inf)


def inside_margin(rows: Inequality) -> np.ndarray:
    """Which damper rows are inside the margin: h(d) < 0, a request to move apart that
    Δq = 0 does not meet (the rows at or outside it have h >= 0)."""
    return rows.h < 0.0


def check_parameters(margin: float, trigger: float, damping: float) -> None:
    """One clear line for each bad parameter."""
    for key, value in (("margin", margin), ("trigger", trigger), ("damping", damping)):
        if not isinstance(value, (int, float)) or not np.isfinite(value):
            raise ConfigurationError(f"self_collision {key} must be a number, got {value!r}")
    if margin < 0:
        raise ConfigurationError(f"self_collision margin must be >= 0 m, got {margin}")
    if trigger <= margin:
        raise ConfigurationError(
            f"self_collision trigger ({trigger} m) must be larger than the margin ({margin} m)"
        )
    if not 0 < damping <= 1:
        raise ConfigurationError(f"self_collision damping must be in (0, 1], got {damping}")


# ---------------------------------------------------------------------- Constraint glue
class SelfCollisionConstraint(Constraint):
    """No two links closer than ``margin`` (m): velocity-damper rows for the pairs closer
    than ``trigger``, with the smooth activation of the module docstring.

    ``pairs``: explicit link pairs (skips the selection); otherwise the pairs that can meet
    (:func:`choose_pairs`, ``samples`` random configurations, seeded) plus ``include``, minus
    ``exclude``. ``common_frame`` (the default; ``False``: the world's): each row's normal
    fixed in the frame of the joints that carry both links (their columns 0: a common rotation
    changes no distance), not in the world, whose rotating normal moves a pair's two points
    apart along it on the base's columns: degenerate active sets, `walk_strict`'s slow ticks
    (benchmarks/self_collision.md, ninth and tenth passes: its p99 2–3× lower; safe with the
    damper's cap MAX_CLOSURE, stress trial 5101: 6.58 mm). Usable at
    any level of :class:`~wbc.solvers.TaskStack`; rows below the pulling tasks' level are what
    make it hold (inside one level it trades with the tasks).
    """

    held_rows_met = True  # the pairs inside the margin are requests (:meth:`split`)

    def __init__(
        self,
        robot: Robot,
        margin: float = DEFAULT_MARGIN,
        trigger: float = DEFAULT_TRIGGER,
        damping: float = DEFAULT_DAMPING,
        include: Iterable[Sequence[str]] = (),
        exclude: Iterable[Sequence[str]] = (),
        pairs: Iterable[Sequence[str]] | None = None,
        samples: int = DEFAULT_SAMPLES,
        seed: int = 0,
        name: str = "self_collision",
        common_frame: bool = True,
        cut_in_box: bool = False,
        in_tick: bool = True,
    ) -> None:
        super().__init__(name)
        check_parameters(margin, trigger, damping)
        flags = (("common_frame", common_frame), ("cut_in_box", cut_in_box), ("in_tick", in_tick))
        for flag, value in flags:
            if not isinstance(value, bool):
                raise ConfigurationError(
                    f"self_collision {flag} must be true or false, got {value!r}"
                )
        #: a compiled plan passes its tick's box to :meth:`rows_into`, which leaves out the
        #: rows that cannot bind in it (``cut_in_box``; off by default: the kernel's test
        #: costs about what the cascade saves, benchmarks/self_collision.md, fifteenth session)
        self.rows_in_box = cut_in_box
        #: a compiled plan makes the rows inside its tick (``in_tick``, the default:
        #: :attr:`row_placer`, one call from Python for the rows and the solve, bit for bit
        #: the rows made before it), else before it (:meth:`rows_into`)
        self.in_tick = in_tick
        self.robot = robot
        #: [margin, trigger, damping, UNREACHABLE, common_frame, 1: the rows that cannot bind
        #: in the box left out] (read by the kernel)
        self._params = np.array(
            [margin, trigger, damping, UNREACHABLE, common_frame, 0.0], dtype=float
        )
        cm = _cached_collision_model(robot)
        #: the robot's pair choice (None: explicit ``pairs``)
        self.choice: PairChoice | None = None
        if pairs is not None:
            wanted = _link_pairs(pairs, set(cm.links), "pairs")
            chosen = [
                p
                for p in candidate_pairs(robot, cm, include=[tuple(w) for w in wanted])
                if frozenset((cm.links[p[0]], cm.links[p[1]])) in wanted
            ]
        else:
            key = (
                "pairs",
                self.margin,
                self.trigger,
                tuple(map(tuple, include)),
                tuple(map(tuple, exclude)),
                samples,
                seed,
            )
            cache = robot.__dict__.setdefault("_self_collision_pairs", {})
            if key not in cache:
                cache[key] = choose_pairs(
                    robot, self.margin, self.trigger, include, exclude, samples, seed
                )
            self.choice = cache[key]
            chosen = self.choice.included
        self.pair_links = [(cm.links[i], cm.links[j]) for i, j in chosen]
        self.pair_geoms = [
            (cm.geometry.geometryObjects[i].name, cm.geometry.geometryObjects[j].name)
            for i, j in chosen
        ]
        self.distances = PairDistances(robot, cm, chosen)
        most = 17 * len(chosen)  # rows per pair at most: the witness and 8 + 8 corners
        self._G, self._h = np.zeros((most, robot.nv)), np.zeros(most)
        self._empty = np.zeros(0)
        self._pair_buf, self._gap_buf = np.zeros(most, np.int64), np.zeros(most)
        #: per pair: the control ticks in a row that found it deep inside the margin
        self._inside = np.zeros(len(chosen), np.int64)
        self._counting = False  # (any of _inside non-zero)
        self._out = self.distances.out_buffers()  # (last compute's close pairs)
        self._last: Witness | None = None  # (built from _out when asked: :attr:`last`)
        self._rows: Inequality | None = None  # (copies of the last rows, made when asked)
        self._n_rows = 0
        #: the configuration of the last rows (NaN: none yet), and the kernel's buffers by
        #: address (:data:`~wbc.limits.collision_packed.PACKED`; made at the first compute,
        #: dropped by a copy: :meth:`__getstate__`)
        self._rows_q = np.full(robot.nq, np.nan)
        self._closest = np.full(1, np.inf)  # (the close pairs' smallest distance: the kernel)
        self._packed: tuple | None = None
        #: the box's limits (q_min, q_max, steps: :meth:`rows_into`'s ``box``) packed, and
        #: the kernel's box scratch (6 x nv: :func:`~wbc.limits.collision_packed.packed_rows`)
        self._box: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._boxed = False  # (params[5] as written)
        self._box_work = np.full((6, robot.nv), np.nan)
        #: the kernel's arguments for one Kinematics, its entry points by the buffers written
        self._call: tuple | None = None
        self._entries: dict[tuple[int, int], tuple] = {}
        #: where the last rows are: (G, h, first row) — the limit's own buffers, or a
        #: compiled plan's (:meth:`rows_into`)
        self._where: tuple[np.ndarray, np.ndarray, int] = (self._G, self._h, 0)
        #: :meth:`snapshot`'s (buffer, backup) pairs
        self._backups: list[tuple[np.ndarray, np.ndarray]] = []

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_packed"] = None  # (addresses of this object's buffers: a copy re-packs)
        state["_call"], state["_entries"] = None, {}  # (the same, a Kinematics' views)
        state["_backups"] = []
        if self._where[0] is not self._G:  # (the last rows in a plan's buffers: made again)
            state["_where"] = (self._G, self._h, 0)
            state["_rows_q"] = np.full(self.robot.nq, np.nan)
        return state

    margin = property(lambda self: float(self._params[0]), doc="kept between links (m)")
    trigger = property(lambda self: float(self._params[1]), doc="rows below it (m)")
    damping = property(lambda self: float(self._params[2]), doc="ξ: closed per tick")
    common_frame = property(
        lambda self: bool(self._params[4]), doc="rows' normals fixed in the pair's common frame"
    )

    def _pack(self) -> tuple:
        """(addresses, shapes, buffers) of :func:`~wbc.limits.collision_packed.packed_rows`."""
        pd = self.distances
        buffers = (
            self._rows_q, pd._q, pd._bound, pd._L_start, pd._L_pair, pd._L_arm, pd.box_frame,
            pd.box_R, pd.box_p, pd.half, pd.radius, pd.pair_a, pd.pair_b, pd.support, pd.Rw,
            pd.cw, pd._placed,
            *self._out, pd._counts, self._pair_buf, self._gap_buf,
            self._params, self._closest, pd._last_axis, pd._work, pd._iwork,
            *(self._box if self._box is not None else (self._empty,) * 3), self._box_work,
        )  # fmt: skip
        self._packed = (*pack(buffers), buffers)
        return self._packed

    @property
    def _n_close(self) -> int:
        """The close pairs of the last rows (the kernel's count, read when asked)."""
        return int(self.distances._counts[2])

    @property
    def n_pairs(self) -> int:
        return len(self.pair_links)

    def witness(self, kin: Kinematics, below: float | None = None) -> Witness:
        """The pairs closer than ``below`` (default: the trigger) at ``kin``."""
        return self.distances.below(kin, self.trigger if below is None else below)

    def min_distance(self, kin: Kinematics) -> float:
        """Smallest distance over all pairs (exact; for diagnostics and tests)."""
        w = self.distances.below(kin, np.inf)
        return float(w.distance.min()) if w.distance.size else np.inf

    @property
    def last(self) -> Witness:
        """The pairs closer than the trigger at the last :meth:`compute` (copies)."""
        if self._last is None:
            self._last = Witness(*(a[: self._n_close].copy() for a in self._out))
        return self._last

    @last.setter
    def last(self, w: Witness) -> None:
        self._last = w

    @property
    def max_rows(self) -> int:
        """The most rows a tick can have (17 a pair: the witness and 8 + 8 corners): the room
        :meth:`rows_into` needs."""
        return int(self._h.shape[0])

    def _update(
        self, kin: Kinematics, G: np.ndarray, h: np.ndarray, r0: int = 0, box: tuple | None = None
    ) -> int:
        """The rows at ``kin`` into ``G[r0:]``, ``h[r0:]`` (one compiled call,
        :func:`~wbc.limits.collision_packed.packed_rows`, or at the configuration and in the
        box of the last call a copy of its rows if they went elsewhere); returns their number.
        ``box``: :meth:`rows_into`'s."""
        pd = self.distances
        if not pd.pairs:
            self._n_rows = 0
            self._closest[0] = np.inf
            self._rows = None
            return 0
        if box is not None and box is not self._box:
            self._set_box(box)
        if self._boxed is not (box is not None):  # (a write only for a change)
            self._boxed = box is not None
            self._params[5] = 1.0 if self._boxed else 0.0
        call = self._call
        if call is None or call[0] is not kin:
            call = self._bind(kin)
        found = self._entries.get((id(G), id(h)))
        entry = found[0] if found is not None else self._entry(call, G, h)
        r = entry(kin.q, call[1], call[2], call[3], call[4], call[5], G, h, r0)
        where = self._where
        self._where = (G, h, r0)
        if r == -1:  # (the configuration of the last rows: where they are)
            r = self._n_rows
            G0, h0, s0 = where
            if r and (G0 is not G or s0 != r0):
                G[r0 : r0 + r] = G0[s0 : s0 + r]
                h[r0 : r0 + r] = h0[s0 : s0 + r]
            return r
        if r < 0:
            self._where = where
            raise ConfigurationError(
                f"{self.name}: rows_into needs room for {self.max_rows} rows of {self.robot.nv}"
                f" floats from row {r0}, got G {G.shape}, h {h.shape}"
            )
        self._n_rows, self._last, self._rows = r, None, None
        return r

    def _set_box(self, box: tuple) -> None:
        """Pack the box's limits ``box`` (q_min, q_max, steps: 1-D float64, n_joints long,
        the arrays the stack's limits read: their values at each call), unless they are the
        arrays packed (each plan has its own tuple: a support switch re-packed them, and the
        kernel's entry point was looked up again, ~1–15 ms)."""
        kept = self._box
        if kept is not None and all(a is b for a, b in zip(box, kept, strict=True)):
            self._box = box  # (another plan's tuple of the same arrays: nothing to pack)
            return
        nj = self.robot.n_joints
        for a in box:
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (nj,)):
                raise ConfigurationError(f"{self.name}: a box's limits are {nj} floats each")
        self._box = box
        self._packed = None
        self._call, self._entries = None, {}

    def _bind(self, kin: Kinematics) -> tuple:
        """The kernel's arguments for ``kin`` (kin, addresses, shapes, frame rotations and
        positions, joint Jacobians), kept while ``kin`` is the same object (views following
        its updates), the entry points forgotten; not kept if the frames are copies."""
        pd = self.distances
        packed = self._packed if self._packed is not None else self._pack()
        Rf, pf = pd.frames(kin)
        call = (kin, packed[0], packed[1], Rf, pf, pd.jacobians)
        self._call = call if pd._frames is not None else None
        self._entries = {}
        return call

    def _entry(self, call: tuple, G: np.ndarray, h: np.ndarray):
        """The kernel for ``call`` into ``G``, ``h``: its entry point for these arrays' types,
        kept by the buffers' identity (with them: their ids stay theirs) — cold, in a 50 Hz
        loop, the dispatcher's typing of the nine arguments cost ~5 µs a tick, the entry's
        call ~1 (``kin.q``: C-contiguous float64, :meth:`~wbc.Robot.check_configuration`).
        The dispatcher where the frames are copies."""
        if self._call is None:
            return packed_rows
        # (compiled, or loaded from numba's cache, for these types without running it)
        entry = entry_point(packed_rows, (call[0].q, *call[1:], G, h, 0), compile=True)
        if len(self._entries) >= KEPT_ENTRIES:
            self._entries.clear()
        self._entries[(id(G), id(h))] = (entry, G, h)
        return entry

    #: the kernel a compiled tick calls for the rows (and the files it calls), when
    #: :attr:`rows_in_tick`
    row_placer = ROW_PLACER

    @property
    def rows_in_tick(self) -> bool:
        """True if a compiled plan's tick makes the rows (``in_tick``; not with ``cut_in_box``,
        nor for a subclass's rows, nor without pairs)."""
        return (
            self.in_tick
            and not self.rows_in_box
            and type(self).compute is SelfCollisionConstraint.compute
            and bool(self.distances.pairs)
        )

    def placed_args(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray] | None:
        """The kernel's buffers by address (addresses, shapes) for a tick at ``kin``'s frames
        and joint Jacobians (the views it reads; None: its frames are copies)."""
        call = self._call
        if call is None or call[0] is not kin:
            call = self._bind(kin)
        return (call[1], call[2]) if self._call is not None else None

    def placing(self, where: tuple) -> None:
        """Before a tick that makes the rows at ``where`` (G, h, first row): the last rows
        forgotten if they are elsewhere (the tick's kernel then makes them again)."""
        if self._where is not where:
            self._rows_q[0] = np.nan

    def snapshot(self) -> Callable[[], None]:
        """A function that puts the limit back as it is now: every buffer its kernel writes
        and a later call reads (the last rows' configuration and box, the distance bounds,
        placements and separating axes it starts from, the last close pairs and rows' pairs
        and gaps, the counts; not its scratch, written before it is read, nor its constant
        geometry), copied into backups kept from call to call, and where its last rows are
        (a tick rehearsed and forgotten: :func:`wbc.solvers.rehearsal.rehearse`)."""
        pd = self.distances
        written = (
            self._rows_q, pd._q, pd._bound, pd.Rw, pd.cw, pd._placed, *self._out, pd._counts,
            self._pair_buf, self._gap_buf, self._closest, pd._last_axis, self._box_work,
        )  # fmt: skip
        backups = self._backups
        if len(backups) != len(written) or any(
            a is not b for a, (b, _) in zip(written, backups, strict=True)
        ):
            backups = self._backups = [(a, np.empty_like(a)) for a in written]
        for a, kept in backups:
            np.copyto(kept, a)
        state = self._where, self._n_rows, self._last, self._rows

        def put_back() -> None:
            for a, kept in backups:
                np.copyto(a, kept)
            self._where, self._n_rows, self._last, self._rows = state

        return put_back

    def placed(self, where: tuple, m: int, made: bool) -> None:
        """After that tick: its ``m`` rows at ``where`` (``made``: computed, not kept)."""
        self._where = where
        self._n_rows = m
        if made:
            self._last = self._rows = None

    def rows_into(
        self, kin: Kinematics, G: np.ndarray, h: np.ndarray, r0: int, box: tuple | None = None
    ) -> int:
        """The rows at ``kin`` written into ``G[r0:]``, ``h[r0:]`` (C-contiguous float64
        buffers with nv columns and room for :attr:`max_rows` rows from ``r0``;
        ConfigurationError else): a compiled plan's buffers, without a copy. Returns their
        number. The rows are those of :meth:`compute`, which finds them there while the
        caller leaves them — but with ``box`` (q_min, q_max, steps: the arrays of a stack
        whose box limits are the joint position then the joint velocity limit), only those
        that can bind in the tick's box [lower, upper] of Δq
        (:func:`~wbc.limits.collision_packed.joint_box`): a row G_i Δq <= h_i with

            max_{lower <= Δq <= upper} G_i Δq = Σ_k max(G_ik lower_k, G_ik upper_k)
                                              <= h_i − 1e-8 (1 + Σ_k |G_ik|)

        is met by every Δq the solvers can return (within the box to their tolerance, 1e-9),
        so it never joins a working set, blocks a step or keeps a slack
        (:func:`~wbc.limits.collision_kernels.can_bind`): left out, the answer is the same
        (86-92 % of the rows on the Bioloid's walks). :meth:`compute` at the same
        configuration then makes every row again."""
        if type(self).compute is not SelfCollisionConstraint.compute:  # (a subclass's rows)
            rows = self.compute(kin)
            m = rows.h.shape[0]
            G[r0 : r0 + m] = rows.G
            h[r0 : r0 + m] = rows.h
            return m
        return self._update(kin, G, h, r0, box)

    @property
    def rows_left_out(self) -> int:
        """The rows left out so far as unable to bind in their tick's box (:meth:`rows_into`)."""
        return int(self.distances._counts[4])

    def forget_rows(self) -> None:
        self._rows_q[:] = np.nan  # (the kernel's "configuration of the last rows")

    def rows_view(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """(G, h) of :meth:`compute` as views of the limit's buffers, valid until its next
        call: for a caller that copies them at once (a compiled plan's rows)."""
        if type(self).compute is not SelfCollisionConstraint.compute:  # (a subclass's rows)
            return tuple(self.compute(kin))  # type: ignore[return-value]
        r = self._update(kin, self._G, self._h)
        return self._G[:r], self._h[:r]

    def compute(self, kin: Kinematics) -> Inequality:
        """The rows at ``kin`` (copies, kept for a second call at the same configuration, e.g.
        a tick the compiled path hands back to DAQP)."""
        r = self._update(kin, self._G, self._h)
        if self._rows is None:  # (copies: the rows outlive the next call, e.g. in a backend's)
            self._rows = Inequality(self._G[:r].copy(), self._h[:r].copy())
        return self._rows

    def solved(self) -> None:
        """Count, per pair, the control ticks in a row that found it more than
        :data:`RECOVERY_TOL` inside the margin (at the last :meth:`compute`); raise
        :class:`InfeasibleError` naming the pairs past :data:`RECOVERY_TICKS` (every later
        tick raises too). The solvers call it after each tick with this constraint at a hard
        level: a pair held inside its margin is a hard level not met."""
        # (Python floats, no numpy scalars: their code is cold in a 50 Hz loop's tick)
        deep_min = self._params.item(0) - RECOVERY_TOL
        if self._last is None:  # (the kernel's smallest distance of the last compute)
            deep = self._closest.item(0) < deep_min
        else:
            d = self._last.distance
            deep = bool(d.size and d.min() < deep_min)
        inside = self._inside
        if not deep:
            if self._counting:
                inside[:] = 0
                self._counting = False
            return
        self._counting = True
        w = self.last
        deep = w.index[w.distance < self.margin - RECOVERY_TOL]
        kept = inside[deep] + 1
        inside[:] = 0
        inside[deep] = kept
        if kept.max() > RECOVERY_TICKS:
            names = ", ".join(
                f"{a} / {b} ({w.distance[w.index == k][0] * 1e3:.2f} mm apart)"
                for k in deep[kept > RECOVERY_TICKS].tolist()
                for a, b in [self.pair_links[k]]
            )
            raise InfeasibleError(
                f"{self.name}: the pair(s) {names} stayed inside the {self.margin * 1e3:g} mm "
                f"margin for more than {RECOVERY_TICKS} ticks in a row: the hard tasks hold "
                "them there (start the robot with its links apart, or exclude the pair)"
            )

    def split(self, kin: Kinematics, recovering: bool = False) -> tuple[Inequality, Inequality]:
        """The rows at ``kin`` as (rows to hold, requests): the rows of the pairs at or
        outside the margin (every row h >= 0, met by Δq = 0), and those of the pairs inside
        it (a row with h < 0: move apart; their box corners' rows keep parallel faces from
        turning into each other). A solver that cannot meet the requests with its hard
        tasks ranks them below those (and below the way back of joints outside their
        limits): held as hard rows, a pair already inside the margin can pin the legs of a
        start with overlapping boxes.

        ``recovering``: the rows to hold of a tick that is infeasible with the damper's
        rate: h = max(h(d), d − m), a pair may approach down to the margin in one step (the
        rate only smooths the rows' activation; a hard contact's second-order drift can
        need more than a fraction ξ of the gap to be corrected)."""
        rows = self.compute(kin)
        r = self._n_rows  # (each row's pair, a row of :attr:`last`, and gap (m) along its normal)
        row_pair, row_gap = self._pair_buf[:r], self._gap_buf[:r]
        pair_inside = np.zeros(self._n_close, dtype=bool)
        # any of its rows (a corner's gap to the witness plane can come out a hair below the
        # witness distance: the plane's normal is the distance query's, to its tolerance)
        pair_inside[row_pair[inside_margin(rows)]] = True
        ask = pair_inside[row_pair]
        h_held = rows.h[~ask]
        if recovering:
            h_held = np.maximum(h_held, row_gap[~ask] - self.margin)
        return Inequality(rows.G[~ask], h_held), Inequality(rows.G[ask], rows.h[ask])


def _cached_collision_model(robot: Robot) -> CollisionModel:
    """The robot's collision model, built once per Robot object."""
    cache = robot.__dict__
    if "_collision_model" not in cache:
        cache["_collision_model"] = collision_model(robot)
    return cache["_collision_model"]
