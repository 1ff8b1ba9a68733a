"""The `magna` entry point, from a clone (./magna) and from a sourced devel space."""
import subprocess
from pathlib import Path

from magna_master import cli

ROOT = Path(__file__).resolve().parents[3]


def test_help_lists_the_existing_commands(capsys):
    assert cli.main([]) == 2
    listed = capsys.readouterr().out
    for name, _module in cli.COMMANDS:
        assert name in listed


def test_every_command_has_help(capsys):
    for name, _module in cli.COMMANDS:
        try:
            cli.main([name, "--help"])
        except SystemExit as done:
            assert done.code == 0
        assert f"usage: magna {name}" in capsys.readouterr().out


def run_in_clean_shell(script: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """`script` in bash with nothing of the test's ROS or venv environment."""
    return subprocess.run(["bash", "-c", script], env={"PATH": "/usr/bin:/bin", "HOME": str(Path.home())},
                          capture_output=True, text=True, timeout=timeout)


def test_repository_wrapper_runs_without_a_sourced_environment():
    out = run_in_clean_shell(f"{ROOT}/magna --help")
    assert out.returncode == 0, out.stderr
    assert "doctor" in out.stdout


def test_magna_is_on_path_after_sourcing_devel():
    out = run_in_clean_shell(f"source {ROOT}/devel/setup.bash && command -v magna && command -v python3 "
                             "&& magna --help")
    assert out.returncode == 0, out.stderr
    magna_path, python_path = out.stdout.splitlines()[:2]
    assert magna_path == str(ROOT / "devel" / "bin" / "magna")
    assert python_path == str(ROOT / ".venv" / "bin" / "python3")  # the env hook puts the venv first
    assert "doctor" in out.stdout


def test_ros_nodes_run_by_system_python_see_the_venv():
    """rosrun relays use /usr/bin/python3; after sourcing, the venv's packages must import there too."""
    out = run_in_clean_shell(f"source {ROOT}/devel/setup.bash && "
                             "/usr/bin/python3 -c 'import torch, pybullet, matplotlib, rospy'")
    assert out.returncode == 0, out.stderr


def test_unknown_command_is_a_usage_error():
    out = subprocess.run([str(ROOT / "magna"), "fly-to-the-moon"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert "invalid choice" in out.stderr
