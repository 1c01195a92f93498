"""Dynamixel Protocol 2.0: packets, the X-series servo map, the bus on the XM430 emulator, and
the deployment's safety bounds on it (the AX-12A path's, tests/test_servos_playback.py)."""

from __future__ import annotations

import argparse
import functools
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.cli import deploy as deploy_cmd
from wbc.exceptions import ServoMapError
from wbc.servo_map import ServoMap
from wbc.servos.bus import COMM_OK, COMM_TIMEOUT
from wbc.servos.config import DeployConfig
from wbc.servos.emulator import Fault
from wbc.servos.emulator2 import XEmulator
from wbc.servos.plan import plan_lines
from wbc.servos.protocol1 import ax_budget, read_variant
from wbc.servos.protocol2 import (
    HEALTH_BLOCK,
    Dynamixel2Bus,
    crc16,
    instruction_packet2,
    parse_packet2,
    status_packet2,
    stuff,
    take_packet2,
    unstuff,
    x_budget,
)
from wbc.xseries import ADDR_BUS_WATCHDOG, ADDR_TORQUE_ENABLE, HW_OVERHEATING, HW_OVERLOAD

Emulator = functools.partial(XEmulator, process=True)


# ---------------------------------------------------------------- packets
def test_ping_packet_matches_the_manual():
    # e-Manual, Protocol 2.0, PING example: ID 1
    assert instruction_packet2(1, 0x01).hex(" ") == "ff ff fd 00 01 03 00 01 19 4e"


def test_read_packet_matches_the_manual():
    # e-Manual, Protocol 2.0, READ example: ID 1, Present Position (132), 4 bytes
    pkt = instruction_packet2(1, 0x02, [0x84, 0x00, 0x04, 0x00])
    assert pkt.hex(" ") == "ff ff fd 00 01 07 00 02 84 00 04 00 1d 15"


def test_crc_is_the_sdks():
    from dynamixel_sdk import Protocol2PacketHandler

    data = list(instruction_packet2(7, 0x03, [116, 0, 1, 2, 3, 4])[:-2])
    assert crc16(data) == Protocol2PacketHandler().updateCRC(0, data, len(data))


@given(st.binary(max_size=40))
def test_stuffing_round_trips_and_hides_every_header(body):
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    pkt = status_packet2(3, 0, body)
    assert pkt[3:].find(b"\xff\xff\xfd\x00") < 0 or b"\xff\xff\xfd\xfd" in pkt  # no fake header
    buf = bytearray(b"\x00\xff" + pkt + b"\xff")
    assert parse_packet2(take_packet2(buf)) == (3, bytes([0x55, 0, *body]))


def test_a_stuffed_packet_is_longer_and_parses_back():
    params = [0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00]
    pkt = instruction_packet2(1, 0x03, params)
    assert b"\xff\xff\xfd\xfd" in pkt and pkt[5] == len(params) + 3 + 1
    assert parse_packet2(pkt) == (1, bytes([0x03, *params]))


def test_take_packet_skips_noise_and_splits_packets():
    a, b = status_packet2(1, 0, [1, 2]), status_packet2(2, 0x80, [])
    buf = bytearray(b"\x13\xff\xff" + a + b[:5])
    assert take_packet2(buf) == a
    assert take_packet2(buf) is None
    buf += b[5:]
    assert take_packet2(buf) == b
    bad = bytearray(a[:-1] + bytes([a[-1] ^ 1]))
    assert parse_packet2(take_packet2(bad)) is None  # CRC


# ---------------------------------------------------------------- servo map
def write_map(tmp_path, bus: str, settings: str = "") -> str:
    path = tmp_path / "servos.toml"
    path.write_text(
        f"[bus]\n{bus}\n[joints]\na = {{ id = 1, sign = 1, zero_tick = 2048 }}\n{settings}"
    )
    return str(path)


def test_protocol_2_selects_the_x_series_ticks(tmp_path):
    sm = ServoMap.from_file(write_map(tmp_path, "protocol = 2.0"))
    assert (sm.tick_min, sm.tick_max) == (0, 4095)
    assert sm.angles_to_ticks([np.pi / 2])[0] == 3072


@pytest.mark.parametrize(
    ("bus", "settings", "words"),
    [
        ("protocol = 3.0", "", "protocol = 3.0"),
        ("protocol = 2.0\nticks_over_range = 1023", "", "ticks_over_range"),
        ("protocol = 2.0\nbaud = 1000000", "", "unknown keys ['baud']"),
        ("protocol = 2.0", "[settings]\ncompliance_slope = 32", "compliance_slope"),
        ("protocol = 2.0", "[settings]\nposition_p_gain = 99999", "position_p_gain"),
        ("protocol = 2.0", "[extra]\nx = 1", "unknown tables/keys ['extra']"),
        (
            "protocol = 2.0",
            "[settings.joints]\na = { position_p_gain = 99999 }",
            "[settings].joints.a.position_p_gain = 99999",
        ),
    ],
)
def test_every_key_is_read_or_refused(tmp_path, bus, settings, words):
    with pytest.raises(ServoMapError, match=words.replace("[", r"\[").replace("]", r"\]")):
        ServoMap.from_file(write_map(tmp_path, bus, settings))


def test_the_ax12a_map_is_unchanged(robot):
    assert robot.servo_map.protocol == 1.0 and robot.servo_map.tick_max == 1023


# ---------------------------------------------------------------- budget
def test_budget_of_20_servos_at_2_mbps_with_reads():
    b = x_budget(20, 2_000_000, read_positions=True)
    # SYNC_WRITE 14 + 20 x 5 = 114 B; SYNC_READ 14 + 20 B out, 20 x (11 + 12) B in
    assert b.bytes_per_tick == 114 + 34 + 20 * 23
    assert b.replies_per_tick == 1  # one transaction: one host turnaround
    assert b.tick_time(1e-3) < 0.25 * ax_budget(20, 1_000_000, True).tick_time(1e-3)


def test_plan_prints_the_ax12a_budget_beside(op3):
    bus = Dynamixel2Bus("", op3.servo_map)
    lines = "\n".join(plan_lines(bus, DeployConfig(rate=50.0), 1e-3))
    assert "SYNC_READ health block" in lines and "20 AX-12A (Protocol 1.0" in lines


# ---------------------------------------------------------------- the bus on the emulator
@pytest.fixture
def open_bus(op3):
    """The bus on a thread emulator, with a 100 ms reply deadline and 6 start-up attempts:
    on this shared machine the test process (and the emulator's thread in it) can stall.
    Every bus opened is closed at the test's end, failed or not: a failed test's open bus
    would hold its port's lock in this process, and the next emulator's pty, given the same
    /dev/pts number, would be refused ("in use by PID ... (pytest)") test after test."""
    buses: list[Dynamixel2Bus] = []

    def open_(port, **kw) -> Dynamixel2Bus:
        bus = Dynamixel2Bus(port, op3.servo_map, reply_timeout_ms=100.0, attempts=6, **kw)
        buses.append(bus)
        bus.open()
        lo, hi = bus.codec.safe_range(op3.q_min, op3.q_max, op3.joint_names)
        bus.set_command_limits(lo, hi)
        return bus

    yield open_
    for bus in buses:
        bus.close()


def test_start_up_writes_the_settings_and_reads_everything_in_one_sync_read(op3, open_bus):
    with XEmulator() as emu:
        bus = open_bus(emu.port)
        bus.identify()
        bus.configure()
        knee = op3.servo_map.spec("l_knee").id
        assert emu.register(knee, 84, 2) == 2000 and emu.register(knee, 82, 2) == 500
        assert emu.register(knee, 9) == 0  # return delay
        lo = emu.register(knee, 52, 4)
        assert lo == bus.cmd_lo[op3.servo_map.index_of_id(knee)]
        reads = emu.sync_reads
        statuses = bus.read_positions()
        assert emu.sync_reads == reads + 1
        assert [s.comm for s in statuses] == [COMM_OK] * 20
        assert {s.position for s in statuses} == {2048.0}
        assert statuses[0].voltage == 12.0 and statuses[0].temperature == 35.0
        bus.close()
    assert emu.error is None


def test_a_late_sync_read_reply_is_never_taken_for_the_next(op3, open_bus):
    """Consecutive SYNC_READs differ in length (rotated form): servo 5's reply to the first
    comes 150 ms late (deadline 100 ms), while the second waits for it (servo 5 is silent
    then); that stale reply is discarded, so the second read times out instead of reading
    old data."""
    assert read_variant(224, len(HEALTH_BLOCK), 0)[1] != read_variant(224, 10, 1)[1]
    with XEmulator() as emu:
        bus = open_bus(emu.port)
        bus.configure()
        n = emu.packets_to(5)
        emu.faults += [
            Fault("late", 5, delay_s=0.15, count=1),
            Fault("timeout", 5, after_packets=n + 1, count=1),
        ]
        i = op3.servo_map.index_of_id(5)
        assert bus.read_positions()[i].comm == COMM_TIMEOUT  # 100 ms deadline
        second = bus.read_positions()  # waits 100 ms for servo 5; the late reply comes in
        assert second[i].comm == COMM_TIMEOUT
        assert bus.log.late.get(5, 0) == 1
        assert bus.read_positions()[i].comm == COMM_OK
        bus.close()


def test_hardware_error_names_the_fault(op3, open_bus):
    sid = 9
    with XEmulator() as emu:
        bus = open_bus(emu.port)
        bus.configure()
        emu.faults.append(Fault("error_bits", sid, bits=HW_OVERHEATING))
        status = bus.read_positions()[op3.servo_map.index_of_id(sid)]
        assert status.faults == ("overheating",) and status.temperature == 85.0
        assert emu.register(sid, ADDR_TORQUE_ENABLE) == 0  # Shutdown cut its torque
        bus.close()


def test_bus_watchdog_stops_a_servo_whose_host_went_silent(op3, open_bus):
    with XEmulator() as emu:
        bus = open_bus(emu.port, watchdog_ms=60.0)
        bus.identify()
        bus.configure()
        bus.set_torque(True)
        assert emu.register(1, ADDR_BUS_WATCHDOG) == 3  # 3 x 20 ms
        goal = np.clip(np.full(20, 2100), bus.cmd_lo, bus.cmd_hi)
        assert bus.write_goals(goal) == COMM_OK
        time.sleep(0.15)  # the process was killed: no packet for 150 ms
        bus.write_goals(goal + np.where(goal + 50 <= bus.cmd_hi, 50, 0))
        time.sleep(0.02)
        accepted = [g for g in emu.goals if g.time > emu.goals[19].time]
        assert accepted and not any(g.accepted for g in accepted)
        assert emu.register(1, ADDR_BUS_WATCHDOG) == 255
        assert bus.torque_off() == []  # disarms the watchdog, torque off read back
        assert all(emu.register(s, ADDR_TORQUE_ENABLE) == 0 for s in range(1, 21))
        bus.close()


# ---------------------------------------------------------------- the deployment
@pytest.fixture(scope="module")
def squat(op3, pose_recording):
    """1 s at 50 Hz: the standing pose plus a knee bend (0.15 rad at the hips)."""
    bends = (("l_hip_pitch", -1), ("r_hip_pitch", 1), ("l_knee", 2), ("r_knee", -2),
             ("l_ank_pitch", 1), ("r_ank_pitch", -1))  # fmt: skip
    return pose_recording(op3, "stand", bends, name="squat")


def run_deploy(port, recording, *extra, capsys, timeout_ms=None):
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    # reply deadline and start-up attempts generous enough for a stall of the emulator's
    # process on this shared machine (as tests/test_servos_playback.py)
    argv = [recording, "--robot", "op3", "--port", port, "--rate", "50", "--attempts", "6"]
    timeout = str(timeout_ms or (10 if "--read" in extra else 15))
    rc = deploy_cmd.run(parser.parse_args([*argv, "--reply-timeout-ms", timeout, *extra]))
    out, err = capsys.readouterr()
    return rc, out, err


def start_ticks(op3):
    sm = op3.servo_map
    return sm.ticks_by_id(sm.angles_to_ticks(op3.configuration("stand")[7:]))


FAULTS = [
    (Fault("timeout", 7, after_goals=12), ["--read"]),
    (Fault("late", 12, after_goals=12, delay_s=0.021), []),
    (Fault("bad_checksum", 16, after_goals=12), ["--read"]),
    (Fault("error_bits", 14, after_goals=12, bits=HW_OVERHEATING), []),
]


@pytest.mark.parametrize(("fault", "extra"), FAULTS, ids=[f[0].kind for f in FAULTS])
def test_any_fault_stops_motion_within_100_ms_at_50_hz(op3, squat, capsys, fault, extra):
    with Emulator(positions=start_ticks(op3), faults=[fault]) as emu:
        rc, _, err = run_deploy(emu.port, squat, "--on-fault", "torque-off", *extra, capsys=capsys)
    assert emu.error is None
    assert rc == deploy_cmd.EXIT_SAFE_STOP, err
    if f"): id {fault.servo_id} " not in err:  # the servo that failed is named, unless the
        # emulator's process stalled and another servo failed 3 times in a row first (then
        # many servos show timeouts; the stop is still in bound)
        timeouts = err.split("timeouts: ")[1].split("\n")[0].count("id ")
        assert timeouts >= 5 and "3 consecutive failed exchanges" in err, err
    # the fault is on from the 12th goal write: the last goal follows within the bound (as
    # test_servos_playback's twin: a stall-stopped run may end before the onset, 0 ms)
    times = emu.sync_goal_times
    on = times[min(fault.after_goals, len(times)) - 1]
    assert times[-1] - on <= 0.100 + 0.02  # + stamp jitter of the emulator
    # every servo's torque read back off, every goal inside the limits
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())
    assert all(g.accepted for g in emu.goals)


def test_overload_crouches_then_cuts_torque(op3, squat, capsys):
    fault = Fault("error_bits", 13, after_goals=12, bits=HW_OVERLOAD)
    with Emulator(positions=start_ticks(op3), faults=[fault]) as emu:
        rc, _, err = run_deploy(emu.port, squat, capsys=capsys, timeout_ms=30)
    assert rc == deploy_cmd.EXIT_SAFE_STOP
    assert "SAFE STOP (crouch, torque-off)" in err and "overload" in err
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for s in emu.servos.values())


def test_playback_is_soft_started_and_rate_limited(op3, squat, capsys):
    """Servos 0.2 rad from the first pose: the soft start moves them at --soft-speed; no
    goal ever moves faster than the servo speed (elapsed time, emulator stamps)."""
    sm = op3.servo_map
    q = op3.configuration("stand")[7:].copy()
    q[op3.joint_names.index("l_el")] += 0.2
    start = sm.ticks_by_id(sm.angles_to_ticks(q))
    with Emulator(positions=start) as emu:
        rc, out, err = run_deploy(emu.port, squat, "--read", capsys=capsys, timeout_ms=30)
    assert rc == deploy_cmd.EXIT_OK, err
    assert "soft start" in out
    speed = np.minimum(op3.v_max, Dynamixel2Bus.servo_speed) / sm.rad_per_tick
    for sid, goals in emu.goals_by_id().items():
        goals = [g for g in goals if g.via == "sync_write"]
        t = np.array([g.time for g in goals])
        c = np.array([g.tick for g in goals], float)
        i = sm.index_of_id(sid)
        steps = np.abs(np.diff(c)) - (speed[i] * (np.diff(t) + 0.02) + 1)
        assert np.all(steps <= 1e-9), sid
        assert np.all((c >= 0) & (c <= 4095))


@pytest.mark.long(12)
def test_identify_names_missing_and_doubled_servos(op3, open_bus):
    from wbc.exceptions import ServoError

    with XEmulator(faults=[Fault("missing", 4)], duplicate_ids=[9]) as emu:
        bus = open_bus(emu.port)
        with pytest.raises(ServoError) as info:
            bus.identify()
        bus.close()
    text = str(info.value)
    assert "no reply to PING from id 4 (l_sho_roll)" in text
    # two servos answering at once: no valid packet reaches the host, so the ID is named
    # (as silent: the AND of two status packets has no valid length or CRC)
    assert "id 9 (r_hip_roll)" in text
    assert "id 6" not in text  # the others answer


def test_garbage_before_a_sync_read_reply_fails_that_servo(op3, open_bus):
    with XEmulator() as emu:
        bus = open_bus(emu.port)
        bus.configure()
        emu.faults.append(Fault("garbage", 6, count=1))
        statuses = bus.read_positions()
        i = op3.servo_map.index_of_id(6)
        assert statuses[i].comm == "corrupt"
        assert all(s.comm == COMM_OK for k, s in enumerate(statuses) if k != i)
        assert bus.read_positions()[i].comm == COMM_OK  # one garbled reply, then clean
        bus.close()


def test_stiffness_writes_the_position_p_gains_and_refuses_what_they_cannot_hold(op3, open_bus):
    """set_stiffness(f): every servo's Position P Gain (84) = its configured gain × f in one
    SYNC_WRITE (I and D untouched); 1 restores servos.toml's; a gain outside 0..16383 is
    refused in one line naming the servos, nothing sent."""
    from wbc.exceptions import ServoError

    sm = op3.servo_map
    configured = {int(i): int(p) for i, p in zip(sm.ids, sm.settings.position_p_gain, strict=True)}
    with XEmulator() as emu:
        bus = open_bus(emu.port)
        bus.identify()
        bus.configure()
        bus.set_stiffness(2.0)
        time.sleep(0.05)
        assert {s: emu.register(s, 84, 2) for s in configured} == {
            s: 2 * p for s, p in configured.items()
        }
        knee = sm.spec("l_knee").id
        assert emu.register(knee, 82, 2) == 500  # the I gain as configured
        writes = [w for w in emu.writes if w.address == 84 and w.via == "sync_write"]
        assert len(writes) == len(configured)
        bus.set_stiffness(1.0)
        time.sleep(0.05)
        assert {s: emu.register(s, 84, 2) for s in configured} == configured
        n = len(emu.writes)
        with pytest.raises(ServoError, match=r"position P gain allowed 0\.\.16383\): .*l_knee"):
            bus.set_stiffness(20.0)  # 1000 x 20 = 20000
        time.sleep(0.05)
        assert len(emu.writes) == n
        bus.close()
    assert emu.error is None
