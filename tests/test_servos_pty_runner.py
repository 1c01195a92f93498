"""The emulators' pty runner: the device clock waits for the runners it watches, only those."""

from __future__ import annotations

import os
import select
import threading
import time

from wbc.servos.pty_runner import DeviceClock, PtyRunner, sleep_until


class _Held(PtyRunner):
    """Echoes what it is sent once ``release`` is set (a device still working on a request)."""

    def __init__(self) -> None:
        super().__init__()
        self.release = threading.Event()

    def _on_bytes(self, chunk: bytes, now: float) -> None:
        self.release.wait(10.0)
        self._send(chunk)


def _readable(fd: int) -> bool:
    return bool(select.select([fd], [], [], 0)[0])


def test_device_clock_waits_for_the_runners_it_watches():
    clock, other = DeviceClock(), DeviceClock()
    with clock.watch(_Held()) as runner:
        host = os.open(runner.port, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(host, b"ping")
            while runner.idle():  # (until its reader has taken the bytes)
                time.sleep(0.001)
            other()  # a clock that does not watch it reads at once
            assert not runner.idle() and not _readable(host)
            threading.Timer(0.05, runner.release.set).start()
            clock()  # waits until the reply is on the line
            assert runner.idle() and _readable(host)
            assert os.read(host, 16) == b"ping"
        finally:
            os.close(host)
    t = time.perf_counter()
    clock()  # a stopped runner is idle
    assert time.perf_counter() - t < 1.0


def test_sleep_until_reaches_its_deadline():
    deadline = time.monotonic() + 0.01
    sleep_until(deadline, spin_s=0.002)
    assert time.monotonic() >= deadline
