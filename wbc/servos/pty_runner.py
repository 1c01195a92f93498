"""What the bus emulators share: a pseudo-terminal whose far end a reader answers, in a thread
or a forked process (:class:`PtyRunner`); :class:`DeviceClock`, the reply-deadline clock of
tests on an emulator (``ServoBus.reply_clock``); :func:`sleep_until`, an emulator's wait."""

from __future__ import annotations

import multiprocessing
import os
import select
import termios
import threading
import time
import tty
import weakref
from typing import TypeVar

R = TypeVar("R", bound="PtyRunner")


class DeviceClock:
    """``time.perf_counter()`` once every runner it watches has answered all it was sent
    (:meth:`PtyRunner.settle`). Reply deadlines on this clock (a test sets
    ``ServoBus.reply_clock`` to it) count the emulated device's time, not the time the test
    machine's load kept an emulator from running; silence and late replies still fail. Whoever
    starts the runners owns one and tells it which (:meth:`watch`)."""

    def __init__(self) -> None:
        self._runners: weakref.WeakSet[PtyRunner] = weakref.WeakSet()

    def watch(self, runner: R) -> R:
        """Wait for ``runner`` at each reading from now on (once stopped, it is idle); returns
        it (``with clock.watch(Emulator(...)) as emu:``)."""
        self._runners.add(runner)
        return runner

    def __call__(self) -> float:
        for runner in list(self._runners):
            runner.settle()
        return time.perf_counter()


class PtyRunner:
    """A pty plus a reader calling ``self._on_bytes``, in a thread or (``process=True``) in a
    forked process, like a separate device; a process sends its state back at :meth:`stop`."""

    _state: tuple[str, ...] = ()  # attributes a process sends back

    def __init__(self, process: bool = False) -> None:
        self.process = process
        self._master: int | None = None
        self._slave: int | None = None
        self._done_r: int | None = None
        self._done_w: int | None = None
        self._thread: threading.Thread | None = None
        self._proc = None
        self._conn = None
        self._stop = threading.Event()
        self.port = ""
        self.error: BaseException | None = None
        self._scheduled: list[tuple[float, bytes]] = []  # (monotonic time, bytes) to send
        # 1 from the moment the reader takes bytes until it has answered them (shared memory)
        self._busy = multiprocessing.get_context("fork").RawValue("b", 0)

    def start(self):
        master, slave = os.openpty()
        tty.setraw(slave)
        self._master, self._slave = master, slave
        self._done_r, self._done_w = os.pipe()  # a byte each time the reader is done (settle)
        os.set_blocking(self._done_r, False)
        os.set_blocking(self._done_w, False)
        self.port = os.ttyname(slave)
        if self.process:
            ctx = multiprocessing.get_context("fork")
            self._stop = ctx.Event()
            self._conn, child = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=self._child, args=(child,), daemon=True)
            self._proc.start()
        else:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._run, name=type(self).__name__, daemon=True)
            self._thread.start()
        return self

    def _child(self, conn) -> None:
        self._run()
        conn.send({name: getattr(self, name) for name in (*self._state, "error")})
        conn.close()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._proc is not None:
            if self._conn.poll(5.0):
                self.__dict__.update(self._conn.recv())
            self._proc.join(timeout=2.0)
            if self._proc.is_alive():
                self._proc.kill()
            self._proc = None
        for fd in (self._master, self._slave, self._done_r, self._done_w):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = self._done_r = self._done_w = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def idle(self) -> bool:
        """The emulator has answered every byte the host sent it, or has stopped (the
        ``select`` also moves bytes the kernel still holds into the pty's buffer)."""
        master = self._master
        if master is None or not self.running():
            return True
        try:
            pending = select.select([master], [], [], 0)[0]
        except (OSError, ValueError):
            return True
        return not pending and not self._busy.value

    def running(self) -> bool:
        """The reader (thread or process) is alive."""
        if self._proc is not None:
            return self._proc.is_alive()
        return self._thread is not None and self._thread.is_alive()

    def settle(self, limit_s: float = 5.0) -> None:
        """Wait until :meth:`idle` (up to ``limit_s``), then move the replies the kernel still
        holds to the host's side of the pty."""
        give_up = time.perf_counter() + limit_s
        while not self.idle() and (left := give_up - time.perf_counter()) > 0:
            select.select([self._done_r], [], [], min(left, 1e-3))  # woken when it is done
            try:
                os.read(self._done_r, 4096)
            except OSError:
                pass
        if (slave := self._slave) is not None:
            try:
                select.select([slave], [], [], 0)
            except (OSError, ValueError):
                pass

    def _host_speed(self) -> int:
        return termios.tcgetattr(self._master)[4]

    def _send(self, data: bytes) -> None:
        if data and self._master is not None:
            os.write(self._master, data)

    def _run(self) -> None:
        try:
            while True:  # after stop(), drain what the host already wrote, then exit
                stopping = self._stop.is_set()
                wait = 0.0 if stopping else 0.05
                if self._scheduled:
                    wait = min(wait, max(0.0, self._scheduled[0][0] - time.monotonic()))
                ready, _, _ = select.select([self._master], [], [], wait)
                self._send_due()
                if not ready:
                    if stopping:
                        break
                    continue
                self._busy.value = 1
                try:
                    chunk = os.read(self._master, 4096)
                except OSError:
                    self._busy.value = 0
                    continue
                self._on_bytes(chunk, time.monotonic())
                self._busy.value = 0
                try:
                    os.write(self._done_w, b"\0")
                except OSError:  # full: the host has not looked yet, it sees busy == 0
                    pass
        except BaseException as exc:  # surfaced to tests through .error
            self.error = exc

    def _on_bytes(self, chunk: bytes, now: float) -> None:
        raise NotImplementedError

    def _schedule(self, at: float, data: bytes) -> None:
        """Send ``data`` at time ``at`` (monotonic) without blocking other replies."""
        self._scheduled.append((at, data))
        self._scheduled.sort(key=lambda x: x[0])

    def _send_due(self) -> None:
        now = time.monotonic()
        while self._scheduled and self._scheduled[0][0] <= now:
            self._send(self._scheduled.pop(0)[1])


def sleep_until(deadline: float, spin_s: float = 0.0) -> None:
    """Wait until ``deadline`` (``time.monotonic``, the emulators' clock): sleep, then spin the
    last ``spin_s`` (sleep alone overshoots by ~0.1 ms)."""
    delay = deadline - time.monotonic() - spin_s
    if delay > 0:
        time.sleep(delay)
    while time.monotonic() < deadline:
        pass
