"""The tail of the control tick's time on random problems (issue 28): the ``walk`` stack.

    python benchmarks/tick_tail.py --n 400 --ticks 10

Trials drawn as ``benchmarks/stress.py`` draws them (seed 2024), always on the ``walk`` stack
(hard contacts and self-collision rows), DAQP, compiled or numpy path as drawn; ``--ticks``
ticks each. Ticks from starts outside the limits or inside a collision margin are infeasible
as linearised and go through the recovery re-solve; they make the tail. Prints the median,
p99 and largest tick time (ms) and the ticks above 5 and 20 ms, with the slowest trials, and
the Gauss–Newton steps of the ticks' recoveries (``recovery_steps``, at most
``TICK_RECOVERY_STEPS``); the first ``--skip`` trials (4) are left out (they load the kernels).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

from wbc import WbcError, load_robot
from wbc.solvers.recovery import TICK_RECOVERY_STEPS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--ticks", type=int, default=10)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--skip", type=int, default=4)
    args = ap.parse_args()
    path = Path(__file__).with_name("stress.py")
    spec = importlib.util.spec_from_file_location("wbc_stress_benchmark", path)
    stress = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = stress
    spec.loader.exec_module(stress)
    stress.compile_first()
    robot = load_robot("bioloid")
    times, where, steps = [], [], []
    for trial in range(args.n):
        p = stress.draw(robot, np.random.default_rng([args.seed, trial]), ["daqp"])
        q = stress.start(robot, p)
        compiled = None if p["compiled"] else False
        solver, _, com, swing, torso = stress.walk_stack(
            robot, q, p["kind"], "daqp", compiled, p["double"]
        )
        stress.move_targets(p, com, swing, torso)
        for tick in range(args.ticks):
            start = time.perf_counter()
            try:
                q = solver.step(q, 0.01)
            except WbcError:
                break
            finally:
                if trial >= args.skip:
                    times.append(time.perf_counter() - start)
                    where.append((trial, tick))
                    steps.append(solver.recovery_steps)
    t = np.asarray(times) * 1e3
    order = np.argsort(t)[::-1][:5]
    print(
        f"{t.size} ticks: median {np.median(t):.2f} ms, p99 {np.percentile(t, 99):.1f} ms, "
        f"largest {t.max():.1f} ms; above 5 ms: {(t > 5).sum()}, above 20 ms: {(t > 20).sum()}"
    )
    print("slowest (trial, tick): " + ", ".join(f"{where[i]} {t[i]:.1f} ms" for i in order))
    s = np.asarray(steps)
    most = np.argsort(s)[::-1][:5]
    print(
        f"Gauss–Newton steps of a tick's recovery: ticks with any {(s > 0).sum()}, most "
        f"{s.max()} (at most {TICK_RECOVERY_STEPS}); the most (trial, tick): "
        + ", ".join(f"{where[i]} {s[i]} ({t[i]:.1f} ms)" for i in most)
    )


if __name__ == "__main__":
    main()
