"""Endurance (issue 26, item 5): a 50-simulation batch of a short mission at --rtf max, watched from outside.

Run by `make test-faults` (python -m pytest -s tests/faults/endurance.py), never by `make test`: its
name does not match test_*.py, so only a run that names the file collects it. It takes about
50 times a short simulation with its report (10-30 wall s each, depending on the machine's load).
MAGNA_ENDURANCE_SIMULATIONS=N runs N instead of 50 (for a quick look; the target runs 50).

One `magna run --n-iter N` of tests/missions/Test/1UAV_Short_Hop.json, with bags and reports as a
user's batch has them. While it runs, every 0.2 s the test reads the Master's (the `magna run`
process's) resident memory and open file descriptors from /proc; each time a summary row appears
(a simulation is done) it also looks for processes of finished simulations and measures the ROS
home (ROS_HOME, which is ~/.ros unless set: here a folder of the test's own, so other programs'
logs do not count) and the temporary folder (TMPDIR, also the test's own).

Asserted: the batch runs to its end; zero processes of a finished simulation alive after each
simulation; per simulation (least squares over the simulations after the first five) the
Master's memory grows by less than 256 kB and its descriptors by less than 0.05; the ROS home and the
temporary folder do not grow with the simulations. The figures are printed, and written to
MAGNA_ENDURANCE_REPORT (a JSON file) when that is set.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import pytest

from magna_common.storage_tree import simulation_dir
from tests.faults.batch_runs import MagnaRun, check_dataset, dataset_dir, summary_ids

pytestmark = [pytest.mark.ros, pytest.mark.timeout(6 * 3600)]

SIMULATIONS = int(os.environ.get("MAGNA_ENDURANCE_SIMULATIONS", "50"))
WARM_UP = 5  # simulations before the slopes are taken: imports, caches and the first report settle
MAX_RSS_GROWTH_KB = 256.0  # per simulation
MAX_FD_GROWTH = 0.05  # per simulation: one descriptor leaked every 20 simulations fails


@dataclass
class Sample:
    simulation: int  # the simulation whose row appeared
    wall: float  # s since the batch started
    rss_kb: int  # the Master's peak resident memory while this simulation ran
    fds: int  # the fewest descriptors the Master held while this simulation ran
    ros_home_kb: int
    ros_home_files: int
    tmp_kb: int
    tmp_files: int
    orphans: list[str] = field(default_factory=list)


def proc_rss_kb(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def proc_fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def folder_size(folder: Path) -> tuple[int, int]:
    """kB and number of files under `folder`."""
    size = files = 0
    for path in folder.rglob("*"):
        try:
            if path.is_file():
                size += path.stat().st_size
                files += 1
        except OSError:  # removed while counted
            continue
    return size // 1024, files


def environ_of(pid: int) -> dict[str, str]:
    try:
        items = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    except OSError:
        return {}
    return dict(item.decode(errors="replace").split("=", 1) for item in items if b"=" in item)


def orphans_of_finished(run: MagnaRun, dataset: Path, finished: int) -> list[str]:
    """Live processes of simulations 1..finished: their ROS_LOG_DIR is in the simulation's folder."""
    left = []
    for pid, command in run.alive():
        if pid == run.pid:
            continue
        log_dir = environ_of(pid).get("ROS_LOG_DIR", "")
        for m in range(1, finished + 1):
            if log_dir.startswith(str(simulation_dir(dataset, m)) + os.sep):
                left.append(f"simulation {m}: {pid} {command[:160]}")
    return left


def slope(xs: list[float], ys: list[float]) -> float:
    """Least-squares growth of ys per unit of xs."""
    n = len(xs)
    mean_x, mean_y = sum(xs) / n, sum(ys) / n
    var = sum((x - mean_x) ** 2 for x in xs)
    return sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, ys, strict=True)) / var if var else 0.0


def test_a_long_batch_leaves_no_process_and_keeps_the_master_flat(tmp_path, monkeypatch):
    ros_home, tmp = tmp_path / "ros_home", tmp_path / "tmp"
    ros_home.mkdir()
    tmp.mkdir()
    monkeypatch.setenv("ROS_HOME", str(ros_home))
    monkeypatch.setenv("TMPDIR", str(tmp))
    data_root = tmp_path / "data"
    dataset = dataset_dir(data_root)
    run = MagnaRun(data_root, tmp_path / "run", ("--n-iter", str(SIMULATIONS), "--time-limit", "300"))
    samples: list[Sample] = []
    started = time.monotonic()
    try:
        run.start()
        peak_rss, fewest_fds, done = 0, 1 << 30, 0
        while run.running():
            try:
                peak_rss = max(peak_rss, proc_rss_kb(run.pid))
                fewest_fds = min(fewest_fds, proc_fds(run.pid))
            except OSError:  # the batch just ended
                break
            rows = len(summary_ids(dataset))
            if rows > done:
                done = rows
                ros_kb, ros_files = folder_size(ros_home)
                tmp_kb, tmp_files = folder_size(tmp)
                samples.append(Sample(done, round(time.monotonic() - started, 1), peak_rss, fewest_fds, ros_kb,
                                      ros_files, tmp_kb, tmp_files, orphans_of_finished(run, dataset, done)))
                print(f"simulation {done:3d} at {samples[-1].wall:7.1f} s: rss {peak_rss} kB, fds {fewest_fds}, "
                      f"ROS_HOME {ros_kb} kB/{ros_files} files, TMPDIR {tmp_kb} kB/{tmp_files} files, "
                      f"orphans {len(samples[-1].orphans)}", flush=True)
                peak_rss, fewest_fds = 0, 1 << 30
            time.sleep(0.2)
        status = run.wait(timeout=600)
        left = run.wait_for_no_process()
    finally:
        run.kill_everything()
    assert status == 0, run.output()[-3000:]
    assert not left, f"processes left after the batch: {left}"
    results = check_dataset(dataset)
    assert sorted(results) == list(range(1, SIMULATIONS + 1))
    missed = sorted(set(range(1, SIMULATIONS + 1)) - {s.simulation for s in samples})
    assert len(samples) >= SIMULATIONS - len(missed)

    steady = [s for s in samples if s.simulation > WARM_UP]
    assert len(steady) >= 3, f"too few simulations after the warm-up to measure a growth: {len(steady)}"
    xs = [float(s.simulation) for s in steady]
    figures = {
        "simulations": SIMULATIONS,
        "wall_s": round(time.monotonic() - started, 1),
        "successes": sum(r["success"] for r in results.values()),
        "rss_kb_first_last": [steady[0].rss_kb, steady[-1].rss_kb],
        "rss_growth_kb_per_simulation": round(slope(xs, [float(s.rss_kb) for s in steady]), 2),
        "fds_first_last": [steady[0].fds, steady[-1].fds],
        "fd_growth_per_simulation": round(slope(xs, [float(s.fds) for s in steady]), 4),
        "ros_home_kb_first_last": [samples[0].ros_home_kb, samples[-1].ros_home_kb],
        "ros_home_growth_kb_per_simulation": round(slope(xs, [float(s.ros_home_kb) for s in steady]), 2),
        "tmp_kb_first_last": [samples[0].tmp_kb, samples[-1].tmp_kb],
        "tmp_files_last": samples[-1].tmp_files,
        "orphans_after_a_simulation": sum(len(s.orphans) for s in samples),
        "samples": [asdict(s) for s in samples],
    }
    print("\nendurance: " + json.dumps({k: v for k, v in figures.items() if k != "samples"}), flush=True)
    if os.environ.get("MAGNA_ENDURANCE_REPORT"):
        Path(os.environ["MAGNA_ENDURANCE_REPORT"]).write_text(json.dumps(figures, indent=2))

    assert not [o for s in samples for o in s.orphans], [o for s in samples for o in s.orphans]
    assert figures["rss_growth_kb_per_simulation"] < MAX_RSS_GROWTH_KB, figures
    assert figures["fd_growth_per_simulation"] < MAX_FD_GROWTH, figures
    # ~/.ros and the temporary folder hold nothing per simulation (the logs are in each simulation's folder)
    assert figures["ros_home_growth_kb_per_simulation"] < 1.0, figures
    assert samples[-1].tmp_files <= samples[0].tmp_files, figures
