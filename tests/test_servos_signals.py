"""Every way a ``wbc deploy`` ends is a safe stop: SIGTERM, SIGHUP and SIGQUIT sent to a real
``wbc deploy`` process (a subprocess on the AX-12A emulator's pty) take the path of Ctrl-C:
the configured stop (torque off, verified per servo), the ``--log`` written, one line saying
why, exit code 128 + the signal's number."""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from wbc.servos.emulator import AX12Emulator
from wbc.servos.protocol1 import ADDR_TORQUE_ENABLE

Emulator = functools.partial(AX12Emulator, process=True)


@pytest.fixture(scope="module")
def still(robot, pose_recording):
    """3 s at Walk Ready (long enough for any signal to land mid-playback)."""
    return pose_recording(robot, "walk_ready", seconds=3.0, name="still")


def deploy_process(port, recording, log, *extra):
    cmd = [sys.executable, "-m", "wbc.cli", "deploy", recording, "--port", port, "--rate", "50"]
    cmd += ["--reply-timeout-ms", "50", "--max-failures", "10", "--log", str(log), *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT])
def test_stop_signals_end_in_the_safe_stop(walk_ready_ticks, still, tmp_path, signum):
    pid = multiprocessing.Value("i", 0)  # the deploy's PID, read by the servos' process

    def send():
        os.kill(pid.value, signum)

    log = tmp_path / "log.npz"
    with Emulator(positions=walk_ready_ticks, on_goal_write={10: send}) as emu:
        proc = deploy_process(emu.port, still, log, "--on-fault", "torque-off")
        pid.value = proc.pid
        try:
            _, err = proc.communicate(timeout=60)
        finally:
            proc.kill()
    assert emu.error is None
    assert proc.returncode == 128 + signum, err
    name = signal.Signals(signum).name
    stops = [line for line in err.splitlines() if line.startswith("SAFE STOP")]
    assert stops == [f"SAFE STOP (torque-off): operator: {stops[0].split('operator: ')[1]}"], err
    assert name in stops[0]
    # every servo's torque is off (the emulator's own control tables), confirmed by reads
    assert {sid: s.table[ADDR_TORQUE_ENABLE] for sid, s in emu.servos.items()} == {
        sid: 0 for sid in emu.servos
    }
    assert 10 <= emu.sync_goal_writes <= 12  # stopped at the next tick boundary
    data = np.load(log)  # the log was written, up to the last goal
    assert data["goal"].shape[0] == emu.sync_goal_writes - 1  # (start goal not logged)
