"""Where the robot descriptions and declarative task stacks live.

In a source checkout (and an editable install) they are the top-level ``robots/`` and
``tasks/`` folders; a wheel ships them as the ``wbc.robots`` and ``wbc.task_stacks`` packages.
"""

from __future__ import annotations

import importlib
from pathlib import Path

_REPO = Path(__file__).resolve().parent.parent


def _data_dir(repo_name: str, package: str) -> Path:
    candidate = _REPO / repo_name
    if candidate.is_dir():
        return candidate
    # installed wheel: a data-only (namespace) package inside wbc
    return Path(next(iter(importlib.import_module(package).__path__)))


def robots_dir() -> Path:
    """Folder holding one sub-folder per robot (``bioloid/`` with URDF and servo map)."""
    return _data_dir("robots", "wbc.robots")


def stacks_dir() -> Path:
    """Folder holding the declarative task-stack files (``*.toml``)."""
    return _data_dir("tasks", "wbc.task_stacks")
