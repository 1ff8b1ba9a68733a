#!/usr/bin/env python3
"""MAGNA's package graph, read from the imports, checked against the declared layers.

    python scripts/import_graph.py            check: exit 1 and list every import that breaks the layers
    python scripts/import_graph.py --dot F    also write the graph in graphviz's language (F.svg with --svg)

The layers are declared in pyproject.toml, `[tool.magna.layers]`: a package may import only packages
of lower layers. Every import counts, also one inside a function (a lazy import still ties the
packages together). Tests are not checked: a package's tests may drive the layers above it.

A message package (no Python of ours, only generated message types) may also be imported from its own
layer: it imports nothing of ours, so it closes no circle.

Three more rules are checked:
- a catkin package's package.xml declares (depend/exec_depend) exactly the MAGNA packages it imports;
- no two modules of one package import each other, directly or around a circle;
- every package of the workspace has a layer.
"""
from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
import tomllib
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP_LEVEL_PACKAGES = ("mlr", "voice")  # Python packages at the repository root, beside the catkin ones


@dataclass(frozen=True)
class Import:
    source: str  # importing package
    target: str  # imported package
    where: str  # file:line
    module: str  # the importing module
    imported: str  # the imported module


@dataclass
class Graph:
    packages: dict[str, Path]  # package -> folder of its Python code
    imports: list[Import] = field(default_factory=list)

    def edges(self) -> dict[tuple[str, str], list[Import]]:
        found: dict[tuple[str, str], list[Import]] = defaultdict(list)
        for imp in self.imports:
            if imp.source != imp.target:
                found[(imp.source, imp.target)].append(imp)
        return dict(found)

    def is_messages(self, package: str) -> bool:
        """A message package: no Python of ours, only the generated message and service types."""
        return not (self.packages[package] / "__init__.py").exists()

    def breaks_layers(self, source: str, target: str, level: dict[str, int]) -> bool:
        return level[target] > level[source] or level[target] == level[source] and not self.is_messages(target)


def declared_layers(pyproject: Path = ROOT / "pyproject.toml") -> list[list[str]]:
    """The layers, bottom first, as pyproject.toml declares them."""
    config = tomllib.loads(pyproject.read_text())
    try:
        layers = config["tool"]["magna"]["layers"]["order"]
    except KeyError:
        raise SystemExit(f"{pyproject}: no [tool.magna.layers] order = [[...], ...]; "
                         "declare the layers there") from None
    return [list(layer) for layer in layers]


def _is_test(path: Path) -> bool:
    return any(part in ("test", "tests") for part in path.parts) or path.name.startswith("test_") \
        or path.name == "conftest.py"


def _python_files(folder: Path) -> list[Path]:
    """The package's modules and its nodes (executables without .py that start with a python shebang)."""
    files = [p for p in folder.rglob("*.py") if not _is_test(p.relative_to(folder))]
    nodes = folder.parent.parent / "nodes" if folder.parent.name == "src" else None
    if nodes is not None and nodes.is_dir():
        for node in sorted(nodes.iterdir()):
            if node.is_file() and node.read_bytes()[:40].startswith(b"#!") and b"python" in node.read_bytes()[:40]:
                files.append(node)
    return sorted(files)


def find_packages(root: Path = ROOT) -> dict[str, Path]:
    packages = {}
    for package_xml in sorted(root.glob("src/*/package.xml")):
        name = package_xml.parent.name
        code = package_xml.parent / "src" / name
        packages[name] = code if code.is_dir() else package_xml.parent
    for name in TOP_LEVEL_PACKAGES:
        if (root / name / "__init__.py").exists():
            packages[name] = root / name
    return packages


def _module_name(path: Path, folder: Path, package: str) -> str:
    if path.suffix != ".py":
        return f"{package}.nodes.{path.name}"
    parts = [package, *path.relative_to(folder).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def read_graph(root: Path = ROOT) -> Graph:
    packages = find_packages(root)
    graph = Graph(packages)
    for package, folder in packages.items():
        if not (folder / "__init__.py").exists():
            continue  # a message or C++ package: no Python of ours
        for path in _python_files(folder):
            module = _module_name(path, folder, package)
            tree = ast.parse(path.read_bytes(), filename=str(path))
            for node in ast.walk(tree):
                names = []
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom):
                    if node.level:  # relative: inside the package
                        base = module.split(".")[: len(module.split(".")) - node.level + (path.name == "__init__.py")]
                        prefix = ".".join(base)
                        names = [f"{prefix}.{node.module}" if node.module else prefix]
                        names += [f"{names[0]}.{alias.name}" for alias in node.names]
                    elif node.module:
                        names = [node.module, *(f"{node.module}.{alias.name}" for alias in node.names)]
                for name in names:
                    top = name.split(".")[0]
                    if top in packages:
                        where = f"{path.relative_to(root)}:{node.lineno}"
                        graph.imports.append(Import(package, top, where, module, name))
    return graph


def layer_problems(graph: Graph, layers: list[list[str]]) -> list[str]:
    level = {package: n for n, layer in enumerate(layers) for package in layer}
    problems = [f"{package}: no layer; add it to [tool.magna.layers] order in pyproject.toml"
                for package in graph.packages if package not in level]
    for (source, target), imports in sorted(graph.edges().items()):
        if source not in level or target not in level:
            continue
        if graph.breaks_layers(source, target, level):
            direction = "sideways" if level[target] == level[source] else "up"
            for imp in {imp.where: imp for imp in reversed(imports)}.values():  # one line per import statement
                problems.append(f"{imp.where}: {source} imports {imp.imported}, {direction} in the layers "
                                f"({source} is in layer {level[source]}, {target} in layer {level[target]})")
    return problems


_DEPEND = re.compile(r"<(?:exec_depend|depend|run_depend)>\s*([A-Za-z0-9_]+)\s*</")


def package_xml_problems(graph: Graph, root: Path = ROOT) -> list[str]:
    """Each catkin package declares every workspace package its Python imports, and nothing more but
    what its launch files start or include (message packages are left to catkin_lint)."""
    imported: dict[str, set[str]] = defaultdict(set)
    for source, target in graph.edges():
        imported[source].add(target)
    problems = []
    python_packages = {p for p, folder in graph.packages.items() if (folder / "__init__.py").exists()}
    for package in sorted(graph.packages):
        xml = root / "src" / package / "package.xml"
        if not xml.exists():
            continue
        declared = {d for d in _DEPEND.findall(xml.read_text()) if d in python_packages}
        for missing in sorted(imported[package] & python_packages - declared):
            problems.append(f"{xml.relative_to(root)}: imports {missing} but does not declare it; "
                            f"add <exec_depend>{missing}</exec_depend>")
        for extra in sorted(declared - imported[package] - launched(root / "src" / package)):
            problems.append(f"{xml.relative_to(root)}: declares {extra} but imports nothing of it; "
                            f"remove <exec_depend>{extra}</exec_depend>")
    return problems


_LAUNCHED = re.compile(r'pkg="([A-Za-z0-9_]+)"|\$\(find ([A-Za-z0-9_]+)\)')


def launched(package_dir: Path) -> set[str]:
    """The packages a package's launch files start nodes of or include files from."""
    found = set()
    for launch in package_dir.glob("launch/**/*.launch"):
        for node_pkg, find_pkg in _LAUNCHED.findall(launch.read_text()):
            found.add(node_pkg or find_pkg)
    return found


def module_cycles(graph: Graph) -> list[list[str]]:
    """Circles of imports between the modules of one package (Tarjan's strongly connected components)."""
    modules = {imp.module for imp in graph.imports} | {imp.imported for imp in graph.imports}
    edges: dict[str, set[str]] = defaultdict(set)
    for imp in graph.imports:
        if imp.source == imp.target and imp.imported in modules and imp.imported != imp.module \
                and imp.imported != imp.source:  # `from pkg import x` of a package's own __init__ is not a circle
            edges[imp.module].add(imp.imported)
    known = {m for m in modules}
    edges = {m: {t for t in targets if t in known and _is_module(graph, t)} for m, targets in edges.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10000))
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return cycles


def _is_module(graph: Graph, name: str) -> bool:
    package, *rest = name.split(".")
    folder = graph.packages.get(package)
    if folder is None or not rest:
        return False
    path = folder.joinpath(*rest)
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def check(root: Path = ROOT) -> list[str]:
    graph = read_graph(root)
    problems = layer_problems(graph, declared_layers(root / "pyproject.toml"))
    problems += package_xml_problems(graph, root)
    problems += [f"import circle between modules: {' -> '.join(c)}" for c in module_cycles(graph)]
    return problems


def dot(graph: Graph, layers: list[list[str]]) -> str:
    """The package graph in graphviz's language, one rank per layer (bottom layer at the bottom); an arrow
    goes from the importing package to the imported one, faint when it points at a message package."""
    lines = ["digraph magna {", "  rankdir=TB;", '  node [shape=box, style="rounded,filled", fillcolor="#eef3fb", '
             'fontname="Helvetica"];', '  edge [color="#555555"];']
    level = {package: n for n, layer in enumerate(layers) for package in layer}
    for n, layer in enumerate(layers):
        present = [p for p in layer if p in graph.packages]
        lines.append(f'  {{ rank=same; {" ".join(present)} }}  // layer {n}')
    for (source, target), imports in sorted(graph.edges().items()):
        bad = source in level and target in level and graph.breaks_layers(source, target, level)
        messages = graph.is_messages(target)
        style = ' [color="#c62828", penwidth=2]' if bad else ' [color="#cccccc"]' if messages else ""
        lines.append(f"  {source} -> {target}{style};  // {len(imports)} import(s)")
    lines.append("}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    parser.add_argument("--dot", type=Path, metavar="FILE", help="write the package graph (graphviz) to FILE")
    parser.add_argument("--svg", action="store_true", help="with --dot, also render FILE.svg with graphviz's dot")
    args = parser.parse_args(argv)
    graph = read_graph()
    layers = declared_layers()
    if args.dot:
        args.dot.write_text(dot(graph, layers))
        print(f"graph: {args.dot}")
        if args.svg:
            svg = args.dot.with_suffix(".svg")
            subprocess.run(["dot", "-Tsvg", str(args.dot), "-o", str(svg)], check=True)
            print(f"picture: {svg}")
    problems = check()
    for line in problems:
        print(line)
    edges = graph.edges()
    print(f"{len(graph.packages)} packages, {len(edges)} package edges, "
          f"{sum(len(v) for v in edges.values())} imports between packages; {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
