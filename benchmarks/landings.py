"""The odometry's reading of each landing, over many landings: per random command sequence
and randomised model (as ``benchmarks/drive.py --random``), at every landing the walker
measures (the double support's last tick, :attr:`wbc.walking.engine.WalkEngine.on_landing`),
the landed sole's placement from the stance sole as the walker's odometry reads it against
the simulator's truth at the same tick — in the stance sole's frame: ``x`` forward, ``out``
sideways away from the stance sole, ``yaw`` the relative heading —, beside shadow readings
that change nothing the walker does (the same landings for all):

* ``main``: the walker's own (the present joints, the play taken out, :class:`PlayInverse
  <wbc.drive.odometry.PlayInverse>`; with ``Walker(landing_share=F)`` the mean it took);
* ``raw``: the encoders' readings as they are (the middle of the play);
* ``mean``: ``main``'s links averaged over the double support (``LandingMean``, share 1);
* ``raw_mean``: the raw readings averaged over the double support;
* ``first``: ``main``'s links at the double support's first tick;
* ``hold10`` … ``hold50``: ``main`` with the play's side held 10 … 50 ms (the walker's
  ``play_hold``, 0.1 s by default) after a reading's last change;
* ``stance_raw``, ``landed_raw``: ``main``'s links but the stance / landed leg's raw;
* ``side``: the raw readings + half the play toward the simulator's own link (the bound of
  any rule that finds the play's side);
* ``links``: the simulator's joints (the kinematics' own error: the soles' flatness);
* ``truth_mean``: the truth averaged over the double support, against the truth at the tick
  (the soles' own motion in double support).

Each landing is classed by its planned step (in the stance sole's planned frame: ``turn``
|Δheading| > 3°, else ``side`` the sideways step off the standing width > 5 mm and larger
than the forward one, ``fwd`` / ``back`` |x| > 5 mm, else ``spot``) and its place in the
walk (``first``: the walk's first two landings; ``last``: after the stop, the closing and
finish steps; ``mid``). Per landing too: the stance sole's unseen slide since its own
landing was measured (the simulator's, in its frame), the odometry's stance-heading error.

``--out FILE`` appends one JSON line per landing; ``--summary FILE ...`` prints the error's
mean and spread per reading and class over every landing of the files (mm, °): the mean is
the bias a run's landings add up, the spread what averages out. benchmarks/drive.md quotes
it::

    nice -n 10 python benchmarks/landings.py --sequences 13 --models 0 --out L.jsonl
    python benchmarks/landings.py --summary L.jsonl
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from drive_odometry import shadowed_runs

import wbc.drive.sim as drive_sim_module
from wbc import load_robot
from wbc.drive.odometry import PlayInverse
from wbc.geometry import wrap_angle, yaw_of
from wbc.types import SUPPORT_DOUBLE
from wbc.walking.geometry import rot2

SOLES = {"left": "l_sole", "right": "r_sole"}
HOLDS = {"hold10": 0.01, "hold20": 0.02, "hold30": 0.03, "hold50": 0.05}
READINGS = ("main", "raw", "mean", "raw_mean", "first", *HOLDS, "stance_raw", "landed_raw",
            "side", "links")  # fmt: skip
TURN, SIDE, FWD = math.radians(3.0), 0.005, 0.005


def relative(robot, q: np.ndarray) -> np.ndarray:
    """(x, y, yaw) of the right sole in the left's frame, then of the left in the right's."""
    (rel,) = robot.placements_in(q, SOLES["left"], [SOLES["right"]])
    inv = rel.inverse()
    return np.r_[rel.translation[:2], yaw_of(rel.rotation), inv.translation[:2],
                 yaw_of(inv.rotation)]  # fmt: skip


def true_relative(sim) -> np.ndarray:
    """:func:`relative` of the simulated soles (flat: x, y, heading)."""
    L, R = (sim.site_pose(f) for f in SOLES.values())
    out = []
    for a, b in ((L, R), (R, L)):
        ya = yaw_of(a.rotation)
        d = rot2(ya).T @ (b.translation[:2] - a.translation[:2])
        out.append(np.r_[d, wrap_angle(yaw_of(b.rotation) - ya)])
    return np.concatenate(out)


def pick(rows: np.ndarray, side: str) -> np.ndarray:
    """The landed ``side``'s placement in the other sole's frame from :func:`relative`."""
    return rows[..., :3] if side == "right" else rows[..., 3:]


def classify(step, stance, width: float) -> tuple[str, np.ndarray]:
    """The planned step's class (module docstring) and its (x, out, yaw) in the stance
    sole's planned frame."""
    d = rot2(stance.yaw).T @ (step.xy - stance.xy)
    out = d[1] if step.side == "left" else -d[1]
    dyaw = wrap_angle(step.yaw - stance.yaw)
    if abs(dyaw) > TURN:
        kind = "turn"
    elif abs(out - width) > SIDE and abs(out - width) > abs(d[0]):
        kind = "side"
    elif abs(d[0]) > FWD:
        kind = "fwd" if d[0] > 0 else "back"
    else:
        kind = "spot"
    return kind, np.array([d[0], out, dyaw])


def run(args) -> None:
    robot = load_robot("bioloid")
    walkers: list = []
    sims: list = []
    base, odometer = drive_sim_module.Walker, drive_sim_module.Odometer
    out = open(args.out, "a") if args.out else None

    class Shadowed(base):  # the run's walker, its landings read every way
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            walkers.append(self)
            self.ds: list[dict] = []  # per tick of the walking double support so far
            self.sampled_at = -1  # the engine tick last sampled
            self.walk_steps0 = 0  # steps taken when this walk started
            self.was_walking = False
            self.landed_n = 0
            self.measured_at: dict[str, np.ndarray] = {}  # each sole's truth at its landing
            self.rows: list[dict] = []
            st = self.engine.feet
            m = self.robot.model
            self.legs = {}  # side -> the leg's joints (indices into the joints)
            for side, frame in SOLES.items():
                chain = m.supports[m.frames[self.robot.frame_id(frame)].parentJoint]
                self.legs[side] = [m.joints[j].idx_q - 7 for j in chain if m.joints[j].nq == 1]
            play = 2 * self.play.half if self.play is not None else 0.0
            n = self.robot.n_joints
            self.holds = {k: PlayInverse(play, n, h) for k, h in HOLDS.items()}
            self.held: dict = {}
            d = rot2(st["left"].yaw).T @ (st["right"].xy - st["left"].xy)
            self.width = abs(float(d[1]))

        def sample(self) -> None:
            """This tick's readings of the soles' relative placement (once per tick)."""
            if self.sampled_at == self.engine.k or not sims:
                return
            self.sampled_at = self.engine.k
            sim = sims[-1]
            raw = self.present()
            links = self._links if self.play is not None else raw
            if raw is None or links is None or not np.all(np.isfinite(raw)):
                return
            true_q = sim.q()[7:]
            row = {"raw": raw, "main": links, "links": true_q, **self.held}
            for side, leg in self.legs.items():
                mixed = np.array(links, dtype=float)
                mixed[leg] = raw[leg]
                row[f"{side}_raw"] = mixed
            if self.play is not None:
                row["side"] = raw + self.play.half * np.sign(true_q - raw)
            else:
                row["side"] = raw
            rel = {k: relative(self.robot, self.robot.with_joints(np.asarray(v, float)))
                   for k, v in row.items()}  # fmt: skip
            rel["truth"] = true_relative(sim)
            self.ds.append(rel)

        def tick(self, dt=None):
            raw = self.present()
            if raw is not None:  # (as the walker's own, before its tick)
                step = self.engine.dt if dt is None else dt
                self.held = {k: h.update(raw, step) for k, h in self.holds.items()}
            q = super().tick(dt)
            e, engine = self.last, self.engine
            if engine.walking and not self.was_walking:
                self.walk_steps0 = engine.steps_taken
            self.was_walking = engine.walking
            if e is not None and e.support == SUPPORT_DOUBLE and engine.walking:
                self.sample()
            else:
                self.ds.clear()
            return q

        def _landed(self, step):
            engine = self.engine
            stance_side = "right" if step.side == "left" else "left"
            stance = engine.feet[stance_side]
            taken = self.landing.placed(step.side) if self.landing is not None else None
            result = super()._landed(step)
            if not sims or self._present_configuration() is None:
                return result
            self.sample()  # (this tick, if the tick has not sampled it yet)
            sim = sims[-1]
            ds = self.ds
            if not ds:
                return result
            last = ds[-1]
            truth = pick(last["truth"], step.side)
            read = {
                "main": pick(last["main"], step.side) if taken is None else np.asarray(taken),
                "raw": pick(last["raw"], step.side),
                "mean": pick(np.mean([r["main"] for r in ds], 0), step.side),
                "raw_mean": pick(np.mean([r["raw"] for r in ds], 0), step.side),
                "first": pick(ds[0]["main"], step.side),
                **{k: pick(last[k], step.side) for k in HOLDS},
                "stance_raw": pick(last[f"{stance_side}_raw"], step.side),
                "landed_raw": pick(last[f"{step.side}_raw"], step.side),
                "side": pick(last["side"], step.side),
                "links": pick(last["links"], step.side),
                "truth_mean": pick(np.mean([r["truth"] for r in ds], 0), step.side),
            }
            sign = 1.0 if step.side == "left" else -1.0  # (y → outward)
            errors = {}
            for k, v in read.items():
                e = np.asarray(v, float) - truth
                errors[k] = [1000 * e[0], 1000 * sign * e[1], math.degrees(wrap_angle(e[2]))]
            kind, planned = classify(step, stance, self.width)
            n = engine.steps_taken - self.walk_steps0
            if engine.state == "stopping" or engine._stop_requested or engine.ending:
                where = "last"
            elif n <= 2:
                where = "first"
            else:
                where = "mid"
            # the stance sole's unseen slide since its own landing was measured (its frame;
            # out: away from the landed sole)
            M = sim.site_pose(SOLES[stance_side])
            yaw = yaw_of(M.rotation)
            was = self.measured_at.get(stance_side)
            slide = [0.0, 0.0, 0.0]
            if was is not None:
                d = rot2(yaw).T @ (M.translation[:2] - was[:2])
                slide = [1000 * d[0], -1000 * sign * d[1], math.degrees(wrap_angle(yaw - was[2]))]
            Mw = sim.site_pose(SOLES[step.side])
            self.measured_at[step.side] = np.r_[Mw.translation[:2], yaw_of(Mw.rotation)]
            odo = self.odometry
            heading = (math.degrees(wrap_angle(odo.soles[stance_side][2] - yaw))
                       if odo is not None and odo.started else None)  # fmt: skip
            self.rows.append({
                "t": sim.time, "side": step.side, "n": n, "kind": kind, "where": where,
                "planned": [1000 * planned[0], 1000 * planned[1], math.degrees(planned[2])],
                "command": [float(c) for c in engine.command_velocity],
                "ds_ticks": len(ds), "errors": errors, "slide": slide,
                "heading_error": heading, "stance_yaw": yaw,
            })  # fmt: skip
            return result

    class Sampled(odometer):
        def __init__(self, sim) -> None:
            super().__init__(sim)
            sims.append(sim)

    for i, m, _, r in shadowed_runs(
        robot,
        args.sequences,
        args.models,
        args.seed,
        args.duration,
        Shadowed,
        Sampled,
        (walkers, sims),
        landing_share=args.landing_share,
        play_hold=args.play_hold,
    ):
        w = walkers[0]
        err, rel = 1000 * r["xy_error_m"], r["xy_error_rel"]
        print(f"sequence {i} model {m}: fell {r['fell']}, error {err:.1f} mm "
              f"({'—' if rel is None else f'{100 * rel:.0f} %'}), "
              f"{math.degrees(r['travelled_yaw_rad'] - r['commanded_yaw_rad']):+.1f}°, "
              f"{len(w.rows)} landings", flush=True)  # fmt: skip
        for row in w.rows:
            row.update(sequence=i, model=m, run_error_mm=err)
            if out is not None:
                out.write(json.dumps(row) + "\n")
        if out is not None:
            out.flush()
        if args.runs:
            with open(args.runs, "a") as f:
                keep = ("fell", "failed_solves", "xy_error_m", "xy_error_rel", "yaw_error_rad",
                        "yaw_error_rel", "commanded_xy_m", "travelled_xy_m",
                        "commanded_yaw_rad", "travelled_yaw_rad", "walk_tick_ms_p50",
                        "tilt_max_deg")  # fmt: skip
                f.write(json.dumps({"sequence": i, "model": m, "play_hold": args.play_hold,
                                    **{k: r[k] for k in keep}}) + "\n")  # fmt: skip
        print("\n".join(summary(w.rows)), flush=True)


def stats(values: list) -> str:
    a = np.asarray(values, float)
    if a.ndim != 2 or not len(a):
        return "—"
    m, s = a.mean(0), a.std(0)
    return f"{m[0]:+5.2f}±{s[0]:.2f} {m[1]:+5.2f}±{s[1]:.2f} {m[2]:+5.2f}±{s[2]:.2f}"


def along(row: dict, error: list, width: float) -> float:
    """The error's part along the planned step (mm; the step from the standing placement
    beside the stance sole; > 0: read long), 0 for a step of < 5 mm."""
    d = np.array([row["planned"][0], row["planned"][1] - width])
    n = float(np.linalg.norm(d))
    return float(np.dot(error[:2], d) / n) if n > 5.0 else 0.0


def summary(rows: list[dict], by: str = "kind") -> list[str]:
    """Per reading, the error's mean ± spread (x mm, out mm, yaw °; ``along``: along the
    planned step, > 0 long) over all landings and per class (``by``: ``kind``, ``where``,
    ``side``, ``model``, ``sequence``)."""
    names = [k for k in (*READINGS, "truth_mean") if rows and k in rows[0]["errors"]]
    spot = [r["planned"][1] for r in rows if abs(r["planned"][0]) < 1.0]
    width = float(np.median(spot)) if spot else 0.0
    out = [f"  {len(rows)} landings; error mean±sd (x mm, out mm, yaw °; along the step mm) "
           f"per reading"]  # fmt: skip
    groups: dict = {"all": rows}
    for r in rows:
        groups.setdefault(f"{by} {r[by]}", []).append(r)
    for g, rs in groups.items():
        out.append(f"  {g} ({len(rs)}): slide {stats([r['slide'] for r in rs])}")
        for k in names:
            a = np.array([along(r, r["errors"][k], width) for r in rs])
            out.append(f"    {k:10s} {stats([r['errors'][k] for r in rs])}; along "
                       f"{a.mean():+5.2f}±{a.std():.2f}")  # fmt: skip
    return out


def run_sums(rows: list[dict]) -> list[str]:
    """Per reading, each run's placement errors summed in the world (by the stance soles'
    true headings: what the odometry's chain adds up over the walk) — alone, and less the
    stance soles' unseen slides (the odometry's position error but for its heading) —: the
    mean and median of their norms over the runs and the runs where the reading's is below
    ``main``'s (mm)."""
    runs: dict = {}
    for r in rows:
        if "stance_yaw" in r:
            runs.setdefault((r["sequence"], r["model"]), []).append(r)
    if not runs:
        return []
    names = [k for k in (*READINGS, "truth_mean") if k in rows[0]["errors"]]
    norms: dict = {k: ([], []) for k in names}
    slides = []
    for rs in runs.values():
        slide = np.zeros(2)
        for r in rs:  # (out: away from the landed sole)
            x, out = r["slide"][:2]
            slide += rot2(r["stance_yaw"]) @ np.array([x, -out if r["side"] == "left" else out])
        slides.append(float(np.linalg.norm(slide)))
        for k in names:
            total = np.zeros(2)
            for r in rs:  # (out: away from the stance sole)
                x, out = r["errors"][k][:2]
                local = np.array([x, out if r["side"] == "left" else -out])
                total += rot2(r["stance_yaw"]) @ local
            norms[k][0].append(float(np.linalg.norm(total)))
            norms[k][1].append(float(np.linalg.norm(total - slide)))
    out = [f"  {len(runs)} runs: |Σ placement error| and |Σ placement error − Σ slide| "
           f"(world, mm) per run: mean / median, runs below main's; |Σ slide| mean / median "
           f"{np.mean(slides):.1f} / {np.median(slides):.1f}"]  # fmt: skip
    for k in names:
        cols = []
        for j in (0, 1):
            a, base = np.array(norms[k][j]), np.array(norms["main"][j])
            cols.append(f"{a.mean():6.1f} / {np.median(a):6.1f}, {int(np.sum(a < base))}")
        out.append(f"    {k:10s} {cols[0]};  {cols[1]}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, nargs="+", default=[0])
    ap.add_argument("--models", type=int, nargs="+", default=[0])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--landing-share", type=float, default=None, metavar="F",
                    help="as benchmarks/drive.py --landing-share")  # fmt: skip
    ap.add_argument("--play-hold", type=float, default=None, metavar="S",
                    help="as benchmarks/drive.py --play-hold (the walker's reading)")  # fmt: skip
    ap.add_argument("--runs", default=None, metavar="FILE",
                    help="append each run's record (JSONL: errors, ratings' inputs)")  # fmt: skip
    ap.add_argument("--out", default=None, metavar="FILE", help="append the landings (JSONL)")
    ap.add_argument("--summary", nargs="+", default=None, metavar="FILE",
                    help="summarise the landings of these files instead of running")  # fmt: skip
    ap.add_argument("--by", nargs="+", default=["kind", "where"],
                    help="--summary: the classes (kind, where, side, model, sequence)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.summary:
        rows = [json.loads(line) for f in args.summary for line in open(f) if line.strip()]
        for by in args.by:
            print("\n".join(summary(rows, by)))
        print("\n".join(run_sums(rows)))
        return 0
    run(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
