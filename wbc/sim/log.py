"""The log of a simulated run: the state every control tick (:class:`SimLog`, written by
:class:`SimLogger`), and a deployment's result beside it (:class:`PlayResult`). The runs:
:func:`wbc.bench.play.play` (a recording through the deployment path),
:func:`wbc.bench.closed_loop.play_closed_loop` (a controller live, closed loop).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import convex_hull, signed_distance
from ..servos.playback import DeployResult
from .bus import SimServoBus
from .simulator import Simulation


@dataclass
class SimLog:
    """Per control tick: time (s, simulation clock, 0 = first tick), configuration (wbc
    convention), CoM, CoP (NaN in the air), normal force under each sole, joint goals (rad),
    peak |torque| per joint over the tick (N·m), and which ticks belong to the playback."""

    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    com: list[np.ndarray] = field(default_factory=list)
    cop: list[np.ndarray] = field(default_factory=list)
    sole_force: list[np.ndarray] = field(default_factory=list)
    soles: list[np.ndarray] = field(default_factory=list)  # (2, 3) l, r sole positions
    goal: list[np.ndarray] = field(default_factory=list)
    peak_torque: list[np.ndarray] = field(default_factory=list)
    cop_margin: list[float] = field(default_factory=list)  # m, to the contact points' hull

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


@dataclass
class PlayResult:
    """The deployment's result, the simulation log and the playback start time (s)."""

    deploy: DeployResult
    log: dict[str, np.ndarray]
    playback_start: float
    sim: Simulation
    #: a closed loop whose walk ran off its reference's clock (a held lift-off, the
    #: stabilizer's slowed clock: :attr:`wbc.balance.live.SessionSource.played`): (2, n), the
    #: walk's time since the playback start and the reference time it played (s); None: the
    #: reference's own clock (what the physics record compares the run with)
    played: np.ndarray | None = None


def hull_margin(points: np.ndarray, p: np.ndarray) -> float:
    """Signed distance (m) from ``p`` to the edge of the convex hull of ``points`` (positive
    inside; 0 when the hull is a point or a segment: a foot resting on an edge tips):
    :func:`wbc.geometry.signed_distance` of :func:`wbc.geometry.convex_hull`."""
    pts = np.asarray(points, dtype=float)
    hull = convex_hull(pts[:, :2]) if len(pts) else pts
    if len(hull) < 3:
        return 0.0
    return float(signed_distance(hull, np.asarray(p, dtype=float)[:2]))


class SimLogger:
    """Logs the simulated state into a :class:`SimLog`, called once per control tick (the
    bus's ``on_tick``); :attr:`t0` is the simulation clock at its start."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.log = SimLog()
        self.t0 = sim.time
        m = sim.model
        mj = sim.mj
        self.feet = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, b) for b in sim.robot_feet()]

    def __call__(self, bus: SimServoBus | None = None) -> None:
        sim, log = self.sim, self.log
        log.t.append(sim.time - self.t0)
        log.q.append(sim.q())
        log.com.append(sim.com())
        pts, fz, body = sim.contacts()
        total = fz.sum()
        cop = (pts[:, :2] * fz[:, None]).sum(axis=0) / total if total > 1e-9 else np.full(2, np.nan)
        log.cop.append(cop)
        log.cop_margin.append(hull_margin(pts[fz > 1e-9, :2], cop) if total > 1e-9 else np.nan)
        log.sole_force.append(np.array([fz[body == b].sum() for b in self.feet]))
        log.soles.append(
            np.array([sim.site_pose("l_sole").translation, sim.site_pose("r_sole").translation])
        )
        log.goal.append(sim.servos.goal_angles())
        log.peak_torque.append(sim.reset_peak())
