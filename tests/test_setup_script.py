"""scripts/setup.sh (what `make setup` runs): quick when done, and clear without root."""
import os
import subprocess
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_second_run_does_nothing():
    out = subprocess.run(["bash", "scripts/setup.sh"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "installing" not in out.stdout
    assert "catkin build" not in out.stdout
    assert "ready" in out.stdout


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to switch to an unprivileged user")
def test_without_root_it_prints_the_exact_apt_command():
    # In /tmp itself: pytest's own tmp_path is readable by root only.
    with tempfile.NamedTemporaryFile("w", suffix=".txt", dir="/tmp") as handle:
        handle.write("bash\nmagna-no-such-package  # missing on purpose\n")
        handle.flush()
        os.chmod(handle.name, 0o644)
        out = _run_as_nobody(handle.name)
    assert out.returncode == 1
    assert ("sudo sh -c 'apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y "
            "--no-install-recommends magna-no-such-package'") in out.stderr
    assert "make setup" in out.stderr


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to switch to an unprivileged user")
def test_an_unreadable_package_list_stops_before_any_other_step():
    out = _run_as_nobody("/root/magna-no-such-list.txt")
    assert out.returncode == 2
    assert "cannot read the package list /root/magna-no-such-list.txt" in out.stderr


def _run_as_nobody(apt_list):
    return subprocess.run(
        ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "bash", "scripts/setup.sh"],
        cwd=ROOT, env={"PATH": "/usr/bin:/bin", "MAGNA_APT_LIST": str(apt_list)},
        capture_output=True, text=True, timeout=60)
