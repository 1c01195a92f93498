"""Protocol 2.0 servo bus benchmark: ``wbc deploy --robot op3`` against the XM430 emulator.

Two tables (``benchmarks/servo_bus2.md`` records them):

* fault detection at 50 Hz: every fault kind of the emulator, write-only and ``--read``,
  ``--runs`` runs each (the fault switched on at goal write 12, 13, ...): the time from that
  goal write to the last goal (both stamped by the emulator), whether the right servo is
  named, and the goals the servos refused or that fell outside the joint limits;
* free-running ticks (goals + one SYNC_READ of 20 servos, or goals + 18 AX-12A READs) with
  the emulators' wire timing and a 1 ms USB latency per reply: the achievable rate, side by
  side in one run.

Usage::

    python benchmarks/servo_bus2.py --runs 4 --ticks 200
    python benchmarks/servo_bus2.py --write-squat squat.npz   # the motion, for wbc deploy/sim
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wbc import load_robot
from wbc.cli import deploy as deploy_cmd
from wbc.recording import Recording
from wbc.servos.emulator import Fault
from wbc.servos.emulator2 import XEmulator
from wbc.servos.protocol2 import Dynamixel2Bus
from wbc.xseries import HW_OVERHEATING, HW_OVERLOAD

sys.path.insert(0, str(Path(__file__).resolve().parent))
from servo_bus import free_running as ax_free_running
from servo_bus import timed_ticks

CASES = [
    ("silent (timeout)", dict(kind="timeout", servo_id=7)),
    ("missing", dict(kind="missing", servo_id=10)),
    ("late 21 ms", dict(kind="late", servo_id=12, delay_s=0.021)),
    ("late 40 ms", dict(kind="late", servo_id=5, delay_s=0.04)),
    ("bad CRC", dict(kind="bad_checksum", servo_id=16)),
    ("overheating bit", dict(kind="error_bits", servo_id=14, bits=HW_OVERHEATING)),
    ("overload bit", dict(kind="error_bits", servo_id=3, bits=HW_OVERLOAD)),
]


def squat(robot, path: Path) -> str:
    """2 s at 50 Hz: the standing pose down 0.15 rad at the hips and back."""
    q0 = robot.configuration("stand")
    t = np.arange(0.0, 2.0 + 1e-9, 0.02)
    s = 0.15 * np.sin(np.pi * t / 2.0) ** 2
    q = np.tile(q0, (t.size, 1))
    for name, k in (("l_hip_pitch", -1), ("r_hip_pitch", 1), ("l_knee", 2), ("r_knee", -2),
                    ("l_ank_pitch", 1), ("r_ank_pitch", -1)):  # fmt: skip
        q[:, robot.q_index(name)] += k * s
    Recording(t, q, robot.joint_names).save(path)
    return str(path)


def fault_run(robot, recording: str, fault: Fault, read: bool) -> dict:
    sm = robot.servo_map
    start = sm.ticks_by_id(sm.angles_to_ticks(robot.configuration("stand")[7:]))
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    argv = [recording, "--robot", "op3", "--rate", "50", "--on-fault", "hold"]
    argv += ["--reply-timeout-ms", "10"] + (["--read"] if read else [])
    out, err = io.StringIO(), io.StringIO()
    with XEmulator(positions=start, faults=[fault], process=True) as emu:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = deploy_cmd.run(parser.parse_args([*argv, "--port", emu.port]))
    on = emu.sync_goal_times[fault.after_goals - 1] if emu.sync_goal_writes >= 12 else None
    lo, hi = (robot.q_min, robot.q_max)
    goals = [g for g in emu.goals if g.via == "sync_write"]
    outside = 0
    for g in goals:
        i = sm.index_of_id(g.servo_id)
        q = sm.ticks_to_angles(np.where(np.arange(sm.ids.size) == i, g.tick, sm.zero_ticks))[i]
        outside += not (lo[i] - 1e-9 <= q <= hi[i] + 1e-9)
    return {
        "stopped": rc == deploy_cmd.EXIT_SAFE_STOP,
        "ms": None if on is None else (emu.sync_goal_times[-1] - on) * 1e3,
        "named": f"id {fault.servo_id} " in err.getvalue(),
        "refused": sum(not g.accepted for g in goals),
        "outside": outside,
    }


def free_running(robot, ticks: int) -> dict[str, float]:
    """Back-to-back ticks with wire timing and 1 ms USB latency: SYNC_WRITE + SYNC_READ."""
    sm = robot.servo_map
    base = sm.angles_to_ticks(robot.configuration("stand")[7:])
    with XEmulator(
        positions=sm.ticks_by_id(base), timing=True, usb_latency_s=1e-3, process=True
    ) as emu:
        bus = Dynamixel2Bus(emu.port, sm, reply_timeout_ms=20.0)
        lo, hi = bus.codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
        bus.set_command_limits(lo, hi)
        bus.open()
        bus.identify()
        bus.configure()
        out = timed_ticks(bus, base, lo, hi, ticks, lambda k: bus.read_positions())
        bus.close()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4, help="runs per fault case and mode")
    ap.add_argument("--ticks", type=int, default=200, help="free-running ticks per bus")
    ap.add_argument("--write-squat", metavar="NPZ", help="only write the squat recording")
    args = ap.parse_args(argv)
    robot = load_robot("op3")
    if args.write_squat:
        print(f"wrote {squat(robot, Path(args.write_squat))}")
        return 0
    lines = [
        f"### Fault detection at 50 Hz, 20 XM430 (Protocol 2.0), {args.runs} runs per case",
        "",
        "| fault | mode | stopped | fault -> last goal p50 / max (ms) | right servo named "
        "| goals refused / outside limits |",
        "|---|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        recording = squat(robot, Path(tmp) / "squat.npz")
        for label, kw in CASES:
            for read in (False, True):
                runs = [
                    fault_run(robot, recording, Fault(after_goals=12 + k, **kw), read)
                    for k in range(args.runs)
                ]
                ms = np.array([r["ms"] for r in runs if r["ms"] is not None])
                lines.append(
                    f"| {label} | {'write + read' if read else 'write-only'} | "
                    f"{sum(r['stopped'] for r in runs)}/{len(runs)} | "
                    f"{np.median(ms):.1f} / {ms.max():.1f} | "
                    f"{sum(r['named'] for r in runs)}/{len(runs)} | "
                    f"{sum(r['refused'] for r in runs)} / {sum(r['outside'] for r in runs)} |"
                )
                print(lines[-1], flush=True)
    x = free_running(robot, args.ticks)
    ax = ax_free_running(load_robot("bioloid"), "wire+usb", True, args.ticks)
    lines += [
        "",
        f"### Free-running ticks with position reads ({args.ticks} ticks, wire timing, "
        "1 ms USB latency per reply)",
        "",
        "| bus | tick p50 / p99 (ms) | rate (Hz) | failed reads |",
        "|---|---|---|---|",
        f"| 20 XM430, Protocol 2.0, 2 Mbps: SYNC_WRITE + 1 SYNC_READ | {x['p50'] * 1e3:.2f} / "
        f"{x['p99'] * 1e3:.2f} | {x['rate']:.0f} | {x['failures']} |",
        f"| 18 AX-12A, Protocol 1.0, 1 Mbps: SYNC_WRITE + 18 READs | {ax['p50'] * 1e3:.2f} / "
        f"{ax['p99'] * 1e3:.2f} | {ax['rate']:.0f} | {ax['failures']} |",
    ]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
