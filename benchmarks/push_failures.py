"""Which rows fail in a push screen: ``pushes.py``'s arguments, each failed walking tick's
error counted by message (its first tick, the push's rise then).

    python benchmarks/push_failures.py --robot op3 --solvers wqp-daqp --trajectory walk10_wb \
        --loops step --gains '{"push_rise": 0.015}' --screen away:1.1:0 away:1.2:0

Prints pushes.py's screen line, then ``FAIL count first_tick dz | message`` per distinct
message (its first 160 characters; the residuals differ tick by tick, so most are one each),
then ``KNEES first_tick`` and the left and right legs' room to rise (mm) on the commanded
configuration at that tick, their knees straight (:class:`wbc.balance.push_rise.KneeRoom`,
bend 0), and the least room each leg had while the rise was up in that run; at the first
failed tick of a run with the rise up, ``LIMITS`` (the joints within 2° of a limit) and
``PAIRS`` (each self-collision constraint's pairs within its trigger at its last rows, mm);
``RISE``: the ticks the push trigger started (the phase) and the rise came back to 0.
``--at TICK ...`` (last on the line): ``LIMITS`` and ``PAIRS`` at those ticks of every run.
"""

from __future__ import annotations

import collections
import gc
import runpy
import sys
from pathlib import Path

import numpy as np

from wbc.balance.push_rise import KneeRoom
from wbc.limits.self_collision import SelfCollisionConstraint
from wbc.walking import loop


def _report(session, i: int, q: np.ndarray) -> None:
    """Print the joints of ``q`` within 2° of a limit (``LIMITS``) and each self-collision
    constraint's pairs within its trigger at its last rows (``PAIRS``, mm) at tick ``i``."""
    r, j = session.robot, q[7:]
    near = [
        f"{r.joint_names[n]} {np.degrees(j[n]):+.1f}° ({lim})"
        for n in range(len(j))
        for lim, v in (("min", r.q_min[n]), ("max", r.q_max[n]))
        if abs(j[n] - v) < 0.035
    ]
    print(f"LIMITS {i}: joints within 2° of a limit: {', '.join(near) or 'none'}")
    for c in gc.get_objects():  # (the run's self-collision rows: their last pairs)
        if isinstance(c, SelfCollisionConstraint) and c.robot is r:
            w = c.last
            close = [
                f"{'/'.join(c.pair_links[k])} {d * 1e3:.1f}"
                for k, d in zip(w.index, w.distance, strict=True)
            ]
            print(f"PAIRS {i} (mm): {', '.join(close) or 'none'}")


def main() -> None:
    args = sys.argv[1:]  # (--at TICK ...: LIMITS and PAIRS at those ticks too, any run)
    at = {int(a) for a in args[args.index("--at") + 1 :]} if "--at" in args else set()
    rest = args[: args.index("--at")] if "--at" in args else args
    fails: collections.Counter[str] = collections.Counter()
    first: dict[str, tuple[int, float | None, str]] = {}
    tick = loop.Session.tick
    knees: dict[int, KneeRoom] = {}
    least: dict[int, list[float]] = {}  # (per session: the least room while risen)
    at_fail: dict[int, tuple[int, float, float]] = {}

    spans: dict[int, list[str]] = {}  # (per session: the rise's starts and ends, ticks)
    was: dict[int, tuple[float, float]] = {}

    def traced(self, i: int):
        q = tick(self, i)
        if i in at:
            _report(self, i, q)
        rise = getattr(self.stabilizer, "_rise", None)
        if rise is not None:
            dz0, since0 = was.get(id(self), (0.0, 0.0))
            log = spans.setdefault(id(self), [])
            if rise.since > 0 and since0 == 0:
                log.append(f"trigger {i} ({self.targets(i).phase})")
            if rise.dz == 0 and dz0 > 0:
                log.append(f"down {i}")
            was[id(self)] = (rise.dz, rise.since)
        if rise is not None and rise.dz > 0:
            k = knees.setdefault(id(self.robot), KneeRoom(self.robot, 0.0))
            rooms = [k.room(q, (s,))[1] * 1e3 for s in ("l_sole", "r_sole")]
            low = least.setdefault(id(self), [float("inf")] * 2)
            least[id(self)] = [min(a, b) for a, b in zip(low, rooms, strict=True)]
            if self.failed and id(self) not in at_fail:
                at_fail[id(self)] = (i, *rooms)
                _report(self, i, q)
        if self.failed:
            msg = str(self.failure)[:300]
            key = f"{type(self.failure).__name__}: {msg[:160]}"
            fails[key] += 1
            if key not in first:
                rise = getattr(self.stabilizer, "_rise", None)
                first[key] = (i, getattr(rise, "dz", None), msg)
        return q

    loop.Session.tick = traced  # type: ignore[method-assign]
    sys.argv = ["pushes.py", *rest]
    try:
        runpy.run_path(str(Path(__file__).with_name("pushes.py")), run_name="__main__")
    finally:
        for key, n in fails.most_common():
            i, dz, msg = first[key]
            print(f"FAIL {n} {i} {dz} | {msg}")
        for log in spans.values():
            print("RISE " + ", ".join(log))
        for key, low in least.items():
            i, left, right = at_fail.get(key, (-1, float("nan"), float("nan")))
            print(
                f"KNEES {i} room at it L {left:.1f} R {right:.1f} mm; "
                f"least while risen L {low[0]:.1f} R {low[1]:.1f} mm"
            )


if __name__ == "__main__":
    main()
