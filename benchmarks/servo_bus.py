"""Servo bus benchmark: loop rate and jitter against the AX-12A emulator at 1 Mbps.

Two tick kinds through the real dynamixel-sdk port code (``DynamixelBus``):

* write-only: one SYNC_WRITE of 18 goals + one 8-byte health READ (what ``wbc deploy`` does);
* write + read: one SYNC_WRITE + 18 two-byte READs of Present Position (``--read``).

Three emulator settings (the emulator runs in its own process, like separate hardware):

* ``pty``: replies at once. A pty has no baud rate, so this measures only the software
  (SDK busy-wait receive loop, pyserial, the emulator's parser): the host overhead floor.
* ``wire``: the emulator models the 1 Mbps half-duplex wire: 10 bits per byte for every
  packet, a 22 µs servo response after each instruction (Return Delay 0), replies delayed
  accordingly; the bus model's wire-only prediction applies.
* ``wire+usb``: as ``wire`` plus 1 ms per reply, the latency timer of an FTDI USB adapter set
  to 1 ms (the common fix); the bus model with a 1 ms turnaround applies.

For each: back-to-back ticks (highest achievable rate, tick time p50/p99) beside the bus
model's prediction, and a fixed-rate ``Deployment`` (100 Hz write-only, 50 Hz write + read)
with its achieved rate and jitter (tick-start lateness p50/p99).

Run: ``/work/venv/bin/python benchmarks/servo_bus.py [--ticks 400] [--out benchmarks/servo_bus.md]``
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wbc import load_robot
from wbc.servos.deploy import CallableSource, DeployConfig, Deployment
from wbc.servos.dynamixel import AX12_RESPONSE_S, DynamixelBus, ax_budget
from wbc.servos.emulator import AX12Emulator

BAUD = 1_000_000
MODES = {
    "pty": {"timing": False, "usb_latency_s": 0.0},
    "wire": {"timing": True, "usb_latency_s": 0.0},
    "wire+usb": {"timing": True, "usb_latency_s": 1e-3},
}


POLL_WAIT_S = 1e-3  # DynamixelBus's select wait; 0 = the SDK's busy-wait (--sdk-spin)


def _emulator(robot, mode: str) -> AX12Emulator:
    sm = robot.servo_map
    positions = sm.ticks_by_id(sm.pose_ticks("walk_ready"))
    return AX12Emulator(positions=positions, baud=BAUD, process=True, **MODES[mode])


def free_running(robot, mode: str, read: bool, ticks: int, configure: bool = True) -> dict:
    """Back-to-back ticks: goals (a small sway) + health poll or 18 position reads.

    ``configure`` runs the deployment's start-up (Return Delay 0, angle limits); without it
    the servos keep the factory Return Delay of 250 (500 µs before every status packet)."""
    sm = robot.servo_map
    base = sm.pose_ticks("walk_ready")
    with _emulator(robot, mode) as emu:
        bus = DynamixelBus(emu.port, sm, BAUD, 20.0, poll_wait_s=POLL_WAIT_S)  # long timeouts
        lo, hi = bus.codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
        bus.set_command_limits(lo, hi)
        bus.open()
        bus.identify()
        if configure:
            bus.configure()
        times = np.empty(ticks)
        failures = 0
        for k in range(ticks):
            goals = np.clip(base + round(5 * np.sin(k / 10)), lo, hi)
            t0 = time.perf_counter()
            bus.write_goals(goals.astype(int))
            statuses = bus.read_positions() if read else [bus.poll(k % 18)]
            times[k] = time.perf_counter() - t0
            failures += sum(s.comm != "ok" for s in statuses)
        bus.close()
    return {
        "p50": float(np.percentile(times, 50)),
        "p99": float(np.percentile(times, 99)),
        "rate": ticks / float(times.sum()),
        "failures": failures,
    }


def fixed_rate(robot, mode: str, read: bool, rate: float, seconds: float) -> dict:
    """A ``Deployment`` of Walk Ready plus a sway at ``rate``: achieved rate and jitter."""
    q0 = robot.configuration("walk_ready")[7:]
    j = robot.joint_index("l_knee")
    n = int(seconds * rate)

    def sway(tick, t):
        if tick >= n:
            return None
        q = q0.copy()
        q[j] += 0.2 * np.sin(np.pi * t / seconds) ** 2
        return q

    with _emulator(robot, mode) as emu:
        bus = DynamixelBus(emu.port, robot.servo_map, BAUD, 20.0, poll_wait_s=POLL_WAIT_S)
        bus.turnaround_s = MODES[mode]["usb_latency_s"]
        source = CallableSource(sway, q0, robot.joint_names)
        cfg = DeployConfig(rate=rate, read=read)
        result = Deployment(bus, source, robot, cfg, out=lambda s: None).run()
    tm = result.timing
    return {
        "completed": result.completed,
        "achieved": tm.achieved_rate,
        "late_p50": tm.pct(tm.lateness, 50),
        "late_p99": tm.pct(tm.lateness, 99),
        "work_p50": tm.pct(tm.work, 50),
        "work_p99": tm.pct(tm.work, 99),
        "overruns": tm.overruns,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=400, help="back-to-back ticks per case")
    ap.add_argument("--seconds", type=float, default=3.0, help="fixed-rate run length")
    ap.add_argument("--out", help="also write the markdown table to this file")
    ap.add_argument(
        "--sdk-spin", action="store_true", help="the SDK's busy-wait receive (no select wait)"
    )
    args = ap.parse_args(argv)
    global POLL_WAIT_S
    if args.sdk_spin:
        POLL_WAIT_S = 0.0
    robot = load_robot("bioloid")
    ms = 1e3
    lines = [
        f"Machine: {platform.machine()}, {os.cpu_count()} cores, "
        f"{platform.python_implementation()} {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M')}, load average before the run "
        f"{os.getloadavg()[0]:.2f} (shared machine); emulator in its own process; receive "
        + ("busy-wait (SDK)." if args.sdk_spin else "waits in select (<= 1 ms)."),
        "",
        "### Back-to-back ticks (highest rate) vs the bus model",
        "",
        "| tick | emulator | model tick (ms) | model max (Hz) | measured p50 / p99 (ms) "
        "| measured rate (Hz) | failed replies |",
        "|---|---|---|---|---|---|---|",
    ]
    cases = [(read, mode, True) for read in (False, True) for mode in MODES]
    cases.append((True, "wire", False))  # factory Return Delay 250 = 500 µs per reply
    for read, mode, configure in cases:
        delay = AX12_RESPONSE_S + (0.0 if configure else 500e-6)
        budget = ax_budget(18, BAUD, read_positions=read, return_delay_s=delay)
        r = free_running(robot, mode, read, args.ticks, configure)
        turn = MODES[mode]["usb_latency_s"]
        model = "n/a (no baud timing)" if mode == "pty" else f"{budget.tick_time(turn) * ms:.3f}"
        model_hz = "n/a" if mode == "pty" else f"{budget.max_rate(turn):.0f}"
        label = mode if configure else f"{mode}, Return Delay 250"
        lines.append(
            f"| {budget.name} | {label} | {model} | {model_hz} | "
            f"{r['p50'] * ms:.3f} / {r['p99'] * ms:.3f} | {r['rate']:.0f} | {r['failures']} |"
        )
        print(lines[-1], flush=True)
    lines += [
        "",
        f"### Fixed-rate playback ({args.seconds:g} s through `Deployment`)",
        "",
        "| tick | emulator | rate (Hz) | achieved (Hz) | jitter p50 / p99 (ms) "
        "| work p50 / p99 (ms) | overruns |",
        "|---|---|---|---|---|---|---|",
    ]
    for read, rate in ((False, 100.0), (True, 50.0)):
        for mode in MODES:
            r = fixed_rate(robot, mode, read, rate, args.seconds)
            name = "write + read" if read else "write-only"
            lines.append(
                f"| {name} | {mode} | {rate:g} | {r['achieved']:.2f} | "
                f"{r['late_p50'] * ms:.3f} / {r['late_p99'] * ms:.3f} | "
                f"{r['work_p50'] * ms:.3f} / {r['work_p99'] * ms:.3f} | {r['overruns']} |"
            )
            print(lines[-1], flush=True)
    if args.out:
        Path(args.out).write_text("\n".join(lines) + "\n")
    else:
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
