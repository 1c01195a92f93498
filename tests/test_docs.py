"""The documentation site: its examples run, and the stack file reference matches wbc.stacks."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from wbc import load_robot, stacks
from wbc.solvers import BACKENDS
from wbc.tasks.task import STACK_TYPES

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = sorted((DOCS / "examples").glob("*.py"))


def _reference() -> str:
    return (DOCS / "stack-files.md").read_text()


def _table_keys(text: str, heading: str) -> list[str]:
    """The `key` cells of the first column of the table under a heading."""
    section = text.split(heading, 1)[1].split("\n#", 1)[0]
    body = section.split("|---", 1)[1]  # below the header row
    return re.findall(r"^\| `([a-z_]+)` \|", body, flags=re.M)


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(path: Path, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, str(path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip(), f"{path.name} printed nothing"


def test_examples_are_included_in_the_site() -> None:
    site = "".join(p.read_text() for p in DOCS.rglob("*.md"))
    for path in EXAMPLES:
        assert f'--8<-- "docs/examples/{path.name}"' in site, path.name


def test_reference_documents_every_task_and_constraint_type() -> None:
    types = set(_table_keys(_reference(), "### Task types"))
    package_classes = {k for k, c in STACK_TYPES.items() if c.__module__.startswith("wbc.")}
    assert {"relative_position", "com", "contact"} <= package_classes
    assert types == package_classes
    text = _reference()
    for kind in stacks.CONSTRAINT_TYPES:
        assert f'"{kind}"' in text.split("## Constraints", 1)[1], kind


def test_reference_documents_every_task_key() -> None:
    documented = set(_table_keys(_reference(), "### Keys every task accepts"))
    assert documented == stacks._TASK_KEYS
    assert "`axis`" in _reference()  # the one type-specific key (torso_orientation)


def test_reference_documents_solvers_and_backends() -> None:
    top = _reference().split("## Top-level keys", 1)[1].split("\n## ", 1)[0]
    for name in (*stacks.SOLVERS, *BACKENDS, *stacks.PHASES):
        assert f'"{name}"' in _reference(), name
    assert "`levels`" in top


def test_every_documented_top_level_key_is_accepted() -> None:
    """A key the page lists is one build_stack accepts (and an unlisted one is refused)."""
    robot = load_robot("bioloid")
    keys = _table_keys(_reference(), "## Top-level keys")
    values = {
        "name": "x",
        "description": "",
        "solver": "hierarchical",
        "backend": "daqp",
        "method": "cascade",
        "regularization": 1e-6,
        "on_infeasible": "raise",
        "velocity_limits": True,
        "import": [],
        "design_leg": 0.14886,
        "support_switch": {"posture_lag": 0.1, "landing_time": 0.1, "landing_band": 0.005},
        "levels": [{"hard": True, "tasks": [{"type": "contact", "frame": "support"}]}],
    }
    assert set(keys) == set(values)
    stacks.build_stack({k: values[k] for k in keys}, robot)
    with pytest.raises(stacks.TaskError, match="unknown keys"):
        stacks.build_stack({**values, "undocumented": 1}, robot)
