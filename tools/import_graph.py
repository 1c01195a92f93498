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
    ("tasks and limits", ("wbc.tasks", "wbc.limits")),
    ("solvers", ("wbc.solvers", "wbc.pinv", "wbc.ik", "wbc.pose_ik")),
    ("stacks", ("wbc.stacks", "wbc.stack_tables", "wbc.warmup")),
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
    ("command line", ("wbc.cli",)),
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


def modules(root: Path = ROOT) -> dict[str, Path]:
    return {
        ".".join(_parts(p.relative_to(root))): p for p in sorted((root / PACKAGE).rglob("*.py"))
    }


def _parts(rel: Path) -> list[str]:
    parts = list(rel.with_suffix("").parts)
    return parts[:-1] if parts[-1] == "__init__" else parts


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


def svg(pg: dict[str, set[str]], bad: set[tuple[str, str]], title: str) -> str:
    """The package graph drawn by layer, bottom layer at the bottom: grey arrows go down or
    sideways, red ones run up or close a circle (``bad``)."""
    by_layer: dict[int, list[str]] = defaultdict(list)
    for node in sorted(pg):
        by_layer[layer_of(node) if layer_of(node) is not None else len(LAYERS)].append(node)
    row_h, char_w, pad, gap = 70, 6.6, 8, 14
    rows = sorted(by_layer)
    width = max(
        sum(len(n.removeprefix("wbc.")) * char_w + 2 * pad + gap for n in by_layer[r]) for r in rows
    )
    width = max(width + 180, 700)
    height = row_h * len(rows) + 60
    box: dict[str, tuple[float, float, float]] = {}  # node -> (x centre, y top, width)
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height}" '
        f'font-family="monospace" font-size="11">',
        '<defs><marker id="a" markerWidth="6" markerHeight="6" refX="5" refY="3" '
        'orient="auto"><path d="M0,0 L6,3 L0,6 z" fill="#999"/></marker>'
        '<marker id="r" markerWidth="6" markerHeight="6" refX="5" refY="3" orient="auto">'
        '<path d="M0,0 L6,3 L0,6 z" fill="#d22"/></marker></defs>',
        f'<text x="8" y="18" font-size="13" font-weight="bold">{title}</text>',
    ]
    for i, r in enumerate(rows):
        y = height - (i + 1) * row_h
        name = LAYERS[r][0] if r < len(LAYERS) else "no layer"
        out.append(f'<text x="8" y="{y + 16}" fill="#666">{name}</text>')
        x = 170.0
        for node in by_layer[r]:
            w = len(node.removeprefix("wbc.")) * char_w + 2 * pad
            box[node] = (x + w / 2, y, w)
            x += w + gap
    for a in sorted(pg):
        for b in sorted(pg[a]):
            if b not in box:
                continue
            (xa, ya, _), (xb, yb, _) = box[a], box[b]
            red = (a, b) in bad
            y0 = ya + 24 if yb > ya else ya
            y1 = yb if yb > ya else yb + 24
            if ya == yb:
                y0 = y1 = ya + 24
            mid = (y0 + y1) / 2 + (18 if ya == yb else 0)
            colour, marker = ("#d22", "r") if red else ("#bbb", "a")
            out.append(
                f'<path d="M{xa:.0f},{y0:.0f} C{xa:.0f},{mid:.0f} {xb:.0f},{mid:.0f} '
                f'{xb:.0f},{y1:.0f}" fill="none" stroke="{colour}" stroke-width='
                f'"{1.4 if red else 0.6}" marker-end="url(#{marker})"/>'
            )
    for node, (xc, y, w) in box.items():
        out.append(
            f'<rect x="{xc - w / 2:.0f}" y="{y:.0f}" width="{w:.0f}" height="24" rx="4" '
            f'fill="#f4f6fb" stroke="#456"/><text x="{xc:.0f}" y="{y + 16:.0f}" '
            f'text-anchor="middle">{node.removeprefix("wbc.") or "wbc"}</text>'
        )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dot", type=Path, help="write the package graph as Graphviz DOT")
    ap.add_argument("--mermaid", type=Path, help="write the package graph as a Mermaid flowchart")
    ap.add_argument("--json", type=Path, help="write the module graph and its circles as JSON")
    ap.add_argument("--svg", type=Path, help="write the package graph by layer as SVG")
    ap.add_argument("--title", default="the wbc package", help="--svg: the figure's title")
    ap.add_argument(
        "--root", type=Path, default=ROOT, help="the tree to read (default: this checkout)"
    )
    ap.add_argument(
        "--check",
        action="store_true",
        help="exit 1 on any circle, arrow running up, module in no layer or module over 800 lines",
    )
    args = ap.parse_args(argv)
    mods = modules(args.root)
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
    if args.svg:
        bad = {(a, b) for a in pg for b in pg[a] if any(a in c and b in c for c in pcycles)}
        for a, b in up:
            bad.add((package_of(a), package_of(b)))
        args.svg.write_text(svg(pg, bad, args.title))
    if args.check and (cycles or pcycles or up or unplaced or big):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
