"""Helpers shared by tests of several packages (importable as tests.support)."""
import importlib.util
import os
import re
import sys
import time
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
# The real ROS-MAGNA files, read in place (never copied into the project): ../shared/ros_magna_corpus.
CORPUS = Path(os.environ.get("MAGNA_CORPUS", ROOT.parent / "shared" / "ros_magna_corpus"))

# The smallest mission a simulation runs: add the world of the hyperparameters, end.
WORLD_ONLY = {
    "Agents_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]}],
    "State_Machine": [
        {"type": "CBState", "state_type": "world_config", "name": "new_world",
         "parameters": {"action": "spawn", "id": 1}, "outcomes": {"completed": "add_world"}},
        {"type": "CBState", "state_type": "world_config", "name": "add_world",
         "parameters": {"action": "add", "world_part_def": "from_hyperparameters"},
         "outcomes": {"completed": "completed"}},
    ],
}

WAIT = 10.0  # s: a guard against hangs, never a performance expectation


def wait_until(predicate, what: str, timeout: float = WAIT, poll: float = 0.005) -> None:
    """Return as soon as `predicate()` holds; fail the test naming `what` after `timeout` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll)
    raise AssertionError(f"timed out waiting for {what}")


def load_module(path: Path, name: str | None = None) -> ModuleType:
    """The Python file at `path` as a module named `name` (its file name without .py by default): scripts and
    test helpers that are no package's modules. Its `if __name__ == "__main__"` part does not run. Registered in
    sys.modules under that name first, as dataclasses look their module up there while a class is made."""
    spec = importlib.util.spec_from_file_location(name or Path(path).stem, path)
    assert spec is not None and spec.loader is not None, f"{path} is no Python file"
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def ros_nodes(root: Path = ROOT) -> list[tuple[str, str]]:
    """(package, node) for every node a user can rosrun: the scripts in each package's nodes/, those
    installed by catkin_install_python, and the C++ programs installed as RUNTIME targets."""
    found = set()
    for package in sorted(path.parent for path in root.glob("src/*/package.xml")):
        found |= {(package.name, script.name) for script in (package / "nodes").glob("*") if script.is_file()}
        cmake = package / "CMakeLists.txt"
        text = cmake.read_text() if cmake.is_file() else ""
        for programs in re.findall(r"catkin_install_python\s*\(\s*PROGRAMS(.*?)DESTINATION", text, re.S):
            found |= {(package.name, os.path.basename(program)) for program in programs.split()}
        found |= {(package.name, name) for name in re.findall(r"install\(TARGETS\s+(\w+)\s+RUNTIME", text)}
    return sorted(found)


def exit_unless_in_workspace(package: str, needed: tuple[str, ...]) -> None:
    """From a package's conftest: with a Python outside the workspace (pyenv's, the system's) its tests
    would fail one by one on imports; say so once, with the command that works."""
    import pytest

    missing = [name for name in needed if importlib.util.find_spec(name) is None]
    if missing:
        pytest.exit(f"{package}'s tests need the workspace's environment (this Python cannot import "
                    f"{', '.join(missing)}): run them as scripts/with_env.sh python -m pytest {package}",
                    returncode=2)
