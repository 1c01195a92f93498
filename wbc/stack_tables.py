"""A stack file's tables beyond its levels: ``[support_switch]`` (:class:`SupportSwitch`), and
the check of a positive number that the stack file's other numbers share (:func:`is_positive`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from .exceptions import TaskError


def is_positive(value: Any) -> bool:
    """True if a stack file's ``value`` is a finite number > 0 (a TOML bool is not one)."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    return number and math.isfinite(value) and value > 0


@dataclass(frozen=True)
class SupportSwitch:
    """A stack file's ``[support_switch]`` table, for this robot: how a walking controller
    carries the stack across a support switch (:mod:`wbc.walking.handover`). ``posture_lag``
    (s): the legs' posture targets follow their set points (Walk Ready for the swing leg, the
    held pose for a leg in contact) with this time constant; ``landing_time`` (s): a landing
    contact is anchored where the sole touches down, at most ``landing_band`` (m) from its
    reference placement (the rest of a larger miss asked at once), and walked there in this
    time. None (or no band: inf): off. ``carry_contact_targets``: a leg in contact carries its
    posture target with its joints, its touch-down offset decaying with ``posture_lag`` (False:
    the target lags them). ``second_order_swing``: the freed leg's target walks to Walk Ready
    through two such lags in series (no step in its speed at the lift-off: a shorter
    ``posture_lag`` for the same joint speed; benchmarks/balance.md, "Sixth follow-up" item 5).
    ``fit_speed`` (default): a freed leg's lag is lengthened, for that swing, until its first
    step asks no joint for more than the sized share of its servo's no-load speed
    (:meth:`wbc.walking.handover.SwitchHandover.swing_share`; never shortened); false: as stated.
    ``landing_fallback``: a tick whose hard level fails while a landing is under way (a miss
    beyond the band asked of the hard row, more than the servos move in a tick) is solved
    again with that landing re-anchored where the sole is and walked from there in a new
    ``landing_time`` (:meth:`wbc.walking.handover.SwitchHandover.solve`; counted); false: the
    tick fails (the controller holds its last configuration). ``fallback_hold``: that anchor
    held where the sole is through the double support, not walked to the reference.
    ``brace`` (issue 30): such a tick is instead solved braced — the landed contact anchored
    where the sole is, the CoM and torso targets where they are: the pose held by a solve
    (:meth:`wbc.walking.handover.SwitchHandover._braced`; counted), the next tick trying the
    landing again; ``brace_speed`` (m/s; none: held): the braced anchor one step of that
    speed from the sole toward the landing's (the miss settled at that speed).
    Stated for the file's ``design_leg``; on a robot λ times that size the times are scaled by
    √λ (the sizing's time scale, :func:`wbc.walking.sizing.scale_options`) and the band by λ."""

    posture_lag: float | None = None
    landing_time: float | None = None
    landing_band: float = math.inf
    carry_contact_targets: bool = False
    second_order_swing: bool = False
    fit_speed: bool = True
    landing_fallback: bool = False
    fallback_hold: bool = False
    brace: bool = False
    brace_speed: float = 0.0


#: the keys of a stack file's ``[support_switch]`` table: :class:`SupportSwitch`'s fields
SWITCH_KEYS = tuple(f.name for f in fields(SupportSwitch))
#: its keys that are true or false (the others are positive numbers): the fields typed bool
_SWITCH_FLAGS = tuple(f.name for f in fields(SupportSwitch) if f.type in (bool, "bool"))


def parse_support_switch(table: Any, unit: float, where: str) -> SupportSwitch | None:
    """The ``[support_switch]`` table checked (known keys; positive numbers, or true/false for
    the flags) and scaled to a robot of ``unit`` times the file's ``design_leg``."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise TaskError(f"{where}: support_switch must be a table with keys {list(SWITCH_KEYS)}")
    unknown = set(table) - set(SWITCH_KEYS)
    if unknown:
        raise TaskError(
            f"{where}: support_switch has unknown keys {sorted(unknown)}; allowed: "
            f"{list(SWITCH_KEYS)}"
        )
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key in _SWITCH_FLAGS:
            if not isinstance(value, bool):
                raise TaskError(
                    f"{where}: support_switch.{key} must be true or false, got {value!r}"
                )
            values[key] = value
            continue
        if not is_positive(value):
            raise TaskError(
                f"{where}: support_switch.{key} must be a positive number (posture_lag and "
                f"landing_time in s, landing_band in m, brace_speed in m/s), got {value!r}"
            )
        values[key] = float(value) * (unit if key == "landing_band" else math.sqrt(unit))
    return SupportSwitch(**values)
