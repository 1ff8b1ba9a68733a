"""Where the MAGNA workspace is, and what of it is set up."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from magna_common.workspace_bootstrap import is_checkout


class WorkspaceNotFound(RuntimeError):
    pass


def find_root(start: Path | None = None) -> Path:
    """The repository root: $MAGNA_ROOT, else the clone this module lives in, else a parent of `start`."""
    env_root = os.environ.get("MAGNA_ROOT")
    if env_root and is_checkout(Path(env_root)):
        return Path(env_root).resolve()
    candidates = [Path(__file__).resolve()]
    candidates.append((start or Path.cwd()).resolve())
    for candidate in candidates:
        for parent in [candidate, *candidate.parents]:
            if is_checkout(parent):
                return parent
    raise WorkspaceNotFound(
        "cannot find the MAGNA workspace: run magna from a clone, or set MAGNA_ROOT to the repository root"
    )


@dataclass(frozen=True)
class Workspace:
    root: Path

    @classmethod
    def locate(cls) -> Workspace:
        return cls(find_root())

    @property
    def devel_setup(self) -> Path:
        return self.root / "devel" / "setup.bash"

    @property
    def apt_packages_file(self) -> Path:
        return self.root / "scripts" / "apt-packages.txt"

    def apt_packages(self) -> list[str]:
        lines = self.apt_packages_file.read_text().splitlines()
        return [line.split("#", 1)[0].strip() for line in lines if line.split("#", 1)[0].strip()]


def node_script(package: str, node: str) -> str:
    """The script `rosrun package node` runs (the built workspace's relay to the node's source); RuntimeError with the
    fix when it is not built."""
    import roslib.packages

    found = roslib.packages.find_node(package, node)
    if not found:
        raise RuntimeError(f"rosrun {package} {node} is not found: build the workspace (catkin build)")
    return found[0]
