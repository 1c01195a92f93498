"""The robot and the controller in meshcat: live, replayed, or exported as one HTML file.

``Viewer(robot)`` starts a private meshcat server and draws the robot; ``viewer.update(q,
...)`` each control tick, ``viewer.play(recording, speed)`` to replay, ``export_html(robot,
recording, path)`` to share a run. Names are imported lazily so that ``wbc`` works without
the optional ``meshcat`` dependency.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Viewer": "scene",
    "FrameState": "scene",
    "export_html": "scene",
    "scene_commands": "scene",
    "MeshcatServer": "server",
    "ViewerError": "server",
    "Camera": "geometry",
    "VisualShape": "geometry",
    "fit_camera": "geometry",
    "support_polygon": "geometry",
    "visual_shapes": "geometry",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
