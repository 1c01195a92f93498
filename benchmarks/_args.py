"""The trace scripts' shared command-line arguments, one definition each: the plant of a
sweep to replay (``--walk``, ``--seed``, ``--plant``), the settings over the defaults as
checked JSON (``--gains``, ``--stepping``), a push (``--impulse``, ``--direction``,
``--offset``) and a trace's rows (``--from``, ``--every``).

    import _args
    p = argparse.ArgumentParser()
    _args.plant(p, walk="lateral_wb", seed=0, plant=18)
    _args.rows(p, start=2.0, every=0.04)
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import fields

from wbc.balance.stabilizer import Gains
from wbc.balance.stepping import SteppingParams
from wbc.bench.pushes import PUSH_DIRECTIONS


def json_setting(cls: type) -> Callable[[str], dict]:
    """The argparse type of one ``--gains`` / ``--stepping`` setting: a JSON object of
    ``cls``'s keywords (anything else: one line naming the argument and what is allowed)."""
    allowed = {f.name for f in fields(cls)}

    def parse(text: str) -> dict:
        try:
            value = json.loads(text)
        except json.JSONDecodeError as err:
            raise argparse.ArgumentTypeError(f"not JSON ({err.msg}): {text!r}") from None
        if not isinstance(value, dict):
            raise argparse.ArgumentTypeError(f"a JSON object of keywords, got {text!r}")
        unknown = sorted(set(value) - allowed)
        if unknown:
            names = ", ".join(sorted(allowed))
            raise argparse.ArgumentTypeError(
                f"{cls.__name__} has no {', '.join(unknown)} (allowed: {names})"
            )
        return value

    return parse


def settings(p: argparse.ArgumentParser, stepping: bool = True) -> None:
    """``--gains`` (Gains keywords over the run's gains) and, with ``stepping``,
    ``--stepping`` (SteppingParams keywords): one JSON object each, default ``{}``."""
    p.add_argument("--gains", type=json_setting(Gains), default={}, help="JSON Gains keywords")
    if stepping:
        p.add_argument("--stepping", type=json_setting(SteppingParams), default={},
                       help="JSON SteppingParams keywords")  # fmt: skip


def plant(
    p: argparse.ArgumentParser, walk: str, seed: int, plant: int, nominal: bool = False
) -> None:
    """``--walk``, ``--seed``, ``--plant`` (plant_sweep.py's plant ``plant`` of ``seed``'s
    sweep; with ``nominal``, -1 is the nominal plant) and ``--gains`` (:func:`settings`)."""
    p.add_argument("--walk", default=walk)
    p.add_argument("--seed", type=int, default=seed, help="the sweep's seed")
    help_ = "the sweep's plant" + (" (-1: nominal)" if nominal else "")
    p.add_argument("--plant", type=int, default=plant, help=help_)
    settings(p, stepping=False)


def push(p: argparse.ArgumentParser, impulse: float, direction: str, offset: float) -> None:
    """``--impulse`` (N·s), ``--direction`` (PUSH_DIRECTIONS), ``--offset`` (s after mid
    single support): a push at mid single support, as pushes.py gives it."""
    p.add_argument("--impulse", type=float, default=impulse, help="N·s")
    p.add_argument("--direction", default=direction, choices=PUSH_DIRECTIONS)
    p.add_argument("--offset", type=float, default=offset, help="s after mid single support")


def rows(p: argparse.ArgumentParser, start: float, every: float | None = None) -> None:
    """``--from`` (s: the first row, as ``start``) and, given a default, ``--every`` (s
    between rows)."""
    p.add_argument("--from", dest="start", type=float, default=start, help="s: first row")
    if every is not None:
        p.add_argument("--every", type=float, default=every, help="s between rows")
