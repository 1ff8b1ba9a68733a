"""`python -m mlr|voice` and `python bench/X.py` find the workspace themselves, from any Python."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from magna_common import workspace_bootstrap as bootstrap

ROOT = Path(__file__).resolve().parents[3]

# Pythons that are not the workspace's: the venv's own without devel/setup.bash sourced, and the
# system's (Debian's ROS runs on it, so it is there wherever the workspace builds).
FOREIGN_PYTHONS = [sys.executable] + [p for p in ("/usr/bin/python3",) if Path(p).is_file()]


def bare_env(home: Path) -> dict:
    """What a new terminal has: nothing of ROS, the devel space or the venv."""
    return {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": str(home), "LANG": "C.UTF-8"}


def fake_checkout(tmp_path: Path, set_up: bool) -> Path:
    """A checkout's shape: the magna script, src/magna_master, devel/setup.bash and .venv/bin/python if `set_up`."""
    root = tmp_path / "clone"
    (root / "src" / "magna_master").mkdir(parents=True)
    (root / "magna").write_text("#!/bin/sh\n")
    if set_up:
        (root / "devel").mkdir()
        (root / "devel" / "setup.bash").write_text("export CMAKE_PREFIX_PATH=\"$root/devel\"\n")
        (root / ".venv" / "bin").mkdir(parents=True)
        python = root / ".venv" / "bin" / "python"
        python.symlink_to(sys.executable)
    return root


# --- what it decides ------------------------------------------------------------------------------------------

def test_in_the_workspace_the_command_runs_here(tmp_path):
    root = fake_checkout(tmp_path, set_up=True)
    env = {"CMAKE_PREFIX_PATH": f"{root / 'devel'}:/usr"}
    assert bootstrap.in_workspace(root, prefix=str(root / ".venv"), environ=env)
    assert bootstrap.decide(root, ("no_such_module_xyz",), prefix=str(root / ".venv"), environ=env) == "run"


def test_another_python_or_an_unsourced_shell_starts_it_again_in_the_workspace(tmp_path):
    root = fake_checkout(tmp_path, set_up=True)
    sourced = {"CMAKE_PREFIX_PATH": str(root / "devel")}
    assert bootstrap.decide(root, (), prefix="/usr", environ=sourced) == "reexec"  # another Python
    assert bootstrap.decide(root, (), prefix=str(root / ".venv"), environ={}) == "reexec"  # devel not sourced


def test_started_again_and_still_missing_modules_is_an_error_not_a_loop(tmp_path):
    root = fake_checkout(tmp_path, set_up=True)
    verdict = bootstrap.decide(root, ("no_such_module_xyz",), prefix="/usr",
                               environ={bootstrap.REEXEC_MARK: str(root)})
    assert verdict.startswith("cannot import no_such_module_xyz even in the workspace's environment")
    assert "run 'make setup' there first" in verdict


def test_a_checkout_not_set_up_says_make_setup_unless_this_python_has_everything(tmp_path):
    root = fake_checkout(tmp_path, set_up=False)
    assert bootstrap.decide(root, ("no_such_module_xyz",), prefix="/usr", environ={}) == (
        f"the workspace in {root} is not set up yet: run 'make setup' there first")
    assert bootstrap.decide(root, ("json",), prefix="/usr", environ={}) == "run"  # an installation of another kind


def test_the_command_started_again_is_the_same_in_the_same_folder_with_devel_sourced(tmp_path):
    root = fake_checkout(tmp_path, set_up=True)
    argv = bootstrap.reexec_argv(root, ["-m", "mlr", "train", "x.yaml"])
    assert argv[:2] == ["bash", "-c"] and argv[3:] == ["magna-workspace", str(root),
                                                       str(root / ".venv" / "bin" / "python"),
                                                       "-m", "mlr", "train", "x.yaml"]
    # the script: the devel space sourced, the venv first on PATH, then exactly the command
    done = subprocess.run(argv[:4] + [str(root), "sh", "-c", 'echo "$CMAKE_PREFIX_PATH|$PATH|$MAGNA_ROOT|$PWD|$1"',
                                      "sh", "one arg"], capture_output=True, text=True, cwd=tmp_path)
    cmake, path, magna_root, pwd, arg = done.stdout.strip().split("|")
    assert (cmake, magna_root, pwd, arg) == (str(root / "devel"), str(root), str(tmp_path), "one arg")
    assert path.split(":")[0] == str(root / ".venv" / "bin")
    env = bootstrap.reexec_env(root, [root], environ={"PYTHONPATH": "/a"})
    assert env[bootstrap.REEXEC_MARK] == str(root) and env["PYTHONPATH"] == f"{root}:/a"


# --- from a bare terminal, as the READMEs say -----------------------------------------------------------------

@pytest.mark.parametrize("python", FOREIGN_PYTHONS)
def test_python_m_voice_parse_works_from_a_bare_terminal(python, tmp_path):
    done = subprocess.run([python, "-m", "voice", "parse", "all drones land"], cwd=ROOT, env=bare_env(tmp_path),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert '"command": {"intent": "basic_action", "action": "land", "agent": "all"' in done.stdout


@pytest.mark.parametrize("python", FOREIGN_PYTHONS)
def test_python_m_mlr_works_from_a_bare_terminal(python, tmp_path):
    done = subprocess.run([python, "-m", "mlr", "pickle", "--help"], cwd=ROOT, env=bare_env(tmp_path),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "-o PATH.npz, --output PATH.npz" in done.stdout


@pytest.mark.parametrize("python", FOREIGN_PYTHONS)
def test_a_bench_script_runs_from_any_folder_with_any_python(python, tmp_path):
    done = subprocess.run([python, str(ROOT / "bench" / "sm_engine.py"), "--transitions", "20", "--repeats", "1"],
                          cwd=tmp_path, env=bare_env(tmp_path), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "transition, no observer (us)" in done.stdout


def test_a_checkout_that_is_not_set_up_says_so_in_one_line(tmp_path):
    root = fake_checkout(tmp_path, set_up=False)
    shutil.copytree(ROOT / "src" / "magna_common" / "src", root / "src" / "magna_common" / "src",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (root / "mlr").mkdir()
    shutil.copy(ROOT / "mlr" / "__main__.py", root / "mlr" / "__main__.py")
    (root / "mlr" / "__init__.py").write_text("")
    done = subprocess.run([sys.executable, "-m", "mlr", "--help"], cwd=root, env=bare_env(tmp_path),
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"python -m mlr: the workspace in {root} is not set up yet: run 'make setup' there first"]
