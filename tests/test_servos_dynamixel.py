"""DynamixelBus exchanges against the AX-12A emulator: matched replies, late replies never
taken as fresh, verified torque-off."""

from __future__ import annotations

import time

import numpy as np
import pytest

from wbc.servos.bus import COMM_OK, COMM_TIMEOUT
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator, Fault
from wbc.servos.protocol1 import ADDR_PRESENT_POSITION, ADDR_TORQUE_ENABLE


@pytest.fixture()
def bus_on(robot):
    def make(emu: AX12Emulator, timeout_ms: float) -> DynamixelBus:
        bus = DynamixelBus(emu.port, robot.servo_map, reply_timeout_ms=timeout_ms)
        bus.open()
        return bus

    return make


def test_a_late_reply_is_never_the_answer_to_the_next_request(robot, bus_on):
    """Servo 1 answers 90 ms late twice. The 1st READ times out (30 ms deadline); the 2nd,
    sent 60 ms after the 1st with a 120 ms deadline, meets the 1st's late reply first (at
    90 ms): same ID, but the READ's form differs, so its length does not match: discarded
    as late, and the 2nd's own reply (at 150 ms) is taken. (Times are 3x the bus's real
    ones so that a loaded machine's scheduling jitter, tens of ms, cannot reorder them.)"""
    i = robot.servo_map.index_of_id(1)
    fault = Fault("late", 1, count=2, delay_s=0.09)
    with AX12Emulator(positions={1: 500}, ids=[*range(1, 19)], faults=[fault]) as emu:
        bus = bus_on(emu, 30.0)
        t0 = time.perf_counter()
        assert bus.read(i, ADDR_PRESENT_POSITION, 2)[0] == COMM_TIMEOUT
        time.sleep(max(0.0, 0.06 - (time.perf_counter() - t0)))
        bus.reply_timeout_ms = 120.0
        comm, error, data = bus.read(i, ADDR_PRESENT_POSITION, 2)
        bus.close()
    assert comm == COMM_OK and error == 0
    assert data[0] | (data[1] << 8) == 500
    assert bus.log.late == {1: 1} and bus.log.timeouts == {1: 1}
    assert len(bus.log.rtt) == 1 and bus.log.rtt[0] > 0.075  # the 2nd's own, late, reply


def test_torque_off_is_acknowledged_and_read_back(robot, bus_on):
    with AX12Emulator(faults=[Fault("missing", 9)]) as emu:
        for s in emu.servos.values():
            s.table[ADDR_TORQUE_ENABLE] = 1
        bus = bus_on(emu, 10.0)
        unconfirmed = bus.torque_off()
        bus.close()
    assert unconfirmed == ["id 9 (r_hip_roll)"]
    assert all(s.table[ADDR_TORQUE_ENABLE] == 0 for sid, s in emu.servos.items() if sid != 9)
    reads = [w for w in emu.writes if w.address == ADDR_TORQUE_ENABLE and w.servo_id == 1]
    assert len(reads) >= 2  # the broadcast, then its own acknowledged WRITE


def test_torque_limit_for_the_safe_fall(robot, bus_on):
    """set_torque_limit (the protective fall, wbc.balance.fall): one broadcast WRITE of
    register 34 reaches every servo; a share outside 0..1 is refused."""
    from wbc.exceptions import ServoError

    with AX12Emulator() as emu:
        bus = bus_on(emu, 20.0)
        try:
            bus.set_torque_limit(0.3)
            time.sleep(0.05)
            ids = [int(i) for i in robot.servo_map.ids]
            assert {emu.register(i, 34, 2) for i in ids} == {round(0.3 * 1023)}
            with pytest.raises(ServoError, match="torque limit share"):
                bus.set_torque_limit(1.5)
        finally:
            bus.close()


def test_stiffness_writes_the_compliance_slopes_and_refuses_what_they_cannot_hold(robot, bus_on):
    """set_stiffness(f): every servo's CW and CCW Compliance Slope (28/29) = its configured
    slope / f in one SYNC_WRITE (margins untouched); 1 restores servos.toml's; a factor the
    registers (1..254) cannot hold is refused in one line naming the servos, nothing sent."""
    from wbc.exceptions import ServoError
    from wbc.servos.protocol1 import ADDR_CW_COMPLIANCE_MARGIN, ADDR_CW_COMPLIANCE_SLOPE

    sm = robot.servo_map
    configured = {int(i): int(s) for i, s in zip(sm.ids, sm.settings.compliance_slope, strict=True)}
    assert configured[1] == 128 and configured[15] == 64 and configured[11] == 32
    with AX12Emulator() as emu:
        bus = bus_on(emu, 20.0)
        try:
            bus.set_stiffness(4.0)
            time.sleep(0.05)
            for sid, slope in configured.items():
                assert emu.register(sid, ADDR_CW_COMPLIANCE_SLOPE) == slope // 4
                assert emu.register(sid, ADDR_CW_COMPLIANCE_SLOPE + 1) == slope // 4
                assert emu.register(sid, ADDR_CW_COMPLIANCE_MARGIN) == 1  # the default
            assert np.all(bus.stiffness == 4.0)
            writes = [w for w in emu.writes if w.address == ADDR_CW_COMPLIANCE_SLOPE]
            assert {w.via for w in writes} == {"sync_write"} and len(writes) == 18
            per_joint = np.ones(18)
            per_joint[sm.index_of_id(1)] = 2.0
            bus.set_stiffness(per_joint)
            time.sleep(0.05)
            assert emu.register(1, ADDR_CW_COMPLIANCE_SLOPE) == 64
            assert emu.register(2, ADDR_CW_COMPLIANCE_SLOPE) == 128
            bus.set_stiffness(1.0)
            time.sleep(0.05)
            assert {s: emu.register(s, ADDR_CW_COMPLIANCE_SLOPE) for s in configured} == configured
            n = len(emu.writes)
            with pytest.raises(ServoError, match=r"compliance slope allowed 1\.\.254\): .*id 11"):
                bus.set_stiffness(0.1)  # 32 / 0.1 = 320 ticks
            with pytest.raises(ServoError, match=r"id 1 \(r_shoulder_pitch\) x300"):
                bus.set_stiffness(300.0)  # 128 / 300 < 1
            with pytest.raises(ServoError, match="finite and > 0"):
                bus.set_stiffness(-1.0)
            with pytest.raises(ServoError, match="expected 18 factors"):
                bus.set_stiffness([2.0, 2.0])
            time.sleep(0.05)
            assert len(emu.writes) == n  # nothing sent
            assert np.all(bus.stiffness == 1.0)
        finally:
            bus.close()
