"""The house's layers (``tools/import_graph.py``, imports inside functions counted): no module
or package import circle, no arrow running up, every module in a layer, none over 800 lines;
and the core's layers checked one by one, so a failure names where the house broke."""

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


def test_the_whole_house_has_no_circle_and_no_arrow_running_up(graph):
    tool, g = graph
    assert tool.circles(g) == []
    assert tool.circles(tool.package_graph(g, tool.modules())) == []
    assert tool.arrows_up(g) == []
    assert [m for m in g if tool.layer_of(m) is None] == []


def test_the_compiled_kernels_are_a_leaf(graph):
    tool, g = graph
    kernels = layer(tool, "kernels")
    for m in (m for m in g if m.startswith("wbc.compiled")):
        assert all(tool.layer_of(t) <= kernels for t in g[m]), (m, sorted(g[m]))


#: process entry points of the kernels' background workers (started by module name; each
#: parses its own few arguments and wires nothing across the house)
WORKER_ENTRY_POINTS = {"wbc.compiled.__main__", "wbc.compiled.worker", "wbc.warmup"}


def test_only_the_command_line_parses_arguments(graph):
    tool, _ = graph
    parsers = [
        name
        for name, path in tool.modules().items()
        if not name.startswith("wbc.cli") and "argparse" in path.read_text()
    ]
    assert sorted(set(parsers) - WORKER_ENTRY_POINTS) == []
    for name in set(parsers) & WORKER_ENTRY_POINTS:
        text = tool.modules()[name].read_text()
        assert 'if __name__ == "__main__":' in text, name


def test_no_module_is_over_800_lines(graph):
    tool, _ = graph
    big = {m: n for m, p in tool.modules().items() if (n := len(p.read_text().splitlines())) > 800}
    assert big == {}
