"""A landing's anchor made ahead and placed in the idle part, on and off alternated in one process.

:meth:`wbc.walking.handover.SwitchHandover.place_ahead` writes the anchor that
:meth:`~wbc.walking.handover.SwitchHandover.prepare` made (packed and checked ahead:
:meth:`wbc.tasks.FramePoseTask.pack_target`) into its contact in the idle part; the tick then
copies it. "off" is the behaviour before (twenty-first session): nothing placed, nothing packed
(the tick's ``set_target`` checks and copies the anchor). A 50 Hz loop on a 100 Hz walk (every
other reference tick), the ticks on the thread's CPU clock: through the deployment on the
AX-12A emulator (``--deploy``: :func:`live_warm.play`, the Bioloid only) or a paced loop in
this process (the idle part's ``prepare_next``, a sleep, ``warm_next`` and 0.5 ms spun, as
the deployment's ``Ticker``; any robot). Per walk: the tick's median and p99 (µs), the
slowest first tick of a phase ÷ the median, the touch-downs' median ÷ the median, the
landing's next ticks' (up to 4 after a touch-down) ÷ the median, and
:meth:`SwitchHandover.update`'s median, at the touch-downs and on the landings' next ticks
(µs; benchmarks/self_collision.md, twenty-second session).

Run: ``python benchmarks/landing_ahead.py [--robot bioloid] [--trajectory walk10]
[--stack walk] [--rounds 6] [--deploy]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from wbc import load_robot
from wbc.bench.trajectories import build
from wbc.stacks import load_stack
from wbc.tasks import FramePoseTask
from wbc.walking.handover import SwitchHandover
from wbc.walking.loop import RunOptions, Session, StackController

PLACE, PACK, UPDATE, TICK = (
    SwitchHandover.place_ahead,
    FramePoseTask.pack_target,
    SwitchHandover.update,
    Session.tick,
)


def instrument(on: bool, updates: list[float], ticks: list[tuple[int, float]]) -> None:
    """The landing placed ahead ``on`` or off; each update's and each tick's time kept."""

    def update(self, *a):
        start = time.thread_time_ns()
        try:
            return UPDATE(self, *a)
        finally:
            updates.append((time.thread_time_ns() - start) / 1e3)

    def tick(self, i):
        q = TICK(self, i)
        ticks.append((i, self.solve_time * 1e6))
        return q

    SwitchHandover.place_ahead = PLACE if on else (lambda self: None)  # type: ignore[method-assign]
    FramePoseTask.pack_target = PACK if on else (lambda self, t: None)  # type: ignore[method-assign]
    SwitchHandover.update = update  # type: ignore[method-assign]
    Session.tick = tick  # type: ignore[method-assign]


def paced(robot, ref, stack: str) -> None:
    """One walk at 50 Hz in this process (every other reference tick)."""
    controller = StackController(load_stack(stack, robot, solver="hierarchical"))
    session = Session(controller, robot, ref, options=RunOptions(clock="cpu"))
    for i in range(0, ref.n, 2):
        session.tick(i)
        session.prepare_next()
        time.sleep(0.0185)
        session.warm_next()
        end = time.perf_counter() + 5e-4
        while time.perf_counter() < end:  # (spun, as the Ticker)
            pass


def figures(ref, ticks: list, updates: list) -> tuple:
    index = np.array([i for i, _ in ticks])
    t = np.array([x for _, x in ticks])
    u = np.array(updates[-len(t) :])
    support = ref.support[index]
    first = np.flatnonzero(support[1:] != support[:-1]) + 1
    down = first[support[first] == 0]
    way = [k for k in range(len(t)) if support[k] == 0 and any(0 < k - d <= 4 for d in down)]
    med = float(np.median(t))
    return (
        med, float(np.percentile(t, 99)), float(t[first].max()) / med,
        float(np.median(t[down])) / med, float(np.median(t[way])) / med,
        float(np.median(u)), float(np.median(u[down])), float(np.median(u[way])),
    )  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="bioloid")
    parser.add_argument("--trajectory", default="walk10")
    parser.add_argument("--stack", default="walk")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--deploy", action="store_true", help="through the servo emulator")
    args = parser.parse_args()
    robot = load_robot(args.robot)
    ref = build(args.trajectory, robot)
    runs: dict[bool, list[tuple]] = {False: [], True: []}
    for r in range(args.rounds):
        for on in (False, True) if r % 2 == 0 else (True, False):
            updates: list[float] = []
            ticks: list[tuple[int, float]] = []
            instrument(on, updates, ticks)
            if args.deploy:
                from live_warm import play

                play(robot, ref, args.stack, True, 50.0, clock="cpu")
            else:
                paced(robot, ref, args.stack)
            runs[on].append(figures(ref, ticks, updates))
            print(
                f"{r} {'on ' if on else 'off'} median %.0f p99 %.0f first max/median %.2f "
                "touch-downs/median %.2f landing/median %.2f | update µs median %.1f "
                "touch-downs %.1f landing %.1f" % runs[on][-1],
                flush=True,
            )
    for on in (False, True):
        med = np.median(np.array(runs[on]), axis=0)
        print(
            f"{'on ' if on else 'off'}: median of the walks " + " · ".join(f"{x:.2f}" for x in med)
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
