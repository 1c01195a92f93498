"""Where the closed loop's tick goes on the default ``wbc sim`` configuration, part by part.

The run is :func:`wbc.bench.closed_loop.play_closed_loop` as ``wbc sim --solver S
--trajectory walk10_wb`` makes it (the closed loop through the simulated IMU and encoders, the
step adjustment, the lift-off hold, fall detection, the start-up calibration, the compliance
feed-forward at :func:`wbc.balance.best_compensate`), on the nominal simulated Bioloid.

Two kinds of pass, alternated:

* **plain** (nothing instrumented): the source's own per-tick times — the closed loop's part
  (step adjustment + estimator + feedback, the sensor reads apart), the controller's tick —
  and :func:`wbc.balance.live.loop_share` (issue 30's bar: ≤ 0.30); besides, the
  feed-forward (:class:`wbc.balance.compliance.CompensatedSource` less its inner source) timed
  by one wrapper;
* **split**: the parts timed by ``perf_counter`` wrappers put on the objects of that run
  (instance attributes; the stabilizer's compiled tick through its module's name):
  the sensor reads, the estimator + feedback kernel (``_feedback_tick``), the Python of
  ``Stabilizer.adjust`` around it, the swing's landing (``StepAdjuster.land``), the step
  adjustment's re-plan check (``StepAdjuster.update``; inside it the push trigger
  ``PushTrigger.watch`` and the reference DCM ``_dcm_ref``), the lift-off hold, the
  solve (``controller.track``), the feed-forward, the source's bookkeeping (``SessionSource``
  around ``Session.at_time``) and the rest of ``at_time`` (the clock, the reference's index).
  A wrapper costs ~0.2 µs, which the nested parts add to their parents'.

Medians over the walking ticks (the first 20 left out), µs, best of the rounds.

    nice -n 5 python benchmarks/loop_trace.py [--solvers hqp-daqp wqp-daqp] [--rounds 3]
        [--walk walk10_wb] [--compensate GAIN] [--against ROOT]

``--against ROOT`` runs the same passes on another checkout (a subprocess with
``PYTHONPATH=ROOT``), alternating with this one round by round: a change's before / after.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("WBC_WAIT_FOR_COMPILE", "1")  # the compiled ticks, not the interim

import numpy as np

SKIP = 20  # walking ticks left out (warm caches)


class Timers:
    """Per-tick sums of the timed parts."""

    def __init__(self) -> None:
        self.now: dict[str, float] = defaultdict(float)
        self.ticks: list[dict[str, float]] = []

    def wrap(self, owner, name: str, part: str, module: bool = False) -> None:
        """``owner.name`` timed into ``part`` (an instance's attribute, or a module's)."""
        inner = getattr(owner, name)
        now, clock = self.now, time.perf_counter

        def timed(*args, **kwargs):
            start = clock()
            try:
                return inner(*args, **kwargs)
            finally:
                now[part] += clock() - start

        setattr(owner, name, timed)

    def close_tick(self) -> None:
        self.ticks.append(dict(self.now))
        self.now.clear()

    def medians(self, skip: int) -> dict[str, float]:
        parts = sorted({k for t in self.ticks for k in t})
        rows = self.ticks[skip:]
        return {p: 1e6 * float(np.median([t.get(p, 0.0) for t in rows])) for p in parts}


def run(solver: str, walk: str, split: bool, compensate: float | None = None) -> dict[str, float]:
    """One closed-loop run (module docstring; ``compensate``: the feed-forward's gain, None:
    the best, as ``wbc sim``); the medians (µs) and ``share``."""
    from wbc import load_robot
    from wbc.balance import best_compensate
    from wbc.balance import stabilizer as stab_mod
    from wbc.balance.stepping import SteppingParams
    from wbc.bench import closed_loop as cl
    from wbc.bench.physics import physics_entry
    from wbc.bench.trajectories import build

    robot = load_robot("bioloid")
    ref = build(walk, robot)
    spec = cl.ClosedLoopSpec(physics_entry(solver, robot).make, ref, None, True, True,
                             SteppingParams())  # fmt: skip
    timers = Timers()
    built: list = []
    from wbc.balance import live

    original = live.closed_loop
    kernel = stab_mod._feedback_tick

    def instrumented(*args, **kwargs):
        loop = original(*args, **kwargs)
        built.append(loop)
        dep, src, session = loop.deployment, loop.source, loop.session
        outer = dep.source
        comp = outer if hasattr(outer, "compensator") else None
        if comp is not None:  # the feed-forward = the compensated source less its inner one
            timers.wrap(src, "f", "ff: inner")  # (the SessionSource's function)
        if split:
            stab, steps, hold = loop.stabilizer, loop.stepping, loop.hold
            timers.wrap(stab, "adjust", "adjust (all)")
            if steps is not None:
                timers.wrap(steps, "update", "step: update (re-plan check)")
                timers.wrap(steps, "land", "step: land (swing in the measured frame)")
                trig = getattr(steps, "trigger", None)
                if trig is not None:
                    timers.wrap(trig, "watch", "step: push trigger (watch)")
                timers.wrap(steps, "_dcm_ref", "step: reference DCM (_dcm_ref)")
            if hold is not None:
                timers.wrap(hold, "wait", "hold: wait")
            timers.wrap(session.controller, "track", "solve (controller.track)")
            timers.wrap(session, "tick", "session.tick (all)")
            timers.wrap(session, "at_time", "session.at_time (all)")

        def ticked(tick, t, _outer=outer):
            start = time.perf_counter()
            q = _outer(tick, t)
            timers.now["source (all)"] += time.perf_counter() - start
            if not (loop.stabilizer.calibrating or q is None):
                timers.close_tick()
            else:
                timers.now.clear()
            return q

        from wbc.servos.sources import CallableSource

        wrapped = CallableSource(ticked, outer.first(), outer.joint_names)
        wrapped.idle = getattr(outer, "idle", None)  # type: ignore[attr-defined]
        dep.source = wrapped
        return loop

    def timed_kernel(*args):
        start = time.perf_counter()
        try:
            return kernel(*args)
        finally:
            timers.now["estimator + feedback kernel (_feedback_tick)"] += (
                time.perf_counter() - start
            )

    live.closed_loop = instrumented
    if split:
        stab_mod._feedback_tick = timed_kernel
    try:
        gain = best_compensate(robot) if compensate is None else compensate
        _, loop = cl.play_closed_loop(spec, robot, settle=0.0, compensate=gain)
    finally:
        live.closed_loop = original
        stab_mod._feedback_tick = kernel
    src = loop.source
    out = timers.medians(SKIP)
    fb, rd, sv = (np.asarray(x[SKIP:]) for x in (src.feedback_time, src.read_time, src.solve_time))
    out["loop (source: step adjustment + estimator + feedback)"] = 1e6 * float(np.median(fb))
    out["reads (source)"] = 1e6 * float(np.median(rd))
    out["solve (source)"] = 1e6 * float(np.median(sv))
    out["share"] = float(src.cost_share(SKIP))
    n = min(len(timers.ticks), len(fb)) - SKIP
    if n > 0 and "ff: inner" in timers.ticks[0]:
        ff = np.array([t["source (all)"] - t["ff: inner"] for t in timers.ticks[SKIP : SKIP + n]])
        out["feed-forward (compensated source less inner)"] = 1e6 * float(np.median(ff))
        loop_ff = fb[:n] + ff
        out["share with the feed-forward"] = float(np.median(loop_ff / (loop_ff + sv[:n])))
    return out


def runs(solvers: list[str], walk: str, gain: float | None) -> dict[str, dict]:
    """{solver: {"plain": ..., "split": ...}} for one round."""
    return {s: {"plain": run(s, walk, False, gain), "split": run(s, walk, True, gain)}
            for s in solvers}  # fmt: skip


def against(root: Path, solvers: list[str], walk: str, gain: float | None) -> dict:
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, __file__, "--solvers", *solvers, "--walk", walk, "--json"]
    cmd += [] if gain is None else ["--compensate", str(gain)]
    text = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(text.strip().splitlines()[-1])


def best(rounds: list[dict], solver: str, kind: str) -> dict[str, float]:
    """Per part, the smallest median over the rounds (shares too)."""
    keys = rounds[0][solver][kind]
    return {k: min(r[solver][kind].get(k, np.nan) for r in rounds) for k in keys}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--solvers", nargs="+", default=["hqp-daqp", "wqp-daqp"])
    p.add_argument("--walk", default="walk10_wb")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--against", type=Path, metavar="ROOT")
    p.add_argument("--compensate", type=float, default=None,
                   help="the feed-forward's gain (default: the best, as wbc sim; 0: none, the "
                   "closed loop's gains without it)")  # fmt: skip
    p.add_argument("--json", action="store_true", help="one round, one JSON line")
    args = p.parse_args()
    if args.json:
        print(json.dumps(runs(args.solvers, args.walk, args.compensate)))
        return
    mine: list[dict] = []
    other: list[dict] = []
    for _ in range(args.rounds):
        mine.append(runs(args.solvers, args.walk, args.compensate))
        if args.against is not None:
            other.append(against(args.against, args.solvers, args.walk, args.compensate))
    if args.against is not None:
        print(f"ROOT: {args.against}")
    for solver in args.solvers:
        for kind in ("plain", "split"):
            a = best(mine, solver, kind)
            b = best(other, solver, kind) if other else {}
            print(f"\n{args.walk} {solver}, {kind} (best of {args.rounds}; µs, shares as such)")
            print("| part | this | ROOT |" if other else "| part | this |")
            print("|---|---|---|" if other else "|---|---|")
            for k in sorted(set(a) | set(b)):
                places = 3 if "share" in k else 1
                cells = [f"{d.get(k, np.nan):.{places}f}" for d in ((a, b) if other else (a,))]
                print(f"| {k} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
