"""The core's layers (``tools/import_graph.py``, imports inside functions counted): the base
layer imports nothing above it, the model layer is no circle, the solvers import nothing
above them and are no circle among themselves."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def graph():
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "tools/import_graph.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool, tool.imports(tool.modules())


def layer(tool, name: str) -> int:
    return next(i for i, (n, _) in enumerate(tool.LAYERS) if n == name)


def test_the_base_and_model_layers_import_nothing_above_them_and_are_no_circle(graph):
    tool, g = graph
    core = {m for m in g if tool.layer_of(m) in (layer(tool, "base"), layer(tool, "model"))}
    assert {"wbc.geometry", "wbc.recording", "wbc.roles", "wbc.model", "wbc.version"} <= core
    assert [(a, b) for a, b in tool.arrows_up(g) if a in core] == []
    assert [c for c in tool.circles(g) if set(c) & core] == []


def test_the_solvers_import_nothing_above_them_and_are_no_circle_among_themselves(graph):
    tool, g = graph
    solvers = {m for m in g if m.startswith("wbc.solvers")}
    assert [(a, b) for a, b in tool.arrows_up(g) if a in solvers] == []
    inside = {m: {t for t in g[m] if t in solvers} for m in solvers}
    assert tool.circles(inside) == []
