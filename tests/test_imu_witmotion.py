"""The WitMotion WT901-family reader: packet parsing, scales, resynchronisation, and the
reader against its pty emulator (stale data, bad port, configuration commands)."""

from __future__ import annotations

import math
import time

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.imu import GRAVITY, ImuError
from wbc.imu_witmotion import (
    ACC,
    ACC_SCALE,
    ANGLE_SCALE,
    GYRO_SCALE,
    WitEmulator,
    WitImu,
    WitParser,
    checksum,
    command,
    encode_sample,
    packet,
)


def test_packet_by_hand():
    """0x55 0x51, four int16 little endian, checksum = low byte of the sum."""
    p = packet(ACC, (2048, -1, 0, 100))  # 2048 units = 1 g
    assert p == bytes([0x55, 0x51, 0x00, 0x08, 0xFF, 0xFF, 0x00, 0x00, 0x64, 0x00, p[10]])
    assert p[10] == (0x55 + 0x51 + 0x08 + 0xFF + 0xFF + 0x64) & 0xFF == checksum(p[:10])
    parser = WitParser()
    assert parser.feed(p) == 1
    assert parser.acc == pytest.approx([GRAVITY, -ACC_SCALE, 0.0])
    assert command(0x03, 0x0B) == bytes([0xFF, 0xAA, 0x03, 0x0B, 0x00])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3),
    st.lists(st.floats(-30.0, 30.0), min_size=3, max_size=3),
    st.lists(st.floats(-100.0, 100.0), min_size=3, max_size=3),
)
def test_sample_round_trip(rpy, gyro, acc):
    """encode → parse gives the sample back within the protocol's resolution."""
    R = pin.rpy.rpyToMatrix(*rpy)
    quat = pin.Quaternion(R).coeffs()
    parser = WitParser()
    assert parser.feed(encode_sample(quat, np.array(gyro), np.array(acc))) == 4
    assert np.abs(parser.gyro - gyro).max() <= GYRO_SCALE
    assert np.abs(parser.acc - acc).max() <= ACC_SCALE
    q = parser.orientation()
    assert abs(abs(q @ quat) - 1.0) < 1e-4  # same rotation (sign free)
    angle_R = pin.Quaternion(parser.angle_quat).toRotationMatrix()  # the 0x53 angles agree
    assert np.abs(pin.log3(angle_R.T @ R)).max() < 4 * ANGLE_SCALE


@settings(max_examples=30, deadline=None)
@given(st.binary(max_size=40), st.integers(1, 11))
def test_garbage_and_split_packets(garbage, cut):
    """Garbage before a packet and a packet split across reads: the parser resynchronises
    on 0x55 after bad checksums and still reads every good packet."""
    good = encode_sample(np.array([0, 0, 0, 1.0]), np.array([0.1, 0.2, 0.3]), np.zeros(3))
    parser = WitParser()
    stream = garbage + good
    n = parser.feed(stream[: len(garbage) + cut]) + parser.feed(stream[len(garbage) + cut :])
    assert n >= 4
    assert parser.gyro == pytest.approx([0.1, 0.2, 0.3], abs=GYRO_SCALE)


def test_corrupted_packet_is_dropped():
    p = bytearray(packet(ACC, (2048, 0, 0, 0)))
    p[3] ^= 0x01
    parser = WitParser()
    assert parser.feed(bytes(p)) == 0
    assert parser.acc is None and parser.bad == 1


def test_reader_on_the_emulator():
    """The reader on the pty: the emulated sample in the IMU interface's units and frames,
    the rate configuration written at open, a mount rotation, stale data as one clear error."""
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    gyro, acc = np.array([0.5, -1.0, 2.0]), R.T @ np.array([0, 0, GRAVITY])
    with WitEmulator(lambda: (pin.Quaternion(R).coeffs(), gyro, acc)) as emu:
        imu = WitImu(emu.port, rate=100)
        with imu:
            imu.wait_ready()
            r = imu.read()
            assert np.abs(pin.log3(r.rotation().T @ R)).max() < 1e-3
            assert r.angular_velocity == pytest.approx(gyro, abs=GYRO_SCALE)
            assert r.linear_acceleration == pytest.approx(acc, abs=ACC_SCALE)
            assert r.tilt() == pytest.approx(math.acos(R[2, 2]), abs=1e-3)
            emu.paused = True
            # stale data raises once stale_s has passed without a sample; on a loaded machine
            # the reader may still be draining samples the pty buffered before the pause
            deadline = time.monotonic() + 5.0
            with pytest.raises(ImuError, match="no data for"):
                while time.monotonic() < deadline:
                    imu.read()
                    time.sleep(0.05)
        time.sleep(0.05)
        assert bytes(emu.received).startswith(command(0x69, 0xB588) + command(0x03, 0x09))
        mount = pin.rpy.rpyToMatrix(0.0, 0.0, math.pi / 2)  # module turned 90° on the torso
        emu.paused = False
        with WitImu(emu.port, mount=mount) as turned:
            turned.wait_ready()
            r = turned.mount.to_torso(turned.read())  # the closed loop applies Imu.mount
            assert r.angular_velocity == pytest.approx(mount @ gyro, abs=2 * GYRO_SCALE)
            assert np.abs(pin.log3(r.rotation().T @ (R @ mount.T))).max() < 1e-3


def test_bad_input_one_clear_line():
    with pytest.raises(ImuError, match="cannot open the port"):
        WitImu("/dev/does-not-exist").open()
    with pytest.raises(ImuError, match="baud"):
        WitImu("/dev/ttyUSB1", baud=1234)
    with pytest.raises(ImuError, match="rate"):
        WitImu("/dev/ttyUSB1", rate=7)
    with pytest.raises(ImuError, match="mount"):
        WitImu("/dev/ttyUSB1", mount=np.ones((3, 3)))
    with WitEmulator() as emu:  # wrong baud / silent device: names port, baud and packets
        emu.paused = True
        imu = WitImu(emu.port, stale_s=0.05)
        with imu, pytest.raises(ImuError, match="no complete WitMotion sample"):
            imu.wait_ready(timeout=0.1)


def test_deploy_imu_options(capsys):
    """``wbc deploy``: --imu with --open-loop, and --closed-loop without --live, are
    refused with one line before anything moves; a bad --imu port is named."""
    from wbc.cli import main as wbc_main

    argv = ["deploy", "--live", "walk", "--dry-run", "--open-loop", "--imu", "/dev/x"]
    assert wbc_main(argv) == 2
    assert "--imu / --encoders-only / --stepping belong to the closed loop" in (
        capsys.readouterr().err
    )
    assert wbc_main(["deploy", "rec.npz", "--dry-run", "--closed-loop"]) == 2
    assert "give --live STACK" in capsys.readouterr().err
    argv = ["deploy", "--live", "walk", "--dry-run", "--closed-loop", "--imu", "/dev/nope"]
    assert wbc_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--imu /dev/nope: cannot open the port" in err[0]


def test_deploy_picks_the_imu():
    """--closed-loop's IMU: the simulated torso IMU on --sim, a WitMotion reader on --imu
    PORT, none with --encoders-only (and not both)."""
    import argparse

    from wbc.cli.wiring import make_imu as _imu

    class FakeSimBus:
        sim = None

    args = argparse.Namespace(encoders_only=True, imu=None, imu_baud=115200)
    assert _imu(args, FakeSimBus()) is None
    args = argparse.Namespace(encoders_only=False, imu="/dev/ttyUSB1", imu_baud=115200)
    imu = _imu(args, FakeSimBus())
    assert isinstance(imu, WitImu) and imu.port == "/dev/ttyUSB1" and imu.serial is None
    args = argparse.Namespace(encoders_only=True, imu="/dev/ttyUSB1", imu_baud=115200)
    with pytest.raises(Exception, match="either --imu PORT or --encoders-only"):
        _imu(args, FakeSimBus())
    args = argparse.Namespace(encoders_only=False, imu=None, imu_baud=115200)
    said = []
    assert _imu(args, FakeSimBus(), out=said.append) is None  # encoders only, saying so
    assert len(said) == 1 and "no IMU given (--imu PORT): estimating from the servos'" in said[0]
    from wbc.model import load_robot
    from wbc.sim.bus import SimImu, SimServoBus
    from wbc.sim.simulator import Simulation

    assert isinstance(_imu(args, SimServoBus(Simulation(load_robot()))), SimImu)
