"""Draw a state machine with graphviz: containers as clusters, transitions as labelled edges,
active states highlighted.

Works from `ContainerStructure` records, so the same code draws a machine in
this process (`draw(container, ...)`) and one seen only through introspection
messages (the viewer node).
"""
from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterable
from pathlib import Path

from magna_sm.container import Container, ContainerStructure

ACTIVE_FILL = "#7fd17f"
ACTIVE_CLUSTER = "#e4f6e4"
OUTCOME_FILL = "#f4c7c3"


class DrawError(RuntimeError):
    pass


def active_paths(root: Container) -> set[str]:
    """Paths of every state running now, containers included."""
    return {f"{container.path}/{label}" for container in root.walk() for label in container.get_active_states()}


def structures_of(root: Container) -> list[ContainerStructure]:
    return [container.describe() for container in root.walk()]


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_dot(structures: Iterable[ContainerStructure], active: Iterable[str] = (), title: str = "") -> str:
    """Graphviz source for the machine; `active` holds paths of running states."""
    by_path = {s.path: s for s in structures}
    if not by_path:
        raise DrawError("nothing to draw: no container structure given")
    active = set(active)
    roots = [path for path in by_path if path.rsplit("/", 1)[0] not in by_path]
    lines = ["digraph magna_sm {", "  compound=true; rankdir=TB; fontname=Helvetica;",
             "  node [fontname=Helvetica, fontsize=11, shape=box, style=\"rounded,filled\", fillcolor=white];",
             "  edge [fontname=Helvetica, fontsize=9];"]
    if title:
        lines.append(f"  label={_quote(title)}; labelloc=t; fontsize=16;")
    edges: list[str] = []

    def anchor(path: str) -> str:
        """A node to hang edges on: the state itself, or a container's invisible anchor."""
        return _quote(path + ("/__anchor" if path in by_path else ""))

    def emit(path: str, indent: str) -> None:
        structure = by_path[path]
        is_active = path in active or any(a.startswith(path + "/") for a in active)
        lines.append(f"{indent}subgraph {_quote('cluster_' + path)} {{")
        lines.append(f"{indent}  label={_quote(path.rsplit('/', 1)[-1] + '  [' + structure.container_type + ']')};")
        cluster_fill = ACTIVE_CLUSTER if is_active else "#f7f7f7"
        lines.append(f"{indent}  style=\"rounded,filled\"; fillcolor={_quote(cluster_fill)};")
        lines.append(f"{indent}  {_quote(path + '/__anchor')} [shape=point, style=invis, width=0];")
        for label, child_type in zip(structure.children, structure.child_types, strict=True):
            child_path = f"{path}/{label}"
            if child_path in by_path:
                emit(child_path, indent + "  ")
            else:
                fill = ACTIVE_FILL if child_path in active else "white"
                border = ", penwidth=2" if label in structure.initial_states else ""
                lines.append(f"{indent}  {_quote(child_path)} [label={_quote(label + chr(10) + child_type)}, "
                             f"fillcolor={_quote(fill)}{border}];")
        for outcome in structure.container_outcomes:
            lines.append(f"{indent}  {_quote(path + '/:' + outcome)} [label={_quote(outcome)}, shape=box, "
                         f"style=\"filled\", fillcolor={_quote(OUTCOME_FILL)}];")
        lines.append(f"{indent}}}")
        for source, outcome, target in structure.transitions:
            source_path = f"{path}/{source}"
            target_path = f"{path}/{target}" if target in structure.children else f"{path}/:{target}"
            attributes = [f"label={_quote(outcome)}"]
            if source_path in by_path:
                attributes.append(f"ltail={_quote('cluster_' + source_path)}")
            if target_path in by_path:
                attributes.append(f"lhead={_quote('cluster_' + target_path)}")
            target_node = anchor(target_path) if target in structure.children else _quote(target_path)
            edges.append(f"  {anchor(source_path)} -> {target_node} [{', '.join(attributes)}];")

    for root in roots:
        emit(root, "  ")
    lines.extend(edges)
    lines.append("}")
    return "\n".join(lines) + "\n"


def render(dot_source: str, output: Path) -> Path:
    """Write `output` (.png, .svg or .pdf by its suffix; .dot writes the source) atomically."""
    output = Path(output)
    fmt = output.suffix.lstrip(".").lower()
    if fmt not in {"png", "svg", "pdf", "dot"}:
        raise DrawError(f"{output}: unknown picture format '{output.suffix}'; use .png, .svg, .pdf or .dot")
    output.parent.mkdir(parents=True, exist_ok=True)
    partial = output.with_name(f".{output.name}.partial")
    if fmt == "dot":
        partial.write_text(dot_source)
    else:
        if shutil.which("dot") is None:
            raise DrawError("graphviz's 'dot' is not installed: run 'make setup' (Debian package graphviz)")
        done = subprocess.run(["dot", f"-T{fmt}", "-o", str(partial)], input=dot_source, text=True,
                              capture_output=True)
        if done.returncode != 0:
            partial.unlink(missing_ok=True)
            raise DrawError(f"graphviz failed to draw {output}: {done.stderr.strip()}")
    partial.replace(output)
    return output


def draw(container: Container, output: Path, title: str = "", show_active: bool = True) -> Path:
    """Draw a machine as it is now (its running states highlighted) to a picture file."""
    active = active_paths(container) if show_active else set()
    return render(to_dot(structures_of(container), active, title), output)
