"""A data root that cannot take the data, and a disk that fills up during a batch (issue 26, item 8).

Each test mounts a small tmpfs of its own as the data root (as root; otherwise the test runs itself
again inside `unshare -rm`, a user namespace in which it may mount one) and unmounts it at the end.

- A read-only data root, or one whose disk is full or below --min-free-space, is refused before
  anything starts: exit status 2, one line naming the folder and the fix, no process started.
- A disk that fills up while a simulation flies: that simulation ends, the batch stops with a clear
  error naming the disk's folder and --append, summary.csv stays whole (the finished simulation's
  row, readable), no half-written file and no process is left; once there is room again, --append
  continues the dataset and gives the cut simulation its summary row.
"""
from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from magna_common.records import SummaryRow
from magna_common.storage_tree import SUMMARY_FILE, existing_simulations, simulation_dir
from tests.faults.batch_runs import (
    MagnaRun,
    append_one_simulation,
    dataset_dir,
    summary_ids,
    temporary_files,
    wait_for,
)

IN_NAMESPACE_ENV = "MAGNA_DISK_TEST_IN_NAMESPACE"


def rerun_in_user_namespace(request) -> None:
    """Not root: run this very test again inside `unshare -rm` (root there, with a mount namespace)."""
    if os.environ.get(IN_NAMESPACE_ENV):
        pytest.fail("inside `unshare -rm` this process is still not root: user namespaces do not map root here")
    if shutil.which("unshare") is None:
        pytest.fail("mounting a size-limited tmpfs needs root, or `unshare -rm` (util-linux), which is not "
                    "installed: run the test as root or install util-linux")
    done = subprocess.run(["unshare", "-rm", sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           f"{request.node.path}::{request.node.name}"], env={**os.environ, IN_NAMESPACE_ENV: "1"},
                          capture_output=True, text=True, cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, f"the test inside `unshare -rm` failed:\n{done.stdout[-5000:]}\n{done.stderr[-2000:]}"


class SmallDisk:
    """A tmpfs of `size` mounted at `path` (the caller is root)."""

    def __init__(self, path: Path, size: str):
        self.path = path
        path.mkdir(parents=True, exist_ok=True)
        mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size},mode=0755", "tmpfs", str(path)],
                                 capture_output=True, text=True)
        if mounted.returncode != 0:
            pytest.fail(f"cannot mount a tmpfs at {path}: {mounted.stderr.strip()} (the test needs root or "
                        "`unshare -rm`)")

    def read_only(self) -> None:
        subprocess.run(["mount", "-o", "remount,ro", str(self.path)], check=True)

    def fill(self, keep_bytes: int = 0) -> Path:
        """Write a file until the disk is full, or has only about `keep_bytes` free."""
        filler = self.path / f"filler_{len(list(self.path.glob('filler_*')))}"
        chunk = b"\0" * 65536
        with open(filler, "wb", buffering=0) as out:
            try:
                while shutil.disk_usage(self.path).free > keep_bytes:
                    out.write(chunk[:max(4096, min(len(chunk), shutil.disk_usage(self.path).free - keep_bytes))])
            except OSError as err:
                if err.errno != errno.ENOSPC:
                    raise
        return filler

    def unmount(self) -> None:
        subprocess.run(["umount", "-l", str(self.path)], capture_output=True)


@pytest.fixture
def small_disk(request, tmp_path):
    """Make SmallDisk(size) at tmp_path/disk; unmounted at the end. None when the test reran in a namespace."""
    disks: list[SmallDisk] = []

    def make(size: str) -> SmallDisk:
        disk = SmallDisk(tmp_path / "disk", size)
        disks.append(disk)
        return disk

    yield make
    for disk in disks:
        disk.unmount()


def needs_root(request) -> bool:
    """True when this process may mount; otherwise the test reran itself in a user namespace (asserted)."""
    if os.geteuid() == 0:
        return True
    rerun_in_user_namespace(request)
    return False


def refused(run: MagnaRun) -> tuple[int, str]:
    status = run.start().wait(timeout=120)
    left = run.wait_for_no_process()
    run.kill_everything()
    assert not left, f"processes started although the batch was refused: {left}"
    return status, run.output()


@pytest.mark.parametrize("dataset_exists", [False, True], ids=["new dataset", "existing dataset"])
def test_a_read_only_data_root_is_refused_before_anything_starts(request, small_disk, tmp_path, dataset_exists):
    if not needs_root(request):
        return
    disk = small_disk("4m")
    data_root = disk.path / "data"
    if dataset_exists:
        dataset_dir(data_root).mkdir(parents=True)
    disk.read_only()
    status, output = refused(MagnaRun(data_root, tmp_path / "run"))
    assert status == 2, output
    folder = dataset_dir(data_root) if dataset_exists else disk.path
    assert f"{folder} is not writable (Read-only file system)" in output, output
    assert "or choose another --data-root" in output
    assert "Traceback" not in output
    assert not dataset_exists or not any(dataset_dir(data_root).iterdir())


def test_a_full_disk_or_one_below_the_floor_is_refused_before_anything_starts(request, small_disk, tmp_path):
    if not needs_root(request):
        return
    disk = small_disk("8m")
    data_root = disk.path / "data"
    disk.fill(keep_bytes=3_000_000)
    status, output = refused(MagnaRun(data_root, tmp_path / "below", ("--min-free-space", "5")))
    assert status == 2, output
    assert f"MB free on the disk of {dataset_dir(data_root)}, less than the 5 MB a batch keeps free" in output, output
    assert "--min-free-space" in output and "Traceback" not in output

    disk.fill()
    status, output = refused(MagnaRun(data_root, tmp_path / "full", ("--min-free-space", "0")))
    assert status == 2, output
    assert "no space left on the disk of" in output and str(disk.path) in output, output
    assert "free space there, or choose another --data-root" in output and "Traceback" not in output
    assert not existing_simulations(dataset_dir(data_root))


@pytest.mark.ros
@pytest.mark.timeout(900)
def test_a_disk_that_fills_during_a_flight_ends_the_batch_with_a_clear_error(request, small_disk, tmp_path):
    if not needs_root(request):
        return
    disk = small_disk("24m")
    data_root = disk.path / "data"
    dataset = dataset_dir(data_root)
    run = MagnaRun(data_root, tmp_path / "run", ("--n-iter", "3", "--min-free-space", "4", "--time-limit", "120",
                                                 "--no-report"))
    try:
        run.start()
        wait_for(lambda: (simulation_dir(dataset, 2) / "mission.json").is_file(), "simulation 2's flight", run)
        disk.fill()  # another program takes the rest of the disk while simulation 2 flies
        status = run.wait(timeout=600)
        left = run.wait_for_no_process()
    finally:
        run.kill_everything()
    output = run.output()
    assert status == 1, output[-3000:]
    assert not left, f"processes left behind: {left}"
    assert "no space left on the disk of" in output and "stopped" in output, output[-3000:]
    assert "--append" in output and "Traceback" not in output, output[-3000:]
    # summary.csv is whole: it parses, and holds the finished simulation as it was written
    rows = SummaryRow.read(dataset / SUMMARY_FILE)
    assert [(row.id, row.outcome) for row in rows] == [(1, "completed")]
    assert existing_simulations(dataset) == [1, 2]  # the third never started
    assert not temporary_files(dataset), temporary_files(dataset)

    # room again: --append continues; the cut simulation gets its row, then a new one runs to its end
    for filler in disk.path.glob("filler_*"):
        filler.unlink()
    results = append_one_simulation(data_root, tmp_path / "again", "--min-free-space", "4")
    assert sorted(results) == [1, 2, 3] and summary_ids(dataset) == [1, 2, 3]
    assert results[2]["success"] is False
    assert results[3]["outcome"] == "completed"
    print(f"\nsimulation 2 after the disk filled: {results[2]['termination']}: {results[2]['message'][:300]}")
