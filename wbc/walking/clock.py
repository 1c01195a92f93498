"""The clocks a control loop times its ticks with (:attr:`wbc.walking.loop.RunOptions.clock`).

``wall``: :func:`time.perf_counter`, the time a tick takes on the wall, the operating
system's preemptions included (another process scheduled in the middle of a tick adds its
whole time slice: ~4 ms on a loaded Linux machine). ``cpu``: :func:`time.thread_time`, the
CPU time of the calling thread only: what the tick itself costs, preemptions left out (a
solver whose work ran on other threads would be under-counted: none of the benchmark's do,
benchmarks/tick_clock.md). A call costs ~0.7 µs against ~0.2 µs (a system call, not the
vDSO), on every tick of every solver alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from ..exceptions import ConfigurationError

#: name -> the clock (seconds, float)
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.thread_time}


def tick_clock(name: str) -> Callable[[], float]:
    """The clock named ``name`` (:data:`CLOCKS`); a clear error for another name."""
    try:
        return CLOCKS[name]
    except KeyError:
        raise ConfigurationError(
            f"clock must be one of {', '.join(CLOCKS)}, got {name!r}"
        ) from None
