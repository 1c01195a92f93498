"""Velocity command sequences: the ``--commands FILE`` of ``wbc drive`` and the benchmark's.

A commands file is TOML with one ``[[command]]`` table per segment, played in order::

    [[command]]
    duration = 3.0   # s, > 0
    vx = 0.06        # m/s forward (default 0)
    vy = 0.0         # m/s to the left (default 0)
    wz = 0.0         # rad/s counter-clockwise (default 0)

The walk starts with the first command and stops (a closing step) after the last.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import ConfigurationError
from ..paths import read_toml

KEYS = ("duration", "vx", "vy", "wz")


@dataclass(frozen=True)
class Command:
    """One segment: ``duration`` s at ``(vx, vy, wz)`` (m/s, m/s, rad/s)."""

    duration: float
    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0

    @property
    def velocity(self) -> tuple[float, float, float]:
        return (self.vx, self.vy, self.wz)


def parse_commands(data: object, where: str) -> list[Command]:
    """Commands from the parsed TOML ``data`` (``where`` names it in errors)."""
    if not isinstance(data, dict):
        raise ConfigurationError(f"{where}: expected [[command]] tables")
    extra = sorted(set(data) - {"command"})
    if extra:
        raise ConfigurationError(f"{where}: unknown keys {extra}; allowed: [[command]] tables")
    tables = data.get("command")
    if not isinstance(tables, list) or not tables:
        raise ConfigurationError(f"{where}: no [[command]] tables (duration, vx, vy, wz)")
    out = []
    for k, table in enumerate(tables, start=1):
        if not isinstance(table, dict):
            raise ConfigurationError(f"{where}: command {k} must be a table")
        bad = sorted(set(table) - set(KEYS))
        if bad:
            raise ConfigurationError(
                f"{where}: command {k} has unknown keys {bad}; allowed: {', '.join(KEYS)}"
            )
        if "duration" not in table:
            raise ConfigurationError(f"{where}: command {k} needs a duration (s)")
        vals = {}
        for key in KEYS:
            v = table.get(key, 0.0)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ConfigurationError(
                    f"{where}: command {k} {key} = {v!r}: must be a finite number"
                )
            vals[key] = float(v)
        if vals["duration"] <= 0:
            raise ConfigurationError(
                f"{where}: command {k} duration = {vals['duration']}: must be > 0 s"
            )
        out.append(Command(**vals))
    return out


def load_commands(path: str | Path) -> list[Command]:
    """Read and check a commands file (one-line :class:`ConfigurationError` otherwise)."""
    data = read_toml(Path(path), "commands file", ConfigurationError)
    return parse_commands(data, f"commands file {path}")


class CommandScript:
    """The command in force at time ``t`` (s from the walk's start; None after the last)."""

    def __init__(self, commands: Sequence[Command]) -> None:
        self.commands = list(commands)
        self.ends = np.cumsum([c.duration for c in self.commands])

    @property
    def duration(self) -> float:
        return float(self.ends[-1]) if len(self.ends) else 0.0

    def at(self, t: float) -> Command | None:
        i = int(np.searchsorted(self.ends, t + 1e-12, side="right"))
        return self.commands[i] if i < len(self.commands) else None


def integrate(
    commands: Sequence[Command | tuple[float, float, float, float]], dt: float = 0.001
) -> tuple[np.ndarray, float]:
    """The displacement ``(x, y)`` (m, start frame) and heading change (rad) of a body
    following the commands exactly: ``ṗ = R(θ) (vx, vy)``, ``θ̇ = ωz`` (closed form per
    segment where ``ωz ≠ 0``: the arc; ``dt`` unused, kept for callers)."""
    p = np.zeros(2)
    th = 0.0
    for c in commands:
        T, vx, vy, wz = (c.duration, c.vx, c.vy, c.wz) if isinstance(c, Command) else c
        if abs(wz) < 1e-12:
            p += T * np.array(
                [math.cos(th) * vx - math.sin(th) * vy, math.sin(th) * vx + math.cos(th) * vy]
            )
        else:  # ∫ R(θ + ωz s) v ds
            a, b = th, th + wz * T
            ix = (math.sin(b) - math.sin(a)) / wz  # ∫ cos
            iy = (math.cos(a) - math.cos(b)) / wz  # ∫ sin
            p += np.array([ix * vx - iy * vy, iy * vx + ix * vy])
        th += wz * T
    return p, th


def walked(
    commands: Sequence[Command | tuple[float, float, float, float]],
) -> tuple[float, float]:
    """The path length (m) and the turn (rad, summed unsigned) of a body following the
    commands exactly: ``Σ T·|(vx, vy)|`` and ``Σ T·|ωz|`` — what a run walks on the way to
    its net displacement and heading (:func:`integrate`)."""
    path = turn = 0.0
    for c in commands:
        T, vx, vy, wz = (c.duration, c.vx, c.vy, c.wz) if isinstance(c, Command) else c
        path += T * math.hypot(vx, vy)
        turn += T * abs(wz)
    return path, turn


def random_commands(
    rng: np.random.Generator,
    limits: tuple[float, float, float, float],
    duration: float = 30.0,
    change: tuple[float, float] = (2.0, 5.0),
    share: float = 1.0,
) -> list[Command]:
    """A random sequence of ``duration`` s: a new command every ``change`` s (uniform), each
    inside ``share`` × the velocity envelope ``limits = (vx_forward, vx_backward, vy, wz)``
    (a direction drawn uniformly on the diamond's surface, a magnitude uniformly in it)."""
    out: list[Command] = []
    t = 0.0
    fwd, back, vy_m, wz_m = limits
    while t < duration - 1e-9:
        T = min(float(rng.uniform(*change)), duration - t)
        w = rng.exponential(size=3)
        w = w / w.sum() * rng.uniform(0.0, 1.0) * share
        signs = rng.choice([-1.0, 1.0], size=3)
        vx = signs[0] * w[0] * (fwd if signs[0] > 0 else back)
        out.append(
            Command(T, float(vx), float(signs[1] * w[1] * vy_m), float(signs[2] * w[2] * wz_m))
        )
        t += T
    return out
