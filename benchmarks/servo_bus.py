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

With ``--faults RUNS``: detection latency per fault type at 50 Hz, write-only and with
``--read``: the time from the goal write at which the emulator switches the fault on (the
12th, 13th, ... in successive runs: every phase of the health rotation) to the last goal
write (both stamped by the emulator), and the goal writes in between.
With ``--startups N``: N start-ups (PING, configuration, first reads, torque on/off) with the
default reply deadline (4.1 ms at a 1 ms USB latency), with and without retries.

Run: ``python benchmarks/servo_bus.py [--ticks 400] [--out benchmarks/servo_bus.md]``
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from wbc import load_robot
from wbc.servos import CallableSource, DeployConfig, Deployment
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator, Fault
from wbc.servos.protocol1 import AX12_RESPONSE_S, ERR_OVERHEATING, ERR_OVERLOAD, ax_budget

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
        out = timed_ticks(
            bus, base, lo, hi, ticks, lambda k: bus.read_positions() if read else [bus.poll(k % 18)]
        )
        bus.close()
    return out


def timed_ticks(bus, base: np.ndarray, lo, hi, ticks: int, feedback) -> dict:
    """``ticks`` free-running ticks: a SYNC_WRITE of ``base`` plus a ±5-tick sway (clipped to
    ``lo..hi``), then ``feedback(k)`` (the statuses read): tick p50/p99 (s), rate (Hz) and
    the failed reads."""
    times = np.empty(ticks)
    failures = 0
    for k in range(ticks):
        goals = np.clip(base + round(5 * np.sin(k / 10)), lo, hi)
        t0 = time.perf_counter()
        bus.write_goals(goals.astype(int))
        statuses = feedback(k)
        times[k] = time.perf_counter() - t0
        failures += sum(s.comm != "ok" for s in statuses)
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


FAULTS = {
    "silent (timeout)": Fault("timeout", 7, after_goals=12),
    "missing": Fault("missing", 10, after_goals=12),
    "late 21 ms": Fault("late", 12, after_goals=12, delay_s=0.021),
    "late 40 ms": Fault("late", 5, after_goals=12, delay_s=0.04),
    "bad checksum": Fault("bad_checksum", 16, after_goals=12),
    "overheating bit": Fault("error_bits", 14, after_goals=12, bits=ERR_OVERHEATING),
    "overload bit": Fault("error_bits", 3, after_goals=12, bits=ERR_OVERLOAD),
}


def detection(robot, fault: Fault, read: bool, runs: int) -> dict:
    """Fault -> last goal (ms, emulator stamps) and goal writes after the onset, per run."""
    q0 = robot.configuration("walk_ready")[7:]
    sm = robot.servo_map
    ms, writes, named, early = [], [], 0, 0
    for k in range(runs):
        # the onset moves by one goal write per run: every phase of the health rotation
        fault = dataclasses.replace(fault, after_goals=12 + k)
        source = CallableSource(lambda tick, t: None if tick >= 100 else q0, q0, robot.joint_names)
        positions = sm.ticks_by_id(sm.pose_ticks("walk_ready"))
        with AX12Emulator(positions=positions, faults=[fault], process=True) as emu:
            bus = DynamixelBus(emu.port, sm, BAUD, 1.0)  # default deadline: 4.1 ms
            cfg = DeployConfig(rate=50.0, read=read, on_fault="hold")
            try:
                result = Deployment(bus, source, robot, cfg, out=lambda s: None).run()
            except Exception as exc:  # a refused start-up: not a detection
                print(f"start-up refused: {exc}", file=sys.stderr)
                continue
        t = emu.sync_goal_times
        if len(t) < fault.after_goals:  # tripped before the fault (a stalled emulator)
            early += 1
            continue
        ms.append((t[-1] - t[fault.after_goals - 1]) * 1e3)
        writes.append(len(t) - fault.after_goals)
        named += result.trip is not None and result.trip.index == sm.index_of_id(fault.servo_id)
    return {
        "ms": np.array(ms),
        "writes": np.array(writes),
        "named": named,
        "runs": len(ms),
        "early": early,
    }


def startups(robot, n: int, attempts: int) -> tuple[int, list[str]]:
    """Start-ups (then torque off) with the default 4.1 ms reply deadline: successes, errors."""
    q0 = robot.configuration("walk_ready")[7:]
    sm = robot.servo_map
    ok, errors = 0, []
    for _ in range(n):
        source = CallableSource(lambda tick, t: None, q0, robot.joint_names)
        positions = sm.ticks_by_id(sm.pose_ticks("walk_ready"))
        with AX12Emulator(positions=positions, process=True) as emu:
            bus = DynamixelBus(emu.port, sm, BAUD, 1.0, attempts=attempts)
            cfg = DeployConfig(rate=50.0, at_end="torque-off")
            try:
                result = Deployment(bus, source, robot, cfg, out=lambda s: None).run()
                ok += result.completed and not result.warnings
            except Exception as exc:  # a refused start-up
                errors.append(str(exc))
    return ok, errors


def false_alarms(robot, n: int) -> list[str]:
    """N deployments of a 1 s sway at 50 Hz (write-only, no fault injected), alternating the
    fixed 4.1 ms reply deadline and the adaptive one: how many stop on a false alarm."""
    q0 = robot.configuration("walk_ready")[7:]
    sm = robot.servo_map
    j = robot.joint_index("l_knee")

    def sway(tick, t):
        if t > 1.0:
            return None
        q = q0.copy()
        q[j] += 0.1 * np.sin(np.pi * t) ** 2
        return q

    counts = {"fixed 4.1 ms": [0, 0, []], "adaptive": [0, 0, []]}
    for k in range(2 * n):
        name = "fixed 4.1 ms" if k % 2 == 0 else "adaptive"
        timeout = 4.1 if k % 2 == 0 else None
        positions = sm.ticks_by_id(sm.pose_ticks("walk_ready"))
        with AX12Emulator(positions=positions, process=True) as emu:
            bus = DynamixelBus(emu.port, sm, BAUD, 1.0, reply_timeout_ms=timeout)
            cfg = DeployConfig(rate=50.0, on_fault="hold")
            source = CallableSource(sway, q0, robot.joint_names)
            try:
                result = Deployment(bus, source, robot, cfg, out=lambda s: None).run()
                ok = result.completed
                why = "" if ok else str(result.trip)
            except Exception as exc:  # refused at start-up
                ok, why = False, f"start-up: {exc}"
        c = counts[name]
        c[0] += 1
        c[1] += ok
        if why:
            c[2].append(why[:90])
    lines = [
        f"### False alarms at load {os.getloadavg()[0]:.1f} ({n} runs each, alternating)",
        "",
        "| reply deadline | completed | first false alarms |",
        "|---|---|---|",
    ]
    for name, (runs, ok, why) in counts.items():
        lines.append(f"| {name} | {ok}/{runs} | {'; '.join(why[:2]) or '-'} |")
    return lines


def fault_tables(robot, runs: int, n_startups: int) -> list[str]:
    lines = [
        f"### Fault detection at 50 Hz ({runs} runs per case, reply deadline 4.1 ms)",
        "",
        "| fault | mode | fault -> last goal p50 / max (ms) | goal writes after onset (max) "
        "| right servo named | tripped before the fault |",
        "|---|---|---|---|---|---|",
    ]
    for name, fault in FAULTS.items():
        for read in (False, True):
            r = detection(robot, fault, read, runs)
            lines.append(
                f"| {name} | {'write + read' if read else 'write-only'} | "
                f"{np.median(r['ms']):.1f} / {r['ms'].max():.1f} | {r['writes'].max()} | "
                f"{r['named']}/{r['runs']} | {r['early']} |"
            )
            print(lines[-1], flush=True)
    if n_startups:
        lines += [
            "",
            f"### Start-ups ({n_startups} each, reply deadline 4.1 ms)",
            "",
            "| attempts per exchange | succeeded | first refusals |",
            "|---|---|---|",
        ]
        for attempts in (1, 3):
            ok, errors = startups(robot, n_startups, attempts)
            first = "; ".join(errors[:2]) or "-"
            lines.append(f"| {attempts} | {ok}/{n_startups} | {first} |")
            print(lines[-1], flush=True)
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=400, help="back-to-back ticks per case")
    ap.add_argument("--seconds", type=float, default=3.0, help="fixed-rate run length")
    ap.add_argument("--out", help="also write the markdown table to this file")
    ap.add_argument(
        "--sdk-spin", action="store_true", help="the SDK's busy-wait receive (no select wait)"
    )
    ap.add_argument("--faults", type=int, default=0, help="runs per fault case (only these)")
    ap.add_argument("--startups", type=int, default=0, help="--faults: also N start-ups")
    ap.add_argument(
        "--false-alarms", type=int, default=0, help="N nominal runs per reply deadline (only)"
    )
    args = ap.parse_args(argv)
    global POLL_WAIT_S
    if args.sdk_spin:
        POLL_WAIT_S = 0.0
    robot = load_robot("bioloid")
    ms = 1e3
    if args.false_alarms:
        print("\n".join(false_alarms(robot, args.false_alarms)))
        return 0
    if args.faults:
        stamp = time.strftime("%Y-%m-%d %H:%M")
        lines = [
            f"Machine: {platform.machine()}, {os.cpu_count()} cores, {stamp}, load average "
            f"before the run {os.getloadavg()[0]:.2f} (shared machine); emulator in its own "
            "process (pty, no wire timing).",
            "",
            *fault_tables(robot, args.faults, args.startups),
        ]
        if args.out:
            Path(args.out).write_text("\n".join(lines) + "\n")
        else:
            print("\n".join(lines))
        return 0
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
