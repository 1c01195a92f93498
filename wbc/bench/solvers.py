"""The solvers the benchmark compares, by name and family.

Every entry builds a :class:`~wbc.walking.controller.Controller` for a robot:

* ``wqp-<backend>`` / ``hqp-<backend>`` — a walking stack as a weighted or a lexicographic QP,
  for each backend (daqp, proxqp, quadprog, osqp): the benchmark's stack (:data:`BENCH_STACKS`),
  or another one named ``<entry>@<stack>`` (``wbc bench --stack``);
* ``qp-<scheme>`` — the QP counterparts of the thesis's six walking schemes (``tasks/``);
* ``pinv-<scheme>`` — the thesis's pseudo-inverse schemes themselves (:mod:`wbc.pinv`);
* ``placo``, ``pink`` — the peers, same URDF and the run's stack's tasks (optional extra);
* ``nlp-ipopt`` / ``nlp-ipopt-hard`` — each pose as one nonlinear program (casadi + IPOPT),
  weighted like the ``walk`` stack or with the CoM and swing sole as equalities: the accuracy
  references of the converged mode.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import ConfigurationError
from ..model import Robot
from ..solvers.backends import BACKENDS
from ..stacks import RENAMED_STACKS, available_stacks, load_stack, stack_file
from ..walking.loop import Controller, StackController, TickTargets
from ..walking.reference import WalkingReference
from .peers import PEERS, available, peer_stack

THESIS_SCHEMES = ("vat", "vatl", "cj_foot", "cj_com", "cjl_foot", "cjl_com")
FAMILIES = ("qp-weighted", "qp-hierarchical", "qp-thesis", "pinv", "peer", "nlp")

#: the stack of the wqp-*/hqp-* entries in each benchmark. The kinematic one (``wbc bench``)
#: is the thesis's comparison of a hierarchy (CJ) with a weighting (VAT) on the paper motion:
#: the strict three-level layout, where the hierarchy is exact wherever the reference is
#: feasible. On a body (``wbc bench --physics``, pushes, the closed loop) the recommended
#: ``walk``: the strict layout pays for a reference that outruns a servo with a hip hike and
#: full-speed arms, which tip the robot (benchmarks/balance.md, issue 15).
BENCH_STACKS = {"kinematic": "walk_strict", "physics": "walk"}


@dataclass(frozen=True)
class SolverEntry:
    name: str
    family: str
    make: Callable[[Robot], Controller]
    real_time: bool = True  # False: only meaningful in converged mode (the NLP)
    needs: str | None = None  # optional module that must be importable
    stack: str | None = None  # the task stack file of a wqp-*/hqp-*/qp-* entry


class PinvController(Controller):
    """A thesis pseudo-inverse scheme; the support root switches with the walking phases."""

    family = "pinv"

    def __init__(self, scheme: str) -> None:
        self.scheme_name = scheme
        self.name = f"pinv-{scheme}"

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        from ..pinv import ThesisScheme

        self.schemes = {
            sup: ThesisScheme.make(self.scheme_name, robot, support=sup, swing=sw)
            for sup, sw in (("l_sole", "r_sole"), ("r_sole", "l_sole"))
        }
        self.active = None

    def _prepare(self, q: np.ndarray, targets: TickTargets, phase_changed: bool):
        scheme = self.schemes[targets.support]
        if scheme is not self.active:
            scheme.reset(q)  # anchor the new support sole where it is
            self.active = scheme
        scheme.set_targets(targets.com, targets.swing_position, targets.swing_rotation)
        return scheme

    def track(self, q, targets, dt, phase_changed):
        return self._prepare(q, targets, phase_changed).step(q)

    def converge(self, q, targets, tol, max_iterations, phase_changed):
        scheme = self._prepare(q, targets, phase_changed)
        q_next, info = scheme.solve_pose(q, tol=tol, max_iterations=max_iterations)
        return q_next, info.iterations


def _stack(
    name: str, backend: str, solver: str | None, label: str
) -> Callable[[Robot], Controller]:
    def make(robot: Robot) -> Controller:
        return StackController(load_stack(name, robot, backend=backend, solver=solver), label)

    return make


def _nlp(hard: bool, stack: str | None) -> Callable[[Robot], Controller]:
    def make(robot: Robot) -> Controller:
        from .nlp import NlpController, NlpWeights

        if hard:  # the thesis's tasks alone (no weights, no polygon)
            return NlpController(hard_com_and_swing=True, com_margin=None)
        tasks = peer_stack(robot, stack)  # the peers' stack, weights and CoM polygon
        return NlpController(com_margin=tasks.com_margin, weights=NlpWeights.of(tasks))

    return make


def _peer(cls: type, stack: str | None) -> Callable[[Robot], Controller]:
    def make(robot: Robot) -> Controller:
        return cls(peer_stack(robot, stack))

    return make


def registry(benchmark: str = "physics", stack: str | None = None) -> dict[str, SolverEntry]:
    """Every solver the benchmark knows, in display order. The wqp-*/hqp-* entries load
    ``stack`` (default: the benchmark's, :data:`BENCH_STACKS`); another stack than the
    benchmark's shows in their names (``hqp-daqp@walk_strict``)."""
    if benchmark not in BENCH_STACKS:
        raise ConfigurationError(
            f"unknown benchmark {benchmark!r}; choose from {list(BENCH_STACKS)}"
        )
    default = BENCH_STACKS[benchmark]
    walk = default if stack is None else RENAMED_STACKS.get(stack, stack)
    suffix = "" if walk == default else f"@{Path(walk).stem}"
    entries: list[SolverEntry] = []
    for prefix, family, kind in (
        ("wqp", "qp-weighted", "weighted"),
        ("hqp", "qp-hierarchical", "hierarchical"),
    ):
        for backend in BACKENDS:
            name = f"{prefix}-{backend}{suffix}"
            entries.append(SolverEntry(name, family, _stack(walk, backend, kind, name), stack=walk))
    for scheme in THESIS_SCHEMES:
        name = f"qp-{scheme}"
        entries.append(
            SolverEntry(name, "qp-thesis", _stack(scheme, "daqp", None, name), stack=scheme)
        )
    for scheme in THESIS_SCHEMES:
        entries.append(
            SolverEntry(f"pinv-{scheme}", "pinv", lambda robot, s=scheme: PinvController(s))
        )
    # the peers and the weighted NLP: the tasks of the stack a command runs on the robot
    # (``stack``, else its folder's stack.toml, else walk: wbc.bench.peers.peer_stack)
    for name, cls in PEERS.items():
        entries.append(SolverEntry(name, "peer", _peer(cls, stack), needs=name))
    # the weighted reference (the peers' weights) and the hard one (CoM and swing sole as
    # equalities: what the hierarchies should reach)
    entries.append(SolverEntry("nlp-ipopt", "nlp", _nlp(False, stack), real_time=False))
    entries.append(SolverEntry("nlp-ipopt-hard", "nlp", _nlp(True, None), real_time=False))
    return {e.name: e for e in entries}


def select(
    names: list[str] | None,
    families: list[str] | None,
    mode: str,
    benchmark: str = "physics",
    stack: str | None = None,
) -> tuple[list[SolverEntry], list[str]]:
    """Entries of :func:`registry` (``benchmark``, ``stack``) matching names (exact or prefix)
    and families; returns (entries, notes) where notes say what was skipped and why (a peer
    not installed, the NLP in tick mode)."""
    if stack is not None:
        check_stack(stack)
    reg = registry(benchmark, stack)
    notes: list[str] = []
    chosen = list(reg.values())
    if families:
        unknown = [f for f in families if f not in FAMILIES]
        if unknown:
            raise ConfigurationError(f"unknown families {unknown}; choose from {list(FAMILIES)}")
        chosen = [e for e in chosen if e.family in families]
    if names:
        picked = []
        for n in names:
            matches = [e for e in chosen if e.name == n] or [
                e for e in chosen if e.name.startswith(n)
            ]
            if not matches:
                raise ConfigurationError(f"unknown solver {n!r}; known: {list(reg)}")
            picked += [m for m in matches if m not in picked]
        chosen = picked
    have = available()
    out = []
    for e in chosen:
        if e.needs and not have.get(e.needs, False):
            notes.append(f"{e.name}: not installed (pip install 'wbc[peers]'), skipped")
        elif mode == "tick" and not e.real_time:
            notes.append(f"{e.name}: an accuracy reference, run only with --mode converge")
        else:
            out.append(e)
    return out, notes


def check_stack(stack: str) -> None:
    """Raise one clear line unless ``stack`` names a file in ``tasks/`` (or a former name of
    one) or is a path to a ``.toml`` stack file."""
    if stack_file(stack) is not None:
        return
    raise ConfigurationError(
        f"--stack {stack!r}: not a stack in tasks/ ({', '.join(available_stacks())}) "
        "nor a .toml file"
    )
