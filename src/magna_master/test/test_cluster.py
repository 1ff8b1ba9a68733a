"""`magna run --cluster` on a LocalCluster of 2 worker processes, with the stand-in ground station: the dataset
the client writes, the workers' check, Ctrl-C, and `magna doctor --cluster`."""
import io
import json
import os
import signal
import threading
import time
import uuid
from pathlib import Path

import pytest

from magna_common.processes import pid_alive, tagged_processes
from magna_common.storage_tree import existing_simulations
from magna_master import cli
from magna_master.batch import run_batch
from magna_master.cluster import ClusterBatch, ClusterError, check_workers, connect
from magna_master.cluster_task import check_worker, describe_inputs

pytestmark = pytest.mark.ros
CLUSTER_ENV = "MAGNA_CLUSTER_TEST_TOKEN"  # carried by the workers and everything they start


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 worker processes of 1 thread each; none of their processes may outlive it."""
    from distributed import LocalCluster

    token = uuid.uuid4().hex
    # the worker processes carry the token, and pass it on to everything they start
    local = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                         host="127.0.0.1", env={CLUSTER_ENV: token})
    local.magna_token = token
    try:
        yield local
    finally:
        local.close()
        deadline = time.monotonic() + 30
        while tagged_processes(CLUSTER_ENV, token) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = tagged_processes(CLUSTER_ENV, token)
        for pid, _command in left:
            os.kill(pid, signal.SIGKILL)
        assert not left, f"processes of the cluster left behind: {left}"


def rows(dataset_dir: Path) -> list[tuple]:
    import csv

    with open(dataset_dir / "summary.csv", newline="") as handle:
        return [(r["id"], r["success"], r["outcome"], r["collisions"], r["duration"]) for r in csv.DictReader(handle)]


def tree(dataset_dir: Path) -> list[str]:
    """The dataset's files, logs and pages left out (the workers' logs are their own)."""
    return sorted(str(p.relative_to(dataset_dir)) for p in dataset_dir.rglob("*")
                  if "logs" not in p.parts and p.suffix != ".html")


def test_a_cluster_batch_writes_the_dataset_a_serial_batch_writes(cluster, make_config, tmp_path):
    meet = ("--rendezvous", str(tmp_path / "meet"), "--rendezvous-seeds", "1,2")  # 1 and 2 on both workers at once
    config = make_config(n_iter=4, fail_seeds="3", stand_in_extra=meet, data_root=tmp_path / "cluster")
    batch = ClusterBatch(config, cluster.scheduler_address, progress=False, out=io.StringIO()).run()
    serial_config = make_config(n_iter=4, fail_seeds="3", data_root=tmp_path / "serial")
    serial = run_batch(serial_config, progress=False, out=io.StringIO())

    assert rows(config.dataset_dir) == rows(serial_config.dataset_dir)
    assert [(s.id, s.seed, s.success) for s in batch.simulations] == [(s.id, s.seed, s.success)
                                                                       for s in serial.simulations]
    assert tree(config.dataset_dir) == tree(serial_config.dataset_dir)
    workers = set()
    for simulation in batch.simulations:
        folder = config.dataset_dir / f"simulation_{simulation.id}"
        assert simulation.directory == folder
        written = json.loads((folder / "result.json").read_text())
        assert written["data_dir"] == str(folder)  # the client's folder, not the worker's scratch
        assert written["mission_file"] == str(config.inputs.mission_file)
        assert written["hyperparameters"]["n_simulation"] == simulation.id and written["hyperparameters"]["N_iter"] == 4
        assert (folder / "logs" / "cluster_worker.log").is_file()
        assert not pid_alive(json.loads((folder / "stand_in.json").read_text())["pid"])
        workers.add(written["worker"]["address"])
    assert workers <= set(cluster.scheduler_info["workers"]) and len(workers) == 2
    assert not [p for p in config.dataset_dir.iterdir() if p.name.startswith(".incoming")]
    # the workers' runners ended with the batch; the workers themselves stay up for the next one
    assert not [c for _, c in tagged_processes(CLUSTER_ENV, cluster.magna_token) if "magna_master.cluster_task" in c]
    assert len(cluster.scheduler_info["workers"]) == 2


def test_ctrl_c_stops_the_simulations_on_the_workers(cluster, make_config, tmp_path):
    meet = tmp_path / "meet"  # the stand-ins of seeds 1 and 2 leave a mark there when they run
    config = make_config(n_iter=4, sleep=60, data_root=tmp_path / "data",
                         stand_in_extra=("--rendezvous", str(meet), "--rendezvous-seeds", "1,2"))
    batch = ClusterBatch(config, cluster.scheduler_address, progress=False, out=io.StringIO())
    outcome = {}
    thread = threading.Thread(target=lambda: outcome.setdefault("result", batch.run()), daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 60
        while len(list(meet.glob("seed_*"))) < 2:  # both workers' simulations are running
            assert thread.is_alive() and time.monotonic() < deadline, "two simulations did not start"
            time.sleep(0.05)
        stand_ins = [c for _, c in tagged_processes(CLUSTER_ENV, cluster.magna_token)
                     if any(word.endswith("stand_in_gs.py") for word in c.split()[:2])]
        assert len(stand_ins) == 2  # the fixture's leak check sees the workers' processes
    finally:
        batch.stop.event.set()  # what Ctrl-C does (the handlers exist only in a main thread)
        thread.join(120)
    assert not thread.is_alive()
    result = outcome["result"]
    assert result.interrupted
    assert [(s.id, s.termination) for s in result.simulations] == [(1, "interrupted"), (2, "interrupted")]
    assert existing_simulations(config.dataset_dir) == [1, 2]  # 3 and 4 never started
    assert [r[2] for r in rows(config.dataset_dir)] == ["interrupted", "interrupted"]


def test_workers_that_differ_from_the_client_are_refused_before_anything_starts(cluster, make_config, tmp_path):
    config = make_config(n_iter=1, data_root=tmp_path / "data")
    manifest = describe_inputs(config)
    assert check_worker(manifest)["problems"] == []
    other = json.loads(json.dumps(manifest))
    other["version"] = "0.0.1 0123456789ab"
    other["files"]["mission"]["sha256"] = "0" * 64
    problems = check_worker(other)["problems"]
    assert any("MAGNA" in p and "0.0.1 0123456789ab on the client" in p and "restart this worker" in p
               for p in problems)
    assert any(p.startswith("the mission file") and "differs from the client's" in p for p in problems)
    client = connect(cluster.scheduler_address)
    try:
        with pytest.raises(ClusterError) as refused:
            check_workers(client, cluster.scheduler_address, other)
    finally:
        client.close()
    message = str(refused.value)
    assert "2 of 2 worker(s) cannot run this batch" in message and message.count("differs from the client's") == 2
    assert not (tmp_path / "data").exists()


def test_no_scheduler_is_a_clear_error(make_config, tmp_path, capsys, corpus):
    from magna_common.ports import free_port

    address = f"tcp://127.0.0.1:{free_port()}"
    with pytest.raises(ClusterError, match="no Dask scheduler answers there"):
        connect(address, timeout=2)
    status = cli.main(["run", "--world", "Gym/1Obs_Central_Cylinder", "--mission", "Gym/2UAVs_2paths_Central_Cylinder",
                       "--search-path", str(corpus), "--data-root", str(tmp_path / "data"), "--cluster", address,
                       "--jobs", "2"])
    assert status == 2 and "--cluster with --jobs 2" in capsys.readouterr().err
    assert not (tmp_path / "data").exists()


def test_doctor_reports_each_worker(cluster, capsys):
    status = cli.main(["doctor", "--cluster", cluster.scheduler_address])
    out = capsys.readouterr().out
    assert status == 0, out
    for address in cluster.scheduler_info["workers"]:
        assert address in out
    assert out.count("ready") >= 2 and f"cores {os.cpu_count()}" in out
    from magna_master.cluster_task import LOADED_VERSION

    assert LOADED_VERSION in out


class WorkersWithoutMagna:
    """A Client whose one worker runs outside MAGNA's environment: every function sent there fails to import."""

    def wait_for_workers(self, n, timeout=None):
        pass

    def nthreads(self):
        return {"tcp://10.0.0.9:4000": 1}

    def run(self, function, *args, on_error="raise"):
        assert on_error == "return"  # a worker that cannot run MAGNA is reported, not raised
        return {"tcp://10.0.0.9:4000": ModuleNotFoundError("No module named 'magna_master'")}

    def close(self):
        pass


def test_a_worker_outside_magnas_environment_is_named_with_the_fix(monkeypatch, capsys):
    with pytest.raises(ClusterError) as refused:
        check_workers(WorkersWithoutMagna(), "tcp://10.0.0.5:8786", {"version": "x", "files": {}})
    message = str(refused.value)
    assert "tcp://10.0.0.9:4000" in message and "No module named 'magna_master'" in message
    assert "scripts/with_env.sh dask worker" in message
    from magna_master import cluster

    monkeypatch.setattr(cluster, "connect", lambda address: WorkersWithoutMagna())
    assert cli.main(["doctor", "--cluster", "tcp://10.0.0.5:8786"]) == 1
    out = capsys.readouterr().out
    assert "[FAIL] tcp://10.0.0.9:4000  not ready: the check failed there" in out and "0 of 1 worker(s) ready" in out
