"""The root works as a plain CMake source space even when another python3 comes first on PATH.

pyenv and conda put a python3 without catkin_pkg first on PATH; catkin's configure step runs
Python and failed on catkin_pkg there. The root CMakeLists.txt picks /usr/bin/python3 itself.
"""
import os
import subprocess

from tests.support import ROOT


def test_cmake_configures_with_a_foreign_python3_first_on_path(tmp_path):
    foreign = tmp_path / "bin"
    foreign.mkdir()
    for name in ("python", "python3"):  # a python3 that has no catkin_pkg (here: none at all)
        script = foreign / name
        script.write_text("#!/bin/sh\necho 'No module named catkin_pkg' >&2\nexit 1\n")
        script.chmod(0o755)
    env = {key: value for key, value in os.environ.items()
           if not key.startswith(("ROS_", "CMAKE_PREFIX_PATH", "PYTHONPATH", "CATKIN_"))}
    env["PATH"] = f"{foreign}:{env['PATH']}"
    result = subprocess.run(["cmake", "-S", str(ROOT), "-B", str(tmp_path / "build"),
                             f"-DCATKIN_DEVEL_PREFIX={tmp_path / 'devel'}"],
                            env=env, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "Using PYTHON_EXECUTABLE: /usr/bin/python3" in result.stdout
