"""Draw a state machine with graphviz: containers as clusters, transitions as labelled edges,
active states highlighted.

Works from `ContainerStructure` records, so the same code draws a machine in
this process (`draw(container, ...)`) and one seen only through introspection
messages (the viewer node).

Graphviz's `dot` cannot rank some machines drawn as nested clusters (it stops with
"trouble in init_rank" and a dump of its ranks). A picture is still written, each
layout tried in turn until one is drawn:

1. `clusters`: containers as nested boxes, transitions from and to their borders;
   tried with dot's usual ranking, then with its other one (`newrank`);
2. `flat`: no boxes; a container is a folder-shaped node with a dashed arrow to
   each state it starts with, and its outcomes are red boxes the transitions leave from;
3. `plain`: as `flat`, with the transitions' outcomes written beside the arrows
   (`xlabel`) instead of in the ranking.

A fallback to `flat` or `plain` is one line on the `magna_sm.draw` logger (once per
picture file in a process); graphviz's own output never reaches the terminal, and
when every layout fails the DrawError holds only the first line of what dot said.
"""
from __future__ import annotations

import logging
import shutil
import subprocess
from collections.abc import Callable, Iterable
from pathlib import Path

from magna_common.files import write_bytes_atomically, write_text_atomically
from magna_sm.container import Container, ContainerStructure

ACTIVE_FILL = "#7fd17f"
ACTIVE_CLUSTER = "#e4f6e4"
IDLE_CLUSTER = "#f7f7f7"
OUTCOME_FILL = "#f4c7c3"
FORMATS = ("png", "svg", "pdf", "dot")
LAYOUTS = ("clusters", "flat", "plain")
RANKINGS = ((), ("-Gnewrank=true",))  # dot's usual ranking, then its other one

log = logging.getLogger("magna_sm.draw")
_FALLBACK_NOTES = {
    "flat": "graphviz could not lay out the clusters; drew them flat",
    "plain": "graphviz could not lay out the machine; drew it flat with the outcomes beside the arrows",
}
_noted: set[tuple[str, str]] = set()


class DrawError(RuntimeError):
    pass


def active_paths(root: Container) -> set[str]:
    """Paths of every state running now, containers included."""
    return {f"{container.path}/{label}" for container in root.walk() for label in container.get_active_states()}


def structures_of(root: Container) -> list[ContainerStructure]:
    return [container.describe() for container in root.walk()]


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def to_dot(structures: Iterable[ContainerStructure], active: Iterable[str] = (), title: str = "",
           layout: str = "clusters") -> str:
    """Graphviz source for the machine; `active` holds paths of running states; `layout` is one of LAYOUTS."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout '{layout}'; use one of {', '.join(LAYOUTS)}")
    by_path = {s.path: s for s in structures}
    if not by_path:
        raise DrawError("nothing to draw: no container structure given")
    active = set(active)
    clusters = layout == "clusters"
    label_attribute = "xlabel" if layout == "plain" else "label"
    roots = [path for path in by_path if path.rsplit("/", 1)[0] not in by_path]
    lines = ["digraph magna_sm {", f"  compound={'true' if clusters else 'false'}; rankdir=TB; fontname=Helvetica;",
             "  node [fontname=Helvetica, fontsize=11, shape=box, style=\"rounded,filled\", fillcolor=white];",
             "  edge [fontname=Helvetica, fontsize=9];"]
    if title:
        lines.append(f"  label={_quote(title)}; labelloc=t; fontsize=16;")
    edges: list[str] = []

    def anchor(path: str) -> str:
        """A node to hang edges on: the state itself, or a container's anchor (its node when flat)."""
        return _quote(path + ("/__anchor" if path in by_path else ""))

    def is_running(path: str) -> bool:
        return path in active or any(a.startswith(path + "/") for a in active)

    def emit(path: str, indent: str) -> None:
        structure = by_path[path]
        caption = path.rsplit("/", 1)[-1] + "  [" + structure.container_type + "]"
        fill = _quote(ACTIVE_CLUSTER if is_running(path) else IDLE_CLUSTER)
        inner = indent + "  " if clusters else indent
        if clusters:
            lines.append(f"{indent}subgraph {_quote('cluster_' + path)} {{")
            lines.append(f"{inner}label={_quote(caption)};")
            lines.append(f"{inner}style=\"rounded,filled\"; fillcolor={fill};")
            lines.append(f"{inner}{anchor(path)} [shape=point, style=invis, width=0];")
        else:
            lines.append(f"{indent}{anchor(path)} [label={_quote(caption)}, shape=folder, style=filled, "
                         f"fillcolor={fill}];")
            for label in structure.initial_states:
                edges.append(f"  {anchor(path)} -> {anchor(f'{path}/{label}')} [style=dashed, arrowhead=empty];")
        for label, child_type in zip(structure.children, structure.child_types, strict=True):
            child_path = f"{path}/{label}"
            if child_path in by_path:
                emit(child_path, inner)
            else:
                child_fill = ACTIVE_FILL if child_path in active else "white"
                border = ", penwidth=2" if label in structure.initial_states else ""
                lines.append(f"{inner}{_quote(child_path)} [label={_quote(label + chr(10) + child_type)}, "
                             f"fillcolor={_quote(child_fill)}{border}];")
        for outcome in structure.container_outcomes:
            lines.append(f"{inner}{_quote(path + '/:' + outcome)} [label={_quote(outcome)}, shape=box, "
                         f"style=\"filled\", fillcolor={_quote(OUTCOME_FILL)}];")
        if clusters:
            lines.append(f"{indent}}}")
        for source, outcome, target in structure.transitions:
            source_path = f"{path}/{source}"
            target_path = f"{path}/{target}" if target in structure.children else f"{path}/:{target}"
            attributes = [f"{label_attribute}={_quote(outcome)}"]
            tail = anchor(source_path)
            if source_path in by_path:
                if clusters:
                    attributes.append(f"ltail={_quote('cluster_' + source_path)}")
                elif outcome in by_path[source_path].container_outcomes:
                    tail = _quote(f"{source_path}/:{outcome}")  # flat: leave from the container's outcome box
            if clusters and target_path in by_path:
                attributes.append(f"lhead={_quote('cluster_' + target_path)}")
            head = anchor(target_path) if target in structure.children else _quote(target_path)
            edges.append(f"  {tail} -> {head} [{', '.join(attributes)}];")

    for root in roots:
        emit(root, "  ")
    lines.extend(edges)
    lines.append("}")
    return "\n".join(lines) + "\n"


def _format_of(output: Path) -> str:
    fmt = output.suffix.lstrip(".").lower()
    if fmt not in FORMATS:
        raise DrawError(f"{output}: unknown picture format '{output.suffix}'; use .png, .svg, .pdf or .dot")
    return fmt


def _first_line(text: str) -> str:
    return next((line.strip() for line in text.splitlines() if line.strip()), "no message")


def _write(output: Path, sources: Iterable[tuple[str, Callable[[], str]]]) -> tuple[Path, str]:
    """Write `output` from the first (layout, source) graphviz draws, atomically (replacing it).

    Returns the output and the layout drawn, `+newrank` appended when dot's other ranking drew it."""
    output = Path(output)
    fmt = _format_of(output)
    if fmt != "dot" and shutil.which("dot") is None:
        raise DrawError("graphviz's 'dot' is not installed: run 'make setup' (Debian package graphviz)")
    output.parent.mkdir(parents=True, exist_ok=True)
    first_error = ""
    for layout, make_source in sources:
        source = make_source()
        if fmt == "dot":  # the source itself: nothing to lay out
            return write_text_atomically(output, source, overwrite=True), layout
        for ranking in RANKINGS:
            done = subprocess.run(["dot", f"-T{fmt}", *ranking], input=source.encode(), capture_output=True)
            if done.returncode == 0 and done.stdout:
                drawn = layout + ("+newrank" if ranking else "")
                return write_bytes_atomically(output, done.stdout, overwrite=True), drawn
            first_error = first_error or _first_line(done.stderr.decode(errors="replace"))
    raise DrawError(f"graphviz could not draw {output}: {first_error}")


def render(dot_source: str, output: Path) -> Path:
    """Write `output` (.png, .svg or .pdf by its suffix; .dot writes the source) atomically.

    A source dot cannot rank is tried again with its other ranking; `draw_structures` also
    tries simpler layouts."""
    return _write(output, [("given", lambda: dot_source)])[0]


def draw_structures(structures: Iterable[ContainerStructure], output: Path, active: Iterable[str] = (),
                    title: str = "") -> Path:
    """Draw a machine's structures to a picture file, in the first of LAYOUTS graphviz can draw."""
    structures, active = list(structures), set(active)
    sources = [(layout, lambda layout=layout: to_dot(structures, active, title, layout)) for layout in LAYOUTS]
    output, layout = _write(output, sources)
    if layout.endswith("+newrank"):  # the whole picture still: not worth a line
        log.debug("%s: dot could not rank the %s layout; drew it with newrank", output, layout.split("+")[0])
    note = _FALLBACK_NOTES.get(layout.split("+")[0])
    if note and (str(output), note) not in _noted:
        _noted.add((str(output), note))
        log.warning("%s: %s", output, note)
    return output


def draw(container: Container, output: Path, title: str = "", show_active: bool = True) -> Path:
    """Draw a machine as it is now (its running states highlighted) to a picture file."""
    active = active_paths(container) if show_active else set()
    return draw_structures(structures_of(container), output, active, title)
