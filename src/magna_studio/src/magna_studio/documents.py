"""What the world and mission designers share: diagnostics placed on a field, finding files, saving them.

A `Diagnostic` is one finding of `magna world check` or `magna mission check`, with the JSON path of
the field it is about, so the page can show it on that field, and the exact line the command prints.
The checkers report `file: JSON.path: message`; `finding` takes such a text apart, keeping the path
only when it names a place of the document (a message may hold colons too). Paths of a migrated file
are turned into the current schema's with `current_path`, since the page edits the migrated document.

Files are found as `magna run` finds them (magna_common.search_path), and saved atomically, as the
original's files are written: 4-space indentation, a list of numbers on one line.
"""
from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from magna_common import search_path as lookup
from magna_common.errors import UsageError
from magna_common.files import write_text_atomically
from magna_common.json_fields import UnreadableJson, read_json_document

Severity = Literal["error", "warning"]
WARNING_PREFIX = "warning: "  # how the commands print what the original tolerated
PROJECT_ORIGIN = "project"
INDENT = "    "


@dataclass(frozen=True)
class Diagnostic:
    """One finding of a check, placed on the field it is about."""

    severity: Severity
    path: str  # JSON path in the document, e.g. "scenario.volumes[0].geometries[1].dimensions"; "" = whole file
    message: str  # what is wrong and how to fix it, as the command says it
    line: str  # the line `magna world check` / `magna mission check` prints, without its "magna world: " prefix

    def to_json(self) -> dict[str, str]:
        return asdict(self)


class DocumentExists(Exception):
    """A save refused: the file exists and overwriting it was not asked for."""


class DesignError(Exception):
    """A file that cannot be opened or saved; the message names the file and the fix."""


def one_line(text: str) -> str:
    """A finding on one line, as the commands print it."""
    return " ".join(text.split())


def command_line(severity: Severity, text: str) -> str:
    """The line `magna world|mission check` prints for a finding, without the command's prefix."""
    return (WARNING_PREFIX if severity == "warning" else "") + one_line(text)


def on_field(severity: Severity, path: str, message: str, text: str) -> Diagnostic:
    """A finding whose parts are known: on `path` ("" the whole file); `text` is what the checker prints."""
    return Diagnostic(severity, path, one_line(message), command_line(severity, text))


def finding(severity: Severity, text: str, source: str, *documents: Any) -> Diagnostic:
    """A checker's `source: JSON.path: message` as a Diagnostic on that path. The path is kept when it names a
    place of one of `documents` (a file as written and as migrated: the checkers speak of both); a finding about
    another file (an included world), or one whose path names no place, is about the whole file (path "") and
    keeps its full text as the message."""
    flat = one_line(text)
    head = f"{source}: "
    if not flat.startswith(head):
        return Diagnostic(severity, "", flat, command_line(severity, text))
    rest = flat[len(head):]
    path, separator, message = rest.partition(": ")
    if separator and any(names_a_place(document, path) for document in documents):
        return Diagnostic(severity, path, message, command_line(severity, text))
    return Diagnostic(severity, "", rest, command_line(severity, text))


_KEY = re.compile(r"[^.\[\]\s]+")
_INDEX = re.compile(r"\[(\d+)\]")


def path_steps(path: str) -> list[str | int] | None:
    """`a.b[2].c` -> ["a", "b", 2, "c"]; None when `path` is not a JSON path (spaces, stray brackets or dots)."""
    steps: list[str | int] = []
    position = 0
    while position < len(path):
        index = _INDEX.match(path, position)
        if index is not None:
            steps.append(int(index.group(1)))
            position = index.end()
            continue
        dot = 1 if steps and path.startswith(".", position) else 0
        key = _KEY.match(path, position + dot)
        if key is None or (steps and not dot):  # a key after another step follows a dot
            return None
        steps.append(key.group())
        position = key.end()
    return steps or None


def names_a_place(document: Any, path: str) -> bool:
    """Whether `path` is a place of `document`: every step but the last exists, and the last fits its parent
    (a key of an object, an index of a list): a missing key is a place too, where a field is asked for."""
    steps = path_steps(path)
    if steps is None:
        return False
    node = document
    for step in steps[:-1]:
        if isinstance(step, str) and isinstance(node, dict) and step in node:
            node = node[step]
        elif isinstance(step, int) and isinstance(node, list) and step < len(node):
            node = node[step]
        else:
            return False
    last = steps[-1]
    return isinstance(node, dict) if isinstance(last, str) else isinstance(node, list)


def current_path(renamed: Mapping[str, str], path: str) -> str:
    """A JSON path of a file as it is written -> the path in its migrated document (`renamed` maps the migrated
    paths to the file's, as magna_worlds.migrate.Migration.renamed)."""
    best_old, best_new = "", ""
    for new, old in renamed.items():
        if (path == old or path.startswith(old + ".") or path.startswith(old + "[")) and len(old) > len(best_old):
            best_old, best_new = old, new
    return best_new + path[len(best_old):] if best_old else path


def in_current_schema(diagnostic: Diagnostic, renamed: Mapping[str, str]) -> Diagnostic:
    """The diagnostic placed on the migrated document's field (its line stays the command's)."""
    if not diagnostic.path or not renamed:
        return diagnostic
    return Diagnostic(diagnostic.severity, current_path(renamed, diagnostic.path), diagnostic.message,
                      diagnostic.line)


def design_error(error: Exception) -> DesignError:
    """A lookup's UsageError, MissionError or an unreadable file, as the one error of a file not opened."""
    return DesignError(one_line(str(error)))


def read_document(path: Path) -> Any:
    """The JSON in `path`; DesignError naming the file and what to do when it cannot be read."""
    try:
        return read_json_document(path)
    except UnreadableJson as error:
        raise DesignError(f"{path}: {error}") from None


def require_object(data: Any, path: Path, what: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise DesignError(f"{path}: the top level is not an object, so the studio cannot show it as a {what}; "
                          f"check it with `magna {what} check {path}`")
    return data


# --- finding files -------------------------------------------------------------------------------------------------

_KINDS: dict[str, lookup.Kind] = {"world": lookup.WORLDS, "mission": lookup.MISSIONS}


def list_files(kind: str, search_path: list[Path]) -> list[dict[str, str]]:
    """The worlds or missions a name `WORLD/SUBWORLD` (`MISSION/SUBMISSION`) finds, as `magna run` finds them:
    [{"name", "path" (absolute), "origin": "project" or the search folder}], in search order, each name once (the
    file `magna run` would take). A JSON file of another kind (an airframe beside the worlds) is left out; one that
    does not parse is listed, so that opening it says what is wrong."""
    if kind not in _KINDS:
        raise ValueError(f"kind must be world or mission, got {kind!r}")
    what = _KINDS[kind]
    try:
        lookup.check_search_dirs(search_path)
    except UsageError as error:
        raise design_error(error) from None
    folders = lookup.search_folders(what, search_path)
    project = what.project_folder()
    listed: dict[str, dict[str, str]] = {}
    for folder in folders:
        for pattern in lookup.candidates(what, "*/*", [folder]):  # the layouts a name is looked up in, in order
            for file in sorted(pattern.parent.parent.glob("*/*.json")):
                name = f"{file.parent.name}/{file.stem}"
                if name in listed or lookup.find(what, name, folders) != file or not _may_be(kind, file):
                    continue
                origin = PROJECT_ORIGIN if project is not None and folder == project else str(folder)
                listed[name] = {"name": name, "path": str(file.resolve()), "origin": origin}
    return list(listed.values())


def _may_be(kind: str, file: Path) -> bool:
    """False for a file that parses as JSON of another kind; a file that does not parse may be either."""
    try:
        data = read_json_document(file)
    except UnreadableJson:
        return True
    if kind == "world":
        return isinstance(data, list) or (isinstance(data, dict) and "scenario" in data)
    if isinstance(data, list):  # the oldest missions are the state list alone
        return bool(data) and all(isinstance(state, dict) and "type" in state for state in data)
    return isinstance(data, dict) and any(key in data for key in ("Agents_Config", "UAVs_Config", "State_Machine"))


# --- saving --------------------------------------------------------------------------------------------------------

def format_document(data: Any) -> str:
    """JSON as the original's files are written: objects one key a line, 4 spaces deep; a list of numbers or
    names (or of such lists, a pose [[x, y, z], [r, p, y]]) on one line."""
    return _format(data, "") + "\n"


def _format(value: Any, indent: str) -> str:
    inner = indent + INDENT
    if isinstance(value, dict) and value:
        items = [f"{inner}{json.dumps(str(key), ensure_ascii=False)}: {_format(item, inner)}"
                 for key, item in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{indent}}}"
    if isinstance(value, list) and value and not _flat(value):
        return "[\n" + ",\n".join(f"{inner}{_format(item, inner)}" for item in value) + f"\n{indent}]"
    return json.dumps(value, ensure_ascii=False, allow_nan=False)


def _flat(items: Iterable[Any]) -> bool:
    return all(not isinstance(item, dict) and (not isinstance(item, list) or _flat(item)) for item in items)


def save_document(data: dict[str, Any], path: Path, overwrite: bool = False) -> Path:
    """Write `data` to `path` (a .json file in an existing folder) atomically: a reader or a crash never sees
    half a file. DocumentExists when `path` exists and `overwrite` is not given; DesignError for a missing
    folder, a name that is not *.json, or a value JSON cannot hold."""
    path = Path(path).expanduser()
    if path.suffix != ".json":
        raise DesignError(f"{path}: worlds and missions are .json files (magna run finds them by that name); "
                          "name it *.json")
    if not path.parent.is_dir():
        raise DesignError(f"{path}: folder {path.parent} does not exist; create it first or save elsewhere")
    if path.is_dir():
        raise DesignError(f"{path}: is a folder; give a file name")
    if path.exists() and not overwrite:
        raise DocumentExists(f"{path}: already exists; save with overwrite to replace it, or choose another name")
    try:
        text = format_document(data)
    except (TypeError, ValueError) as error:  # NaN, infinity or a non-JSON value: the file could not be read back
        raise DesignError(f"{path}: cannot be written as JSON: {error}; give finite numbers, text, lists and "
                          "objects only") from None
    try:
        return write_text_atomically(path, text, overwrite=overwrite)
    except FileExistsError:  # appeared while writing
        raise DocumentExists(f"{path}: already exists; save with overwrite to replace it, or choose another "
                             "name") from None
    except OSError as error:
        raise DesignError(f"{path}: cannot write it: {error.strerror or error}") from None


def document_name(path: Path) -> str:
    """`WORLD/SUBWORLD` (`MISSION/SUBMISSION`): the name `magna run` takes for the file."""
    return f"{path.parent.name}/{path.stem}"
