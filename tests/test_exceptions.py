"""The one rule of wbc/exceptions.py: what the package raises, read from its source."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "wbc"


def _raises(name: str) -> list[tuple[str, int, str]]:
    """(file, line, message start) of every ``raise name(...)`` in the package."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Raise)
                and isinstance(node.exc, ast.Call)
                and isinstance(node.exc.func, ast.Name)
                and node.exc.func.id == name
            ):
                args = node.exc.args
                message = ast.unparse(args[0]) if args else ""
                found.append((str(path.relative_to(PACKAGE)), node.lineno, message))
    return found


def test_wbc_error_itself_is_never_raised() -> None:
    """A mistake raises the ValueError subclass of its subject, a failure its own class;
    WbcError is only caught (exceptions.py: "WbcError itself is never raised")."""
    direct = _raises("WbcError")
    assert not direct, direct


def test_no_bare_value_error_outside_the_compiled_kernels() -> None:
    """A caller's bad value is a WbcError subclass (catchable as both ValueError and
    WbcError), in the compiled plans too (a task's target layout: TaskError). Not checked:
    the numba kernels' own argument checks (njit code raises built-in exceptions)."""
    kernels = {
        "compiled/checks.py", "compiled/lsq.py", "compiled/lsq_subproblem.py",
        "compiled/lsq_linalg.py", "compiled/ticks.py", "compiled/rows.py",
        "compiled/proximal.py",
    }  # fmt: skip
    bare = [(f, line, m) for f, line, m in _raises("ValueError") if f not in kernels]
    assert not bare, bare
