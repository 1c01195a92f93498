"""Which rows fail in a push screen: ``pushes.py``'s arguments, each failed walking tick's
error counted by message (its first tick, the push's rise then).

    python benchmarks/push_failures.py --robot op3 --solvers wqp-daqp --trajectory walk10_wb \
        --loops step --gains '{"push_rise": 0.015}' --screen away:1.1:0 away:1.2:0

Prints pushes.py's screen line, then ``FAIL count first_tick dz | message`` per distinct
message (its first 160 characters; the residuals differ tick by tick, so most are one each).
"""

from __future__ import annotations

import collections
import runpy
import sys
from pathlib import Path

from wbc.walking import loop


def main() -> None:
    fails: collections.Counter[str] = collections.Counter()
    first: dict[str, tuple[int, float | None, str]] = {}
    tick = loop.Session.tick

    def traced(self, i: int):
        q = tick(self, i)
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


if __name__ == "__main__":
    main()
