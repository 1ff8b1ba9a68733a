"""The worker's side of `magna run --cluster`: one simulation of a client's batch per Dask task.

`run_simulation(request)` runs in a thread of a Dask worker (`dask worker`, started in MAGNA's environment).
It checks the worker against the client (`check_worker`: the same MAGNA version, the same world and mission
files), then runs the simulation in a child process, `python -m magna_master.cluster_task`: a Batch of
that one simulation, with everything a serial batch guarantees (its own master and stack, its clean-up,
result.json, an 'interrupted' mark when stopped). The task returns the result and the simulation's folder
as a gzipped tar, so the workers need no file system shared with the client.

The child is in a session of its own and gets SIGTERM when the worker's task thread dies (prctl
PR_SET_PDEATHSIG): a worker that is killed mid-simulation stops its simulation and leaves no process
behind. The scheduler then gives the task to another worker, and the client, which writes only the
results that reach it, gets one result per simulation.

`stop_batch(batch_id)` (sent to every worker by `Client.run` on Ctrl-C) sends SIGINT to the batch's
children and makes its tasks that have not started yet return at once. `worker_report()` is what
`magna doctor --cluster` shows of each worker.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tempfile
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from magna_common.processes import set_parent_death_signal
from magna_common.records import SimulationResult
from magna_common.storage_tree import LOGS_DIR
from magna_common.workspace import find_root, magna_version

CHILD_LOG = "cluster_worker.log"  # the child's output, in the simulation's logs/ folder
OUTCOME_FILE = "outcome.json"  # the child's result, in its scratch folder (there is no folder with --skip-save)
# BatchConfig fields a worker takes from the client as they are (the inputs and paths are mapped; a worker
# keeps no dataset of its own, and runs one simulation at a time per task)
CONFIG_FIELDS = ("n_iter", "name", "n_dataset", "rtf", "seed", "bag", "time_limit", "button_timeout", "stop_grace",
                 "settle", "shutdown_timeout", "launch_command", "output", "battery_floor", "min_free_mb",
                 "cold_start", "managers")
INPUT_ROLES = ("world", "mission", "utm_plan")


class WorkerMismatch(RuntimeError):
    """A worker whose MAGNA version or input files differ from the client's."""


# --- what the client and the workers must share -------------------------------------------------------------------

def file_digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def describe_inputs(config, root: Path | None = None) -> dict[str, Any]:
    """The client's side of the check: its MAGNA version, and each input file by where a worker finds it
    (relative to the checkout when inside it, else its absolute path) and its SHA-256."""
    root = (root or find_root()).resolve()
    files = {"world": config.inputs.world_file, "mission": config.inputs.mission_file}
    if config.utm_plan:
        files["utm_plan"] = config.utm_plan
    described = {}
    for role, path in files.items():
        path = Path(path).resolve()
        relative = str(path.relative_to(root)) if path.is_relative_to(root) else ""
        described[role] = {"relative": relative, "absolute": str(path), "sha256": file_digest(path)}
    return {"version": magna_version(root), "files": described}


def _version_at_import() -> str:
    try:
        return magna_version()
    except Exception as error:  # noqa: BLE001 -- a worker outside a checkout: check_worker says so
        return f"unknown ({error})"


# The version of the code this process loaded: a worker whose checkout changed after it started still runs the old
# code, and must differ from a client on the new one.
LOADED_VERSION = _version_at_import()


def check_worker(manifest: dict[str, Any]) -> dict[str, Any]:
    """This worker against the client's `manifest` (describe_inputs): its host, version, where it found each
    input file, and what differs (empty: it can run the client's simulations)."""
    root = find_root()
    version = LOADED_VERSION
    problems = []
    if version != manifest["version"]:
        problems.append(f"MAGNA {version} here, {manifest['version']} on the client: check out the client's commit "
                        "here (git checkout), run `make setup`, and restart this worker")
    found = {}
    for role, wanted in manifest["files"].items():
        path = root / wanted["relative"] if wanted["relative"] else Path(wanted["absolute"])
        if not path.is_file():
            problems.append(f"the {role} file {path} is missing here: give this worker the client's "
                            + ("checkout (the same commit)" if wanted["relative"] else
                               "file at the same path (a shared folder, or a copy)"))
            continue
        if file_digest(path) != wanted["sha256"]:
            problems.append(f"the {role} file {path} differs from the client's {wanted['absolute']} (SHA-256 "
                            f"{file_digest(path)[:12]} here, {wanted['sha256'][:12]} there): make them the same")
            continue
        found[role] = str(path)
    return {"host": socket.gethostname(), "version": version, "files": found, "problems": problems}


def worker_report() -> dict[str, Any]:
    """What `magna doctor --cluster` says of this worker: host, cores, MAGNA version, and whether it can run a
    simulation (problems, each with its fix)."""
    problems = []
    version = LOADED_VERSION
    try:
        root = find_root()
    except Exception as error:  # noqa: BLE001 -- reported, not raised: doctor shows every worker
        return {"host": socket.gethostname(), "cores": os.cpu_count(), "version": version,
                "problems": [f"no MAGNA checkout found ({error}): start the worker from one, in its environment "
                             "(scripts/with_env.sh dask worker ...)"]}
    if shutil.which("rosmaster") is None:
        problems.append("rosmaster is not on PATH: start the worker in MAGNA's environment "
                        "(scripts/with_env.sh dask worker ...)")
    if not (root / "devel" / "setup.bash").is_file():
        problems.append(f"{root} is not built: run `make setup` there")
    try:
        import magna_gs  # noqa: F401 -- importable means the devel space is sourced
    except ImportError:
        problems.append("magna_gs is not importable: start the worker with scripts/with_env.sh")
    free_mb = shutil.disk_usage(tempfile.gettempdir()).free / 1e6
    if free_mb < 500:
        problems.append(f"only {free_mb:.0f} MB free in {tempfile.gettempdir()}: a simulation's folder needs room")
    return {"host": socket.gethostname(), "cores": os.cpu_count(), "version": version, "root": str(root),
            "free_mb": round(free_mb), "problems": problems}


# --- stopping a batch on this worker --------------------------------------------------------------------------------

_guard = threading.Lock()
_children: dict[str, set[subprocess.Popen]] = {}  # batch id -> its running children on this worker
_stopped: set[str] = set()  # batches stopped by their client: their tasks that start later do nothing


def stop_batch(batch_id: str) -> int:
    """Stop the batch's simulations on this worker as Ctrl-C stops a serial one; returns how many were running."""
    with _guard:
        _stopped.add(batch_id)
        children = list(_children.get(batch_id, ()))
    for child in children:
        try:
            child.send_signal(signal.SIGINT)
        except ProcessLookupError:
            pass
    return len(children)


# --- one simulation ---------------------------------------------------------------------------------------------

def run_simulation(request: dict[str, Any]) -> dict[str, Any]:
    """A Dask task: simulation `request['m']` of the client's batch. Returns {'started': False} when the batch was
    stopped before it began; else the result (SimulationResult.to_dict()), the folder as a gzipped tar (None with
    --skip-save), the worker and the child's exit code. WorkerMismatch when this worker cannot run it."""
    batch_id, m = request["batch"], request["m"]
    with _guard:
        if batch_id in _stopped:
            return {"started": False}
    checked = check_worker(request["manifest"])
    if checked["problems"]:
        raise WorkerMismatch(f"worker on {checked['host']}: " + "; ".join(checked["problems"]))
    worker, name = _worker_identity()
    scratch = Path(tempfile.mkdtemp(prefix=f"magna_sim_{m}_", dir=_local_directory()))
    try:
        job = {**request, "files": checked["files"], "scratch": str(scratch)}
        (scratch / "request.json").write_text(json.dumps(job))
        log_path = scratch / CHILD_LOG
        with open(log_path, "ab") as log:
            child = subprocess.Popen([sys.executable, "-m", "magna_master.cluster_task", str(scratch / "request.json"),
                                      "--parent-pid", str(os.getpid())], stdout=log, stderr=log,
                                     stdin=subprocess.DEVNULL, start_new_session=True)
        with _guard:
            _children.setdefault(batch_id, set()).add(child)
            stopped = batch_id in _stopped
        if stopped:  # stopped between the check above and the start
            child.send_signal(signal.SIGINT)
        code = child.wait()
        with _guard:
            _children[batch_id].discard(child)
        return {"started": True, "worker": worker, "name": name, "host": checked["host"], "exit_code": code,
                **_collect(scratch, request)}  # its own 'started' (False: stopped before it began) wins
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _collect(scratch: Path, request: dict[str, Any]) -> dict[str, Any]:
    """The child's result and its simulation folder (with the child's log in its logs/), as a gzipped tar."""
    outcome_path = scratch / OUTCOME_FILE
    outcome = json.loads(outcome_path.read_text()) if outcome_path.is_file() else {"started": True, "result": None}
    result = outcome["result"]
    folder = _simulation_folder(scratch, request)
    log_tail = _tail(scratch / CHILD_LOG)
    if not outcome["started"]:
        return {"started": False}
    if folder is None:
        return {"result": result, "archive": None, "log_tail": log_tail}
    (folder / LOGS_DIR).mkdir(exist_ok=True)
    shutil.copyfile(scratch / CHILD_LOG, folder / LOGS_DIR / CHILD_LOG)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz", compresslevel=1) as archive:  # bags barely compress
        # files and folders only: ROS's logs/ros/latest is a link, which a client takes from no worker
        archive.add(folder, arcname=folder.name, filter=lambda member: None if member.issym() else member)
    return {"result": result, "archive": buffer.getvalue(), "log_tail": log_tail}


def _simulation_folder(scratch: Path, request: dict[str, Any]) -> Path | None:
    found = sorted((scratch / "data").glob(f"**/simulation_{request['m']}"))
    return found[0] if request["save"] and found and found[0].is_dir() else None


def _tail(path: Path, lines: int = 20) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def _worker_identity() -> tuple[str, str]:
    """This worker's address and name (`dask worker --name`; its address when not named)."""
    try:
        from distributed import get_worker

        worker = get_worker()
        return str(worker.address), str(worker.name)
    except (ImportError, ValueError):  # called outside a worker (a test)
        return f"local process {os.getpid()}", f"local process {os.getpid()}"


def _local_directory() -> str | None:
    """The worker's --local-directory (a node's scratch space under a cluster's scheduler), else the system's."""
    try:
        from distributed import get_worker

        return str(get_worker().local_directory)
    except (ImportError, ValueError):
        return None


# --- the child: a batch of this one simulation ----------------------------------------------------------------------

def child_config(job: dict[str, Any]):
    """The BatchConfig of the child: the client's settings, this worker's files, the scratch folder as data root."""
    from magna_gs.inputs import Inputs
    from magna_master.batch_config import BatchConfig

    names = job["names"]
    files = job["files"]
    inputs = Inputs(names["world"], names["subworld"], names["mission"], names["submission"],
                    Path(files["world"]), Path(files["mission"]))
    fields = {name: job["config"][name] for name in CONFIG_FIELDS}
    fields["launch_command"] = tuple(fields["launch_command"])
    return BatchConfig(inputs=inputs, **fields, utm_plan=Path(files["utm_plan"]) if "utm_plan" in files else None,
                       data_root=Path(job["scratch"]) / "data", save_data=job["save"], jobs=1)


def child_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m magna_master.cluster_task",
                                     description="run one simulation of a `magna run --cluster` batch on this "
                                                 "worker (started by the worker's task, not by hand)")
    parser.add_argument("request", type=Path, help="the task's request.json, in its scratch folder")
    parser.add_argument("--parent-pid", type=int, default=0, help="stop the simulation when this process dies")
    args = parser.parse_args(argv)
    # A stop can come while this process is still starting (Ctrl-C on the client): then no simulation starts.
    early_stop = threading.Event()
    batch = None

    def stop_early(*_) -> None:
        early_stop.set()
        if batch is not None:
            batch.stop.event.set()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop_early)
    from magna_master.batch import Batch
    from magna_master.storage import StoragePlan

    job = json.loads(args.request.read_text())
    config = child_config(job)
    batch = Batch(config, progress=False, out=sys.stdout)
    if early_stop.is_set():
        batch.stop.event.set()
    if args.parent_pid:
        set_parent_death_signal(signal.SIGTERM)  # the worker died: stop the simulation, as at Ctrl-C
        if os.getppid() != args.parent_pid:
            return 1  # it died before prctl took effect: nobody would collect the result
    plan = StoragePlan(config.dataset_dir if config.save_data else None, [job["m"]],
                       reason="" if config.save_data else "saving is off (--skip-save)")
    try:
        result = batch.run(plan)
    finally:
        orphaned = bool(args.parent_pid) and os.getppid() != args.parent_pid
        if orphaned:  # nobody will collect the folder
            shutil.rmtree(job["scratch"], ignore_errors=True)
    if orphaned:
        return 1
    simulation = result.simulations[0] if result.simulations else None
    if simulation is not None:
        outcome = {"started": True, "result": dataclasses.replace(simulation, directory=None).to_dict()}
    else:  # stopped before it started, or it could not start (the log says why)
        outcome = {"started": not result.interrupted, "result": None}
    (Path(job["scratch"]) / OUTCOME_FILE).write_text(json.dumps(outcome, default=str))
    return 130 if result.interrupted else 0


def placed_result(reply: dict[str, Any], folder: Path | None) -> SimulationResult | None:
    """The SimulationResult a worker sent, for the client (its folder now `folder`), or None when it sent none."""
    if reply.get("result") is None:
        return None
    return dataclasses.replace(SimulationResult.from_dict(reply["result"], f"worker {reply['worker']}"),
                               directory=folder)


if __name__ == "__main__":
    sys.exit(child_main())
