"""``wbc deploy --plan``: the bus budget of a tick, the health schedule and the fault bound.

A tick is one SYNC_WRITE of all goals plus the health checks of :class:`HealthSchedule`
(write-only) or one position READ per servo (``--read``). The bus is *overloaded* when a
tick's bus time exceeds ``LOAD_LIMIT`` (80 %) of the period: replies then push ticks late
and the loop skips ticks. The plan says so and proposes the highest whole rate that fits.
"""

from __future__ import annotations

import math

from .bus import BusBudget, ServoBus
from .config import MAX_RATE_HZ, DeployConfig
from .safety import HealthSchedule

LOAD_LIMIT = 0.8


def schedule(bus: ServoBus, config: DeployConfig, rate: float | None = None) -> HealthSchedule:
    """The health schedule of a deployment at ``rate`` (default: the configured rate)."""
    return HealthSchedule(
        bus.n,
        config.rate if rate is None else rate,
        config.max_failures,
        config.fault_bound_s,
        bus.health_per_servo,
    )


def tick_budget(
    bus: ServoBus, config: DeployConfig, read: bool, rate: float | None = None
) -> BusBudget:
    """Bus time of one tick at ``rate`` (the number of health polls depends on the rate)."""
    polls = 0 if read else schedule(bus, config, rate).polls_per_tick
    return bus.tick_budget(read, polls)


def load(bus: ServoBus, config: DeployConfig, read: bool, rate: float, turnaround_s: float):
    """Fraction of the tick the bus is busy."""
    return tick_budget(bus, config, read, rate).tick_time(turnaround_s) * rate


def proposed_rate(
    bus: ServoBus, config: DeployConfig, read: bool, turnaround_s: float
) -> float | None:
    """The whole rate (Hz) nearest below the configured one whose tick fits in ``LOAD_LIMIT``
    of the period, else the nearest above (<= 100 Hz; fewer health polls are needed at
    higher rates), else None."""
    below = range(math.floor(config.rate), 0, -1)
    above = range(math.floor(config.rate) + 1, int(MAX_RATE_HZ) + 1)
    for r in (*below, *above):
        if load(bus, config, read, float(r), turnaround_s) <= LOAD_LIMIT:
            return float(r)
    return None


def overload_warning(bus: ServoBus, config: DeployConfig, turnaround_s: float) -> str | None:
    """A warning (with a proposed rate) if the configured rate overloads the bus."""
    try:
        b = tick_budget(bus, config, config.read)
    except NotImplementedError:
        return None
    if not b.items:
        return None
    u = b.tick_time(turnaround_s) * config.rate
    if u <= LOAD_LIMIT:
        return None
    r = proposed_rate(bus, config, config.read, turnaround_s)
    fix = f"use --rate {r:g} or lower" if r else "no rate fits"
    return (
        f"the {b.name} tick needs {b.tick_time(turnaround_s) * 1e3:.2f} ms of bus time "
        f"({turnaround_s * 1e3:g} ms turnaround per reply): {u * 100:.0f} % of a "
        f"{1e3 / config.rate:.2f} ms tick at {config.rate:g} Hz overloads the bus (limit "
        f"{LOAD_LIMIT * 100:.0f} %): ticks will run late and be skipped; {fix}"
    )


def budget_line(bus: ServoBus, config: DeployConfig, turnaround_s: float) -> str:
    """One line: the tick's bus time and load at the configured rate (``--plan`` in short)."""
    try:
        b = tick_budget(bus, config, config.read)
    except NotImplementedError:
        return f"bus budget: not available for the {bus.name} backend"
    t = b.tick_time(turnaround_s)
    rate = config.rate
    return (
        f"bus budget ({b.name}, {b.baud} baud): {b.bytes_per_tick} B and "
        f"{b.replies_per_tick} replies per tick = {t * 1e3:.2f} ms, {t * rate * 100:.0f} % "
        f"of a {1e3 / rate:.2f} ms tick at {rate:g} Hz (max {b.max_rate(turnaround_s):.0f} Hz)"
    )


def _budget_lines(b: BusBudget, turnaround_s: float) -> list[str]:
    lines = [f"  {b.name}:"]
    for item in b.items:
        nbytes = item.bytes_out + item.bytes_in
        lines.append(
            f"    {item.count:2d} x {item.what}: {nbytes} B = "
            f"{nbytes * b.bits_per_byte / b.baud * 1e3:.3f} ms each"
        )
    lines.append(
        f"    {b.bytes_per_tick} B per tick, {b.replies_per_tick} replies: wire "
        f"{b.wire_time() * 1e3:.3f} ms + servo response -> {b.tick_time() * 1e3:.3f} ms "
        f"= max {b.max_rate():.0f} Hz; with {turnaround_s * 1e3:g} ms host turnaround per "
        f"reply {b.tick_time(turnaround_s) * 1e3:.3f} ms = max {b.max_rate(turnaround_s):.0f} Hz"
    )
    return lines


def _reference_lines(bus: ServoBus, config: DeployConfig, turnaround_s: float) -> list[str]:
    """For a Protocol 2.0 bus: the same tick on as many AX-12A servos (Protocol 1.0, 1 Mbps,
    one READ per servo), for comparison."""
    if getattr(bus, "name", "") != "dynamixel2":
        return []
    from .protocol1 import ax_budget

    polls = schedule(bus, config).polls_per_tick
    rate = config.rate
    parts = []
    for read in (False, True):
        b = ax_budget(bus.n, 1_000_000, read, 0 if read else polls)
        t = b.tick_time(turnaround_s)
        parts.append(f"{b.name} {t * 1e3:.2f} ms = {t * rate * 100:.0f} %")
    return [
        f"  the same tick on {bus.n} AX-12A (Protocol 1.0 at 1000000 baud, one READ per "
        f"servo): " + ", ".join(parts)
    ]


def plan_lines(bus: ServoBus, config: DeployConfig, turnaround_s: float) -> list[str]:
    """The bus budget per tick with and without position reads at the configured rate, how
    faults are detected and within what time, and a warning with a proposed rate for each
    mode that overloads the bus."""
    rate = config.rate
    modes = [False] + ([True] if bus.can_read else [])
    try:
        budgets = [(read, tick_budget(bus, config, read)) for read in modes]
    except NotImplementedError:
        return [f"bus budget: not available for the {bus.name} backend"]
    b0 = budgets[0][1]
    lines = [
        f"bus budget at {rate:g} Hz ({1e3 / rate:.2f} ms per tick): {bus.n} servos on "
        f"{bus.name} at {b0.baud} baud ({b0.bits_per_byte} bits per byte, "
        f"{b0.return_delay_s * 1e6:.0f} us servo response per reply)"
    ]
    for _, b in budgets:
        lines += _budget_lines(b, turnaround_s)
    if not bus.can_read:
        lines.append("  write + read: not possible (the backend cannot read positions)")
    usage = ", ".join(
        f"{b.name} {b.tick_time(turnaround_s) * rate * 100:.0f} %" for _, b in budgets
    )
    lines.append(f"  at {rate:g} Hz the bus is busy: {usage}")
    lines += _reference_lines(bus, config, turnaround_s)
    h = schedule(bus, config)
    f = config.max_failures
    lines.append("fault detection (error bit, silence, late or unmatched replies):")
    if bus.health_per_servo:
        lines.append(
            f"  write-only: {h.polls_per_tick} health READs per tick (failing servos first, "
            f"then the longest unchecked, hottest first): every servo checked at least every "
            f"{h.rotation} ticks; an error bit stops motion within {h.rotation / rate * 1e3:.0f} "
            f"ms, silence or late replies ({f} in a row) within {h.detection_s * 1e3:.0f} ms"
        )
    else:
        lines.append(
            f"  write-only: one board query per tick; silence ({f} in a row) stops motion "
            f"within {h.detection_s * 1e3:.0f} ms (no per-servo status on this bus)"
        )
    if bus.can_read:
        lines.append(
            f"  write + read: every servo read every tick: an error bit stops motion within "
            f"{1e3 / rate:.0f} ms, silence or late replies within {f / rate * 1e3:.0f} ms"
        )
    margin = config.fault_bound_s - h.detection_s
    if margin < 1.0 / rate - 1e-9:
        lines.append(
            f"  note: at {rate:g} Hz the {config.fault_bound_s * 1e3:.0f} ms bound leaves no "
            f"tick for lateness ({f} failed checks take {f / rate * 1e3:.0f} ms); use at least "
            f"{math.ceil((f + 1) / config.fault_bound_s)} Hz"
        )
    else:
        lines.append(
            f"  (on schedule; the {margin * 1e3:.0f} ms left of the "
            f"{config.fault_bound_s * 1e3:.0f} ms bound absorb late ticks on a loaded host)"
        )
    for read, b in budgets:
        u = b.tick_time(turnaround_s) * rate
        if u > LOAD_LIMIT:
            r = proposed_rate(bus, config, read, turnaround_s)
            fix = f"propose --rate {r:g}" if r else "no rate fits"
            lines.append(
                f"warning: {b.name} at {rate:g} Hz overloads the bus ({u * 100:.0f} % > "
                f"{LOAD_LIMIT * 100:.0f} %): ticks would run late and be skipped; {fix}"
            )
    return lines
