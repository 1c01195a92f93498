"""One owner per bus: a second program on a port is refused before it writes a byte, with
one line naming the process that holds it; the first is unaffected."""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

import numpy as np
import pytest

from wbc.cli import deploy as deploy_cmd
from wbc.exceptions import ServoError
from wbc.recording import Recording
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.emulator import AX12Emulator, Ssc32Emulator
from wbc.servos.portlock import PortLock, lock_path, open_locked
from wbc.servos.protocol1 import ADDR_TORQUE_ENABLE
from wbc.servos.ssc32 import Ssc32Bus, Ssc32Map


def test_a_second_deploy_on_the_port_is_refused_and_the_first_completes(
    robot, walk_ready_ticks, tmp_path, capsys
):
    """Two ``wbc deploy`` on one pty, the second started while the first plays: the second
    exits 2 naming the first's PID before sending a byte; the first plays to the end."""
    t = np.arange(0.0, 3.0 + 1e-9, 0.02)
    q = np.tile(robot.configuration("walk_ready"), (t.size, 1))
    rec = tmp_path / "still.npz"
    Recording(t, q, robot.joint_names).save(rec)
    with AX12Emulator(positions=walk_ready_ticks) as emu:  # a thread: its records are live
        cmd = [sys.executable, "-m", "wbc.cli", "deploy", str(rec), "--port", emu.port]
        cmd += ["--reply-timeout-ms", "50", "--max-failures", "10"]
        first = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 60
            while emu.sync_goal_writes < 5 and time.monotonic() < deadline:
                time.sleep(0.01)
            assert emu.sync_goal_writes >= 5, first.stderr.read() if first.poll() else ""
            packets = emu.packets
            parser = argparse.ArgumentParser()  # the second: in this process (no start-up wait)
            deploy_cmd.add_arguments(parser)
            rc = deploy_cmd.run(parser.parse_args(cmd[4:]))
            second_err = capsys.readouterr().err
            assert first.poll() is None  # the first was still playing
            writes_mid = len(emu.writes)
            out, err = first.communicate(timeout=60)
        finally:
            first.kill()
    assert rc == 2, second_err
    lines = second_err.strip().splitlines()
    assert len(lines) == 1 and f"in use by PID {first.pid} (wbc deploy" in lines[0], lines
    assert emu.error is None
    assert first.returncode == 0, err
    assert "completed" in out
    # the second sent nothing: no write but the first's goals, torque never turned off
    assert packets > 0
    assert all(w.address != ADDR_TORQUE_ENABLE for w in emu.writes[writes_mid - 1 :])
    assert all(s.table[ADDR_TORQUE_ENABLE] == 1 for s in emu.servos.values())


def test_the_lock_names_its_holder_and_is_released(robot, walk_ready_ticks):
    with AX12Emulator(positions=walk_ready_ticks) as emu:
        held = PortLock.acquire(emu.port)
        bus = DynamixelBus(emu.port, robot.servo_map)
        with pytest.raises(ServoError, match=r"in use by PID \d+ \(.*\): one program per bus"):
            bus.open()
        assert emu.packets == 0
        held.release()
        bus.open()  # free again
        try:
            with pytest.raises(ServoError, match="in use by PID"):  # now the bus holds it
                PortLock.acquire(emu.port)
        finally:
            bus.close()
        PortLock.acquire(emu.port).release()  # closed: released
    assert lock_path(emu.port).name.startswith("wbc-dev_pts_")


def test_ssc32_port_is_locked_and_opened_with_xon_xoff(robot):
    import termios

    ssc_map = Ssc32Map.default(robot.joint_names)
    with Ssc32Emulator() as emu:
        bus = Ssc32Bus(emu.port, ssc_map)
        bus.open()
        try:
            assert termios.tcgetattr(emu._master)[0] & termios.IXON
            with pytest.raises(ServoError, match="in use by PID"):
                Ssc32Bus(emu.port, ssc_map).open()
        finally:
            bus.close()
        assert emu.lines == []  # nothing written by either


def test_open_locked_leaves_nothing_locked_or_open_when_a_step_fails(tmp_path):
    """The port-open-with-lock sequence (every bus and the IMU): a failed open releases the
    port's lock; a refused device lock releases it and closes the device; success holds it."""
    port = str(tmp_path / "ttyFAKE")
    open(port, "w").close()
    closed = []

    def fail():
        raise ServoError("cannot open port: no such device")

    with pytest.raises(ServoError, match="cannot open port"):
        open_locked(port, fail, lambda d: d.fileno(), closed.append)
    PortLock.acquire(port).release()  # free again: the failed open left no lock

    holder = open(port)  # another program holding the device's flock
    import fcntl

    fcntl.flock(holder.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    try:
        with pytest.raises(ServoError, match="locked by another program"):
            open_locked(port, lambda: open(port), lambda d: d.fileno(), closed.append)
        assert len(closed) == 1  # the device opened, refused, then closed
        PortLock.acquire(port).release()  # and its lock file's lock released
    finally:
        holder.close()
        closed[0].close()
    device, lock = open_locked(port, lambda: open(port), lambda d: d.fileno(), lambda d: d.close())
    try:
        assert lock.held
        with pytest.raises(ServoError, match="in use by PID"):
            PortLock.acquire(port)
    finally:
        lock.release()
        device.close()
