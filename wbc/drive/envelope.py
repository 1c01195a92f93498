"""The planning envelope of a robot: its velocity limits and whole-body balance window,
measured on the model once and kept on disk.

:meth:`~wbc.walking.engine.VelocityLimits.from_robot` (a bisection of tracked walks, tens
of seconds on a busy machine) and :meth:`~wbc.walking.window.BalanceWindow.from_robot`
(seconds) depend only on the model, its standing pose and feet, and the gait: the result is
stored in the cache directory (``$WBC_CACHE_DIR``, else ``~/.cache/wbc``) under a hash of
exactly those, so a changed URDF, pose or gait is measured again.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from ..walking.engine import EngineParams, VelocityLimits
from ..walking.window import BalanceWindow

#: bump when the measurement itself changes
VERSION = 3  # 3: the window's max_lateral holds the torso pitch and heading (issue 29)


def _key(robot: Any, params: EngineParams) -> str:
    h = hashlib.sha256()
    h.update(robot.urdf_path.read_bytes())
    h.update(np.asarray(robot.configuration("stand"), dtype=float).tobytes())
    h.update(repr((tuple(robot.foot_size), params, VERSION)).encode())
    return h.hexdigest()[:20]


def planning_envelope(
    robot: Any, params: EngineParams | None = None, refresh: bool = False
) -> tuple[VelocityLimits, BalanceWindow | None]:
    """``(limits, window)`` for ``robot`` walking with ``params`` (measured, or read back
    from the cache; ``refresh``: measure again); ``window`` None unless
    ``params.whole_body``."""
    from ..compiled.dispatch import cache_dir

    params = (params or EngineParams()).check()
    path = cache_dir() / "drive" / f"{robot.name}-{_key(robot, params)}.json"
    if path.is_file() and not refresh:
        try:
            data = json.loads(path.read_text())
            return VelocityLimits(**data["limits"]).check(), BalanceWindow.from_dict(data["window"])
        except (ValueError, KeyError, TypeError):
            pass  # a damaged file: measure again
    stand = robot.configuration("stand")
    window = BalanceWindow.from_robot(robot, stand) if params.whole_body else None
    limits = VelocityLimits.from_robot(robot, params, window)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    table = window.as_dict() if window is not None else None
    tmp.write_text(json.dumps({"limits": limits.as_dict(), "window": table}))
    tmp.replace(path)
    return limits, window
