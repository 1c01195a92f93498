"""Steering from a terminal keyboard or a gamepad, polled once per control tick.

:class:`Keyboard` reads single keys from the terminal (termios cbreak mode, ``select`` with
no wait: no display server, no thread)::

    w / s   faster forward / backward        a / d   faster left / right
    q / e   turn left / right faster         space   zero the command (walk on the spot)
    g       start walking                    h       stop (closing step, stand)
    x, Esc  end the run (the deployment's safe end)

:class:`Gamepad` reads a Linux joystick through ``evdev`` (``pip install 'wbc[gamepad]'``;
maintained, no display server): the left stick gives ``vx``/``vy``, the right stick's x
``ωz``, as shares of the velocity limits; South (A) starts, East (B) stops, Select/Back
ends. Both are objects with ``poll(walker) -> bool`` (False: end the run).
"""

from __future__ import annotations

import select
import sys
from typing import Any

from ..exceptions import ConfigurationError

STEP = 0.25  # share of a limit per key press
KEYS = "w/s forward/back, a/d left/right, q/e turn, space zero, g start, h stop, x quit"


class Keyboard:
    """Terminal keys → velocity commands (module docstring). ``stream``: a terminal."""

    def __init__(self, stream: Any = None, out: Any = None) -> None:
        self.stream = stream or sys.stdin
        self.out = out or sys.stdout
        self.share = [0.0, 0.0, 0.0]
        self._saved = None

    def open(self) -> None:
        import termios
        import tty

        if not self.stream.isatty():
            raise ConfigurationError("--keyboard needs a terminal on stdin (or give --commands)")
        fd = self.stream.fileno()
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        print(f"keys: {KEYS}", file=self.out, flush=True)

    def close(self) -> None:
        if self._saved is not None:
            import termios

            termios.tcsetattr(self.stream.fileno(), termios.TCSADRAIN, self._saved)
            self._saved = None

    def keys(self) -> str:
        """The keys pressed since the last poll (no wait)."""
        out = ""
        while select.select([self.stream], [], [], 0.0)[0]:
            ch = self.stream.read(1)
            if not ch:
                break
            out += ch
        return out

    def apply(self, keys: str, walker: Any) -> bool:
        """Apply ``keys`` to ``walker``; False to end the run."""
        moves = {"w": (0, 1), "s": (0, -1), "a": (1, 1), "d": (1, -1), "q": (2, 1), "e": (2, -1)}
        changed = False
        for ch in keys.lower():
            if ch in ("x", "\x1b"):
                walker.stop()
                return False
            if ch in moves:
                axis, sign = moves[ch]
                self.share[axis] = max(-1.0, min(1.0, self.share[axis] + sign * STEP))
                changed = True
            elif ch == " ":
                self.share = [0.0, 0.0, 0.0]
                changed = True
            elif ch == "g":
                walker.start()
            elif ch == "h":
                self.share = [0.0, 0.0, 0.0]
                changed = True
                walker.stop()
        if changed:
            cmd = walker.command(*shares_to_velocity(self.share, walker.limits))
            print(f"command vx {cmd[0]:+.3f} m/s, vy {cmd[1]:+.3f} m/s, wz {cmd[2]:+.2f} rad/s",
                  file=self.out, flush=True)  # fmt: skip
        return True

    def poll(self, walker: Any) -> bool:
        return self.apply(self.keys(), walker)


def shares_to_velocity(share: list[float], limits: Any) -> tuple[float, float, float]:
    """Shares (−1..1) of each axis's limit → a command (forward / backward limits apart)."""
    vx = share[0] * (limits.vx_forward if share[0] >= 0 else limits.vx_backward)
    return vx, share[1] * limits.vy, share[2] * limits.wz


class Gamepad:
    """A Linux gamepad through evdev (module docstring). ``path``: its ``/dev/input/event*``
    (None: the first device with analogue sticks)."""

    DEADZONE = 0.1

    def __init__(self, path: str | None = None) -> None:
        self.path = path
        self.device: Any = None
        self.axes: dict[int, float] = {}
        self._ranges: dict[int, tuple[int, int]] = {}

    @staticmethod
    def available() -> str | None:
        """None if evdev imports, else the one line saying what is missing."""
        try:
            import evdev  # noqa: F401
        except ImportError:
            return "gamepad: evdev is not installed (pip install 'wbc[gamepad]'); skipped"
        return None

    def open(self) -> None:
        import evdev

        ecodes = evdev.ecodes
        paths = [self.path] if self.path else evdev.list_devices()
        for p in paths:
            try:
                dev = evdev.InputDevice(p)
            except OSError as exc:
                if self.path:
                    raise ConfigurationError(f"--gamepad {p}: {exc}") from None
                continue
            caps = dev.capabilities(absinfo=True).get(ecodes.EV_ABS, [])
            ranges = {code: (info.min, info.max) for code, info in caps}
            if ecodes.ABS_X in ranges and ecodes.ABS_Y in ranges:
                self.device, self._ranges = dev, ranges
                return
        raise ConfigurationError("--gamepad: no joystick with analogue sticks found")

    def close(self) -> None:
        if self.device is not None:
            self.device.close()
            self.device = None

    def _value(self, code: int) -> float:
        lo, hi = self._ranges.get(code, (-1, 1))
        raw = self.axes.get(code)
        if raw is None or hi <= lo:
            return 0.0
        v = 2.0 * (raw - lo) / (hi - lo) - 1.0
        return 0.0 if abs(v) < self.DEADZONE else max(-1.0, min(1.0, v))

    def poll(self, walker: Any) -> bool:
        from evdev import ecodes

        try:
            events = list(self.device.read())
        except BlockingIOError:
            events = []
        for ev in events:
            if ev.type == ecodes.EV_ABS:
                self.axes[ev.code] = ev.value
            elif ev.type == ecodes.EV_KEY and ev.value == 1:
                if ev.code == ecodes.BTN_SOUTH:
                    walker.start()
                elif ev.code == ecodes.BTN_EAST:
                    walker.stop()
                elif ev.code == ecodes.BTN_SELECT:
                    walker.stop()
                    return False
        share = [
            -self._value(ecodes.ABS_Y),
            -self._value(ecodes.ABS_X),
            -self._value(ecodes.ABS_RX),
        ]
        walker.command(*shares_to_velocity(share, walker.limits))
        return True
