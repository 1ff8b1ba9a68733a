"""Run a `python -m mlr`, `python -m voice` or `python bench/X.py` command in the MAGNA workspace,
whatever Python started it.

Those commands need the workspace's environment: its venv (torch, pocketsphinx, ...) and its devel
space sourced (the catkin packages, rospy, roslaunch on PATH). `./magna` and `scripts/with_env.sh`
set that up themselves; a bare `python` (pyenv's, the system's) does not. So an entry point calls
`run_in_workspace` first thing, before importing anything of MAGNA:

- already in the workspace (its venv's Python, its devel space sourced): nothing happens;
- else, when the workspace is set up (devel/setup.bash and .venv/bin/python exist): the same
  command is started again with the venv's Python, devel/setup.bash sourced, in the same folder
  (the process is replaced: exit status, signals and terminal stay the caller's);
- else, when this Python can import everything the command needs anyway (an installation of
  another kind): nothing happens;
- else: one line saying to run `make setup`, exit status 2.

Only the standard library is used here, so any Python 3 can import this file from the source tree
(e.g. after `sys.path.append(ROOT / "src/magna_common/src")`), before the workspace's paths are known.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

# Set in the command started again, so a workspace that still cannot run it is reported, not re-entered.
REEXEC_MARK = "MAGNA_WORKSPACE_REEXEC"
SETUP_HINT = "run 'make setup' there first"

# bash: source the devel space (in a function, so setup.bash does not see our arguments), put the venv
# first on PATH, then run the command. $1 is the workspace root, the rest is the command.
_ENV_SCRIPT = """\
root="$1"; shift
source_devel() { source "$root/devel/setup.bash"; }
source_devel || exit 2
export PATH="$root/.venv/bin:$PATH" MAGNA_ROOT="$root"
exec "$@"
"""


class WorkspaceNotReady(SystemExit):
    """The workspace cannot run the command; the message says what to do (exit status 2)."""

    def __init__(self, message: str):
        super().__init__(2)
        self.message = message


def is_checkout(folder: Path) -> bool:
    """`folder` is the root of a MAGNA checkout: it holds the `magna` script and src/magna_master."""
    return (folder / "magna").is_file() and (folder / "src" / "magna_master").is_dir()


def find_root(start: str | os.PathLike) -> Path | None:
    """The MAGNA checkout holding `start`."""
    here = Path(start).resolve()
    return next((folder for folder in [here, *here.parents] if is_checkout(folder)), None)


def venv_python(root: Path) -> Path:
    return root / ".venv" / "bin" / "python"


def is_set_up(root: Path) -> bool:
    """`make setup` has been run: the devel space and the venv exist."""
    return (root / "devel" / "setup.bash").is_file() and os.access(venv_python(root), os.X_OK)


def in_workspace(root: Path, prefix: str | None = None, environ: Mapping[str, str] | None = None) -> bool:
    """This is the workspace's venv Python, with the workspace's devel space sourced."""
    env: Mapping[str, str] = os.environ if environ is None else environ
    venv = root / ".venv"
    try:
        same_python = Path(prefix or sys.prefix).resolve() == venv.resolve()
    except OSError:
        same_python = False
    devel = str((root / "devel").resolve())
    sourced = any(part and Path(part).resolve() == Path(devel)
                  for part in env.get("CMAKE_PREFIX_PATH", "").split(os.pathsep))
    return same_python and sourced


def missing_modules(modules) -> list[str]:
    """Those of `modules` this Python cannot import (looked up, not imported)."""
    missing = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            missing.append(name)
    return missing


def reexec_argv(root: Path, command: list[str]) -> list[str]:
    """bash running `.venv/bin/python COMMAND...` with the devel space sourced."""
    return ["bash", "-c", _ENV_SCRIPT, "magna-workspace", str(root), str(venv_python(root)), *command]


def reexec_env(root: Path, python_path: Sequence[Path] = (), environ: Mapping[str, str] | None = None) -> dict:
    env = dict(os.environ if environ is None else environ)
    env[REEXEC_MARK] = str(root)
    extra = [str(p) for p in python_path]
    if extra:
        env["PYTHONPATH"] = os.pathsep.join([*extra, *[p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]])
    return env


def decide(root: Path | None, modules=(), *, prefix: str | None = None,
           environ: Mapping[str, str] | None = None) -> str:
    """What `run_in_workspace` does: 'run' (here), 'reexec', or an error message."""
    env: Mapping[str, str] = os.environ if environ is None else environ
    if root is not None and in_workspace(root, prefix, env):
        return "run"
    if root is not None and is_set_up(root) and not env.get(REEXEC_MARK):
        return "reexec"
    missing = missing_modules(modules)
    if not missing:
        return "run"
    if root is None:
        return (f"cannot import {', '.join(missing)} and this is not inside a MAGNA checkout: run it from a clone "
                "set up with 'make setup'")
    if not is_set_up(root):
        return f"the workspace in {root} is not set up yet: {SETUP_HINT}"
    return (f"cannot import {', '.join(missing)} even in the workspace's environment ({root}): "
            f"the setup is incomplete; {SETUP_HINT}")


def run_in_workspace(prog: str, anchor: str | os.PathLike, command: list[str], modules=(),
                     python_path: list[Path] | None = None) -> None:
    """Return when this Python can run `prog`; else run `command` with the workspace's Python instead.

    anchor: a file of the checkout (the caller's __file__), which locates the workspace.
    command: the arguments after the Python executable, e.g. ["-m", "mlr", *sys.argv[1:]].
    modules: what the command imports (for installations without a workspace venv).
    python_path: folders the command started again needs on its PYTHONPATH (e.g. the root for -m mlr).
    Raises WorkspaceNotReady (a SystemExit, status 2) after printing `prog: <what to do>`.
    """
    root = find_root(anchor)
    verdict = decide(root, modules)
    if verdict == "run":
        return
    if verdict == "reexec" and root is not None:
        argv = reexec_argv(root, command)
        env = reexec_env(root, python_path or [])
        sys.stdout.flush()
        sys.stderr.flush()
        try:
            os.execvpe(argv[0], argv, env)
        except OSError as error:
            verdict = f"cannot start {argv[0]} to enter the workspace in {root}: {error}"
    print(f"{prog}: {verdict}", file=sys.stderr)
    raise WorkspaceNotReady(verdict)


def run_module_in_workspace(module: str, anchor: str | os.PathLike, modules=()) -> None:
    """`python -m MODULE ARGS` from any Python: `run_in_workspace` with the same module and arguments.

    Call it from MODULE/__main__.py (anchor: its __file__); the package's folder goes on the PYTHONPATH
    of the command started again, so it is found from any current folder.
    """
    package_parent = Path(anchor).resolve().parent.parent
    run_in_workspace(f"python -m {module}", anchor, ["-m", module, *sys.argv[1:]], modules,
                     python_path=[package_parent])


def run_script_in_workspace(script: str | os.PathLike, modules=()) -> None:
    """`python SCRIPT ARGS` from any Python: `run_in_workspace` with the same script and arguments.

    Call it under `if __name__ == "__main__":` before the script imports anything of MAGNA.
    """
    path = Path(script).resolve()
    root = find_root(path)
    shown = path.relative_to(root) if root is not None and path.is_relative_to(root) else path
    run_in_workspace(f"python {shown}", path, [str(path), *sys.argv[1:]], modules)
