"""Real simulations run at once (`--jobs 2`) and across Dask workers give the dataset a serial batch gives.

One serial batch of 4 simulations of a 2-UAV crossing is the reference. The same seeds then run with
`--jobs 2`, on a LocalCluster of 2 workers, and on a scheduler and 2 workers started as separate processes,
each worker in a network namespace of its own when this machine allows it (so each stands for a separate
host), with one worker killed in the middle of a simulation. Each summary must match the reference row for
row: outcome, success, collisions, and the simulated duration within DURATION_TOLERANCE (the managers'
threads run against wall-clock scheduling, so flights under a different load differ a little).
"""
import csv
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from magna_common.ports import free_port
from magna_common.processes import end_process_group, tagged_processes
from magna_gs.inputs import resolve_inputs
from magna_master.batch import run_batch
from magna_master.batch_config import BatchConfig
from magna_master.cluster import ClusterBatch
from tests.support import ROOT, wait_until

pytestmark = pytest.mark.ros
WORLD, MISSION = "Gym/Central_Obstacle_Torus", "Gym/2UAVs_Crossing_ORCA"
N = 4
DURATION_TOLERANCE = 0.15  # relative
GUARD = 300.0  # s: a guard against hangs, never a performance expectation
MARK_ENV = "MAGNA_CLUSTER_HOST_MARK"  # carried by one test worker and everything it starts


def config_for(data_root: Path, **overrides) -> BatchConfig:
    return BatchConfig(inputs=resolve_inputs(WORLD, MISSION), n_iter=N, data_root=data_root, rtf="max",
                       time_limit=GUARD, **overrides)


def summary(dataset_dir: Path) -> list[dict[str, str]]:
    with open(dataset_dir / "summary.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def assert_same_rows(rows: list[dict[str, str]], reference: list[dict[str, str]]) -> None:
    assert [r["id"] for r in rows] == [r["id"] for r in reference] == [str(m) for m in range(1, N + 1)]
    for row, ref in zip(rows, reference, strict=True):
        assert (row["success"], row["outcome"], row["collisions"]) == (ref["success"], ref["outcome"],
                                                                       ref["collisions"]), (row, ref)
        assert float(row["duration"]) == pytest.approx(float(ref["duration"]), rel=DURATION_TOLERANCE), (row, ref)


def files(dataset_dir: Path) -> list[str]:
    return sorted(str(p.relative_to(dataset_dir)) for p in dataset_dir.rglob("*")
                  if "logs" not in p.parts and p.suffix not in (".html", ".png"))  # pages and pictures: `magna run`'s


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The serial batch: its summary rows and its files."""
    config = config_for(tmp_path_factory.mktemp("serial"))
    batch = run_batch(config, progress=False, out=io.StringIO())
    assert [s.termination for s in batch.simulations] == ["ground_station"] * N, [s.message for s in batch.simulations]
    return summary(config.dataset_dir), files(config.dataset_dir)


def test_two_jobs_match_the_serial_batch(reference, tmp_path):
    config = config_for(tmp_path, jobs=2)
    run_batch(config, progress=False, out=io.StringIO())
    assert_same_rows(summary(config.dataset_dir), reference[0])
    assert files(config.dataset_dir) == reference[1]


def test_a_local_cluster_of_two_workers_matches_the_serial_batch(reference, tmp_path):
    from distributed import LocalCluster

    config = config_for(tmp_path)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      host="127.0.0.1") as cluster:
        batch = ClusterBatch(config, cluster.scheduler_address, progress=False, out=io.StringIO()).run()
    assert_same_rows(summary(config.dataset_dir), reference[0])
    assert files(config.dataset_dir) == reference[1]
    assert len({s.extra["worker"]["address"] for s in batch.simulations}) == 2
    # each worker thread keeps its stack between its simulations, as a job slot does
    assert sorted(s.extra["stack"]["start"] for s in batch.simulations) == ["cold", "cold", "warm", "warm"]


# --- a scheduler and two workers as separate processes, each worker in a network namespace ----------------------

class Hosts:
    """Network namespaces joined to this one by veth pairs: each test worker's own 'host'. Without the rights to
    make them (not root, no iproute2) the workers share loopback instead, and `isolated` is False."""

    def __init__(self, count: int):
        self.tag = f"mg{os.getpid() % 100000}"
        self.subnet = f"10.231.{os.getpid() % 250}"
        self.names: list[str] = []
        self.isolated = os.geteuid() == 0 and shutil.which("ip") is not None
        if self.isolated:
            try:
                for i in range(count):
                    self._add(i)
            except subprocess.CalledProcessError as error:
                print(f"network namespaces are not allowed here ({error.stderr.strip()}): the workers share "
                      "loopback", file=sys.stderr)
                self.remove()
                self.isolated = False

    def _add(self, i: int) -> None:
        ns, outside, inside = f"{self.tag}n{i}", f"{self.tag}o{i}", f"{self.tag}i{i}"
        steps = [["ip", "netns", "add", ns],
                 ["ip", "link", "add", outside, "type", "veth", "peer", "name", inside],
                 ["ip", "link", "set", inside, "netns", ns],
                 ["ip", "addr", "add", f"{self.subnet}.{4 * i + 1}/30", "dev", outside],
                 ["ip", "link", "set", outside, "up"],
                 ["ip", "netns", "exec", ns, "ip", "addr", "add", f"{self.subnet}.{4 * i + 2}/30", "dev", inside],
                 ["ip", "netns", "exec", ns, "ip", "link", "set", inside, "up"],
                 ["ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up"]]  # each host's ROS masters
        self.names.append(ns)
        for step in steps:
            subprocess.run(step, check=True, capture_output=True, text=True)

    def scheduler_host(self, i: int) -> str:
        """The scheduler's address as worker i reaches it."""
        return f"{self.subnet}.{4 * i + 1}" if self.isolated else "127.0.0.1"

    def worker_host(self, i: int) -> str:
        return f"{self.subnet}.{4 * i + 2}" if self.isolated else "127.0.0.1"

    def prefix(self, i: int) -> list[str]:
        return ["ip", "netns", "exec", self.names[i]] if self.isolated else []

    def remove(self) -> None:
        for ns in self.names:  # its veth pair goes with it
            subprocess.run(["ip", "netns", "delete", ns], capture_output=True)
        self.names = []


def start(argv: list[str], log: Path, env: dict | None = None) -> subprocess.Popen:
    with open(log, "ab") as out:
        return subprocess.Popen(argv, stdout=out, stderr=out, stdin=subprocess.DEVNULL, start_new_session=True,
                                env=env, cwd=ROOT)


def in_flight(local_directory: Path) -> int | None:
    """The id of a simulation of this worker with UAV 1 in the air (its CSV has a few rows), or None."""
    for csv_path in local_directory.glob("**/simulation_*/uav_1.csv"):
        try:
            if csv_path.read_text().count("\n") > 20:
                return int(csv_path.parent.name.split("_")[1])
        except OSError:
            pass
    return None


def test_a_worker_killed_mid_simulation_on_separate_hosts(reference, tmp_path):
    hosts = Hosts(2)
    port = free_port()
    dask = str(ROOT / ".venv" / "bin" / "dask")
    marks = [uuid.uuid4().hex, uuid.uuid4().hex]
    processes: list[subprocess.Popen] = []
    try:
        processes.append(start([dask, "scheduler", "--host", "0.0.0.0" if hosts.isolated else "127.0.0.1",
                                "--port", str(port), "--no-dashboard"], tmp_path / "scheduler.log"))
        workers = []
        for i in range(2):
            local = tmp_path / f"worker{i}"
            local.mkdir()
            env = {**os.environ, MARK_ENV: marks[i]}
            workers.append(start([*hosts.prefix(i), dask, "worker", f"tcp://{hosts.scheduler_host(i)}:{port}",
                                  "--host", hosts.worker_host(i), "--nthreads", "1", "--no-dashboard",
                                  "--local-directory", str(local), "--name", f"host{i}"],
                                 tmp_path / f"worker{i}.log", env))
        processes += workers
        data_root = tmp_path / "data"
        client = start([str(ROOT / "magna"), "run", "--world", WORLD, "--mission", MISSION, "--n-iter", str(N),
                        "--rtf", "max", "--time-limit", str(GUARD), "--data-root", str(data_root), "--no-report",
                        "--cluster", f"tcp://127.0.0.1:{port}"], tmp_path / "client.log")
        processes.append(client)
        wait_until(lambda: in_flight(tmp_path / "worker0") is not None or client.poll() is not None,
                   "a simulation in flight on worker 0", timeout=GUARD, poll=0.1)
        killed = in_flight(tmp_path / "worker0")
        assert client.poll() is None, (tmp_path / "client.log").read_text()
        assert tagged_processes(MARK_ENV, marks[0]), "worker 0's processes do not carry its mark"
        os.killpg(workers[0].pid, signal.SIGKILL)  # the worker and its nanny, with no chance to clean up
        workers[0].wait()
        wait_until(lambda: client.poll() is not None, "the batch to end", timeout=GUARD, poll=0.2)
        log = (tmp_path / "client.log").read_text()
        assert client.returncode == 0, log
        # the killed worker's simulation stopped itself (its parent-death signal): nothing of it is left
        wait_until(lambda: not tagged_processes(MARK_ENV, marks[0]), "worker 0's processes to end", timeout=60,
                   poll=0.2)
        dataset = config_for(data_root).dataset_dir
        rows = summary(dataset)
        assert_same_rows(rows, reference[0])  # no duplicate row: one per simulation
        assert files(dataset) == reference[1]
        ran_on = {m: json.loads((dataset / f"simulation_{m}" / "result.json").read_text())["worker"]["name"]
                  for m in range(1, N + 1)}
        assert ran_on[killed] == "host1", ran_on  # the killed worker's simulation ran again on the other
        print(f"hosts {'in network namespaces' if hosts.isolated else 'on loopback'}; simulation {killed} was "
              f"killed on host0; where each ran: {ran_on}")
    finally:
        for process in reversed(processes):
            end_process_group(process)
        for mark in marks:  # whatever the assertions said, leave nothing behind
            for pid, _command in tagged_processes(MARK_ENV, mark):
                os.kill(pid, signal.SIGKILL)
        hosts.remove()
