"""Where a driven walk's displacement and heading errors come from: per random command
sequence and randomised model (as ``benchmarks/drive.py --random``), the final error of the
base (travelled − commanded, start frame) split into measured causes, from the simulator's
ground truth sampled every control tick:

* ``plan``: the engine's own lag — its planned walking frame (+ the odometry's offset, moved
  to the commanded point, :attr:`WalkEngine.origin`) against the commanded pose at the end
  (start and stop transients, make-up capped by ``catch_up`` and the limits);
* ``swing``: the soles' motion while swinging against the plan's (step length and turn
  short of the plan: the servos' compliance; the encoders see it);
* ``slip``: the soles' motion while in contact (sliding and turning on the floor: the
  encoders cannot see it, the gyro sees the turn);
* ``base``: the base against where the soles' midpoint puts it (``origin``) at the end (a
  torso twisted or leaning over the standing feet);
* ``origin``: for comparison, what the error would be had the command moved the soles'
  midpoint and the base been measured (the start-frame convention of ``commanded_xy_m`` before
  the command moved the base): |(R(θ) − I) b| for the base offset ``b`` and the turn ``θ``;
* ``gyro``: the Walker's IMU heading (:class:`wbc.drive.odometry.PoseOdometry`) against the
  simulated torso's at the end.

Headings in degrees, displacements in cm. benchmarks/drive.md quotes it::

    nice -n 5 python benchmarks/drive_odometry.py --sequences 0 1 2 3 --models 0 1 2 3

``--contact``: the soles' slip in contact per gait phase, from MuJoCo's contacts at every
physics step (:class:`ContactSlip`): where a sole touching the floor moved while touching
it, by the walker's phase — ``ds_lead`` / ``ds_trail`` (double support: the sole that has
just landed, the one that lifts next), ``stance`` (single support), ``swing0..3`` (the
swing sole touching the floor in each quarter of its swing: dragging at lift-off, scuffing,
touching down early).

``--budget``: the outer loop's odometry error at the last landing split per landing into the
encoders' placements, the odometry's heading and the soles' unseen moves
(:class:`LandingBudget`); each run also prints the final error's parts as vectors (start
frame): the plan's, the soles' (the simulated soles against the odometry's) and the base's
standing posture over its soles.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import drive

import wbc.drive.sim as drive_sim_module
from wbc import load_robot
from wbc.bench.variation import models
from wbc.drive.commands import Command, random_commands
from wbc.drive.envelope import planning_envelope
from wbc.drive.odometry import PoseOdometry
from wbc.geometry import mean_angle, relative_pose, wrap_angle, yaw_of
from wbc.types import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking.engine_params import EngineParams
from wbc.walking.geometry import rot2


def breakdown(run: dict, walker, rows: np.ndarray, yaw0: float) -> dict:
    """The error's causes of one run (module docstring); ``rows``: per tick t, the soles'
    (x, y, yaw), the base's (x, y, yaw), the support code, the walker's gyro heading and
    the torso's yaw."""
    e = walker.engine
    Rs = rot2(yaw0).T
    out: dict = {}
    walking = np.isfinite(rows[:, 11])
    k0 = int(np.argmax(walking)) if walking.any() else 0
    cmd = np.asarray(run["commanded_xy_m"])
    # the engine's plan (+ odometry) of the commanded point, start frame
    c0 = walker.start_frame
    origin_w = lambda c: c[:2] + rot2(c[2]) @ e.origin  # noqa: E731
    plan = e.centre + e.odometry_offset
    planned = rot2(c0[2]).T @ (origin_w(plan) - origin_w(c0))
    out["plan_cm"] = 100 * float(np.linalg.norm(planned - cmd))
    out["plan_deg"] = math.degrees(wrap_angle(plan[2] - c0[2] - run["commanded_yaw_rad"]))
    # the odometry's own error: the base against where the plan + odometry put it at the end
    out["odometry_cm"] = 100 * float(np.linalg.norm(np.asarray(run["travelled_xy_m"]) - planned))
    out["odometry_deg"] = math.degrees(wrap_angle(run["travelled_yaw_rad"] - (plan[2] - c0[2])))
    sup = rows[:, 10].astype(int)
    swing_xy, slip_xy, swing_yaw, slip_yaw, planned_xy, planned_yaw = [], [], [], [], [], []
    for col, side, own in ((1, "left", SUPPORT_LEFT), (4, "right", SUPPORT_RIGHT)):
        xy, yaw = rows[k0:, col : col + 2], np.unwrap(rows[k0:, col + 2])
        s = sup[k0:]
        contact = (s == SUPPORT_DOUBLE) | (s == own)
        both = contact[1:] & contact[:-1]
        d, dy = np.diff(xy, axis=0), np.diff(yaw)
        slip_xy.append(Rs @ d[both].sum(0))
        swing_xy.append(Rs @ d[~both].sum(0))
        slip_yaw.append(dy[both].sum())
        swing_yaw.append(dy[~both].sum())
        steps = [s_ for s_ in e.planned if s_.side == side]
        if steps:
            first = rows[k0, col : col + 3]
            planned_xy.append(Rs @ (steps[-1].xy - first[:2]))
            turns = np.diff([first[2]] + [s_.yaw for s_ in steps])
            planned_yaw.append(float(np.sum(wrap_angle(turns))))
        else:
            planned_xy.append(np.zeros(2))
            planned_yaw.append(0.0)
    out["swing_cm"] = 100 * float(np.linalg.norm(np.mean(swing_xy, 0) - np.mean(planned_xy, 0)))
    out["slip_cm"] = 100 * float(np.linalg.norm(np.mean(slip_xy, 0)))
    # the slip along the commanded displacement (negative: the soles slid back, short)
    u = cmd / max(float(np.linalg.norm(cmd)), 1e-9)
    out["slip_along_cm"] = 100 * float(np.mean(slip_xy, 0) @ u)
    out["swing_deg"] = math.degrees(np.mean(swing_yaw) - np.mean(planned_yaw))
    out["slip_deg"] = math.degrees(np.mean(slip_yaw))
    # the base against the soles' midpoint + origin at the end
    last = rows[-1]
    mid_yaw = mean_angle(last[3], last[6])
    mid = 0.5 * (last[1:3] + last[4:6]) + rot2(mid_yaw) @ e.origin
    out["base_cm"] = 100 * float(np.linalg.norm(last[7:9] - mid))
    # the error's parts as vectors (start frame, cm): the plan's, the soles' (where the
    # simulated soles put the base against where the odometry has them: unseen slips and
    # the odometry's own errors) and the base's standing posture over its soles
    out["plan_vec"] = 100 * (planned - cmd)
    start = rows[0, 7:9]
    out["base_vec"] = 100 * (Rs @ (last[7:9] - mid))
    out["soles_vec"] = 100 * (Rs @ (mid - start) - planned)
    out["base_deg"] = math.degrees(wrap_angle(last[9] - mid_yaw))
    theta = run["travelled_yaw_rad"]
    out["origin_cm"] = 100 * float(np.linalg.norm((rot2(theta) - np.eye(2)) @ e.origin))
    gyro = rows[:, 11]
    ok = np.isfinite(gyro)
    if ok.any():
        torso = np.unwrap(rows[ok, 12])
        out["gyro_deg"] = math.degrees((gyro[ok][-1] - gyro[ok][0]) - (torso[-1] - torso[0]))
    return out


class ContactSlip:
    """Per physics step, each sole's contact points with the floor (MuJoCo's contacts, the
    force-weighted centroid in the sole's body frame): where that point moved from the last
    step to this one while the sole touched the floor at both is the slip (a sole rolling
    about its contact does not count), its heading change the turning slip; and the
    friction used, Σ |f_t| / Σ μ f_n (1: sliding). Keyed by the walker's phase (module
    docstring). ``walker()`` gives the run's walker."""

    def __init__(self, sim, walker) -> None:
        self.sim, self.walker = sim, walker
        mj, m = sim.mj, sim.model
        self.feet = [mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, b) for b in sim.robot_feet()]
        self.prev: list = [None, None]
        #: phase -> dx, dy, dyaw, |d|, |dyaw|, physics steps, Σ |f_t|, Σ μ f_n, slip along
        #: the command, the floor's force on the sole along the command (N·steps), Σ f_n
        self.sums: dict[str, np.ndarray] = {}
        self._phase: tuple = (None, -1.0)
        self._f6 = np.zeros(6)
        step = sim.step

        def stepped() -> None:
            step()
            self.sample()

        sim.step = stepped

    def phase(self, foot: int) -> str | None:
        w = self.walker()
        if w is None or w.last is None or not w.engine.walking:
            return None
        e, frame = w.last, SOLE_NAMES[foot]
        if e.support == SUPPORT_DOUBLE:
            return "ds_trail" if e.swing_frame == frame else "ds_lead"
        if e.support_frame == frame:
            return "stance"
        T = w.engine.params.timing
        swing = T.step_time * (1.0 - T.double_support_ratio)
        quarter = min(int(4 * (self.sim.time - self._phase[1]) / swing), 3)
        return f"swing{quarter}"

    def sample(self) -> None:
        sim, w = self.sim, self.walker()
        d, m, mj = sim.data, sim.model, sim.mj
        if w is not None and w.last is not None:
            key = (w.last.support, w.engine.steps_taken)
            if key != self._phase[0]:
                self._phase = (key, sim.time)
        touching: list[list] = [[], []]
        for k in range(d.ncon):
            c = d.contact[k]
            if sim.floor not in (c.geom1, c.geom2):
                continue
            body = m.geom_bodyid[c.geom2 if c.geom1 == sim.floor else c.geom1]
            if body in self.feet:
                mj.mj_contactForce(m, d, k, self._f6)
                f = self._f6
                sign = 1.0 if c.geom1 == sim.floor else -1.0  # the floor's force on the sole
                world = sign * (c.frame.reshape(3, 3).T @ f[:3])
                touching[self.feet.index(body)].append(
                    (c.pos.copy(), f[0], math.hypot(f[1], f[2]), c.friction[0], world)
                )
        for i, body in enumerate(self.feet):
            if not touching[i]:
                self.prev[i] = None
                continue
            R, p = d.xmat[body].reshape(3, 3).copy(), d.xpos[body].copy()
            P = np.array([t[0] for t in touching[i]])
            fn = np.array([t[1] for t in touching[i]])
            centre = P.mean(0) if fn.sum() <= 1e-9 else (P * fn[:, None]).sum(0) / fn.sum()
            label = self.phase(i)
            if self.prev[i] is not None and label is not None:
                Rp, pp, local = self.prev[i]
                dxy = (R @ local + p - Rp @ local - pp)[:2]
                dyaw = wrap_angle(yaw_of(R) - yaw_of(Rp))
                ft = sum(t[2] for t in touching[i])
                cap = sum(t[3] * t[1] for t in touching[i])
                u = self.along(yaw_of(R))
                fw = sum(t[4] for t in touching[i])
                acc = self.sums.setdefault(label, np.zeros(11))
                acc += (dxy[0], dxy[1], dyaw, math.hypot(*dxy), abs(dyaw), 1.0, ft, cap,
                        float(dxy @ u), float(fw[:2] @ u), float(fn.sum()))  # fmt: skip
            self.prev[i] = (R, p, R.T @ (centre - p))

    def along(self, heading: float) -> np.ndarray:
        """The commanded velocity's direction in the world (the sole's heading taken for the
        walking frame's), zero when the command is nearly on the spot (< 1 cm/s)."""
        w = self.walker()
        v = np.asarray(w.engine.command_velocity[:2], dtype=float)
        n = float(np.linalg.norm(v))
        return np.zeros(2) if n < 0.01 else rot2(heading) @ (v / n)

    def lines(self, yaw0: float) -> list[str]:
        """One line per phase: the net slip (start frame, cm; heading °), its path (cm, °),
        the sole-seconds in contact, the friction used, the slip along the command (cm) and
        the floor's mean force on the sole along the command (N) and normal (N)."""
        Rs = rot2(yaw0).T
        order = ("ds_lead", "ds_trail", "stance", "swing0", "swing1", "swing2", "swing3")
        out = []
        for label in (k for k in order if k in self.sums):
            a = self.sums[label]
            net = Rs @ a[:2]
            out.append(f"  {label:8s} net ({100 * net[0]:+.2f}, {100 * net[1]:+.2f}) cm "
                       f"{math.degrees(a[2]):+.1f}°, path {100 * a[3]:.2f} cm "
                       f"{math.degrees(a[4]):.1f}°, in contact {a[5] * self.sim.dt:.2f} s, "
                       f"friction used {a[6] / max(a[7], 1e-9):.2f}, along the command: "
                       f"slip {100 * a[8]:+.2f} cm, force {a[9] / a[5]:+.3f} N "
                       f"(normal {a[10] / a[5]:.2f} N)")  # fmt: skip
        total = sum(self.sums.values())
        if isinstance(total, np.ndarray):
            net = Rs @ total[:2]
            out.append(f"  all      net ({100 * net[0]:+.2f}, {100 * net[1]:+.2f}) cm start "
                       f"frame, ({100 * total[0]:+.2f}, {100 * total[1]:+.2f}) cm world, "
                       f"{math.degrees(total[2]):+.1f}°")  # fmt: skip
        return out


SOLE_NAMES = ("l_sole", "r_sole")


class LandingBudget:
    """The outer loop's odometry error at each measured landing, split (world, m): the
    landed sole is placed from the stance sole's odometry pose by the encoders (forward
    kinematics of the present joints), so its error is the stance sole's error plus three
    parts per landing, summed over the walk — ``placement``: the encoders' relative placement
    against the simulator's (the servos' play and quantisation; the true joints' kinematics
    place it within 0.05 mm rms), rotated by the true stance heading; the odometry's stance
    heading against the true one, applied to the measured placement, in two — ``gyro``: the
    gyro's torso heading against the simulated torso's, ``encoders' turn``: the torso-to-sole
    turn of the present joints against the simulated one —; ``unseen``: minus the stance
    sole's true move since its own landing was measured (its slip or creep in contact,
    which no sensor of the robot sees). ``total``:
    the landed sole's odometry position less the simulator's at the last landing."""

    def __init__(self) -> None:
        self.sums = {k: np.zeros(2) for k in ("placement", "gyro", "encoders' turn", "unseen")}
        self.total = np.zeros(2)
        self.heading_error = 0.0  # rad, the stance sole's at the last landing
        self.placement_norm = 0.0  # m, Σ |placement error| over the landings
        self.landings = 0
        self._placed: dict[str, np.ndarray] = {}  # each sole's true position at its landing

    def landed(self, robot, sim, odometry, side: str, q: np.ndarray, placed=None) -> None:
        """A landing of ``side`` just measured by ``odometry`` (q: the present joints;
        ``placed``: the landed sole's placement the odometry took, if not ``q``'s)."""
        stance = "right" if side == "left" else "left"
        frames = {"left": SOLE_NAMES[0], "right": SOLE_NAMES[1]}
        M_st, M_sw = sim.site_pose(frames[stance]), sim.site_pose(frames[side])
        st_xy, sw_xy, st_yaw = M_st.translation[:2], M_sw.translation[:2], yaw_of(M_st.rotation)
        (rel,) = robot.placements_in(q, frames[stance], [frames[side]])
        measured = rel.translation[:2] if placed is None else np.asarray(placed[:2])
        odo_st = odometry.soles[stance]
        error = rot2(st_yaw) @ (measured - rot2(st_yaw).T @ (sw_xy - st_xy))
        self.sums["placement"] += error
        self.placement_norm += float(np.linalg.norm(error))
        # the heading's error split: the gyro's torso heading against the simulated torso's,
        # and the encoders' torso-to-sole turn against the simulated one
        (torso_sole,) = robot.placements_in(q, "torso", [frames[stance]])
        mid = yaw_of(sim.site_pose("torso").rotation) + yaw_of(torso_sole.rotation)
        self.sums["gyro"] += (rot2(odo_st[2]) - rot2(mid)) @ measured
        self.sums["encoders' turn"] += (rot2(mid) - rot2(st_yaw)) @ measured
        self.sums["unseen"] -= st_xy - self._placed.get(stance, st_xy)
        self._placed[side] = sw_xy.copy()
        self.total = odometry.soles[side][:2] - sw_xy
        self.heading_error = wrap_angle(odo_st[2] - st_yaw)
        self.landings += 1

    def line(self) -> str:
        """The split as one line (mm; the parts add up to the total but for the first
        landing's own error)."""
        parts = ", ".join(f"{k} ({1000 * v[0]:+.1f}, {1000 * v[1]:+.1f})"
                          for k, v in self.sums.items())  # fmt: skip
        x, y = 1000 * self.total
        return (f"  the odometry's error at the last landing (world): ({x:+.1f}, {y:+.1f}) mm, "
                f"heading "
                f"{math.degrees(self.heading_error):+.1f}°, over {self.landings} landings: "
                f"Σ {parts} mm; Σ |placement| {1000 * self.placement_norm:.0f} mm")  # fmt: skip


def soles_mid(sim) -> np.ndarray:
    """The simulated soles' midpoint and mean heading (x, y, heading; world)."""
    L, R = (sim.site_pose(f) for f in SOLE_NAMES)
    m = 0.5 * (L.translation[:2] + R.translation[:2])
    return np.array([m[0], m[1], mean_angle(yaw_of(L.rotation), yaw_of(R.rotation))])


def accrual(run: dict, walker, odometer, commands) -> list[str]:
    """Where the odometry's error accrues: at each landing the walking frame the walker's
    odometry measures against the simulated soles' midpoint (each in its own start frame),
    its change since the last landing classed by the context — ``first2`` (the start's
    first two landings), ``change`` (a command change in the second before), ``turning``
    (|ωz| > 0.15 rad/s), ``spot`` (|vx| + |vy| < 1 cm/s), ``steady`` —; then the
    error at the last landing, what the soles' midpoint did after it (the closing step)
    and the commanded displacement's direction ``u`` the "along" figures project on."""
    c = np.asarray(run["commanded_xy_m"])
    u = c / max(float(np.linalg.norm(c)), 1e-9)
    rows = np.asarray(odometer.rows)
    mid0 = soles_mid_at(rows, 0)
    changes = np.cumsum([cm.duration for cm in commands])[:-1]
    t0 = walker.t_walk if walker.t_walk is not None else 0.0  # (the commands' start)
    sums: dict[str, np.ndarray] = {}
    prev = np.zeros(3)
    for n, (t, est, truth, cmd) in enumerate(walker.landings):
        d = relative_pose(mid0, truth) - relative_pose(walker.start_frame, est)
        d[2] = wrap_angle(d[2])
        inc, prev = d - prev, d
        ts = t - t0
        if n < 2:
            key = "first2"
        elif np.any((changes < ts) & (changes > ts - 1.0)):
            key = "change"
        elif abs(cmd[2]) > 0.15:
            key = "turning"
        elif abs(cmd[0]) + abs(cmd[1]) < 0.01:
            key = "spot"
        else:
            key = "steady"
        acc = sums.setdefault(key, np.zeros(5))
        acc += (inc[0], inc[1], inc[2], math.hypot(inc[0], inc[1]), 1.0)
    out = [f"  odometry's error at the last landing (simulated − measured): "
           f"{100 * prev[0]:+.2f}, {100 * prev[1]:+.2f} cm (along {100 * prev[:2] @ u:+.2f}) "
           f"{math.degrees(prev[2]):+.1f}° over {len(walker.landings)} landings"]  # fmt: skip
    for key in ("first2", "change", "turning", "spot", "steady"):
        if key in sums:
            a = sums[key]
            out.append(f"    {key:8s} {int(a[4]):3d} landings: {100 * a[0]:+.2f}, "
                       f"{100 * a[1]:+.2f} cm (along {100 * a[:2] @ u:+.2f}) "
                       f"{math.degrees(a[2]):+.2f}°, path {100 * a[3]:.2f} cm")  # fmt: skip
    if walker.landings:
        k = int(np.searchsorted(rows[:, 0], walker.landings[-1][0]))
        after = relative_pose(mid0, soles_mid_at(rows, -1)) - relative_pose(
            mid0, soles_mid_at(rows, min(k, len(rows) - 1)))  # fmt: skip
        out.append(f"  the soles' midpoint after the last landing (the closing step): "
                   f"{100 * after[:2] @ u:+.2f} cm along, "
                   f"{math.degrees(wrap_angle(after[2])):+.1f}°")  # fmt: skip
    return out


def soles_mid_at(rows: np.ndarray, k: int) -> np.ndarray:
    """The soles' midpoint and mean heading of the sampled row ``k`` (:func:`main`'s rows)."""
    r = rows[k]
    return np.array([0.5 * (r[1] + r[4]), 0.5 * (r[2] + r[5]), mean_angle(r[3], r[6])])


def vertical_bias(walker, sim) -> str:
    """The gyro's bias about the vertical after the calibration at rest (the simulated IMU's
    true bias less the calibration's, as the heading's rate on the standing torso) and what
    the walker's rest learnt of it (:attr:`PoseOdometry.yaw_bias`), in ° per 30 s."""
    stab = walker.stabilizer
    imu = stab.imu
    mount = imu.mount.rotation if imu.mount is not None else np.eye(3)
    left = mount @ imu.gyro_bias - stab.calibration.gyro_bias  # in the calibrated rate
    R = sim.site_pose("torso").rotation
    rate = PoseOdometry._increment(R, left, 1e-3) / 1e-3
    odo = walker.odometry
    learnt = odo.yaw_bias if odo is not None else 0.0
    rest = odo.rest_time if odo is not None else 0.0
    d = math.degrees(30.0)
    return (f"left by the calibration {d * rate:+.1f}°/30 s, learnt over {rest:.2f} s of rest "
            f"{d * learnt:+.1f}°/30 s: heading error {d * (rate - learnt):+.1f}°/30 s")  # fmt: skip


def shadowed_runs(
    robot,
    sequences,
    model_ids,
    seed: int,
    duration: float,
    walker,
    odometer,
    records=(),
    variations=None,
    **run_kw,
) -> Iterator[tuple[int, int, list, dict]]:
    """Each (sequence ``i``, model ``m``) as ``benchmarks/drive.py --random`` draws them (the
    commands of ``default_rng([seed, 1000 + i])`` over ``duration`` s within the planning
    envelope; model ``m`` of :func:`~wbc.bench.variation.models` of ``seed``, or of
    ``variations``) run by :func:`drive.run_one` on hqp-daqp (``run_kw`` its options) with
    the drive simulator's walker and odometer classes ``walker`` and ``odometer`` (a
    script's subclasses, installed in :mod:`wbc.drive.sim`), the lists in ``records`` (what
    they keep) emptied before each run: yields ``(i, m, the commands, the run's record)``."""
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    if variations is None:
        variations = models(robot, max(model_ids) + 1, seed)
    drive_sim_module.Walker, drive_sim_module.Odometer = walker, odometer
    for i in sequences:
        cmds = random_commands(np.random.default_rng([seed, 1000 + i]), share, duration)
        for m in model_ids:
            for kept in records:
                kept.clear()
            r = drive.run_one(robot, "hqp-daqp", cmds, variations[m], limits=limits,
                              window=window, **run_kw)  # fmt: skip
            yield i, m, cmds, r


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, nargs="+", default=[0])
    ap.add_argument("--models", type=int, nargs="+", default=[0])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-track", dest="track", action="store_false",
                    help="the walker without its outer loop on the IMU-aided pose")  # fmt: skip
    ap.add_argument("--calibrate", type=float, default=None, metavar="S",
                    help="the IMU's rest before the walk (default: the Walker's)")  # fmt: skip
    ap.add_argument(
        "--yaw-rest",
        type=float,
        default=None,
        metavar="S",
        help="the rest that learns the gyro's vertical bias (default: the Walker's)",
    )
    ap.add_argument("--bias", action="store_true",
                    help="per model: the gyro's bias about the vertical the calibration at rest "
                         "leaves, and what the walker's rest learnt of it (°/30 s)")  # fmt: skip
    ap.add_argument(
        "--finish",
        action="store_true",
        help="the walker finishes the commanded path at the script's end",
    )
    ap.add_argument("--contact", action="store_true",
                    help="the soles' slip in contact per gait phase (ContactSlip)")  # fmt: skip
    ap.add_argument("--accrual", action="store_true",
                    help="where the odometry's error accrues: per landing by context "
                         "(accrual)")  # fmt: skip
    ap.add_argument("--budget", action="store_true",
                    help="the odometry's error at the last landing split into the encoders' "
                         "placements, the heading and the soles' unseen moves "
                         "(LandingBudget)")  # fmt: skip
    ap.add_argument("--trace", action="store_true",
                    help="per landing: the stance sole's heading by the encoders' chain, "
                         "the gyro, the blend, the band's switch, against the simulator's; "
                         "then the soles, base and torso after the last landing")  # fmt: skip
    ap.add_argument("--heading-gain", type=float, default=None, metavar="K",
                    help="as benchmarks/drive.py --heading-gain")  # fmt: skip
    ap.add_argument("--lift-gain", type=float, default=None, metavar="G",
                    help="the walker's lift gain (default: the Walker's)")  # fmt: skip
    ap.add_argument("--stride-gain", type=float, default=None, metavar="G",
                    help="as benchmarks/drive.py --stride-gain (1: none)")  # fmt: skip
    ap.add_argument(
        "--swing-settle",
        type=float,
        default=None,
        metavar="F",
        help="EngineParams(settle=F): the swing's last share only comes down",
    )
    ap.add_argument("--no-backlash", action="store_true",
                    help="the randomised models without their gears' backlash (the encoders "
                         "then read the links)")  # fmt: skip
    ap.add_argument("--play", type=drive.play_arg, default=None, metavar="model|DEG",
                    help="as benchmarks/drive.py --play")  # fmt: skip
    ap.add_argument("--play-hold", type=float, default=None, metavar="S",
                    help="as benchmarks/drive.py --play-hold")  # fmt: skip
    ap.add_argument("--play-load", choices=["off", "still", "always"], default=None,
                    help="as benchmarks/drive.py --play-load")  # fmt: skip
    ap.add_argument("--landing-share", type=float, default=None, metavar="F",
                    help="as benchmarks/drive.py --landing-share")  # fmt: skip
    ap.add_argument("--start-yaw", type=float, default=0.0, metavar="DEG",
                    help="the robot starts turned DEG about the simulator's vertical (a drift "
                         "fixed in the floor's frame stays; one of the walk's turns with "
                         "it)")  # fmt: skip
    args = ap.parse_args(argv)
    robot = load_robot("bioloid")

    def trace_line(walker, sim, side: str, q: np.ndarray, chain: float) -> None:
        """--trace: one landing's stance-sole headings (degrees, world): the encoders'
        chain, the gyro's, the blend, the band's switch, the truth; the gyro's torso heading
        and the encoders' torso-to-sole turn against the simulator's."""
        odo = walker.odometry
        stance = "right" if side == "left" else "left"
        frames = {"left": SOLE_NAMES[0], "right": SOLE_NAMES[1]}
        (ts,) = robot.placements_in(q, "torso", [frames[stance]])
        gyro = odo.heading + yaw_of(ts.rotation)
        true_st = yaw_of(sim.site_pose(frames[stance]).rotation)
        true_torso = yaw_of(sim.site_pose("torso").rotation)
        true_ts = wrap_angle(true_st - true_torso)
        switch = abs(wrap_angle(gyro - chain)) > odo.heading_band
        d = math.degrees
        print(f"  trace t {sim.time:6.2f} {stance:5s} stance: chain "
              f"{d(wrap_angle(chain - true_st)):+6.2f} gyro "
              f"{d(wrap_angle(gyro - true_st)):+6.2f} blend "
              f"{d(wrap_angle(odo.soles[stance][2] - true_st)):+6.2f} (against the truth "
              f"{d(true_st):+7.2f}){' SWITCH' if switch else ''}; torso heading "
              f"{d(wrap_angle(odo.heading - true_torso)):+6.2f}, torso-to-sole "
              f"{d(wrap_angle(yaw_of(ts.rotation) - true_ts)):+6.2f}", flush=True)  # fmt: skip

    variations = models(robot, max(args.models) + 1, args.seed)
    if args.no_backlash:
        variations = [replace(v, servo_params=replace(v.servo_params, backlash=0.0))
                      for v in variations]  # fmt: skip
    walkers: list = []
    odometers: list = []
    base, odometer = drive_sim_module.Walker, drive_sim_module.Odometer

    class Recorded(base):  # the run's walker, kept for its engine
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            walkers.append(self)
            self.start_frame = self.engine.centre.copy()
            self.landings: list = []  # (t, the odometry's frame, the simulator's, command)
            self.t_walk: float | None = None  # when the engine started walking (sim time)
            self.budget = LandingBudget()

        def tick(self, dt=None):
            if self.t_walk is None and self.engine.walking and odometers:
                self.t_walk = odometers[-1].sim.time
            return super().tick(dt)

        def _landed(self, step):
            odo = self.odometry
            stance = "right" if step.side == "left" else "left"
            chain = (float(odo.soles[stance][2]) if odo is not None and odo.started
                     and stance in odo.soles else None)  # fmt: skip
            mean = None if self.landing is None else self.landing.placed(step.side)
            out = super()._landed(step)
            if self._offset is not None and odometers:
                sim = odometers[-1].sim
                est = self.engine.centre + self._offset
                truth = soles_mid(sim)
                self.landings.append((sim.time, est, truth, self.engine.command_velocity))
                q = self._present_configuration()
                if q is not None and self.odometry is not None:
                    self.budget.landed(self.robot, sim, self.odometry, step.side, q, mean)
                    if args.trace and chain is not None:
                        trace_line(self, sim, step.side, q, chain)
            return out

    class Sampled(odometer):  # the soles, base, support and headings every tick
        def __init__(self, sim) -> None:
            super().__init__(sim)
            self.rows: list[list[float]] = []
            odometers.append(self)
            if args.contact:
                self.slip = ContactSlip(sim, lambda: walkers[-1] if walkers else None)

        def __call__(self) -> None:
            super().__call__()
            sim, w = self.sim, walkers[-1]
            row = [sim.time]
            for frame in ("l_sole", "r_sole"):
                M = sim.site_pose(frame)
                row += [M.translation[0], M.translation[1], yaw_of(M.rotation)]
            row += [*sim.q()[:2], yaw_of(sim.base_rotation())]
            row.append(w.last.support if w.last is not None else -1)
            odo = w.odometry
            row.append(odo.heading if odo is not None and odo.started else math.nan)
            row.append(yaw_of(sim.site_pose("torso").rotation))
            self.rows.append(row)

    if args.bias:
        drive_sim_module.Walker, drive_sim_module.Odometer = Recorded, Sampled
        limits, window = planning_envelope(robot)
        for m in args.models:
            walkers.clear()
            odometers.clear()
            drive.run_one(robot, "hqp-daqp", [Command(0.05)], variations[m], limits=limits,
                          window=window, calibrate=args.calibrate,
                          yaw_rest=args.yaw_rest)  # fmt: skip
            print(f"model {m}: " + vertical_bias(walkers[0], odometers[0].sim), flush=True)
        return 0
    keys = ("plan", "odometry", "swing", "slip", "base", "origin")
    table = []
    params = None if args.swing_settle is None else EngineParams(settle=args.swing_settle)
    for i, m, cmds, r in shadowed_runs(
        robot,
        args.sequences,
        args.models,
        args.seed,
        args.duration,
        Recorded,
        Sampled,
        (walkers, odometers),
        variations,
        track=args.track,
        calibrate=args.calibrate,
        yaw_rest=args.yaw_rest,
        finish=args.finish,
        lift_gain=args.lift_gain,
        play=args.play,
        stride_gain=args.stride_gain,
        play_hold=args.play_hold,
        heading_gain=args.heading_gain,
        play_load={"off": ""}.get(args.play_load, args.play_load),
        landing_share=args.landing_share,
        params=params,
        start_yaw=math.radians(args.start_yaw),
    ):
        b = breakdown(r, walkers[0], np.asarray(odometers[0].rows), odometers[0].yaw0)
        table.append(b)
        cy, ty = math.degrees(r["commanded_yaw_rad"]), math.degrees(r["travelled_yaw_rad"])
        print(f"sequence {i} model {m}: fell {r['fell']} commanded "
              f"{np.round(r['commanded_xy_m'], 3)} m {cy:.0f}° travelled "
              f"{np.round(r['travelled_xy_m'], 3)} m {ty:.0f}°: error "
              f"{100 * r['xy_error_m']:.1f} cm, {ty - cy:+.1f}°; "
              + ", ".join(f"{k} {b[k + '_cm']:.1f} cm" for k in keys)
              + f" (slip along the command {b['slip_along_cm']:+.1f} cm)"
              + "; " + ", ".join(f"{k} {b[k + '_deg']:+.1f}°"
                                 for k in ("plan", "odometry", "swing", "slip", "base", "gyro")
                                 if k + "_deg" in b),
              flush=True)  # fmt: skip
        err = np.subtract(r["travelled_xy_m"], r["commanded_xy_m"])
        world = rot2(odometers[0].yaw0) @ err
        print(f"  error (travelled − commanded): start frame ({100 * err[0]:+.2f}, "
              f"{100 * err[1]:+.2f}) cm, world ({100 * world[0]:+.2f}, "
              f"{100 * world[1]:+.2f}) cm", flush=True)  # fmt: skip
        print("  parts (start frame): " + ", ".join(
            f"{k} ({b[k + '_vec'][0]:+.2f}, {b[k + '_vec'][1]:+.2f}) cm"
            for k in ("plan", "soles", "base")), flush=True)  # fmt: skip
        if args.trace and walkers[0].landings:
            rows = np.asarray(odometers[0].rows)
            t_last = walkers[0].landings[-1][0]
            for k in range(int(np.searchsorted(rows[:, 0], t_last)), len(rows), 10):
                print(f"  after the last landing: t {rows[k, 0]:6.2f} soles' yaw "
                      f"{math.degrees(rows[k, 3]):+6.1f} {math.degrees(rows[k, 6]):+6.1f}° "
                      f"base {math.degrees(rows[k, 9]):+6.1f}° support {rows[k, 10]:.0f} "
                      f"torso {math.degrees(rows[k, 12]):+6.1f}° odometry's "
                      f"{math.degrees(rows[k, 11]):+6.1f}°",
                      flush=True)  # fmt: skip
        if args.contact:
            print("\n".join(odometers[0].slip.lines(odometers[0].yaw0)), flush=True)
        if args.accrual:
            print("\n".join(accrual(r, walkers[0], odometers[0], cmds)), flush=True)
        if args.budget:
            print(walkers[0].budget.line(), flush=True)
    if len(table) > 1:
        print("mean |.|: " + ", ".join(
            f"{k} {np.mean([abs(b[k]) for b in table if k in b]):.1f}"
            for k in [f"{k}_cm" for k in keys]
            + [f"{k}_deg" for k in ("plan", "odometry", "swing", "slip", "base", "gyro")]
            if any(k in b for b in table)))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
