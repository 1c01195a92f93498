"""Protocol 1.0 packets (bioloid-facts §4.3 worked examples), bus budget, AX-12A emulator."""

from __future__ import annotations

import math
import os
import select
import tty

import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import ServoError
from wbc.servos import protocol1 as dxl
from wbc.servos.emulator import AX12Emulator, Fault

HEX = bytes.fromhex


# ---------------------------------------------------------------- packets: worked examples
@pytest.mark.parametrize(
    ("servo_id", "instruction", "params", "expected"),
    [
        (1, dxl.INST_WRITE, [0x0C, 0x64, 0xAA], "FF FF 01 05 03 0C 64 AA DC"),
        (1, dxl.INST_PING, [], "FF FF 01 02 01 FB"),
        (1, dxl.INST_READ, [43, 1], "FF FF 01 04 02 2B 01 CC"),
        (0xFE, dxl.INST_WRITE, [3, 1], "FF FF FE 04 03 03 01 F6"),
        (1, dxl.INST_REG_WRITE, [0x1E, 0xF4, 0x01], "FF FF 01 05 04 1E F4 01 E2"),
        (0xFE, dxl.INST_ACTION, [], "FF FF FE 02 05 FA"),
        (0, dxl.INST_RESET, [], "FF FF 00 02 06 F7"),
    ],
)
def test_instruction_packets_match_the_manual(servo_id, instruction, params, expected):
    assert dxl.instruction_packet(servo_id, instruction, params) == HEX(expected)


def test_worked_checksum_example():
    # ID=1, LEN=5, INST=3, P=0x0C 0x64 0xAA: sum 0x123, ~0x23 = 0xDC
    assert sum([1, 5, 3, 0x0C, 0x64, 0xAA]) == 0x123
    assert dxl.checksum([1, 5, 3, 0x0C, 0x64, 0xAA]) == 0xDC


def test_status_packets_match_the_manual():
    assert dxl.status_packet(1, 0x24) == HEX("FF FF 01 02 24 D8")
    assert dxl.status_packet(1, 0) == HEX("FF FF 01 02 00 FC")  # reply to PING
    assert dxl.fault_names(0x24) == ("overheating", "overload")


def test_sync_write_packet_matches_the_manual():
    data = {0: [0x10, 0x00, 0x50, 0x01], 1: [0x20, 0x02, 0x60, 0x03]}
    expected = HEX("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
    assert dxl.sync_write_packet(30, 4, data) == expected


@given(st.lists(st.integers(0, 255), max_size=40), st.integers(0, 253), st.integers(0, 0x7F))
def test_checksum_makes_the_byte_sum_0xff(params, servo_id, error):
    pkt = dxl.status_packet(servo_id, error, params)
    assert sum(pkt[2:]) & 0xFF == 0xFF
    assert pkt[3] == len(params) + 2


def test_sdk_group_sync_write_sends_the_manual_bytes():
    """The real SDK port code through a pty: GroupSyncWrite emits our packet byte for byte."""
    from dynamixel_sdk import GroupSyncWrite, PortHandler, Protocol1PacketHandler

    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        port = PortHandler(os.ttyname(slave))
        assert port.setBaudRate(1_000_000)
        sync = GroupSyncWrite(port, Protocol1PacketHandler(), 30, 4)
        assert sync.addParam(0, [0x10, 0x00, 0x50, 0x01])
        assert sync.addParam(1, [0x20, 0x02, 0x60, 0x03])
        assert not sync.addParam(1, [0, 0, 0, 0])  # SDK trap: an ID only once per packet
        assert sync.txPacket() == 0
        select.select([master], [], [], 1.0)
        assert os.read(master, 100) == HEX("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
        port.closePort()
    finally:
        os.close(master)
        os.close(slave)


# ---------------------------------------------------------------- baud, speed, budget
def test_ax_baud_rates():
    assert dxl.ax_baud_register(1_000_000) == 1
    assert dxl.ax_baud_register(57600) == 34
    assert dxl.ax_baud_register(115200) == 16  # 117647 baud, -2.1 %
    assert dxl.ax_baud_register(300_000) is None  # nearest 285714 (n = 6) is 4.8 % off
    dxl.check_baud(1_000_000)
    with pytest.raises(ServoError, match="300000 is not an AX-12A rate"):
        dxl.check_baud(300_000)
    with pytest.raises(ServoError, match="not supported by dynamixel-sdk"):
        dxl.check_baud(123456)  # 1.2 % from 125000 (n = 15): fine for the AX, not the SDK
    with pytest.raises(ServoError, match="not supported by dynamixel-sdk"):
        dxl.check_baud(400_000)  # an AX rate (n = 4) the SDK's PortHandler refuses


def test_speed_register_units():
    assert dxl.speed_register(2 * math.pi * 33.3 / 60) == 300  # 300 ~ 33.3 rpm
    assert dxl.speed_register(100.0) == 1023
    assert dxl.speed_register(1e-6) == 1
    with pytest.raises(ServoError):
        dxl.speed_register(0.0)
    assert dxl.speed_ticks_per_s(0) == pytest.approx(dxl.speed_ticks_per_s(1023))  # capped
    assert dxl.speed_ticks_per_s(0) == pytest.approx(59 * 6 / (300 / 1023))


def test_sync_write_of_18_goals_is_62_bytes_and_0_62_ms_at_1_mbps():
    assert dxl.sync_write_length(18, 2) == 62
    b = dxl.ax_budget(18, 1_000_000, read_positions=False, polls_per_tick=0, return_delay_s=0)
    assert b.bytes_per_tick == 62
    assert b.wire_time() == pytest.approx(0.62e-3)
    assert b.max_rate() == pytest.approx(1 / 0.62e-3)


def test_budget_with_position_reads():
    # 62 B of SYNC_WRITE + 18 x (8 B READ + up to 10 B status: 2-byte position read in its
    # longest varied form, 4 bytes), each reply + 22 us + turnaround
    b = dxl.ax_budget(18, 1_000_000, read_positions=True)
    assert b.bytes_per_tick == 62 + 18 * 18
    assert b.replies_per_tick == 18
    assert b.tick_time() == pytest.approx((62 + 324) * 10e-6 + 18 * 22e-6)
    assert b.tick_time(1e-3) == pytest.approx(b.tick_time() + 18e-3)
    assert 40 < b.max_rate(1e-3) < 50  # pypot's 50 Hz with a 1 ms USB latency does not fit
    w = dxl.ax_budget(18, 1_000_000, read_positions=False)  # one health READ (8-10 B)
    assert w.bytes_per_tick == 62 + 8 + 16
    assert w.tick_time() == pytest.approx(86e-5 + 22e-6)
    w10 = dxl.ax_budget(18, 1_000_000, read_positions=False, polls_per_tick=10)
    assert w10.bytes_per_tick == 62 + 10 * 24 and w10.replies_per_tick == 10


@pytest.mark.parametrize(
    ("k", "expected"), [(0, (36, 8)), (1, (35, 9)), (2, (34, 10)), (3, (36, 8))]
)
def test_read_forms_rotate_so_consecutive_replies_differ_in_length(k, expected):
    assert dxl.read_variant(36, 8, k) == expected
    assert dxl.read_variant(1, 2, 2) == (0, 3)  # never below address 0


def test_status_parser_skips_noise_and_splits_packets():
    a = dxl.status_packet(3, 0, [1, 2])
    b = dxl.status_packet(4, 0x20, [])
    buf = bytearray(b"\x00\x13" + a + b"\xff" + b[:3])
    assert dxl.take_packet(buf) == a
    assert dxl.take_packet(buf) is None  # incomplete: kept
    buf += b[3:]
    assert dxl.take_packet(buf) == b
    assert dxl.take_packet(buf) is None and buf == bytearray()


# ---------------------------------------------------------------- emulator, packet level
@pytest.fixture()
def emu():
    return AX12Emulator(ids=[1, 2], positions={1: 500, 2: 600})


def test_emulator_answers_ping_and_read(emu):
    assert emu.handle(HEX("FF FF 01 02 01 FB"))[1] == HEX("FF FF 01 02 00 FC")
    _, reply = emu.handle(dxl.instruction_packet(1, dxl.INST_READ, [0, 2]))
    assert reply == dxl.status_packet(1, 0, [12, 0])  # model number 12
    _, reply = emu.handle(dxl.instruction_packet(2, dxl.INST_READ, [36, 2]))
    assert reply == dxl.status_packet(2, 0, dxl.word(600))
    assert emu.handle(dxl.instruction_packet(9, dxl.INST_PING))[1] == b""  # no such servo


def test_emulator_checksum_and_range_errors(emu):
    bad = bytearray(dxl.instruction_packet(1, dxl.INST_READ, [36, 2]))
    bad[-1] ^= 1
    assert emu.handle(bytes(bad))[1] == dxl.status_packet(1, dxl.ERR_CHECKSUM)
    assert emu.handle(dxl.instruction_packet(1, dxl.INST_READ, [49, 2]))[1] == dxl.status_packet(
        1, dxl.ERR_RANGE
    )
    # a goal outside the CW/CCW angle limits is refused with the angle-limit bit
    emu.handle(dxl.instruction_packet(1, dxl.INST_WRITE, [6, *dxl.word(400), *dxl.word(700)]))
    _, reply = emu.handle(dxl.instruction_packet(1, dxl.INST_WRITE, [30, *dxl.word(800)]))
    assert reply == dxl.status_packet(1, dxl.ERR_ANGLE_LIMIT)
    assert emu.servo(1).word(30) == 500 and not emu.goals[-1].accepted


def test_emulator_first_order_response_at_moving_speed(emu):
    s = emu.servo(1)
    t0 = 100.0
    s.last = t0
    s.table[dxl.ADDR_TORQUE_ENABLE] = 1
    s.set_word(dxl.ADDR_MOVING_SPEED, 300)  # 33.3 rpm
    s.set_word(dxl.ADDR_GOAL_POSITION, 900)
    v = dxl.speed_ticks_per_s(300)
    s.advance(t0 + 0.1)
    assert s.pos == pytest.approx(500 + 0.1 * v)  # saturated: moving at the set speed
    s.advance(t0 + 10.0)
    assert s.pos == pytest.approx(900, abs=1e-6)
    assert s.read(36, 2, t0 + 10.0) == bytes(dxl.word(900))


def test_emulator_sync_write_records_goals(emu):
    emu.handle(dxl.sync_write_packet(30, 2, {1: dxl.word(510), 2: dxl.word(590)}), now=1.0)
    assert [(g.servo_id, g.tick, g.via) for g in emu.goals] == [
        (1, 510, "sync_write"),
        (2, 590, "sync_write"),
    ]
    assert emu.sync_goal_writes == 1


def test_emulator_faults_at_packet_level():
    emu = AX12Emulator(
        ids=[1, 2, 3, 4],
        faults=[
            Fault("timeout", 1, after_goals=1, count=1),
            Fault("bad_checksum", 2),
            Fault("error_bits", 3, bits=dxl.ERR_OVERLOAD),
            Fault("missing", 4),
        ],
    )
    ping = [dxl.instruction_packet(i, dxl.INST_PING) for i in range(5)]
    assert emu.handle(ping[1])[1] == dxl.status_packet(1, 0)  # not active yet
    emu.handle(dxl.sync_write_packet(30, 2, {1: dxl.word(512)}))
    assert emu.handle(ping[1])[1] == b""  # one timeout
    assert emu.handle(ping[1])[1] == dxl.status_packet(1, 0)  # count exhausted
    reply = emu.handle(ping[2])[1]
    good = dxl.status_packet(2, 0)
    assert reply[:-1] == good[:-1] and reply[-1] != good[-1]
    assert emu.handle(ping[3])[1] == dxl.status_packet(3, dxl.ERR_OVERLOAD)
    assert emu.servo(3).word(dxl.ADDR_TORQUE_LIMIT) == 0  # AX shutdown on overload
    assert emu.handle(ping[4])[1] == b""


def test_duplicate_ids_garble_the_reply():
    emu = AX12Emulator(ids=[7], duplicate_ids=[7])
    reply = emu.handle(dxl.instruction_packet(7, dxl.INST_PING))[1]
    assert reply != dxl.status_packet(7, 0)
    assert sum(reply[2:]) & 0xFF != 0xFF  # the checksum no longer holds
