"""Time the LIPM MPC CoM generator on a multi-step walk (figures for reports).

    python benchmarks/mpc_timing.py                 # 10-step forward walk, osqp, 5 runs
    python benchmarks/mpc_timing.py --steps 10 --solver qrqp --repeat 3
    python benchmarks/mpc_timing.py --horizon 1.0   # receding horizon instead of one QP

Prints, per run and as medians: the casadi QP solve time (all QPs), the MPC build time
(matrices, half-planes, solver creation), and the whole ``forward_walk`` call including the
footstep validation and the pre-motion checks.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Sequence

from wbc.model import load_robot
from wbc.walking.gait import forward_walk
from wbc.walking.mpc import MpcParams
from wbc.walking.reference import StandingState


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--step-length", type=float, default=0.035)
    parser.add_argument("--solver", default="osqp")
    parser.add_argument("--horizon", type=float, default=None)
    parser.add_argument("--margin", type=float, default=None, help="ZMP margin (m)")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    start = StandingState.from_robot(load_robot("bioloid"))
    params = MpcParams(horizon=args.horizon, solver=args.solver)
    rows = []
    for _ in range(max(1, args.repeat)):
        t0 = time.perf_counter()
        kw = {} if args.margin is None else {"margin": args.margin}
        ref = forward_walk(start, args.steps, args.step_length, generator="mpc", mpc=params, **kw)
        total = time.perf_counter() - t0
        m = ref.meta["mpc"]
        rows.append((m["solve_time"], m["build_time"], total))
        print(
            f"QP {m['solve_time'] * 1e3:8.1f} ms ({m['n_qp']} QP, {m['n_variables']} variables, "
            f"{m['n_constraints']} constraints)  build {m['build_time'] * 1e3:6.1f} ms  "
            f"walk() total {total * 1e3:7.1f} ms  min ZMP margin "
            f"{ref.meta['check']['zmp_margin'] * 1e3:.2f} mm"
        )
    med = [statistics.median(c) for c in zip(*rows, strict=True)]
    print(
        f"median over {len(rows)} runs ({args.steps} steps, {ref.duration:.2f} s, solver "
        f"{args.solver}, horizon {args.horizon or 'whole walk'}): QP {med[0] * 1e3:.1f} ms, "
        f"build {med[1] * 1e3:.1f} ms, walk() {med[2] * 1e3:.1f} ms"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
