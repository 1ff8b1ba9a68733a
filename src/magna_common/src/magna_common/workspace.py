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


def magna_version(root: Path | None = None) -> str:
    """This checkout's MAGNA version: the packages' version and its git commit, with a digest of uncommitted
    changes when there are some ('0.1.0 eb8d783a9ab9+3f2a01bc'); two installs with the same string run the
    same code. Without git (an exported tree) only the packages' version is known."""
    import hashlib
    import re
    import subprocess

    root = root or find_root()
    package_xml = (root / "src" / "magna_master" / "package.xml").read_text()
    found = re.search(r"<version>\s*([^<\s]+)\s*</version>", package_xml)
    version = found.group(1) if found else "unknown"

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, timeout=20)
        except (OSError, subprocess.TimeoutExpired):
            return None
        return done.stdout.decode(errors="replace") if done.returncode == 0 else None

    commit = (git("rev-parse", "HEAD") or "").strip()
    if not commit:
        return f"{version} (no git commit)"
    changes = git("diff", "HEAD", "--", "src", "worlds", "missions", "scripts", "requirements.txt")
    local = f"+{hashlib.sha256(changes.encode()).hexdigest()[:8]}" if changes else ""
    return f"{version} {commit[:12]}{local}"
