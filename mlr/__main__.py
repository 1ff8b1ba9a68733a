"""python -m mlr: the learning pipeline's commands (mlr.cli), from any Python.

A Python that is not the workspace's (pyenv's, the system's, the venv's without devel/setup.bash
sourced) runs the same command again in the workspace's environment first
(magna_common.workspace_bootstrap); `./magna learn ...` is the same program.
"""
import sys
from pathlib import Path

sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))  # standard library only
from magna_common.workspace_bootstrap import run_module_in_workspace  # noqa: E402

run_module_in_workspace("mlr", __file__, modules=("magna_uav", "magna_gs", "numpy", "torch", "yaml"))

from mlr.cli import main  # noqa: E402

sys.exit(main())
