"""The warm-up at the end of a paced loop's idle part through the deployment's own loop.

A walk solved live (:class:`wbc.balance.live.SessionSource`, open loop) played by
:class:`wbc.servos.Deployment` on the AX-12A bus emulator (its own process, like hardware) at
``--rate`` Hz on the wall clock, where :meth:`wbc.servos.playback.Ticker.wait` calls the
source's ``warm()`` before each slot's deadline; the solver's ``warm_ahead`` off and on
alternated, ``--rounds`` times. Per run: the controller's tick (``SessionSource.solve_time``)
median and p99, the slowest first tick of a support phase over the median, the warm-ups' mean
time (µs), the slots missed and the ticks' lateness p99 (benchmarks/self_collision.md,
twenty-first session).

Run: ``python benchmarks/live_warm.py [--trajectory walk10] [--stack walk_strict]
[--rounds 2] [--rate 50] [--slowest] [--clock cpu]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from wbc import load_robot
from wbc.balance.live import SessionSource
from wbc.bench.trajectories import build
from wbc.servos import DeployConfig, Deployment
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator
from wbc.stacks import load_stack
from wbc.walking.loop import RunOptions, Session, StackController


def play(
    robot, ref, stack: str, warm: bool, rate: float, verbose: bool = False, clock: str = "wall"
) -> tuple:
    """One walk through the deployment: (median, p99, first ÷ median, warm-up µs, ticks,
    missed slots, lateness p99 µs); ``verbose``: its slowest first ticks of a phase printed;
    ``clock``: the ticks' and warm-ups' clock ("cpu": the thread's CPU time, a loaded
    machine's preemptions left out; :mod:`wbc.walking.clock`)."""
    controller = StackController(load_stack(stack, robot, solver="hierarchical"))
    controller.solver.warm_ahead = warm
    session = Session(controller, robot, ref, options=RunOptions(clock=clock))
    source = SessionSource(session)
    warmed: list[float] = []
    warm_next = session.warm_next

    def timed() -> None:
        warm_next()
        warmed.append(session.warm_time)

    session.warm_next = timed  # type: ignore[method-assign]
    played: list[int] = []  # the reference tick of each target (open loop: one a solve time)
    at_time = session.at_time

    def indexed(t: float) -> np.ndarray | None:
        q = at_time(t)
        if q is not None:
            played.append(int(session.index or 0))
        return q

    session.at_time = indexed  # type: ignore[method-assign]
    servo_map = robot.servo_map
    ticks = servo_map.ticks_by_id(servo_map.pose_ticks("walk_ready"))
    with AX12Emulator(process=True, positions=ticks) as emu:
        bus = DynamixelBus(emu.port, servo_map, reply_timeout_ms=50)
        result = Deployment(bus, source, robot, DeployConfig(rate=rate), lambda s: None).run()
    t = np.array(source.solve_time) * 1e6
    support = ref.support[np.array(played[-len(t) :])]  # (the phases of the ticks played)
    first = np.flatnonzero(support[1:] != support[:-1]) + 1
    med = float(np.median(t))
    if first.size and verbose:
        slow = first[np.argsort(t[first])[::-1][:4]]
        index = played[-len(t) :]
        ticks = ", ".join(f"{index[k]} {support[k]} {t[k]:.0f}" for k in slow)
        print(f"  slowest first ticks (reference tick, support, µs): {ticks}")
    return (
        med,
        float(np.percentile(t, 99)),
        float(np.max(t[first])) / med if first.size else np.nan,
        float(np.mean(warmed[1:])) * 1e6 if len(warmed) > 1 else 0.0,
        len(t),
        result.timing.missed,
        float(np.percentile(result.timing.lateness, 99)) * 1e6,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trajectory", default="walk10")
    parser.add_argument("--stack", default="walk_strict")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--rate", type=float, default=50.0)
    parser.add_argument("--slowest", action="store_true", help="each run's slowest first ticks")
    parser.add_argument("--clock", default="wall", help="the ticks' clock: wall or cpu")
    args = parser.parse_args()
    robot = load_robot("bioloid")
    ref = build(args.trajectory, robot)
    runs: dict[bool, list[tuple]] = {False: [], True: []}
    for r in range(args.rounds):
        for warm in (False, True):
            runs[warm].append(
                play(robot, ref, args.stack, warm, args.rate, args.slowest, args.clock)
            )
            print(
                f"{r} {'warm' if warm else 'off '} median %.0f p99 %.0f first/median %.2f "
                "warm-up %.0f µs ticks %d missed %d lateness p99 %.0f µs" % runs[warm][-1],
                flush=True,
            )
    for warm in (False, True):
        med = np.median(np.array(runs[warm])[:, :3], axis=0)
        print(f"{'warm' if warm else 'off '}: median of the runs %.0f · %.0f · %.2f" % tuple(med))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
