"""Where the robot descriptions and declarative task stacks live.

In a source checkout (and an editable install) they are the top-level ``robots/`` and
``tasks/`` folders; a wheel ships them as the ``wbc.robots`` and ``wbc.task_stacks`` packages.
"""

from __future__ import annotations

import importlib
import tomllib
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


def read_toml(path: Path, what: str, error: type[Exception]) -> dict:
    """A TOML file as a dict; ``error`` (naming ``what`` and the path) if missing or invalid."""
    if not path.is_file():
        raise error(f"{what} not found: {path}")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {path} is not valid TOML: {exc}") from exc
