"""A driven walk's failed solves, counted by cause and reported (never silent)."""

from __future__ import annotations

import re
from typing import Any


def failure_cause(exc: Exception, phase: str) -> str:
    """A failed solve's cause for counting: the support phase, the exception's type and its
    message without the figures in brackets (residuals, distances), e.g. ``double:
    InfeasibleError: hard level 0 is infeasible: cannot satisfy contact_support, ...``."""
    return f"{phase}: {type(exc).__name__}: {_FIGURES.sub('', str(exc))}"


def failure_lines(walker: Any) -> list[str]:
    """The lines that report a walker's failed solves (none if every solve succeeded)."""
    if not walker.failed_solves:
        return []
    lines = [f"WARNING: {walker.failed_solves} of {len(walker.tick_time)} walk ticks failed "
             "to solve (the robot held its last goals):"]  # fmt: skip
    lines += [f"  {n} × {cause}" for cause, n in walker.failure_causes.most_common()]
    return lines


_FIGURES = re.compile(r"\s*\([^()]*\d[^()]*\)")
