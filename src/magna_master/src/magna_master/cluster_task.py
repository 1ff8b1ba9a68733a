"""The worker's side of `magna run --cluster`: one simulation of a client's batch per Dask task.

`run_simulation(request)` runs in a thread of a Dask worker (`dask worker`, started in MAGNA's environment).
It checks the worker against the client (`check_worker`: the same MAGNA version, the same world and mission
files), then hands the simulation to the thread's runner, a child process (`python -m
magna_master.cluster_task`) that runs it as a one-simulation Batch on a job slot it keeps: everything a
serial batch guarantees (its own master, its clean-up, result.json, an 'interrupted' mark when stopped),
and a persistent stack kept up between the thread's simulations of the same settings. The client stops the
runners when its batch ends (`close_runners`). The task returns the
result and the simulation's folder as a gzipped tar, so the workers need no file system shared with the
client.

The runner is in a session of its own and gets SIGTERM when the worker's task thread dies (prctl
PR_SET_PDEATHSIG); its input pipe closes too. A worker that is killed mid-simulation thus stops its
simulation and stack and leaves no process behind. The scheduler then gives the task to another worker, and
the client, which writes only the results that reach it, gets one result per simulation.

`stop_batch(batch_id)` (sent to every worker by `Client.run` on Ctrl-C) sends SIGINT to the runners running
the batch's simulations and makes its tasks that have not started yet return at once. `worker_report()` is
what `magna doctor --cluster` shows of each worker.
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
# BatchConfig fields a worker takes from the client as they are (the inputs and paths are mapped; a worker
# keeps no dataset of its own, and runs one simulation at a time per task)
CONFIG_FIELDS = ("n_iter", "name", "n_dataset", "rtf", "seed", "bag", "time_limit", "button_timeout", "stop_grace",
                 "settle", "shutdown_timeout", "launch_command", "output", "battery_floor", "min_free_mb",
                 "cold_start", "managers")


class WorkerMismatch(RuntimeError):
    """A worker whose MAGNA version or input files differ from the client's."""


# --- what the client and the workers must share -------------------------------------------------------------------

def _version_at_import() -> str:
    try:
        return magna_version()
    except Exception as error:  # noqa: BLE001 -- a worker outside a checkout: check_worker says so
        return f"unknown ({error})"


# The version of the code this process loaded: a worker whose checkout changed after it started still runs the old
# code, and must differ from a client on the new one.
LOADED_VERSION = _version_at_import()


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
    return {"version": LOADED_VERSION, "files": described}


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
        digest = file_digest(path)
        if digest != wanted["sha256"]:
            problems.append(f"the {role} file {path} differs from the client's {wanted['absolute']} (SHA-256 "
                            f"{digest[:12]} here, {wanted['sha256'][:12]} there): make them the same")
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


# --- one simulation, on this worker thread's runner ------------------------------------------------------------

class Runner:
    """A child process that runs this worker thread's simulations one after another (`python -m
    magna_master.cluster_task`), on a persistent stack kept between them as a serial batch keeps its own. It
    takes one job per line on stdin and answers one line on stdout. The stack is kept for jobs of the same
    settings (`key`); a job with other settings gets a new runner."""

    def __init__(self, key: str):
        self.key = key
        self.busy = False  # running a job (under _guard); close_runners leaves a busy runner alone
        self.scratch = Path(tempfile.mkdtemp(prefix="magna_runner_", dir=_local_directory()))
        self.log = open(self.scratch / "runner.log", "ab")  # noqa: SIM115 -- open for the runner's life
        self.process = subprocess.Popen(
            [sys.executable, "-m", "magna_master.cluster_task", "--scratch", str(self.scratch),
             "--parent-pid", str(os.getpid())],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, start_new_session=True, text=True,
            bufsize=1)

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def run(self, job: dict[str, Any]) -> dict[str, Any] | None:
        """Send a job and wait for its answer; None when the runner died first."""
        assert self.process.stdin is not None and self.process.stdout is not None
        try:
            self.process.stdin.write(json.dumps(job) + "\n")
            self.process.stdin.flush()
        except (BrokenPipeError, OSError):
            return None
        line = self.process.stdout.readline()
        return json.loads(line) if line.strip() else None

    def close(self) -> None:
        """End of input: the runner stops its stack and exits."""
        if self.process.stdin is not None:
            try:
                self.process.stdin.close()
            except OSError:
                pass
        try:
            self.process.wait(120)
        except subprocess.TimeoutExpired:
            from magna_common.processes import end_process_group

            end_process_group(self.process)
        self.log.close()
        shutil.rmtree(self.scratch, ignore_errors=True)


_runners: dict[int, Runner] = {}  # worker thread -> its runner


def _runner_for(job: dict[str, Any]) -> Runner:
    """This thread's runner for the job's settings (the one it has, or a new one), marked busy."""
    key = json.dumps({k: v for k, v in job.items() if k not in ("batch", "m", "scratch")}, sort_keys=True)
    thread = threading.get_ident()
    with _guard:
        runner = _runners.pop(thread, None)
    if runner is not None and (runner.key != key or not runner.alive):
        runner.close()
        runner = None
    if runner is None:
        runner = Runner(key)
    with _guard:
        runner.busy = True
        _runners[thread] = runner
    return runner


def run_simulation(request: dict[str, Any]) -> dict[str, Any]:
    """A Dask task: simulation `request['m']` of the client's batch. Returns {'started': False} when the batch was
    stopped before it began; else the result (SimulationResult.to_dict()), the folder as a gzipped tar (None with
    --skip-save), the worker and how the runner ended. WorkerMismatch when this worker cannot run it."""
    batch_id, m = request["batch"], request["m"]
    with _guard:
        if batch_id in _stopped:
            return {"started": False}
    checked = check_worker(request["manifest"])
    if checked["problems"]:
        raise WorkerMismatch(f"worker on {checked['host']}: " + "; ".join(checked["problems"]))
    worker, name = _worker_identity()
    scratch = Path(tempfile.mkdtemp(prefix=f"magna_sim_{m}_", dir=_local_directory()))
    runner = None
    try:
        job = {**request, "files": checked["files"], "scratch": str(scratch)}
        runner = _runner_for(job)
        with _guard:
            _children.setdefault(batch_id, set()).add(runner.process)
            stopped = batch_id in _stopped
        if stopped:  # stopped between the check above and now
            runner.process.send_signal(signal.SIGINT)
        answer = runner.run(job)
        with _guard:
            _children[batch_id].discard(runner.process)
        if answer is None:  # the runner died: say how, from its log
            runner.process.wait()
            answer = {"started": True, "result": None,
                      "log_tail": _tail(runner.scratch / "runner.log"), "exit_code": runner.process.returncode}
        if not answer["started"]:
            return {"started": False}
        return {"started": True, "worker": worker, "name": name, "host": checked["host"],
                "exit_code": answer.get("exit_code"), **_collect(scratch, request, answer)}
    finally:
        if runner is not None:
            with _guard:
                runner.busy = False
        shutil.rmtree(scratch, ignore_errors=True)


def close_runners() -> int:
    """Stop this worker's idle runners and their stacks (a client's batch has ended: nothing of it stays up on the
    workers); returns how many were stopped. A runner busy with another client's job is left alone."""
    with _guard:
        idle = {thread: runner for thread, runner in _runners.items() if not runner.busy}
        for thread in idle:
            del _runners[thread]
    for runner in idle.values():
        runner.close()
    return len(idle)


def _collect(scratch: Path, request: dict[str, Any], answer: dict[str, Any]) -> dict[str, Any]:
    """The runner's result and the simulation's folder (with the job's log in its logs/), as a gzipped tar."""
    folder = _simulation_folder(scratch, request)
    log_tail = answer.get("log_tail") or _tail(scratch / CHILD_LOG)
    if folder is None:
        return {"result": answer["result"], "archive": None, "log_tail": log_tail}
    (folder / LOGS_DIR).mkdir(exist_ok=True)
    if (scratch / CHILD_LOG).is_file():
        shutil.copyfile(scratch / CHILD_LOG, folder / LOGS_DIR / CHILD_LOG)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz", compresslevel=1) as archive:  # bags barely compress
        # files and folders only: ROS's logs/ros/latest is a link, which a client takes from no worker
        archive.add(folder, arcname=folder.name, filter=lambda member: None if member.issym() else member)
    return {"result": answer["result"], "archive": buffer.getvalue(), "log_tail": log_tail}


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


# --- the runner: a batch of one simulation per job, on a kept job slot ------------------------------------------

def child_config(job: dict[str, Any]):
    """The BatchConfig of a job: the client's settings, this worker's files, the job's scratch folder as data root."""
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
                                     description="run the simulations of `magna run --cluster` batches on this "
                                                 "worker thread, one job per line on stdin (started by the "
                                                 "worker's tasks, not by hand)")
    parser.add_argument("--scratch", type=Path, required=True, help="the runner's folder (its stacks' logs)")
    parser.add_argument("--parent-pid", type=int, default=0, help="stop the simulation when this process dies")
    args = parser.parse_args(argv)
    # A stop (Ctrl-C on the client, the worker's death) can come at any time: the running simulation, if any, is
    # stopped as Ctrl-C stops a serial one, and the runner ends after it.
    stopping = threading.Event()
    current: list = []

    def stop(*_) -> None:
        stopping.set()
        if not current:  # between jobs: end now (the stack is stopped on the way out)
            raise SystemExit(0)
        for batch in current:
            batch.stop.event.set()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop)
    # stdout carries the answers alone: anything else written there, by this process or a child that inherits it,
    # goes to the runner's log (stderr) instead
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    if args.parent_pid:
        set_parent_death_signal(signal.SIGTERM)  # the worker died
        if os.getppid() != args.parent_pid:
            return 1
    from magna_master.batch import Batch, JobSlot
    from magna_master.stack import cold_reasons
    from magna_master.storage import StoragePlan

    slot: JobSlot | None = None
    job_scratch: Path | None = None
    try:
        for line in sys.stdin:
            job = json.loads(line)
            job_scratch = Path(job["scratch"])
            config = child_config(job)
            if slot is None:
                slot = JobSlot(0, cold_reasons(config), kept=True, stack_logs=args.scratch)
            with open(Path(job["scratch"]) / CHILD_LOG, "a") as log:
                batch = Batch(config, progress=False, out=log)
                current[:] = [batch]
                if stopping.is_set():
                    batch.stop.event.set()
                plan = StoragePlan(config.dataset_dir if config.save_data else None, [job["m"]],
                                   reason="" if config.save_data else "saving is off (--skip-save)")
                result = batch.run(plan, slot)
                current.clear()
            simulation = result.simulations[0] if result.simulations else None
            answer = {"started": simulation is not None or not result.interrupted,
                      "result": dataclasses.replace(simulation, directory=None).to_dict() if simulation else None}
            try:
                print(json.dumps(answer, default=str), file=answers, flush=True)
            except BrokenPipeError:  # the worker is gone
                break
            if stopping.is_set() or (args.parent_pid and os.getppid() != args.parent_pid):
                break
    finally:
        if slot is not None:
            slot.stop_stack()
        if args.parent_pid and os.getppid() != args.parent_pid:  # the worker died: nobody collects the folders
            shutil.rmtree(args.scratch, ignore_errors=True)
            if job_scratch is not None:
                shutil.rmtree(job_scratch, ignore_errors=True)
    return 0


def placed_result(reply: dict[str, Any], folder: Path | None) -> SimulationResult | None:
    """The SimulationResult a worker sent, for the client (its folder now `folder`), or None when it sent none."""
    if reply.get("result") is None:
        return None
    return dataclasses.replace(SimulationResult.from_dict(reply["result"], f"worker {reply['worker']}"),
                               directory=folder)


if __name__ == "__main__":
    sys.exit(child_main())
