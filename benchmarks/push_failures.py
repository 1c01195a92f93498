"""Which rows fail in a push screen: ``pushes.py``'s arguments, each failed walking tick's
error counted by message (its first tick, the push's rise then).

    python benchmarks/push_failures.py --robot op3 --solvers wqp-daqp --trajectory walk10_wb \
        --loops step --gains '{"push_rise": 0.015}' --screen away:1.1:0 away:1.2:0

Prints pushes.py's screen line, then ``FAIL count first_tick dz | message`` per distinct
message (its first 160 characters; the residuals differ tick by tick, so most are one each),
then ``KNEES first_tick`` and the left and right legs' room to rise (mm) on the commanded
configuration at that tick, their knees straight (:class:`wbc.balance.push_rise.KneeRoom`,
bend 0), and the least room each leg had while the rise was up in that run.
"""

from __future__ import annotations

import collections
import runpy
import sys
from pathlib import Path

from wbc.balance.push_rise import KneeRoom
from wbc.walking import loop


def main() -> None:
    fails: collections.Counter[str] = collections.Counter()
    first: dict[str, tuple[int, float | None, str]] = {}
    tick = loop.Session.tick
    knees: dict[int, KneeRoom] = {}
    least: dict[int, list[float]] = {}  # (per session: the least room while risen)
    at_fail: dict[int, tuple[int, float, float]] = {}

    def traced(self, i: int):
        q = tick(self, i)
        rise = getattr(self.stabilizer, "_rise", None)
        if rise is not None and rise.dz > 0:
            k = knees.setdefault(id(self.robot), KneeRoom(self.robot, 0.0))
            rooms = [k.room(q, (s,))[1] * 1e3 for s in ("l_sole", "r_sole")]
            low = least.setdefault(id(self), [float("inf")] * 2)
            least[id(self)] = [min(a, b) for a, b in zip(low, rooms, strict=True)]
            if self.failed and id(self) not in at_fail:
                at_fail[id(self)] = (i, *rooms)
        if self.failed:
            msg = str(self.failure)[:300]
            key = f"{type(self.failure).__name__}: {msg[:160]}"
            fails[key] += 1
            if key not in first:
                rise = getattr(self.stabilizer, "_rise", None)
                first[key] = (i, getattr(rise, "dz", None), msg)
        return q

    loop.Session.tick = traced  # type: ignore[method-assign]
    sys.argv = ["pushes.py", *sys.argv[1:]]
    try:
        runpy.run_path(str(Path(__file__).with_name("pushes.py")), run_name="__main__")
    finally:
        for key, n in fails.most_common():
            i, dz, msg = first[key]
            print(f"FAIL {n} {i} {dz} | {msg}")
        for key, low in least.items():
            i, left, right = at_fail.get(key, (-1, float("nan"), float("nan")))
            print(
                f"KNEES {i} room at it L {left:.1f} R {right:.1f} mm; "
                f"least while risen L {low[0]:.1f} R {low[1]:.1f} mm"
            )


if __name__ == "__main__":
    main()
