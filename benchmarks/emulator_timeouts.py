"""Reply timeouts of a deployment on the AX-12A emulator (a forked process) under the machine's
load: the wall clock (production) against the emulator's device clock (the tests').

Plays a 1 s knee bend at 50 Hz with ``--read`` (18 servos read each tick) on
``AX12Emulator(process=True)``, a short reply deadline and a failure streak the watchdog never
reaches, and counts the timeouts the bus logged. The emulator answers in well under 1 ms of
its own time: every timeout is the emulator's process waiting for a core.

    PYTHONPATH=$PWD python benchmarks/emulator_timeouts.py --runs 2 --timeout-ms 5
    PYTHONPATH=$PWD python benchmarks/emulator_timeouts.py --runs 2 --timeout-ms 5 --device-clock
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from wbc import load_robot
from wbc.cli import deploy as deploy_cmd
from wbc.recording import Recording
from wbc.servos.bus import ServoBus
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator
from wbc.servos.pty_runner import DeviceClock


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--timeout-ms", default="5")
    ap.add_argument("--device-clock", action="store_true", help="deadlines on device time")
    args = ap.parse_args()
    robot = load_robot("bioloid")
    sm = robot.servo_map
    ticks = sm.ticks_by_id(sm.pose_ticks("walk_ready"))
    t = np.arange(0.0, 1.0 + 1e-9, 0.02)
    q = np.tile(robot.configuration("walk_ready"), (t.size, 1))
    q[:, robot.q_index("l_knee")] += 0.15 * np.sin(np.pi * t) ** 2
    path = str(Path(tempfile.mkdtemp()) / "bend.npz")
    Recording(t, q, robot.joint_names).save(path)
    clock = DeviceClock()  # watches this script's emulators
    if args.device_clock:
        ServoBus.reply_clock = clock  # type: ignore[method-assign]
    buses: list[DynamixelBus] = []
    init = DynamixelBus.__init__

    def keep(self, *a, **k):  # the deployment's bus, to read its exchange log
        init(self, *a, **k)
        buses.append(self)

    DynamixelBus.__init__ = keep  # type: ignore[method-assign]
    for run in range(args.runs):
        with clock.watch(AX12Emulator(positions=ticks, process=True)) as emu:
            parser = argparse.ArgumentParser()
            deploy_cmd.add_arguments(parser)
            argv = [path, "--port", emu.port, "--rate", "50", "--read", "--max-failures", "20"]
            argv += ["--reply-timeout-ms", args.timeout_ms, "--attempts", "10"]
            rc = deploy_cmd.run(parser.parse_args(argv))
        log = buses[-1].log
        print(
            f"run {run}: rc {rc}, {len(log.rtt)} replies, {sum(log.timeouts.values())} timeouts "
            f"({'device' if args.device_clock else 'wall'} clock, {args.timeout_ms} ms)",
            flush=True,
        )


if __name__ == "__main__":
    main()
