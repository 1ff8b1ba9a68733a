"""Every writer of our output files gives the mode a plain open() would: 0o666 less the user's umask.

Each umask runs in a child process of its own (the umask belongs to the process), which writes one
file through every writer of the simulation folder and the dataset: write_*_atomically (new and
replacing), summary.csv, result.json, world.json, a UAV's CSV, and the folders they make. The live
run of tests/faults/test_refused_take_off.py checks a whole `magna run` under a umask too.
"""
import json
import subprocess
import sys
import textwrap

import pytest

from tests.support import ROOT

WRITE_EVERY_KIND = textwrap.dedent("""
    import json, os, sys
    from pathlib import Path

    from magna_common import files
    from magna_common.records import SimulationResult, SummaryRow, WorldRecord
    from magna_master.storage import update_summary, write_result
    from magna_uav.recorder import Recorder

    os.umask(int(sys.argv[2], 8))
    out = Path(sys.argv[1])
    made = {
        "text": files.write_text_atomically(out / "text.txt", "x"),
        "bytes": files.write_bytes_atomically(out / "bytes.bin", b"x"),
        "binary writer": files.write_atomically(out / "plot.png", lambda f: f.write(b"png"), binary=True),
        "replaced": files.write_text_atomically(out / "text.txt", "y", overwrite=True),
        "result.json": write_result(out / "dataset_1" / "simulation_1", SimulationResult(id=1, outcome="completed")),
        "summary.csv": update_summary(out / "dataset_1", SimulationResult(id=1, outcome="completed")),
        "summary.csv rewritten": update_summary(out / "dataset_1", SimulationResult(id=2, outcome="failed")),
        "world.json": WorldRecord(seed=1).write(out / "dataset_1" / "simulation_1" / "world.json"),
        "uav_1.csv": Recorder(1, [2]).save_csv(out / "dataset_1" / "simulation_1" / "uav_1.csv"),
        "folder": out / "dataset_1" / "simulation_1",
    }
    print(json.dumps({name: os.stat(path).st_mode & 0o777 for name, path in made.items()}))
""")


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o027, 0o077])
def test_every_output_writer_honours_the_umask(tmp_path, umask):
    done = subprocess.run([sys.executable, "-c", WRITE_EVERY_KIND, str(tmp_path), f"{umask:o}"], capture_output=True,
                          text=True, cwd=ROOT, check=False)
    assert done.returncode == 0, done.stderr
    modes = json.loads(done.stdout)
    folder = modes.pop("folder")
    assert folder == 0o777 & ~umask, oct(folder)
    wrong = {name: oct(mode) for name, mode in modes.items() if mode != 0o666 & ~umask}
    assert not wrong, f"umask {umask:03o}: expected {0o666 & ~umask:03o}, got {wrong}"
    leftovers = [p.name for p in tmp_path.rglob(".*.tmp")]
    assert not leftovers, leftovers


def test_an_atomic_write_leaves_the_process_umask_alone(tmp_path):
    """The mode comes from the kernel applying the umask at creation: the umask is never set, even for a moment
    (another thread creating a file then would get the wrong one)."""
    script = textwrap.dedent("""
        import os, sys
        from unittest import mock
        from magna_common import files
        os.umask(0o027)
        with mock.patch("os.umask", side_effect=AssertionError("os.umask called")):
            path = files.write_text_atomically(sys.argv[1], "x")
        print(oct(os.stat(path).st_mode & 0o777))
    """)
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path / "f.txt")], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == oct(0o640)

