"""What a real robot's sensors see of the stance sole's slip: per tick of a random command
sequence on a randomised model (as ``benchmarks/drive.py --random``), the IMU's calibrated
specific force and rate as the walker reads them (the reading the stabiliser took, not a
second one), the present links (the play out), the walker's support and odometry heading,
and the simulator's truth (the IMU site's pose, the soles' poses); the landings the walker
measured. Saved as an ``.npz``; ``--analyse FILE ...`` then, per stance interval (a sole's
landing to the next landing: that sole the stance sole throughout), the stance sole's slide
(the simulator's) against what the IMU and the legs can tell of it — the torso's displacement
by the specific force integrated twice, less its displacement over the stance sole by the
kinematics (:class:`wbc.drive.slip.SlipEstimate`'s estimate) — with the torso's rotation the
simulator's (``trueR``) or the kinematics' tilt (``kinR``), the start velocity the
simulator's (``v0true``, an oracle) or the legs' over the last 5 or 10 ticks; ``filtered``:
the same from an accelerometer that averages over the tick (the simulator's acceleration so
averaged, plus the model's white noise: a real IMU's low-pass, which this simulated one
lacks); ``legs``: the simulator's own torso displacement (an ideal IMU): the legs' error
alone; per estimate its error's spread and the best linear blend's (the share fitted on
the truth: the most any Kalman gain on it could take out of the slide)::

    nice -n 10 python benchmarks/slip_probe.py --sequence 13 --model 0 --out /tmp/s13m0.npz
    python benchmarks/slip_probe.py --analyse /tmp/s13m0.npz /tmp/s3m15.npz
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import drive

import wbc.drive.sim as drive_sim_module
from wbc import load_robot
from wbc.bench.variation import models
from wbc.drive.commands import random_commands
from wbc.drive.envelope import planning_envelope
from wbc.drive.odometry import PoseOdometry
from wbc.geometry import heading_free, rot_z, wrap_angle, yaw_of
from wbc.sim.model import CONDIMS
from wbc.types import SUPPORT_DOUBLE
from wbc.walking.engine import EngineParams

SOLES = {"left": "l_sole", "right": "r_sole"}
GRAVITY = np.array([0.0, 0.0, 9.81])
ESTIMATES = ("trueR_v0true", "kinR_v0true", "kinR_v0kin5", "kinR_v0kin10",
             "filtered_trueR_v0true", "filtered_kinR_v0true", "filtered_kinR_v0kin5")  # fmt: skip


def record(args) -> None:
    robot = load_robot("bioloid")
    limits, window = planning_envelope(robot)
    share = (limits.vx_forward, limits.vx_backward, limits.vy, limits.wz)
    variation = models(robot, args.model + 1, args.seed)[args.model]
    variation = replace(variation, model_params=replace(variation.model_params,
                                                        condim=args.condim))  # fmt: skip
    if args.imu_integrate:
        variation = replace(variation, imu={**variation.imu, "integrate": True})
    rows: list[dict] = []
    landings: list[tuple[float, str]] = []
    sims: list = []
    walkers: list = []
    base, odometer = drive_sim_module.Walker, drive_sim_module.Odometer

    class Recorder:
        """The IMU as the walker reads it, the last reading kept."""

        def __init__(self, imu) -> None:
            self.imu, self.last = imu, None

        def read(self):
            self.last = self.imu.read()
            return self.last

        def __getattr__(self, name):
            return getattr(self.imu, name)

    class Probed(base):
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            self.stabilizer.imu = Recorder(self.stabilizer.imu)
            walkers.append(self)

        def tick(self, dt=None):
            q = super().tick(dt)
            stab, e = self.stabilizer, self.last
            reading = stab.imu.last
            if not sims or reading is None or e is None or stab.calibrating:
                return q
            sim = sims[-1]
            w, a = reading.angular_velocity, reading.linear_acceleration
            if stab.mount is not None:
                w, a = stab.mount.rates(w, a)
            if stab.calibration is not None:
                w = w - stab.calibration.gyro_bias
                a = stab.calibration.level @ a
            links = self._links if self.play is not None else self.present()
            imu = sim.site_pose("imu")
            soles = [sim.site_pose(f) for f in SOLES.values()]
            odo = self.odometry
            wrench = [sim.floor_wrench(b, s.translation) for b, s in zip(feet, soles, strict=True)]
            rows.append({
                "t": sim.time, "acc": np.array(a, float), "gyro": np.array(w, float),
                "links": np.array(links, float), "double": e.support == SUPPORT_DOUBLE,
                "stance": 0 if e.support_frame == "l_sole" else 1,
                "walking": bool(self.engine.walking),
                "heading": odo.heading if odo is not None else math.nan,
                "yaw_bias": odo.yaw_bias if odo is not None else math.nan,
                "resting": self._yaw_rest_left > 0,
                "trim": self.trim.bias.copy() if self.trim is not None else np.zeros(3),
                "odo_soles": np.array([odo.soles.get(s, np.full(3, math.nan))
                                       for s in SOLES]) if odo is not None and odo.soles
                else np.full((2, 3), math.nan),
                "pose_cmd": np.array(self.engine.pose_cmd, float),
                "centre": np.array(self.engine.centre + self.engine.odometry_offset, float),
                "base_yaw": yaw_of(sim.base_rotation()),
                "est_R": np.array(stab.last.rotation) if stab.last is not None else np.eye(3),
                "true_R": imu.rotation.copy(), "true_p": imu.translation.copy(),
                "soles": np.array([np.r_[s.translation, yaw_of(s.rotation)] for s in soles]),
                "wrench": np.array([np.r_[F, M] for F, M, _ in wrench]),
                "capacity": np.array([c for _, _, c in wrench]),
                "momenta": branch_momenta(sim, branches), "com": sim.com(),
                "points": np.array([np.count_nonzero(sim.contacts()[2] == b) for b in feet]),
            })  # fmt: skip
            return q

        def _landed(self, step):
            if sims:
                landings.append((sims[-1].time, step.side))
            return super()._landed(step)

    feet: list[int] = []
    branches: np.ndarray = np.zeros(0, int)

    class Sampled(odometer):
        def __init__(self, sim) -> None:
            nonlocal branches
            super().__init__(sim)
            sims.append(sim)
            mj = sim.mj
            feet[:] = [mj.mj_name2id(sim.model, mj.mjtObj.mjOBJ_BODY, b) for b in sim.robot_feet()]
            branches = body_branches(sim.model, sim.root, feet)

    drive_sim_module.Walker = Probed
    drive_sim_module.Odometer = Sampled
    cmds = random_commands(np.random.default_rng([args.seed, 1000 + args.sequence]), share,
                           args.duration)  # fmt: skip
    params = None if args.transfer is None else EngineParams(transfer=args.transfer)
    r = drive.run_one(robot, "hqp-daqp", cmds, variation, limits=limits, window=window,
                      params=params, load_ramp=args.load_ramp,
                      flat_liftoff=args.flat_liftoff, encoder_rest=args.encoder_rest,
                      rest_rotation=args.rest_rotation, yaw_rest=args.yaw_rest,
                      flatten=args.flatten, calibrate_settle=args.calibrate_settle,
                      gyro_trim=args.gyro_trim, rest_periods=args.rest_periods,
                      yaw_momentum=args.yaw_momentum,
                      yaw_momentum_step=args.yaw_momentum_step)  # fmt: skip
    stab = walkers[-1].stabilizer
    imu = stab.imu
    while not hasattr(imu, "gyro_bias") and hasattr(imu, "imu"):
        imu = imu.imu
    if stab.calibration is not None and hasattr(imu, "gyro_bias"):
        true = stab.mount.rotation @ imu.gyro_bias if stab.mount is not None else imu.gyro_bias
        err = np.degrees(stab.calibration.gyro_bias - true)
        print(
            f"start-up calibration: {stab.calibration.samples} samples, the gyro bias learnt "
            f"less the IMU's true bias (torso frame, deg/s): {np.round(err, 3).tolist()}"
        )
    print(f"sequence {args.sequence} model {args.model}: error {1000 * r['xy_error_m']:.1f} mm, "
          f"heading {math.degrees(r['travelled_yaw_rad'] - r['commanded_yaw_rad']):+.2f} deg, "
          f"{len(rows)} ticks, {len(landings)} landings", flush=True)  # fmt: skip
    out = {k: np.array([row[k] for row in rows]) for k in rows[0]}
    out["landing_t"] = np.array([t for t, _ in landings])
    out["landing_side"] = np.array([0 if s == "left" else 1 for _, s in landings])
    out["acc_noise"] = np.array(variation.imu.get("acc_noise", 0.0))
    np.savez(args.out, **out)


BRANCHES = ("torso", "left leg", "right leg", "upper")  # (the root, the soles', the rest)


def body_branches(model, root: int, feet: list[int]) -> np.ndarray:
    """Each body's branch (an index into :data:`BRANCHES`): the root's child it hangs from —
    the left sole's, the right sole's, any other (arms, head) —, the root itself 0, the world
    −1."""
    out = np.full(model.nbody, -1)
    for b in range(1, model.nbody):
        top = b
        while model.body_parentid[top] not in (root, 0):
            top = int(model.body_parentid[top])
        if b == root:
            out[b] = 0
        else:
            legs = [2 if f else 1 for f in range(2) if _hangs_from(model, feet[f], top)]
            out[b] = legs[0] if legs else 3
    return out


def _hangs_from(model, body: int, top: int) -> bool:
    while body > 0:
        if body == top:
            return True
        body = int(model.body_parentid[body])
    return False


def branch_momenta(sim, branches: np.ndarray) -> np.ndarray:
    """Per branch (:data:`BRANCHES`), its angular momentum about the world origin and its
    linear momentum (4 x 6, world axes): ``Σ m_b c_b × v_b + R_b I_b R_bᵀ ω_b``, ``Σ m_b v_b``
    over its bodies (MuJoCo's velocities at each body's centre of mass)."""
    mj, m, d = sim.mj, sim.model, sim.data
    out = np.zeros((len(BRANCHES), 6))
    vel = np.zeros(6)
    for b in range(1, m.nbody):
        if branches[b] < 0:
            continue
        mj.mj_objectVelocity(m, d, mj.mjtObj.mjOBJ_BODY, b, vel, 0)
        R, c, mass = d.ximat[b].reshape(3, 3), d.xipos[b], m.body_mass[b]
        spin = R @ (m.body_inertia[b] * (R.T @ vel[:3]))
        out[branches[b], :3] += mass * np.cross(c, vel[3:]) + spin
        out[branches[b], 3:] += mass * vel[3:]
    return out


def intervals(d: dict) -> list[tuple[int, int, int]]:
    """(first tick, last tick, stance side) of each stance interval between two landings."""
    t, lt, ls = d["t"], d["landing_t"], d["landing_side"]
    idx = np.clip(np.searchsorted(t, lt - 1e-9), 0, len(t) - 1)
    keep = [i for i in range(1, len(lt)) if ls[i] != ls[i - 1] and idx[i - 1] >= 10]
    return [(int(idx[i - 1]), int(idx[i]), int(ls[i - 1])) for i in keep
            if 5 <= idx[i] - idx[i - 1] <= 150]  # fmt: skip


def estimates(robot, d: dict, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """The slides (mm, world xy) of one run's stance intervals and each estimate's."""
    t, p, R, acc = d["t"], d["true_p"], d["true_R"], d["acc"]
    n = len(t)
    v_mid = np.diff(p, axis=0) / np.diff(t)[:, None]  # the velocity over each tick
    a_avg = np.zeros_like(p)
    a_avg[1:-1] = np.diff(v_mid, axis=0) / np.diff(t)[1:, None]
    noise = float(d.get("acc_noise", 0.0))
    filtered = np.einsum("nji,nj->ni", R, a_avg + GRAVITY) + rng.normal(0.0, noise, (n, 3))
    rel = np.zeros((2, n, 3))
    rot = np.zeros((2, n, 3, 3))
    for k in range(n):
        for j, M in enumerate(robot.placements_in(robot.with_joints(d["links"][k]), "torso",
                                                  list(SOLES.values()))):  # fmt: skip
            rel[j, k], rot[j, k] = M.inverse().translation, M.inverse().rotation
    slides, out = [], {}
    for a0, a1, A in intervals(d):
        slides.append(1000 * (d["soles"][a1, A, :2] - d["soles"][a0, A, :2]))
        Rz = rot_z(float(d["soles"][a0, A, 3]))
        legs = 1000 * (Rz @ (rel[A, a1] - rel[A, a0]))[:2]
        out.setdefault("legs", []).append(1000 * (p[a1] - p[a0])[:2] - legs)  # (the ideal IMU)
        for name in ESTIMATES:
            box = name.startswith("filtered")  # (its velocity per tick: exact if noiseless)
            if "v0true" in name:
                v = v_mid[a0 - 1] if box else (p[a0 + 1] - p[a0 - 1]) / (t[a0 + 1] - t[a0 - 1])
            else:
                m = int(name.rsplit("kin", 1)[1])
                v = Rz @ (rel[A, a0] - rel[A, a0 - m]) / (t[a0] - t[a0 - m])
            D = np.zeros(3)
            for k in range(a0, a1):
                h = t[k + 1] - t[k]
                if "trueR" in name:
                    Rk = R[k]
                else:  # the kinematics' tilt, the heading the simulator's
                    Rk = rot_z(yaw_of(R[k])) @ heading_free(Rz @ rot[A, k])
                a = Rk @ (filtered[k] if box else acc[k]) - GRAVITY
                if box:  # the mean velocity over tick k from the mean acceleration around k
                    v = v + a * h
                    D += v * h
                else:
                    D += v * h + 0.5 * a * h * h
                    v = v + a * h
            out.setdefault(name, []).append(1000 * D[:2] - legs)
    sample = np.einsum("nij,nj->ni", R, acc)[1:-1] - GRAVITY - a_avg[1:-1]
    out["_sample"] = sample[:, :2]  # the accelerometer's samples less the tick's mean
    phase = np.zeros((2, 10))  # the slide's path per tenth of the interval (mm), intervals
    for a0, a1, A in intervals(d):
        step = 1000 * np.linalg.norm(np.diff(d["soles"][a0 : a1 + 1, A, :2], axis=0), axis=1)
        np.add.at(phase[0], (10 * np.arange(len(step)) // len(step)), step)
        phase[1] += 1
    out["_phase"] = phase
    return np.array(slides), {k: np.array(v) for k, v in out.items()}


def analyse(files: list[str]) -> None:
    robot = load_robot("bioloid")
    rng = np.random.default_rng(0)
    slides: list = []
    est: dict = {}
    for f in files:
        s, e = estimates(robot, dict(np.load(f)), rng)
        slides.append(s)
        for k, v in e.items():
            est.setdefault(k, []).append(v)
    S = np.concatenate(slides)
    print(f"{len(S)} stance intervals: the slide's mean {np.round(S.mean(0), 2)} and spread "
          f"{np.round(S.std(0), 2)} mm (x, y world); per estimate, its error's mean and "
          f"spread, and the best blend's share and the slide's spread left")  # fmt: skip
    sample = np.concatenate(est.pop("_sample"))
    phase = np.sum(est.pop("_phase"), axis=0)
    print(f"  the accelerometer's samples less the tick's mean acceleration (world xy): "
          f"{np.round(sample.mean(0), 2)} ± {np.round(sample.std(0), 2)} m/s²; the slide's "
          f"path per tenth of the interval: {np.round(phase[0] / phase[1], 2)} mm")  # fmt: skip
    for k, parts in est.items():
        E = np.concatenate(parts)
        c = E - E.mean(0)
        share = (c * S).sum(0) / (c * c).sum(0)
        left = (S - share * c).std(0)
        err = E - S
        spread, kept = np.round(S.std(0), 2), np.round(left, 2)
        print(f"  {k:22s} error {np.round(err.mean(0), 1)} ± {np.round(err.std(0), 1)}; "
              f"blend {np.round(share, 3)}: {spread} -> {kept}")  # fmt: skip


def contacts(d: dict) -> list[tuple[int, int, int, int, int]]:
    """(sole, the first tick of its landing's double support, its first single-support tick,
    the first tick of the double support before its lift-off, its lift-off tick) of each
    whole contact of a walk (a landing's record, :meth:`Walker._landed`, comes at the last
    tick of that double support: the odometry places the sole there)."""
    t, double, stance = d["t"], d["double"], d["stance"]
    n, out = len(t), []
    for lt, side in zip(d["landing_t"], d["landing_side"], strict=True):
        a = b = int(np.searchsorted(t, lt - 1e-9))
        while a > 0 and double[a - 1]:
            a -= 1
        while b < n and double[b]:
            b += 1
        c = b
        while c < n and not double[c] and stance[c] == side:
            c += 1
        e = c
        while e < n and double[e]:
            e += 1
        if e < n and not double[e] and stance[e] != side and d["walking"][e]:
            out.append((int(side), a, b, c, e))
    return out


def phases(f: str) -> None:
    """Each sole's slide (the simulator's, world xy, mm) per contact phase of one recording
    (:func:`contacts`): the vector sums (those after the sole's placement at its landing
    double support's end are what the odometry's chain of landings misses, a drift) and
    the mean path length per contact."""
    d = dict(np.load(f))
    soles = d["soles"]
    parts = {"landing double": (1, 2), "single": (2, 3), "lift-off double": (3, 4)}
    cs = contacts(d)
    print(f"{f}: {len(cs)} contacts")
    total = np.zeros(2)  # the odometry's miss: a sole's slide once placed, to the other's
    for name, (i, j) in parts.items():
        moves = np.array([1000 * (soles[c[j], c[0], :2] - soles[c[i], c[0], :2]) for c in cs])
        paths = [1000 * np.linalg.norm(np.diff(soles[c[i] : c[j] + 1, c[0], :2], axis=0),
                                       axis=1).sum() for c in cs]  # fmt: skip
        total += moves.sum(0) if name != "landing double" else 0.0  # (placed at its end)
        print(
            f"  {name:16s} sum {np.round(moves.sum(0), 1)} mm, mean move "
            f"{np.round(moves.mean(0), 2)} ± {np.round(moves.std(0), 2)}, mean path "
            f"{np.mean(paths):.2f} mm, ticks {np.mean([c[j] - c[i] for c in cs]):.1f}"
        )
    path, height, ticks = np.zeros(10), np.zeros(10), np.zeros(10)  # per tenth of the single
    for side, a, b, c, e in cs:
        seg = soles[b : c + 1, side]
        step = 1000 * np.linalg.norm(np.diff(seg[:, :2], axis=0), axis=1)
        tenth = 10 * np.arange(len(step)) // len(step)
        np.add.at(path, tenth, step)
        np.add.at(height, tenth, 1000 * (seg[1:, 2] - soles[a:e, side, 2].min()))
        np.add.at(ticks, tenth, 1)
    turn = [math.degrees(wrap_angle(soles[c, side, 3] - soles[b, side, 3]))
            for side, a, b, c, e in cs]  # fmt: skip
    print(f"  single support per tenth: path {np.round(path / len(cs), 2)} mm, the sole above "
          f"its contact's lowest {np.round(height / ticks, 2)} mm; its turn ± "
          f"{np.std(turn):.1f}°")  # fmt: skip
    print(
        f"  missed by the landings' chain (single + lift-off double): {np.round(total, 1)} "
        f"mm ({np.linalg.norm(total):.1f})"
    )


def edges(f: str, thresholds: tuple[float, ...] = (2.0, 4.0, 6.0)) -> None:
    """Per whole contact of one recording (:func:`contacts`): the angle between the two
    soles' normals by the encoders at the last tick before the other sole lifts (the
    present links' forward kinematics, :func:`wbc.drive.liftoff.soles_tilt`), the stance
    sole's height above its contact's lowest then (the simulator's: on an edge), its turn
    over the single support that follows; the turn and the slide (single + lift-off double,
    the odometry's miss) of the contacts whose tilt exceeds each threshold."""
    from wbc.drive.liftoff import soles_tilt

    robot = load_robot("bioloid")
    d = dict(np.load(f))
    soles, cs = d["soles"], contacts(d)
    rows = []
    for side, a, b, c, e in cs:
        tilt = math.degrees(soles_tilt(robot, robot.with_joints(d["links"][b - 1])))
        low = soles[a:e, side, 2].min()
        turn = abs(math.degrees(wrap_angle(soles[c, side, 3] - soles[b, side, 3])))
        move = 1000 * (soles[e, side, :2] - soles[b, side, :2])
        rows.append((tilt, 1000 * (soles[b - 1, side, 2] - low), turn, *move))
    R = np.array(rows)
    print(f"{f}: {len(R)} contacts; the tilt at the lift-off against the sole's height "
          f"then: correlation {np.corrcoef(R[:, 0], R[:, 1])[0, 1]:.2f}, against its turn "
          f"{np.corrcoef(R[:, 0], R[:, 2])[0, 1]:.2f}; turn summed {R[:, 2].sum():.1f}°, "
          f"slide {np.round(R[:, 3:5].sum(0), 1)} mm")  # fmt: skip
    for thr in thresholds:
        m = R[:, 0] > thr
        print(
            f"  tilt > {thr:g}°: {m.sum()} contacts (height > 3 mm: {(R[m, 1] > 3).sum()}), "
            f"turn {R[m, 2].sum():.1f}°, slide {np.round(R[m, 3:5].sum(0), 1)} mm"
        )
    top = np.argsort(-R[:, 2])[:5]
    print("  largest turns (tilt °, height mm, turn °): "
          + ", ".join(f"{R[i, 0]:.1f}/{R[i, 1]:.1f}/{R[i, 2]:.1f}" for i in top))  # fmt: skip


def heading(f: str, every: float = 2.0) -> None:
    """The outer loop's heading against the simulator's, tick by tick, of one recording
    (degrees, each from the walk's first tick): the command's (``cmd``, the engine's
    commanded pose), the walking frame the engine aims from (``frame``: its plan plus the
    odometry's offset), the odometry's soles' mean heading (``odo soles``) against the
    simulator's (``soles``), the gyro's torso heading (``gyro``) against the simulator's
    torso (``torso``) and base (``base``), and the bias about the vertical learnt so far
    (deg/s); every ``every`` s and at the end."""
    d = dict(np.load(f))
    t, walking = d["t"], d["walking"]
    k0 = int(np.argmax(walking)) + 1  # (the odometry starts at the walk's first tick)

    def unwrap(a: np.ndarray) -> np.ndarray:  # (from the walk's first tick: NaN before it)
        out = np.full(len(a), math.nan)
        out[k0:] = np.degrees(np.unwrap(a[k0:]) - a[k0])
        return out

    true_torso = unwrap(np.array([yaw_of(R) for R in d["true_R"]]))
    soles_true = unwrap(np.array([math.atan2(np.sin(r).sum(), np.cos(r).sum())
                                  for r in d["soles"][:, :, 3]]))  # fmt: skip
    odo = d["odo_soles"][:, :, 2]
    soles_odo = unwrap(np.array([math.atan2(np.sin(r).sum(), np.cos(r).sum()) for r in odo]))
    cols = {"cmd": unwrap(d["pose_cmd"][:, 2]), "frame": unwrap(d["centre"][:, 2]),
            "odo soles": soles_odo, "soles": soles_true, "gyro": unwrap(d["heading"]),
            "torso": true_torso, "base": unwrap(d["base_yaw"])}  # fmt: skip
    print(f"{f}: walk from t = {t[k0]:.2f} s, bias learnt "
          f"{math.degrees(d['yaw_bias'][k0]):+.3f} deg/s at it, "
          f"{math.degrees(d['yaw_bias'][-1]):+.3f} at the end")  # fmt: skip
    print("  t s   " + "".join(f"{k:>10s}" for k in cols) + "   bias deg/s  walking")
    marks = list(range(k0, len(t), max(1, round(every / float(np.median(np.diff(t)))))))
    for k in [*marks, len(t) - 1]:
        print(f"  {t[k]:5.1f} " + "".join(f"{v[k]:10.2f}" for v in cols.values())
              + f"   {math.degrees(d['yaw_bias'][k]):+.4f}  {int(walking[k])}")  # fmt: skip
    rest, dt = np.flatnonzero(d["resting"]), float(np.median(np.diff(t)))
    if rest.size > 1:  # the rest's learning against the simulator's turn
        a, b = int(rest[0]), int(rest[-1])
        yaw = np.unwrap([yaw_of(R) for R in d["true_R"]])
        step = np.array([PoseOdometry._increment(d["true_R"][k], d["gyro"][k + 1], dt)
                         - (yaw[k + 1] - yaw[k]) for k in range(len(t) - 1)])  # fmt: skip
        walk = walking[:-1]
        print(f"  rest {t[a]:.2f}-{t[b]:.2f} s: the torso turned "
              f"{math.degrees(yaw[b] - yaw[a]):+.3f} deg (simulator); the gyro's rate about "
              f"the vertical less the simulator's "
              f"(on its tilt) {math.degrees(step[a:b].mean() / dt):+.3f} deg/s at rest, "
              f"{math.degrees(step[walk].mean() / dt):+.3f} walking")  # fmt: skip
    end = len(t) - 1
    print(f"  at the end: gyro - torso {cols['gyro'][end] - cols['torso'][end]:+.2f}, odo soles"
          f" - soles {cols['odo soles'][end] - cols['soles'][end]:+.2f}, base - cmd "
          f"{cols['base'][end] - cols['cmd'][end]:+.2f}, frame - cmd "
          f"{cols['frame'][end] - cols['cmd'][end]:+.2f}")  # fmt: skip


def yaw(f: str, spin_deg: float = 5.0, first: int = 8) -> None:
    """Per single support of a recording, the stance sole's turn against the floor's yaw moment
    on it (about its site; the simulator's contact forces, sampled at the ticks), the share of
    its ticks on an edge (≤ 2 contact points) or a corner (1), and the vertical angular
    momentum each branch gains about the whole body's CoM: their sum, dL_z/dt, is the free
    yaw moment the sole must resist (the horizontal force of an inverted pendulum, along
    CoM − CoP, has no moment about the vertical through the CoM)."""
    d = dict(np.load(f))
    if "wrench" not in d:
        raise SystemExit(f"{f}: recorded without contact forces (record it again)")
    t, dt = d["t"], float(np.median(np.diff(d["t"])))
    mom, g = d["momenta"], d["com"][:, None, :]  # (n, branch, 6), (n, 1, 3)
    Lz = mom[:, :, 2] - (g[..., 0] * mom[:, :, 4] - g[..., 1] * mom[:, :, 3])  # about the CoM
    rate = np.diff(Lz.sum(axis=1)) / np.diff(t)  # the free yaw moment, tick to tick
    rows = []
    for side, _a, b, c, _e in contacts(d):
        if c - b < first + 2:
            continue
        mz = d["wrench"][b:c, side, 5]
        yaw_s = np.unwrap(d["soles"][b : c + 1, side, 3])
        stance_b, swing_b = 1 + side, 2 - side
        order = (0, stance_b, swing_b, 3)  # torso, stance leg, swing leg, upper
        gain_first = [Lz[b + first, j] - Lz[b, j] for j in order]
        gain_all = [Lz[c, j] - Lz[b, j] for j in order]
        pts = d["points"][b:c, side]
        rows.append((t[b], side, math.degrees(yaw_s[-1] - yaw_s[0]),
                     math.degrees(yaw_s[first] - yaw_s[0]), mz[:first].sum() * dt,
                     np.abs(rate[b:c]).max(), np.abs(mz).max(), np.mean(pts <= 2),
                     np.mean(pts <= 1),
                     *gain_first, *gain_all))  # fmt: skip
    R = np.array(rows)
    spin = np.abs(R[:, 2]) > spin_deg
    print(
        f"{f}: {len(R)} single supports, {int(spin.sum())} turn > {spin_deg:g} deg (moments "
        "N·mm: the floor's about the stance sole's site, sampled; momenta N·mm·s about the CoM)"
    )
    print(
        "   t s  side  turn° (first) | impulse first, peak |dL_G/dt| | peak |Mz|, edge, corner "
        "first | ΔL_G first: torso stance swing upper | ΔL_G all: torso stance swing upper"
    )
    for r in R:
        mark = "*" if abs(r[2]) > spin_deg else " "
        print(f"{mark}{r[0]:6.2f}  {'LR'[int(r[1])]}  {r[2]:+6.1f} ({r[3]:+5.1f}) | "
              f"{1e3 * r[4]:+6.2f} {1e3 * r[5]:6.1f} | {1e3 * r[6]:6.1f} {r[7]:5.2f} "
              f"{r[8]:5.2f} | "
              + " ".join(f"{1e3 * v:+6.2f}" for v in r[9:13]) + " | "
              + " ".join(f"{1e3 * v:+6.2f}" for v in r[13:17]))  # fmt: skip
    for name, m in (("spinning", spin), ("the rest", ~spin)):
        if not m.any():
            continue
        Q = R[m]
        print(
            f"  {name} ({int(m.sum())}): |turn| {np.abs(Q[:, 2]).mean():.1f}°, |impulse| "
            f"first {1e3 * np.abs(Q[:, 4]).mean():.2f}, peak |dL_G/dt| {1e3 * Q[:, 5].mean():.1f}, "
            f"peak |Mz| {1e3 * Q[:, 6].mean():.1f} (on an edge {Q[:, 7].mean():.2f}, a corner "
            f"{Q[:, 8].mean():.2f}); |ΔL_G| first torso/stance/swing/upper "
            + "/".join(f"{1e3 * np.abs(Q[:, j]).mean():.2f}" for j in range(9, 13))
            + "; all "
            + "/".join(f"{1e3 * np.abs(Q[:, j]).mean():.2f}" for j in range(13, 17))
        )
    net = R[:, 13:17].sum(axis=1)
    c = np.corrcoef(R[:, 2], net)[0, 1]
    print(f"  correlation of the turn with the whole body's ΔL_G {c:+.2f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequence", type=int, default=13)
    ap.add_argument("--model", type=int, default=0)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="/tmp/slip_probe.npz")
    ap.add_argument(
        "--transfer",
        type=float,
        default=None,
        metavar="F",
        help="EngineParams(transfer=F) for the recorded run (default the engine's)",
    )
    ap.add_argument(
        "--load-ramp", action="store_true", help="Walker(load_ramp=True) for the recorded run"
    )
    ap.add_argument("--flat-liftoff", type=float, default=None, metavar="DEG",
                    help="Walker(flat_liftoff=DEG) for the recorded run")  # fmt: skip
    ap.add_argument("--encoder-rest", action="store_true",
                    help="Walker(encoder_rest=True) for the recorded run")  # fmt: skip
    ap.add_argument("--rest-rotation", action="store_true",
                    help="Walker(rest_rotation=True) for the recorded run")  # fmt: skip
    ap.add_argument("--calibrate-settle", type=float, default=None, metavar="S",
                    help="Walker(settle_s=S) for the recorded run")  # fmt: skip
    ap.add_argument("--yaw-rest", type=float, default=None, metavar="S",
                    help="Walker(yaw_rest_s=S) for the recorded run")  # fmt: skip
    ap.add_argument("--condim", type=int, default=3, choices=CONDIMS,
                    help="the floor's contact dimensions (ModelParams.condim)")  # fmt: skip
    ap.add_argument("--gyro-trim", type=float, default=None, metavar="T0",
                    help="Walker(gyro_trim=T0) for the recorded run")  # fmt: skip
    ap.add_argument("--imu-integrate", action="store_true",
                    help="SimImu(integrate=True) for the recorded run")  # fmt: skip
    ap.add_argument("--rest-periods", action="store_true",
                    help="Walker(rest_periods=True) for the recorded run")  # fmt: skip
    ap.add_argument("--flatten", type=float, default=None, metavar="RATE",
                    help="Walker(flatten=RATE) for the recorded run")  # fmt: skip
    ap.add_argument("--edges", nargs="+", default=None, metavar="FILE",
                    help="per recording, the soles' tilt by the encoders at each lift-off "
                         "against the stance sole's height, turn and slide after it")  # fmt: skip
    ap.add_argument("--heading", nargs="+", default=None, metavar="FILE",
                    help="per recording, the outer loop's heading against the simulator's "
                         "every 2 s (the command's, the walking frame's, the soles', the "
                         "gyro's torso; the bias learnt)")  # fmt: skip
    ap.add_argument("--yaw-momentum", type=float, default=None, metavar="W",
                    help="a yaw-momentum task at weight W for the recorded run")  # fmt: skip
    ap.add_argument("--yaw-momentum-step", action="store_true",
                    help="with --yaw-momentum: its target the torso's yaw step")  # fmt: skip
    ap.add_argument("--yaw", nargs="+", default=None, metavar="FILE",
                    help="per recording, each single support's turn against the floor's yaw "
                         "moment on the stance sole, its friction's reach and each branch's "
                         "vertical angular momentum gained")  # fmt: skip
    ap.add_argument("--analyse", nargs="+", default=None, metavar="FILE",
                    help="analyse these recordings instead of running")  # fmt: skip
    ap.add_argument("--phases", nargs="+", default=None, metavar="FILE",
                    help="per recording, each sole's slide over its contact split by phase "
                         "(its landing's double support, its single support, the double "
                         "support before its lift-off): sums and mean lengths")  # fmt: skip
    args = ap.parse_args(argv)
    if args.yaw:
        for f in args.yaw:
            yaw(f)
    elif args.edges:
        for f in args.edges:
            edges(f)
    elif args.heading:
        for f in args.heading:
            heading(f)
    elif args.phases:
        for f in args.phases:
            phases(f)
    elif args.analyse:
        analyse(args.analyse)
    else:
        record(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
