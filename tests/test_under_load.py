"""scripts/under_load.py: its runs count failures and skips as unclean, its busy processes end with it."""
import re
import subprocess
import sys
import textwrap

import pytest

from magna_common.processes import pid_alive
from tests.support import ROOT, load_module

SCRIPT = ROOT / "scripts" / "under_load.py"


def load():
    return load_module(SCRIPT)


def test_a_failure_or_a_skip_makes_the_proof_fail_and_the_hogs_end(tmp_path):
    tests = tmp_path / "test_sample.py"
    tests.write_text(textwrap.dedent("""
        import pytest

        def test_passes():
            assert sorted([3, 1, 2]) == [1, 2, 3]

        def test_fails():
            assert False

        @pytest.mark.skip(reason="hidden")
        def test_skipped():
            pass
    """))
    run = subprocess.run([sys.executable, str(SCRIPT), "--runs", "2", "--hogs", "2", "--", str(tests)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 1, run.stderr
    assert "run  1/2: 1 passed, 1 failed, 1 skipped" in run.stdout
    assert "0 of 2 runs clean" in run.stdout
    pids = [int(pid) for pid in re.search(r"busy processes: ([\d ]+)", run.stdout).group(1).split()]
    assert len(pids) == 2 and not any(pid_alive(pid) for pid in pids), "a busy process outlived the script"


def test_only_passing_tests_are_clean(tmp_path):
    tests = tmp_path / "test_sample.py"
    tests.write_text("def test_passes():\n    assert 1 + 1 == 2\n")
    run = subprocess.run([sys.executable, str(SCRIPT), "--runs", "1", "--hogs", "0", "--", str(tests)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "1 of 1 runs clean" in run.stdout


def test_a_package_test_file_is_run_with_rostest():
    module = load()
    assert module.rostest_command(ROOT / "src/magna_uav/test/uav_manager.test") == [
        "rostest", "magna_uav", "uav_manager.test"]


def test_bad_counts_are_refused():
    with pytest.raises(SystemExit) as stop:
        load().parse_args(["--runs", "0"])
    assert stop.value.code == 2
