"""One owner per bus: an exclusive OS lock on a serial port, taken before a byte is written.

Every bus backend opens its port through :func:`open_locked` (Dynamixel Protocol 1.0, SSC-32,
the Protocol 2.0 bus, the torso IMU), and so does every ``wbc`` command; the pty emulators'
ports are locked the same way (the lock is keyed by the device path, a pty slave included).
Three layers, each enough against another ``wbc``:

1. ``flock`` on a lock file keyed by the *resolved* device path (``/dev/serial/by-id/...``
   and ``/dev/ttyUSB0`` name the same lock) in ``/run/lock`` (else ``/var/lock``, else the
   temporary directory), holding ``PID command line`` of the owner, so a refused program
   names who holds the bus;
2. ``flock`` on the device node itself (what pyserial's ``exclusive=True`` does), which
   every process sees whatever its lock directory;
3. ``TIOCEXCL`` on the open terminal: further ``open()`` of the device fail with ``EBUSY``
   for programs that do not know about locks (root excepted), cleared on release.

A killed process (even ``kill -9``) loses its locks with its file descriptors: the kernel
releases them, no stale lock is left (the lock file stays, empty of meaning).
"""

from __future__ import annotations

import errno
import fcntl
import os
import sys
import tempfile
import termios
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from ..exceptions import ServoError

_LOCK_DIRS = ("/run/lock", "/var/lock")
T = TypeVar("T")


def lock_dir() -> Path:
    """The first writable one of ``/run/lock``, ``/var/lock``, the temporary directory."""
    for d in _LOCK_DIRS:
        if os.path.isdir(d) and os.access(d, os.W_OK | os.X_OK):
            return Path(d)
    return Path(tempfile.gettempdir())


def lock_path(port: str) -> Path:
    """The lock file of a port: ``wbc-<resolved device path with / as _>.lock``."""
    real = os.path.realpath(port)
    return lock_dir() / ("wbc-" + real.strip("/").replace("/", "_") + ".lock")


def _holder(path: Path) -> str:
    """'PID 1234 (wbc deploy walk.npz --port ...)' from a lock file, or a fallback."""
    try:
        text = path.read_text().strip()
    except OSError:
        text = ""
    pid, _, cmd = text.partition(" ")
    if pid.isdigit():
        return f"PID {pid} ({cmd})" if cmd else f"PID {pid}"
    return "another program"


def _command_line() -> str:
    try:
        raw = Path("/proc/self/cmdline").read_bytes()
        args = [a.decode(errors="replace") for a in raw.split(b"\0") if a]
    except OSError:
        args = list(sys.argv)
    if len(args) >= 2 and Path(args[0]).name.startswith("python") and args[1] == "-m":
        args = args[2:]
    if args and Path(args[0]).name.startswith("python"):
        args = args[1:]
    if args:
        args[0] = Path(args[0]).name
        if args[0] in ("wbc.cli", "cli.py", "__main__.py"):
            args[0] = "wbc"
    return " ".join(args)[:200]


class PortLock:
    """The exclusive lock of one serial port (module docstring); :meth:`release` frees it."""

    def __init__(self, port: str) -> None:
        self.port = port
        self.path = lock_path(port)
        self._fd: int | None = None
        self._device_fd: int | None = None

    @classmethod
    def acquire(cls, port: str) -> PortLock:
        """Take the lock file's lock; :class:`ServoError` naming the holder if it is taken."""
        lock = cls(port)
        try:
            fd = os.open(lock.path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise ServoError(f"cannot create the lock file {lock.path} of {port}: {exc}") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ServoError(f"cannot lock {lock.path}: {exc}") from exc
            raise ServoError(
                f"port {port} is in use by {_holder(lock.path)}: one program per bus; "
                "stop it first (lock " + str(lock.path) + ")"
            ) from None
        try:
            os.fchmod(fd, 0o666)
        except OSError:
            pass  # another user's file: the lock is ours all the same
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()} {_command_line()}\n".encode())
        lock._fd = fd
        return lock

    def attach(self, device_fd: int) -> None:
        """Lock the open device too: ``flock`` on its node and ``TIOCEXCL`` (a terminal)."""
        try:
            fcntl.flock(device_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ServoError(
                    f"port {self.port} is locked by another program (flock on the device): "
                    "one program per bus; stop it first"
                ) from None
        try:
            fcntl.ioctl(device_fd, termios.TIOCEXCL)
        except OSError:
            pass  # not a terminal: the flocks remain
        self._device_fd = device_fd

    def release(self) -> None:
        """Clear ``TIOCEXCL`` and free both locks (safe to call twice). Call it before the
        device is closed (``TIOCEXCL`` stays while any other descriptor holds the tty)."""
        fd, self._device_fd = self._device_fd, None
        if fd is not None:
            try:
                fcntl.ioctl(fd, termios.TIOCNXCL)
            except OSError:
                pass
            try:
                fcntl.flock(fd, fcntl.LOCK_UN)
            except OSError:
                pass
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                os.ftruncate(fd, 0)
                fcntl.flock(fd, fcntl.LOCK_UN)
            finally:
                os.close(fd)

    @property
    def held(self) -> bool:
        return self._fd is not None


def open_locked(
    port: str,
    opener: Callable[[], T],
    fileno: Callable[[T], int],
    close: Callable[[T], None],
) -> tuple[T, PortLock]:
    """Open ``port`` as its one owner: take its lock (:meth:`PortLock.acquire`, refused with
    :class:`ServoError` naming the holder, before a byte is sent), open the device
    (``opener()``, whose exceptions pass through), then lock the open device too
    (:meth:`PortLock.attach` on ``fileno(device)``). Returns ``(device, lock)``; on any failure
    nothing stays locked or open (the lock is released before the device is ``close``d)."""
    lock = PortLock.acquire(port)
    try:
        device = opener()
    except BaseException:
        lock.release()
        raise
    try:
        lock.attach(fileno(device))
    except BaseException:
        lock.release()
        close(device)
        raise
    return device, lock
