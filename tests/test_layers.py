"""The workspace's packages import only downwards, as pyproject.toml declares the layers.

The checker (scripts/import_graph.py) is first run on small made-up workspaces, so that each rule is
seen to catch what it should, then on this workspace.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from tests.support import load_module

ROOT = Path(__file__).resolve().parents[1]


graph_checker = load_module(ROOT / "scripts" / "import_graph.py")

LAYERS = """
[tool.magna.layers]
order = [["low_pkg"], ["mid_a", "mid_b"], ["top"]]
"""


def _package(root: Path, name: str, modules: dict[str, str], depends: tuple[str, ...] = ()) -> None:
    code = root / "src" / name / "src" / name
    code.mkdir(parents=True)
    (code / "__init__.py").write_text("")
    for module, text in modules.items():
        (code / f"{module}.py").write_text(textwrap.dedent(text))
    lines = "".join(f"  <exec_depend>{d}</exec_depend>\n" for d in depends)
    xml = f'<package format="3">\n  <name>{name}</name>\n{lines}</package>\n'
    (root / "src" / name / "package.xml").write_text(xml)


@pytest.fixture
def workspace(tmp_path: Path) -> Path:
    (tmp_path / "pyproject.toml").write_text(LAYERS)
    _package(tmp_path, "low_pkg", {"tools": "X = 1\n"})
    _package(tmp_path, "mid_a", {"engine": "from low_pkg.tools import X\n"}, depends=("low_pkg",))
    _package(tmp_path, "mid_b", {"other": "import low_pkg.tools\n"}, depends=("low_pkg",))
    _package(tmp_path, "top", {"cli": "import mid_a.engine\nimport mid_b.other\n"}, depends=("mid_a", "mid_b"))
    return tmp_path


def test_a_workspace_that_imports_downwards_has_no_problem(workspace):
    assert graph_checker.check(workspace) == []


def test_a_lazy_import_upwards_is_caught_with_its_file_and_line(workspace):
    tools = workspace / "src/low_pkg/src/low_pkg/tools.py"
    tools.write_text("X = 1\n\n\ndef later():\n    from top.cli import main\n    return main\n")
    problems = graph_checker.check(workspace)
    assert "src/low_pkg/src/low_pkg/tools.py:5: low_pkg imports top.cli, up in the layers " \
           "(low_pkg is in layer 0, top in layer 2)" in problems
    # and package.xml does not declare it either
    assert any(p.startswith("src/low_pkg/package.xml: imports top but does not declare it") for p in problems)


def test_an_import_sideways_is_caught(workspace):
    (workspace / "src/mid_a/src/mid_a/engine.py").write_text("from low_pkg.tools import X\nimport mid_b.other\n")
    problems = graph_checker.check(workspace)
    assert any("mid_a imports mid_b.other, sideways in the layers" in p for p in problems)


def test_a_message_package_may_be_imported_from_its_own_layer(workspace):
    (workspace / "src/low_msgs").mkdir()  # generated message types only: no Python of ours
    (workspace / "src/low_msgs/package.xml").write_text('<package format="3">\n  <name>low_msgs</name>\n</package>\n')
    (workspace / "pyproject.toml").write_text(LAYERS.replace('["low_pkg"]', '["low_pkg", "low_msgs"]'))
    (workspace / "src/low_pkg/src/low_pkg/tools.py").write_text("from low_msgs.msg import Point\n\nX = 1\n")
    assert graph_checker.check(workspace) == []


def test_a_dependency_declared_but_never_imported_is_caught(workspace):
    _package(workspace, "unused_dep", {})
    (workspace / "pyproject.toml").write_text(LAYERS.replace('["low_pkg"]', '["low_pkg", "unused_dep"]'))
    xml = workspace / "src/mid_a/package.xml"
    xml.write_text(xml.read_text().replace("</package>", "  <exec_depend>unused_dep</exec_depend>\n</package>"))
    assert graph_checker.check(workspace) == [
        "src/mid_a/package.xml: declares unused_dep but imports nothing of it; "
        "remove <exec_depend>unused_dep</exec_depend>"]


def test_a_package_without_a_layer_is_caught(workspace):
    _package(workspace, "stray", {})
    assert "stray: no layer; add it to [tool.magna.layers] order in pyproject.toml" in graph_checker.check(workspace)


def test_a_circle_between_two_modules_of_a_package_is_caught(workspace):
    code = workspace / "src/top/src/top"
    (code / "a.py").write_text("def f():\n    from top import b\n    return b\n")
    (code / "b.py").write_text("import top.a\n")
    assert "import circle between modules: top.a -> top.b" in graph_checker.check(workspace)


def test_this_workspace_imports_only_downwards():
    problems = graph_checker.check(ROOT)
    assert problems == [], "\n".join(problems)
