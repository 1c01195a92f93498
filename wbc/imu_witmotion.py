"""A real IMU for the PC-driven Bioloid: WitMotion WT901 / HWT901B family over a serial port.

Why this one: a WT901-class module (WT901C-TTL/-232, WT901B, HWT901B, the USB WT901SDCL) costs
about as much as two AX-12As, has its own attitude filter, plugs into the PC through a USB
serial adapter (or its own USB), and streams one documented, unified serial protocol that all
WitMotion IMUs share — no vendor library needed (pyserial only, already a dependency of the
servo layer). The BNO055 needs an I²C/UART bridge board and its UART mode is a request/reply
register protocol (a round trip per sample); the WitMotion modules push samples at up to
200 Hz.

**Protocol** (WitMotion "standard protocol", little endian): 11-byte packets
``0x55 TYPE d0..d7 SUM`` with ``SUM = (0x55 + TYPE + d0 + … + d7) & 0xFF`` and four signed
16-bit values ``v0..v3`` in ``d``:

==== ============================== ======================================
TYPE content                         scale
==== ============================== ======================================
0x51 acceleration x, y, z; temp      v/32768 · 16 g;  temp v3/100 °C
0x52 angular velocity x, y, z        v/32768 · 2000 °/s
0x53 angle roll, pitch, yaw          v/32768 · 180 °  (R = Rz(yaw) Ry(pitch) Rx(roll))
0x59 quaternion q0 (w), q1, q2, q3   v/32768
==== ============================== ======================================

Other packet types (time, magnetometer, pressure, …) are skipped. Configuration commands are
``0xFF 0xAA REG LOW HIGH``: unlock ``0x69 0x88 0xB5``, output rate register ``0x03``
(``0x09`` = 100 Hz, ``0x0B`` = 200 Hz), save ``0x00 0x00 0x00``; :class:`WitImu` sends them
only when a ``rate`` is asked for.

**Frames**: readings are in the module's own axes (printed on its case); ``mount`` (an
:class:`~wbc.imu.ImuMount`, or the 3x3 rotation of the module's frame in the torso frame) is
its :attr:`~wbc.imu.Imu.mount`, which the closed loop applies (default: the torso frame). The
accelerometer reads +1 g upward at rest, which is the specific force of :mod:`wbc.imu`.

:class:`WitImu` reads without blocking: every :meth:`~WitImu.read` drains the port, parses the
complete packets (resynchronising on ``0x55`` after a bad checksum) and returns the latest
values; no complete sample for ``stale_s`` seconds raises :class:`~wbc.imu.ImuError` (inside
``wbc deploy`` that is a safe stop). :class:`WitEmulator` streams packets on a pseudo-terminal
for the tests (``wbc.servos.emulator`` does the same for the servos).
"""

from __future__ import annotations

import math
import os
import struct
import threading
import time
import tty
from collections.abc import Callable

import numpy as np

from .exceptions import ConfigurationError
from .imu import GRAVITY, Imu, ImuError, ImuMount, ImuReading

HEADER = 0x55
ACC, GYRO, ANGLE, QUAT = 0x51, 0x52, 0x53, 0x59
ACC_SCALE = 16.0 * GRAVITY / 32768.0  # m/s² per unit
GYRO_SCALE = math.radians(2000.0) / 32768.0  # rad/s per unit
ANGLE_SCALE = math.pi / 32768.0  # rad per unit
RATE_CODES = {10: 0x06, 20: 0x07, 50: 0x08, 100: 0x09, 200: 0x0B}
BAUD_RATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)


def checksum(body: bytes) -> int:
    return sum(body) & 0xFF


def packet(kind: int, values: tuple[int, int, int, int]) -> bytes:
    """One 11-byte packet of four int16 values (clipped to the int16 range)."""
    v = [int(max(-32768, min(32767, round(x)))) for x in values]
    body = bytes([HEADER, kind]) + struct.pack("<4h", *v)
    return body + bytes([checksum(body)])


def command(register: int, value: int) -> bytes:
    """A configuration command ``FF AA REG LOW HIGH``."""
    return bytes([0xFF, 0xAA, register & 0xFF, value & 0xFF, (value >> 8) & 0xFF])


def encode_sample(quat_xyzw: np.ndarray, gyro: np.ndarray, acc: np.ndarray) -> bytes:
    """The four packets a WT901 sends for one sample (acceleration, rate, angles, quaternion)."""
    x, y, z, w = np.asarray(quat_xyzw, dtype=float) / np.linalg.norm(quat_xyzw)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    a = np.asarray(acc, dtype=float) / ACC_SCALE
    g = np.asarray(gyro, dtype=float) / GYRO_SCALE
    return (
        packet(ACC, (a[0], a[1], a[2], 2500))
        + packet(GYRO, (g[0], g[1], g[2], 0))
        + packet(ANGLE, (roll / ANGLE_SCALE, pitch / ANGLE_SCALE, yaw / ANGLE_SCALE, 0))
        + packet(QUAT, (w * 32768, x * 32768, y * 32768, z * 32768))
    )


def _rpy_quat(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """(x, y, z, w) of Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    ])  # fmt: skip


class WitParser:
    """Incremental parser of the byte stream (keeps a partial packet between calls)."""

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.acc: np.ndarray | None = None
        self.gyro: np.ndarray | None = None
        self.quat: np.ndarray | None = None  # x, y, z, w
        self.angle_quat: np.ndarray | None = None
        self.packets = 0
        self.bad = 0  # bad checksums
        self.skipped = 0  # bytes dropped while resynchronising

    def feed(self, data: bytes) -> int:
        """Parse ``data``; returns the number of good packets in it."""
        buf = self.buffer
        buf += data
        good = 0
        while True:
            start = buf.find(HEADER)
            if start < 0:
                self.skipped += len(buf)
                buf.clear()
                break
            if start:
                self.skipped += start
                del buf[:start]
            if len(buf) < 11:
                break
            if checksum(buf[:10]) != buf[10]:
                self.bad += 1
                del buf[:1]
                continue
            kind = buf[1]
            v = struct.unpack_from("<4h", buf, 2)
            del buf[:11]
            good += 1
            self.packets += 1
            if kind == ACC:
                self.acc = np.array(v[:3], dtype=float) * ACC_SCALE
            elif kind == GYRO:
                self.gyro = np.array(v[:3], dtype=float) * GYRO_SCALE
            elif kind == ANGLE:
                self.angle_quat = _rpy_quat(*(np.array(v[:3], dtype=float) * ANGLE_SCALE))
            elif kind == QUAT:
                q = np.array([v[1], v[2], v[3], v[0]], dtype=float) / 32768.0
                n = float(np.linalg.norm(q))
                if n > 0.5:  # an all-zero quaternion: the module does not send one
                    self.quat = q / n
        return good

    def orientation(self) -> np.ndarray | None:
        return self.quat if self.quat is not None else self.angle_quat


class WitImu(Imu):
    """A WitMotion WT901-family IMU on a serial port (module docstring).

    ``port`` e.g. ``/dev/ttyUSB1``; ``baud`` the module's (115200 for the HWT901B and the
    USB modules, 9600 for a factory WT901C-TTL); ``rate`` (Hz, one of 10, 20, 50, 100,
    200) is written to the module at :meth:`open` when given; ``mount`` the module's frame in
    the torso frame; ``stale_s``: no complete sample for this long is an error.
    """

    name = "witmotion"

    def __init__(
        self,
        port: str,
        baud: int = 115200,
        rate: int | None = None,
        mount: np.ndarray | ImuMount | None = None,
        stale_s: float = 0.1,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not port:
            raise ImuError("--imu: give the IMU's serial port, e.g. /dev/ttyUSB1")
        if baud not in BAUD_RATES:
            raise ImuError(f"--imu-baud {baud}: a WitMotion IMU runs at one of {BAUD_RATES}")
        if rate is not None and rate not in RATE_CODES:
            raise ImuError(f"IMU rate {rate} Hz: choose one of {sorted(RATE_CODES)}")
        if not (math.isfinite(stale_s) and stale_s > 0):
            raise ImuError(f"IMU stale_s must be > 0 s, got {stale_s}")
        if mount is not None and not isinstance(mount, ImuMount):
            try:
                mount = ImuMount(np.asarray(mount, dtype=float))
            except ConfigurationError as exc:
                raise ImuError(f"IMU mount must be a 3x3 rotation matrix: {exc}") from None
        self.mount = mount
        self.port, self.baud, self.rate, self.stale_s = port, baud, rate, stale_s
        self.clock = clock
        self.parser = WitParser()
        self.serial = None
        self._last_t: float | None = None

    def open(self) -> None:
        import serial

        from .exceptions import ServoError
        from .servos.portlock import open_locked

        def opener():
            try:
                return serial.Serial(self.port, self.baud, timeout=0)
            except (serial.SerialException, OSError) as exc:
                raise ImuError(f"--imu {self.port}: cannot open the port ({exc})") from None

        try:  # one owner per port, like a servo bus (wbc.servos.portlock)
            self.serial, self._lock = open_locked(
                self.port, opener, lambda s: s.fileno(), lambda s: s.close()
            )
        except ServoError as exc:  # the port's lock: held by another program
            raise ImuError(f"--imu {self.port}: {exc}") from None
        if self.rate is not None:
            for cmd in (command(0x69, 0xB588), command(0x03, RATE_CODES[self.rate]),
                        command(0x00, 0x0000)):  # fmt: skip
                self.serial.write(cmd)
                time.sleep(0.01)
        self._last_t = self.clock()

    def _release(self) -> None:
        lock, self._lock = getattr(self, "_lock", None), None
        if lock is not None:
            lock.release()
        if self.serial is not None:
            self.serial.close()
            self.serial = None

    def close(self) -> None:
        self._release()

    def poll(self) -> int:
        """Drain the port into the parser; the number of good packets read."""
        if self.serial is None:
            raise ImuError(f"imu {self.port}: not open")
        good = 0
        try:
            waiting = self.serial.in_waiting
            if waiting:
                good = self.parser.feed(self.serial.read(waiting))
        except OSError as exc:
            raise ImuError(f"imu {self.port}: read failed ({exc})") from None
        if good:
            self._last_t = self.clock()
        return good

    def read(self) -> ImuReading:
        self.poll()
        p = self.parser
        now = self.clock()
        quat = p.orientation()
        if p.acc is None or p.gyro is None or quat is None:
            if now - (self._last_t or now) > self.stale_s or p.bad > 10:
                raise ImuError(
                    f"imu {self.port}: no complete WitMotion sample (acceleration, rate, "
                    f"angle) at {self.baud} baud ({p.packets} good packets, {p.bad} bad "
                    "checksums): wrong port or baud rate?"
                )
            raise ImuError(f"imu {self.port}: no sample yet (call read() again shortly)")
        if now - (self._last_t or now) > self.stale_s:
            raise ImuError(f"imu {self.port}: no data for {now - self._last_t:.3f} s")
        return ImuReading(now, quat, p.gyro, p.acc)

    def wait_ready(self, timeout: float = 1.0) -> None:
        """Block until a complete sample has arrived (or raise after ``timeout`` s)."""
        end = time.monotonic() + timeout
        while True:
            self.poll()
            p = self.parser
            if p.acc is not None and p.gyro is not None and p.orientation() is not None:
                return
            if time.monotonic() > end:
                raise ImuError(
                    f"imu {self.port}: no complete WitMotion sample within {timeout:g} s at "
                    f"{self.baud} baud ({p.packets} good packets, {p.bad} bad checksums)"
                )
            time.sleep(0.002)


class WitEmulator:
    """A WitMotion IMU on a pseudo-terminal: ``port`` is the slave end to open.

    ``sample()`` returns (quaternion x, y, z, w; gyro rad/s; specific force m/s²) each
    period; :meth:`send_raw` writes arbitrary bytes (garbage, bad checksums) for tests.
    Commands written by the host are recorded in :attr:`received`.
    """

    def __init__(
        self,
        sample: Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
        rate: float = 200.0,
    ) -> None:
        self.sample = sample or (
            lambda: (np.array([0, 0, 0, 1.0]), np.zeros(3), np.array([0, 0, GRAVITY]))
        )
        self.rate = rate
        self.received = bytearray()
        self.sent = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(self.master, False)  # a host that does not read: samples are dropped
        self.port = os.ttyname(slave)
        self._slave = slave
        self.paused = False

    def start(self) -> WitEmulator:
        self._thread = threading.Thread(target=self._run, name="WitEmulator", daemon=True)
        self._thread.start()
        return self

    def _run(self) -> None:
        import select

        period = 1.0 / self.rate
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], period)
            if ready:
                try:
                    self.received += os.read(self.master, 256)
                except BlockingIOError:
                    pass
                except OSError:
                    return
            if not self.paused:
                self.send_raw(encode_sample(*self.sample()))
                self.sent += 1

    def send_raw(self, data: bytes) -> None:
        try:
            os.write(self.master, data)
        except OSError:
            pass

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> WitEmulator:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
