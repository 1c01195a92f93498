"""The import graph of the ``wbc`` package: every import, those inside functions included.

Prints the import circles (strongly connected components of more than one module), the
arrows between packages, and the largest modules; ``--dot FILE`` writes the package-level
graph in Graphviz DOT, ``--mermaid FILE`` as a Mermaid flowchart (the documentation's
architecture page embeds it).

    python tools/import_graph.py [--check] [--dot F.dot] [--mermaid F.mmd] [--json F.json]

The house's layers, bottom first, are :data:`LAYERS`: a module may import its own layer and
those below it; an import of a higher layer is an arrow running back up. ``--check`` exits 1
if there is any circle, any arrow running up, any module in no layer or any module over
800 lines.
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "wbc"
MAX_LINES = 800

#: the layers of the house, bottom first: (name, module prefixes). A module belongs to the
#: layer of its longest matching prefix.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("wbc.exceptions", "wbc.paths", "wbc.geometry", "wbc.types", "wbc.version")),
    ("kernels", ("wbc.compiled",)),
    (
        "model",
        (
            "wbc.model",
            "wbc.robot_data",
            "wbc.roles",
            "wbc.servo_map",
            "wbc.xseries",
            "wbc.urdf_writer",
            "wbc.recording",
        ),
    ),
    ("tasks and limits", ("wbc.tasks", "wbc.limits", "wbc.pinv")),
    ("solvers", ("wbc.solvers", "wbc.ik", "wbc.pose_ik")),
    ("stacks", ("wbc.stacks", "wbc.warmup")),
    (
        "applications",
        (
            "wbc.servos",
            "wbc.imu",
            "wbc.imu_witmotion",
            "wbc.sim",
            "wbc.walking",
            "wbc.balance",
            "wbc.viewer",
            "wbc.drive",
            "wbc.robot_folder",
        ),
    ),
    ("bench", ("wbc.bench",)),
    ("api", ("wbc",)),
    ("command line", ("wbc.cli", "wbc.demo")),
]


def layer_of(mod: str) -> int | None:
    """Index in :data:`LAYERS` of the layer ``mod`` belongs to (longest prefix), or None."""
    best: tuple[int, int] | None = None
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if mod == p or mod.startswith(p + "."):
                if best is None or len(p) > best[0]:
                    best = (len(p), i)
    return None if best is None else best[1]


def arrows_up(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Imports of a higher layer than the importer's."""
    out = []
    for a in sorted(graph):
        la = layer_of(a)
        for b in sorted(graph[a]):
            lb = layer_of(b)
            if la is not None and lb is not None and lb > la:
                out.append((a, b))
    return out


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted((ROOT / PACKAGE).rglob("*.py"))}


def _resolve(current: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = current.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(mods: dict[str, Path]) -> dict[str, set[str]]:
    """module → the wbc modules it imports (a name imported from a package that is itself a
    module counts as that module)."""
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(mod, is_package, node)
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names
                ]
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != mod and t.startswith(PACKAGE):
                    graph[mod].add(t)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, it = work[-1]
            advanced = False
            for nxt in it:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    advanced = True
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out, key=len, reverse=True)


def package_of(mod: str) -> str:
    parts = mod.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 else mod


def package_graph(graph: dict[str, set[str]], mods: dict[str, Path]) -> dict[str, set[str]]:
    """Arrows between sub-packages (``wbc.walking``) and top-level modules (``wbc.model``)."""
    pg: dict[str, set[str]] = defaultdict(set)
    for m, targets in graph.items():
        a = package_of(m)
        pg[a]
        for t in targets:
            b = package_of(t)
            if a != b:
                pg[a].add(b)
    return pg


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dot", type=Path, help="write the package graph as Graphviz DOT")
    ap.add_argument("--mermaid", type=Path, help="write the package graph as a Mermaid flowchart")
    ap.add_argument("--json", type=Path, help="write the module graph and its circles as JSON")
    ap.add_argument(
        "--check",
        action="store_true",
        help="exit 1 on any circle, arrow running up, module in no layer or module over 800 lines",
    )
    args = ap.parse_args(argv)
    mods = modules()
    graph = imports(mods)
    cycles = circles(graph)
    pg = package_graph(graph, mods)
    pcycles = circles(pg)
    n_arrows = sum(len(v) for v in graph.values())
    print(f"{len(mods)} modules, {n_arrows} import arrows (imports inside functions included)")
    print(f"module import circles: {len(cycles)}")
    for c in cycles:
        print(f"  {len(c)} modules: {', '.join(c)}")
    print(f"package import circles: {len(pcycles)}")
    for c in pcycles:
        print(f"  {', '.join(c)}")
    sizes = sorted(((len(p.read_text().splitlines()), m) for m, p in mods.items()), reverse=True)
    big = [(n, m) for n, m in sizes if n > MAX_LINES]
    print(f"modules over {MAX_LINES} lines: {len(big)}" + "".join(f"\n  {m}: {n}" for n, m in big))
    up = arrows_up(graph)
    print(f"arrows running up: {len(up)}")
    for a, b in up:
        print(f"  {a} ({LAYERS[layer_of(a)][0]}) -> {b} ({LAYERS[layer_of(b)][0]})")  # type: ignore[index]
    unplaced = sorted(m for m in mods if layer_of(m) is None)
    print(f"modules in no layer: {len(unplaced)}" + "".join(f"\n  {m}" for m in unplaced))
    if args.dot:
        lines = ["digraph wbc {", "  rankdir=BT; node [shape=box, fontsize=10];"]
        for a in sorted(pg):
            for b in sorted(pg[a]):
                cyc = any(a in c and b in c for c in pcycles)
                lines.append(f'  "{a}" -> "{b}"' + (" [color=red];" if cyc else ";"))
        lines.append("}")
        args.dot.write_text("\n".join(lines) + "\n")
    if args.mermaid:
        ids = {p: p.replace(".", "_") for p in pg}
        lines = ["flowchart BT"]
        for a in sorted(pg):
            for b in sorted(pg[a]):
                lines.append(f"  {ids[a]}[{a}] --> {ids.get(b, b.replace('.', '_'))}[{b}]")
        args.mermaid.write_text("\n".join(lines) + "\n")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "modules": {m: sorted(t) for m, t in graph.items()},
                    "circles": cycles,
                    "package_circles": pcycles,
                    "arrows_up": up,
                },
                indent=1,
            )
        )
    if args.check and (cycles or pcycles or up or unplaced or big):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
