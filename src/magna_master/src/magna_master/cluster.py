"""`magna run --cluster ADDRESS`: the batch's simulations as tasks of a Dask distributed scheduler.

The client (this module) plans the dataset exactly as a serial batch does (storage, lock, ids, seeds),
checks every connected worker (magna_master.cluster_task.check_worker: the same MAGNA version, the same
world and mission files), then submits one task per simulation. A worker thread runs its simulations one
after another on a stack it keeps up (magna_master.cluster_task) and sends back each result and the
simulation's folder (a gzipped tar): workers need no shared file system. The client writes each folder
into the dataset as it arrives (unpacked beside it, then renamed into place, so a folder is never half
there), then its summary.csv row. The storage tree and the summary are those of a serial run of the same seeds.

A worker that dies mid-simulation: the scheduler gives the task to another worker; the dead worker's
result never arrives, so summary.csv gets one row per simulation. Ctrl-C: every worker is told to stop
the batch's simulations (cluster_task.stop_batch); their 'interrupted' results are written as a serial
batch writes them, and no further simulation starts.
"""
from __future__ import annotations

import dataclasses
import io
import shutil
import tarfile
import time
import uuid
from pathlib import Path
from typing import Any

from magna_common.records import SUPERVISOR_FAILED, SimulationResult
from magna_common.storage_tree import StorageError, simulation_dir
from magna_master import storage
from magna_master.batch import Batch, JobSlot, RunningBatch, preflight
from magna_master.batch_config import BatchConfig, BatchError
from magna_master.batch_summary import BatchResult
from magna_master.cluster_task import (
    CONFIG_FIELDS,
    close_runners,
    describe_inputs,
    placed_result,
    run_simulation,
    stop_batch,
)

CONNECT_TIMEOUT = 10.0  # s to reach the scheduler
WORKER_TIMEOUT = 30.0  # s for a first worker to be connected to it
STOP_TIMEOUT = 120.0  # s for the workers' interrupted simulations to come back after Ctrl-C


class ClusterError(BatchError):
    """The cluster cannot run the batch (no scheduler, no worker, workers that differ from the client)."""


def connect(address: str, timeout: float = CONNECT_TIMEOUT):
    """A dask.distributed Client of the scheduler at `address`; ClusterError with the fix when it is not there."""
    from distributed import Client

    try:
        return Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as err:
        raise ClusterError(f"--cluster {address}: no Dask scheduler answers there ({err}); start one with "
                           "`scripts/with_env.sh dask scheduler` and give the address it prints "
                           "(src/magna_master/README.md, 'Batches across machines')") from None


def check_workers(client, address: str, manifest: dict[str, Any], timeout: float = WORKER_TIMEOUT) -> dict:
    """Each connected worker's check (address -> cluster_task.check_worker); ClusterError when there is none, or when
    one differs from the client."""
    try:
        client.wait_for_workers(1, timeout=timeout)
    except TimeoutError:
        raise ClusterError(f"--cluster {address}: no worker joined the scheduler within {timeout:g} s; start workers "
                           f"with `scripts/with_env.sh dask worker {address} --nthreads 1`") from None
    from magna_master.cluster_task import check_worker

    checks = client.run(check_worker, manifest, on_error="return")
    for worker, check in checks.items():
        if isinstance(check, BaseException):  # e.g. no magna_master there: not MAGNA's environment
            checks[worker] = {"host": "?", "problems": [
                f"the check failed there ({type(check).__name__}: {check}); start the worker in MAGNA's "
                "environment: scripts/with_env.sh dask worker ..."]}
    wrong = {worker: check for worker, check in checks.items() if check["problems"]}
    if wrong:
        lines = [f"  {worker} ({check['host']}): " + "; ".join(check["problems"]) for worker, check in wrong.items()]
        raise ClusterError(f"--cluster {address}: {len(wrong)} of {len(checks)} worker(s) cannot run this batch as "
                           "the client would:\n" + "\n".join(lines))
    return checks


class ClusterBatch(Batch):
    """A Batch whose simulations run on the workers of a Dask scheduler (see the module doc)."""

    def __init__(self, config: BatchConfig, address: str, **kwargs):
        super().__init__(config, **kwargs)
        self.address = address
        self.client: Any = None  # a distributed.Client while the batch runs
        self.workers: dict = {}

    def run(self, plan: storage.StoragePlan | None = None, slot: JobSlot | None = None) -> BatchResult:
        config = self.config
        preflight(config)
        for flag, used in (("--fleet", config.fleet), ("--rviz", config.rviz), (f"--jobs {config.jobs}",
                                                                                 config.jobs > 1)):
            if used:
                raise BatchError(f"--cluster with {flag}: " + (
                    "each worker runs as many simulations at once as it has threads (dask worker --nthreads)"
                    if flag.startswith("--jobs") else "the workers fly simulated UAVs, with no display"))
        manifest = describe_inputs(config)
        self.client = connect(self.address)
        try:
            self.workers = check_workers(self.client, self.address, manifest)
            self.manifest = manifest
            threads = self.client.nthreads()
            print(f"magna run: cluster {self.address}: {len(threads)} worker(s), {sum(threads.values())} "
                  f"simulation(s) at once, MAGNA {manifest['version']}", file=self.out, flush=True)
            return super().run(plan)  # the workers have the job slots
        finally:
            client, self.client = self.client, None
            client.close()

    def _loop(self, plan: storage.StoragePlan, kept: JobSlot | None = None) -> BatchResult:
        config, client = self.config, self.client
        started = time.monotonic()
        bar = self._progress_bar(plan)
        run = RunningBatch(plan, bar)
        batch_id = uuid.uuid4().hex
        futures = {client.submit(run_simulation, self._request(batch_id, m, plan), key=f"magna-sim-{m}-{batch_id}",
                                 pure=False): m for m in plan.ids}
        stop_deadline = None
        try:
            while futures:
                if (self.stop or self.storage_error or run.halted) and stop_deadline is None:
                    # stop the running simulations as Ctrl-C stops a serial one; the tasks not started return at once
                    self._on_workers(stop_batch, batch_id)
                    stop_deadline = time.monotonic() + STOP_TIMEOUT
                if stop_deadline is not None and time.monotonic() > stop_deadline:
                    client.cancel(list(futures))
                    print(f"magna run: {len(futures)} simulation(s) did not come back within {STOP_TIMEOUT:g} s of "
                          "the stop; their workers end them", file=self.out, flush=True)
                    break
                done = [future for future in futures if future.done()]
                for future in done:
                    self._arrived(futures.pop(future), future, run)
                if not done:
                    time.sleep(0.1)
        finally:
            bar.close()
            # the workers' runners and their stacks end with the batch, as a serial batch's stack does
            self._on_workers(close_runners)
        results = sorted(run.results, key=lambda r: r.id or 0)
        return BatchResult(config, plan, results, bool(self.stop), time.monotonic() - started, self.storage_error)

    def _on_workers(self, function, *args) -> None:
        """Run `function` on every worker; a worker that died, or a scheduler that is gone, is said, not raised (what
        the batch has is kept)."""
        try:
            self.client.run(function, *args, on_error="ignore")  # a dead worker has nothing to stop or close
        except Exception as error:  # noqa: BLE001 -- the scheduler is gone: its workers end their runners themselves
            print(f"magna run: could not reach the workers ({type(error).__name__}: {error}); each one's "
                  "runner ends with it", file=self.out, flush=True)

    def _request(self, batch_id: str, m: int, plan: storage.StoragePlan) -> dict[str, Any]:
        config = self.config
        inputs = config.inputs
        fields = {name: getattr(config, name) for name in CONFIG_FIELDS}
        fields["launch_command"] = list(fields["launch_command"])
        return {"batch": batch_id, "m": m, "save": plan.save, "manifest": self.manifest, "config": fields,
                "names": {"world": inputs.world, "subworld": inputs.subworld, "mission": inputs.mission,
                          "submission": inputs.submission}}

    def _arrived(self, m: int, future, run: RunningBatch) -> None:
        """Simulation m came back (or failed on the cluster): its folder and summary row, then the progress."""
        plan, inputs = run.plan, self.config.inputs
        try:
            reply = future.result()
        except Exception as error:  # noqa: BLE001 -- a KilledWorker, a WorkerMismatch, a lost scheduler: data
            reply = {"started": True, "worker": "?", "result": None, "archive": None,
                     "error": f"{type(error).__name__}: {error}"}
        if not reply["started"]:
            return  # the batch was stopped before it began
        final = plan.simulation_dir(m)
        result = placed_result(reply, final)
        if result is None:
            result = self._failed(m, plan, reply, final)
        else:  # the client's paths, and where it ran
            result = dataclasses.replace(result, data_dir=final, world_file=inputs.world_file,
                                         mission_file=inputs.mission_file, extra={
                                             **result.extra, "worker": {"address": reply["worker"],
                                                                        "name": reply.get("name", ""),
                                                                        "host": reply.get("host", "")}})
        if plan.dataset_dir is not None:
            try:
                self._place(m, plan, reply, result)
                with self._shared:
                    storage.update_summary(plan.dataset_dir, result)
            except OSError as err:
                self._storage_failed(m, "its folder could not be written", plan.dataset_dir, err)
            except StorageError as err:
                with self._shared:
                    self.storage_error = self.storage_error or f"simulation {m}: {err}"
        self._finished(result, run)

    def _failed(self, m: int, plan: storage.StoragePlan, reply: dict, folder: Path | None) -> SimulationResult:
        """The result of a simulation whose worker sent none (its task failed, or its child died)."""
        why = reply.get("error") or (f"its process on worker {reply['worker']} exited with status "
                                     f"{reply.get('exit_code')} before writing its result"
                                     + (f"; its log ends: {reply['log_tail'].splitlines()[-1]}"
                                        if reply.get("log_tail") else ""))
        known = self._known(m, plan, folder)
        return dataclasses.replace(known, final=True, success=False, termination=SUPERVISOR_FAILED,
                                   outcome=SUPERVISOR_FAILED, message=f"the cluster could not run it: {why}",
                                   directory=folder)

    def _place(self, m: int, plan: storage.StoragePlan, reply: dict, result: SimulationResult) -> None:
        """Unpack the worker's folder of simulation m beside the dataset, write its result.json, then rename it into
        place (an older folder is replaced only when the plan overwrites it)."""
        assert plan.dataset_dir is not None
        final = simulation_dir(plan.dataset_dir, m)
        incoming = plan.dataset_dir / f".incoming_simulation_{m}_{uuid.uuid4().hex[:8]}"
        try:
            incoming.mkdir()
            unpacked = incoming / final.name
            if reply.get("archive"):
                unpack(reply["archive"], incoming)
            unpacked.mkdir(exist_ok=True)
            storage.write_result(unpacked, result)
            with self._shared:
                if final.exists() or final.is_symlink():
                    if m not in plan.overwrite:
                        raise StorageError(f"{final} appeared while the batch ran; it was left as it is. Run again "
                                           "with --append or another --name/--dataset")
                    if final.is_dir() and not final.is_symlink():
                        shutil.rmtree(final)
                    else:
                        final.unlink()
                    storage.remove_summary_row(plan.dataset_dir, m)
                unpacked.rename(final)
        finally:
            shutil.rmtree(incoming, ignore_errors=True)


def unpack(archive: bytes, folder: Path) -> None:
    """Unpack a worker's gzipped tar into `folder`: regular files and folders only, none outside it (this Python
    predates tarfile's extraction filters)."""
    with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
        for member in tar:
            target = (folder / member.name).resolve()
            if not target.is_relative_to(folder.resolve()) or not (member.isfile() or member.isdir()):
                raise StorageError(f"a worker sent {member.name!r} in a simulation's folder: refused (only files "
                                   "and folders inside it are taken)")
            if member.isdir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            source = tar.extractfile(member)
            assert source is not None
            with source, open(target, "wb") as sink:
                shutil.copyfileobj(source, sink)


def run_cluster_batch(config: BatchConfig, address: str, **kwargs) -> BatchResult:
    """`magna run --cluster ADDRESS`: run_batch's contract, on the scheduler's workers."""
    return ClusterBatch(config, address, **kwargs).run()

