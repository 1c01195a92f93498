"""``wbc bench --physics``: does the robot stay up when the plan reaches the servos?

Every controller's run (planned by :func:`wbc.bench.runner.run_entry`) is played through the
deployment path on the simulated robot (:func:`wbc.bench.play.play`). Per run:

* ``fell`` and ``fall_time_s``: the torso deviates more than 45° from the planned base
  orientation or drops below 60 % of its planned height; ``fall_phase`` and
  ``fall_joint`` (the joint with the highest torque / stall in the 0.5 s before the fall)
  say why;
* ``orientation_dev_max_deg``: the largest angle between the real and the planned base
  orientation (before any fall);
* ``distance_ratio``: real base displacement along the planned one / the planned one (None
  after a fall);
* ``foot_slip_max_mm``: how far a sole slides while planned and loaded as a support;
* ``tracking_err_max_deg``: the largest |real − planned| joint angle (and its joint);
* ``torque_peak_ratio``: peak |servo torque| / stall torque (and its joint);
* ``cop_margin_min_mm``: the smallest distance of the real CoP (from the contact forces) to
  the edge of the real contact polygon during single support (0 = tipping over an edge).

Robustness (``--robustness N --seed S``): N randomised models
(:func:`wbc.bench.variation.random_model`); ``up_fraction`` = the share that stay up. Push
(``--push``): a 10 ms force on the torso at mid first single support, forward, backward,
sideways toward and away from the swing foot (:data:`wbc.bench.pushes.PUSH_DIRECTIONS`), each
beside its LIPM bound (:func:`wbc.bench.pushes.push_bounds`); the largest impulse survived
(N·s) by bisection over 0–3 N·s.

The pieces: :mod:`wbc.bench.sim_record` (the record of one run), :mod:`wbc.bench.variation`
(randomised plants), :mod:`wbc.bench.closed_loop` (live closed-loop runs, robustness),
:mod:`wbc.bench.pushes`; this module runs them over the benchmark's entries
(:func:`run_physics`) and prints the tables. The options: :mod:`wbc.cli.bench`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import ConfigurationError, WbcError
from ..model import Robot
from ..recording import Recording
from ..sim.watch import FALL_TILT_DEG
from .closed_loop import ClosedLoopSpec, closed_loop_figures, play_closed_loop, robustness
from .pushes import PUSH_DIRECTIONS, largest_push, push_bounds
from .sim_record import physics_record, simulated_recording
from .solvers import SolverEntry

if TYPE_CHECKING:
    from ..walking.reference import WalkingReference

#: the default solvers of --physics: one per controller (the QP backends give the same joints)
DEFAULT_SOLVERS = (
    "wqp-daqp", "hqp-daqp", "qp-vat", "qp-vatl", "qp-cj_foot", "qp-cj_com", "qp-cjl_foot",
    "qp-cjl_com", "pinv-vat", "pinv-vatl", "pinv-cj_foot", "pinv-cj_com", "pinv-cjl_foot",
    "pinv-cjl_com", "placo", "pink",
)  # fmt: skip


# ---------------------------------------------------------------------- planning
def physics_stack(robot: Robot, stack: str | None = None) -> str | None:
    """The stack of the wqp-*/hqp-* entries on a body (``wbc sim``, ``wbc bench --physics``,
    the closed loop): ``stack`` if given, else the robot folder's ``stack.toml``, else None
    (the benchmark's own, :data:`wbc.bench.solvers.BENCH_STACKS`)."""
    from ..stacks import robot_stack

    if stack is None and robot.default_stack is None:
        return None
    return str(robot_stack(robot, stack)[0])


def physics_entry(solver: str, robot: Robot) -> SolverEntry:
    """The benchmark entry ``solver`` runs on a body (``wbc sim``, open and closed loop): the
    wqp-*/hqp-* solvers on the robot folder's stack.toml when it has one."""
    from .solvers import select

    entries, notes = select([solver], None, "tick", stack=physics_stack(robot))
    if not entries:
        raise ConfigurationError(f"solver {solver!r} cannot run here: {'; '.join(notes)}")
    exact = [e for e in entries if e.name == solver]
    return (exact or entries)[0]


def plan(
    solver: str, trajectory: str, robot: Robot, ref: WalkingReference | None = None
) -> Recording:
    """The recording of one benchmark solver on one trajectory (one solve per tick); the
    wqp-*/hqp-* solvers load the robot folder's stack.toml when it has one. The walk is the
    one played on servos (``build(on_servos=True)``: within their speed), or ``ref`` if given
    (that walk, already built)."""
    from . import trajectories as traj
    from .runner import run_entry

    if ref is None:
        ref = traj.build(trajectory, robot, on_servos=True)
    _, rec = run_entry(physics_entry(solver, robot), robot, ref, "tick")
    return rec


@dataclass(frozen=True)
class PhysicsOptions:
    """What ``wbc bench --physics`` runs beside the plans: the compliance feed-forward gain
    ``compensate`` (``correct``: rescaled from the encoders) and the open-loop gyro feedback
    scale ``gyro``; ``closed_loop``: each controller also runs live, closed through the IMU
    (``use_imu``, else the encoders alone) with step adjustment (``stepping``);
    ``robustness`` randomised plants from ``seed``; ``push``: the largest survived pushes;
    ``all_solvers``: every entry (else :data:`DEFAULT_SOLVERS` only); ``record`` and ``plots``:
    directories for the recordings and the figures (None: none)."""

    compensate: float = 0.0
    gyro: float = 0.0
    correct: bool = False
    closed_loop: bool = True
    use_imu: bool = True
    stepping: bool = True
    robustness: int = 0
    seed: int = 0
    push: bool = False
    all_solvers: bool = False
    record: Path | None = None
    plots: Path | None = None


def run_physics(
    options: PhysicsOptions, console, robot: Robot, entries, refs: dict
) -> list[dict[str, Any]]:
    """Called by ``wbc bench --physics``: every entry on every trajectory in the simulator."""
    from rich.table import Table

    from .runner import run_entry, save_recording

    entries = [e for e in entries if e.real_time]  # plans are one solve per tick
    if not options.all_solvers:
        entries = [e for e in entries if e.name.split("@")[0] in DEFAULT_SOLVERS]
    records: list[dict[str, Any]] = []
    series = {}
    comp = options.compensate or 0.0
    gyro = options.gyro
    from ..sim.actuator import servo_kind

    closed_loop = options.closed_loop
    commanded = closed_loop and servo_kind(robot) == "hobby_pwm"
    if commanded:
        if not options.use_imu:
            raise ConfigurationError(
                f"--encoders-only: {robot.name}'s hobby servos report no positions (its closed "
                "loop is the IMU and the commanded joints)"
            )
        console.print(f"closed loop: {robot.name}'s hobby servos report no positions: the "
                      "estimator uses the IMU and the commanded joint positions (no step "
                      "adjustment)")  # fmt: skip
    for name, ref in refs.items():
        for entry in entries:
            console.print(f"[dim]physics: {entry.name} on {name}[/]")
            planned, rec = run_entry(entry, robot, ref, "tick")
            if options.record:
                save_recording(rec, options.record, entry.name, name)
            excess = np.maximum(robot.q_min - rec.joints, rec.joints - robot.q_max).max()
            specs: list[ClosedLoopSpec | None] = [None]
            if closed_loop:
                from ..balance.stepping import SteppingParams

                imu = options.use_imu
                # (a robot whose servos report nothing: off, wbc.balance.live.closed_loop)
                step = SteppingParams() if options.stepping and not commanded else None
                specs.append(
                    ClosedLoopSpec(entry.make, ref, None, True, imu, step)
                )  # default_gains
            for spec in specs:
                loop = {"compensate": comp, "gyro": gyro if spec is None else 0.0,
                        "correct": options.correct}  # fmt: skip
                started = time.perf_counter()
                try:  # beyond the joint limits: clamped by the deployment (wbc deploy refuses
                    # it unless --limit-tol allows it)
                    if spec is None:
                        from .play import play

                        result = play(rec, robot, settle=1.0, limit_tol=math.inf, **loop)
                        extra: dict[str, Any] = {}
                    else:
                        result, cl = play_closed_loop(spec, robot, compensate=comp,
                                                      correct=loop["correct"])  # fmt: skip
                        extra = closed_loop_figures(cl)
                except WbcError as exc:
                    console.print(f"[red]{entry.name} on {name}: {exc}[/]")
                    records.append({"solver": entry.name, "family": entry.family,
                                    "trajectory": name, "error": str(exc)})  # fmt: skip
                    continue
                r = physics_record(rec, result, robot, ref)
                r.update(extra)
                r["loop"] = (
                    "open" if spec is None else "closed" + ("+step" if spec.stepping else "")
                )
                r["plan_limit_excess_deg"] = float(np.degrees(max(excess, 0.0)))
                r["clamped_ticks"] = int(result.deploy.limits.clamped.max())
                wall = time.perf_counter() - started
                r.update(solver=entry.name, family=entry.family, stack=planned["stack"],
                         trajectory=name, **loop,
                         sim_steps=int(result.sim.steps), wall_s=wall,
                         steps_per_s=result.sim.steps / wall,
                         realtime_factor=r["sim_time_s"] / wall)  # fmt: skip
                label = entry.name if spec is None else f"{entry.name} {r['loop']}"
                series[(label, name)] = (r.pop("_series"), rec, result)
                if options.record:  # the simulated run beside the plan (wbc view replays both)
                    simulated_recording(rec, result, robot).save(
                        Path(options.record) / f"{label.replace(' ', '_')}__{name}__sim.npz"
                    )
                kw = dict(loop, closed=spec)
                if options.robustness:
                    started = time.perf_counter()
                    rob = robustness(rec, robot, options.robustness, options.seed, **kw)
                    r["robustness"] = rob
                    r["up_fraction"] = rob["up_fraction"]
                    r["sweep_wall_s"] = time.perf_counter() - started
                if options.push:
                    for d in PUSH_DIRECTIONS:
                        r[f"push_{d}_ns"] = largest_push(rec, robot, d, **kw)
                    r["push_lateral_ns"] = r["push_away_ns"]
                    r["push_bounds_ns"] = push_bounds(ref, robot)
                records.append(r)
    for name in refs:
        rows = [r for r in records if r["trajectory"] == name and "error" not in r]
        title = f"physics: {name} (deploy path, simulated {_servo_name(robot)})"
        title += f", compliance feed-forward ×{comp:g}" if comp else ""
        title += ", open vs closed loop" if closed_loop else ""
        table = Table(title=title + (f", gyro feedback ×{gyro:g} (open)" if gyro else ""))
        cols = ["solver", "loop", "fell s", "dev°", "ref°", "dist", "slip", "err°", "rms°", "τ/τs"]
        cols += ["CoP mm", "lift mm"]
        if options.robustness:
            cols.append(f"up/{options.robustness}")
        if options.push:
            cols += ["push fwd", "bwd", "toward", "away"]
        for c in cols:
            table.add_column(c, justify="left" if c == "solver" else "right")
        for r in rows:
            cells = [
                r["solver"],
                r["loop"],
                "-" if not r["fell"] else f"{r['fall_time_s']:.2f}",
                f"{r['orientation_dev_max_deg']:.1f}",
                f"{r['torso_ref_dev_max_deg']:.1f}",
                "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}",
                f"{r['foot_slip_max_mm']:.1f}",
                f"{r['tracking_err_max_deg']:.1f}",
                "-" if r["tracking_err_rms_deg"] is None else f"{r['tracking_err_rms_deg']:.2f}",
                f"{r['torque_peak_ratio']:.2f}",
                "-" if r["cop_margin_min_mm"] is None else f"{r['cop_margin_min_mm']:.1f}",
                "-" if r["swing_lift_max_mm"] is None else f"{r['swing_lift_max_mm']:.1f}",
            ]
            if options.robustness:
                cells.append(f"{r['up_fraction']:.2f}")
            if options.push:
                cells += [_ns(r[f"push_{d}_ns"]) for d in PUSH_DIRECTIONS]
            table.add_row(*cells)
        console.print(table)
        bounds = rows[0].get("push_bounds_ns") if rows and options.push else None
        if bounds:
            console.print(
                "  push bounds (N·s, LIPM: one step in the swing's time left; away: the CoP at "
                "the stance sole's edge): "
                + ", ".join(f"{d} {bounds[d]:.3f}" for d in PUSH_DIRECTIONS)
            )
        for r in rows:
            if r["loop"].startswith("closed"):
                share = r.get("feedback_share")
                console.print(
                    f"  {r['solver']} {r['loop']} loop: estimator + feedback + step adjustment "
                    f"{'-' if share is None else f'{100 * share:.0f} %'} of the tick "
                    "(wbc.balance.live.loop_share); "
                    f"goals beyond a joint limit before clamping: "
                    f"{r['goal_limit_excess_deg']:.2f}° max"
                )
            if r["fell"]:
                console.print(
                    f"  {r['solver']}: fell at {r['fall_time_s']:.2f} s in {r['fall_phase']} "
                    f"support; most loaded: {r['fall_joint']}"
                )
            falls = r.get("robustness", {}).get("falls", [])
            if falls:
                console.print(f"  {r['solver']}: {fall_summary(falls)}")
    if options.plots:
        for (solver, name), (s, rec, result) in series.items():
            label = solver.replace(" ", "_")
            physics_figure(s, rec, result, options.plots / f"physics_{label}__{name}.png")
    return records


def fall_summary(falls: list[dict[str, Any]]) -> str:
    """One line on why randomised models fell: phases, most loaded joints, latency share."""
    from collections import Counter

    phases = Counter(f["phase"] for f in falls)
    joints = Counter(str(f["joint"]).split(" ")[0] for f in falls)
    late = sum(1 for f in falls if f.get("latency")) / len(falls)
    return (
        f"{len(falls)} falls: phase "
        + ", ".join(f"{k} {v}" for k, v in phases.most_common())
        + "; most loaded "
        + ", ".join(f"{k} {v}" for k, v in joints.most_common(3))
        + f"; {late:.0%} with one-tick latency"
    )


def _ns(v: float | None) -> str:
    return "fell" if v is None else f"{v:.3f}"


def _servo_name(robot: Robot) -> str:
    """The robot's simulated servo model (AX-12A, or its robot.toml [servo] name)."""
    from ..sim.actuator import nominal_servo

    return getattr(nominal_servo(robot), "name", "AX-12A")


def physics_figure(series: dict, rec: Recording, result, path: Path) -> Path:
    """Deviation from the planned base orientation over time; real vs planned CoM and
    CoP/ZMP (lateral y) over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    log = result.log
    t = series["t"]
    rec_t = rec.t - rec.t[0]
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t, series["dev"], color="C3")
    ax[0].set_ylabel("base orientation\ndeviation (deg)")
    ax[0].axhline(FALL_TILT_DEG, color="k", lw=0.5, ls="--")
    ax[1].plot(rec_t, rec["com"][:, 1] * 1e3, "C0--", label="CoM planned")
    ax[1].plot(t, log["com"][:, 1] * 1e3, "C0", label="CoM real")
    if "zmp" in rec.channels:
        ax[1].plot(rec_t, rec["zmp"][:, 1] * 1e3, "C2--", label="ZMP planned")
    ax[1].plot(t, log["cop"][:, 1] * 1e3, "C2", lw=0.8, label="CoP real")
    ax[1].set_ylabel("lateral y (mm)")
    ax[1].set_xlabel("time (s)")
    ax[1].legend(fontsize=7, ncol=4)
    fig.suptitle(f"{rec.meta.get('controller', '')} on {rec.meta.get('trajectory', '')}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def physics_summary_lines(records: list[dict[str, Any]]) -> list[str]:
    """Plain-text lines (≤ 100 columns) of the physics table."""
    records = [r for r in records if "error" not in r]
    out = [f"{'solver':<14}{'traj':<12}{'fell s':>7}{'dev°':>7}{'dist':>6}{'slip mm':>8}"
           f"{'err°':>6}{'τ/τs':>6}{'CoP mm':>7}{'up':>6}{'p lat':>7}{'p fwd':>7}"]  # fmt: skip
    for r in records:
        fell = f"{r['fall_time_s']:.2f}" if r["fell"] else "-"
        dist = "-" if r["distance_ratio"] is None else f"{r['distance_ratio']:.2f}"
        cop = "-" if r["cop_margin_min_mm"] is None else f"{r['cop_margin_min_mm']:.1f}"
        up = "-" if r.get("up_fraction") is None else f"{r['up_fraction']:.2f}"
        out.append(
            f"{r['solver']:<14}{r['trajectory']:<12}{fell:>7}{r['orientation_dev_max_deg']:>7.1f}"
            f"{dist:>6}{r['foot_slip_max_mm']:>8.1f}{r['tracking_err_max_deg']:>6.1f}"
            f"{r['torque_peak_ratio']:>6.2f}{cop:>7}{up:>6}"
            f"{_ns(r['push_lateral_ns']) if 'push_lateral_ns' in r else '-':>7}"
            f"{_ns(r['push_forward_ns']) if 'push_forward_ns' in r else '-':>7}"
        )
    return out
