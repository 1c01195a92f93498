"""The dependencies (pyproject.toml): a core a user can live with, the rest in extras, and the
command line's "pip install 'wbc[extra]'" hints naming extras that exist."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from wbc.cli import OPTIONAL

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
PROJECT = PYPROJECT["project"]
EXTRAS: dict[str, list[str]] = PROJECT["optional-dependencies"]


def _name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0].lower()


def test_the_core_pins_no_exact_version_and_leaves_casadi_to_an_extra():
    """placo's exact pin 3.8.0 only where placo is (peers); the MPC's casadi in ``mpc``."""
    core = {_name(r): r for r in PROJECT["dependencies"]}
    assert not [r for r in core.values() if "==" in r], core
    assert core["pin"].replace(" ", "") == "pin>=3.8"
    assert "casadi" not in core
    assert "casadi" in {_name(r) for r in EXTRAS["mpc"]}
    peers = {_name(r): r for r in EXTRAS["peers"]}
    assert "placo" in peers and peers["pin"].replace(" ", "") == "pin==3.8.0"


def test_every_install_hint_names_an_extra_that_all_includes():
    """The command line's OPTIONAL map (module -> extra): each extra exists, holds a package
    providing that module, and ``wbc[all]`` includes it."""
    (everything,) = EXTRAS["all"]
    included = set(re.fullmatch(r"wbc\[(.*)\]", everything).group(1).split(","))
    for module, extra in OPTIONAL.items():
        assert extra in EXTRAS and extra in included, (module, extra)
    assert OPTIONAL["casadi"] == "mpc"


def test_a_built_package_holds_every_subpackage():
    """The wheel ships the packages pyproject lists: every folder of ``wbc/`` with an
    ``__init__.py`` must be there (``wbc.drive`` was not: ``pip install .`` had no ``wbc
    drive``; an editable install hid it)."""
    listed = set(PYPROJECT["tool"]["setuptools"]["packages"])
    found = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for p in (ROOT / "wbc").rglob("__init__.py")
        if "__pycache__" not in p.parts
    }
    assert found - listed == set()
