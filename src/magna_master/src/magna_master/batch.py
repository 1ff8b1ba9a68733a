"""The batch loop: N simulations of one mission in one world, on one stack kept up across the batch.

What it runs is a BatchConfig (batch_config: the world and mission found and checked by
magna_gs.inputs, the launch command, the hyperparameters); what it did is a BatchResult
(batch_summary, with the table `magna run` prints).

Per simulation m (ids from storage.plan_storage, 1..N unless appending), on a warm stack
(magna_master.stack: a master, the simulator, the world node and ORCA-3D, started by the first
simulation and reset before each next one): the stack server sets `/magna/hyperparameters`
(magna_common.records.Hyperparameters: world, subworld, mission, submission, n_dataset,
n_simulation=m, N_iter, sm_view, save_data, save_bag, rviz, seed=S+m), starts the ground station
and writes result.json. After anything but a clean report the stack is stopped and the next
simulation starts a fresh one (StackPolicy).

Cold (--cold-start, --rviz, --fleet, --launch-command, or a stack that could not start or reset):

1. a fresh `RosMaster` on a free port: nothing of the previous simulation (/ual_ids, /clock,
   /use_sim_time, ...) can leak into this one;
2. the parameter `/magna/hyperparameters`, as above;
3. a supervisor process (`python -m magna_master.supervisor`, see there) that serves
   `/magna/master/simulation_termination`, starts the launch command and writes result.json
   (magna_common.records.SimulationResult);
4. when the supervisor is done (or hangs past every budget: then its process group is ended),
   every process still carrying the simulation's token is killed, the master is stopped, and
   the summary row is written.

Job slots (--jobs N): N slots, each in a thread of its own, take the next simulation id in turn. Each slot
keeps its own persistent stack (its own master on its own port, simulator, world node and ORCA-3D) or runs
its simulations cold, so simulations at once share nothing but the dataset folder. What they share
(summary.csv, the results, the progress bar, on_simulation) is written under one lock; summary.csv stays in
id order. One simulation's failure stops no other; a stop (Ctrl-C, a full disk) reaches every slot.

Seeds: simulation m runs with seed S+m (S from --seed, default 0), so appended simulations
get new seeds and a dataset can be re-run exactly.

Ctrl-C (SIGINT), SIGTERM or SIGHUP (the terminal closed) during a batch: the running simulation is
stopped (its supervisor ends the launch), *marked* as interrupted (result.json termination/outcome
"interrupted", success false, and its summary row), every process it started is ended, and no
further simulation starts. A simulation whose ground station had already reported keeps its outcome.
Finished simulations and their summary rows are untouched. `BatchResult.interrupted` says so;
`magna run` then exits with status 130, and `--append` continues the dataset.

Storage: before anything starts, the dataset folder must be writable with `min_free_mb` free on its
disk (storage.check_writable), else a StorageError (exit status 2) names the folder and the fix.
Before each simulation the same check runs; when it fails, or a write of the simulation's
result.json or summary row fails (a disk that filled up meanwhile), the batch stops there and
`BatchResult.storage_error` says why. summary.csv and result.json are written atomically, so a
failed write leaves the previous file whole. A folder the last batch could not give a summary row
(killed, or the disk full) gets one when the next batch starts (storage.repair_summary).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import uuid
import xmlrpc.client
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

from magna_common.cli_vocabulary import parse_rtf
from magna_common.processes import TOKEN_ENV, end_process_group, kill_tagged
from magna_common.records import INTERRUPTED, SUPERVISOR_FAILED, SimulationResult
from magna_common.ros_master import RosMaster, RosMasterError
from magna_common.ros_names import HYPERPARAMETERS
from magna_common.storage_tree import LOGS_DIR, RESULT_FILE, SUMMARY_FILE, StorageError
from magna_master import stack, storage
from magna_master.batch_config import BatchConfig, BatchError, hyperparameters, launch_command
from magna_master.batch_summary import BatchResult, status
from magna_master.stack import Stack, StackError, StackPolicy

# --- the loop --------------------------------------------------------------------------------------------------

def preflight(config: BatchConfig) -> None:
    """Check what the batch needs before anything is created or started."""
    if config.n_iter < 1:
        raise BatchError(f"--n-iter must be >= 1, got {config.n_iter}")
    if config.jobs < 1:
        raise BatchError(f"--jobs must be >= 1, got {config.jobs}")
    if config.jobs > 1 and config.fleet:
        raise BatchError(f"--jobs {config.jobs} with --fleet: the fleet's autopilots fly one mission at a time; "
                         "drop --jobs (or give --jobs 1)")
    if config.n_dataset < 0:
        raise BatchError(f"--dataset must be >= 0, got {config.n_dataset}")
    if config.time_limit is not None and config.time_limit < 0:
        raise BatchError(f"--time-limit must be >= 0 seconds (0: none), got {config.time_limit:g}")
    config.rtf = parse_rtf(config.rtf)
    if config.output not in ("log", "screen"):
        raise BatchError(f"output must be log or screen, got {config.output!r}")
    if not config.launch_command:
        raise BatchError("the launch command is empty")
    if config.rviz and not os.environ.get("DISPLAY"):
        raise BatchError("--rviz needs a display and DISPLAY is not set; run without --rviz and watch a "
                         "simulation afterwards with `magna replay --headless SIM_DIR` (screenshots, GIF, MP4)")
    if config.rviz and shutil.which("rviz") is None:
        raise BatchError("--rviz: rviz is not on PATH; install the Debian package rviz (make setup)")
    if shutil.which("rosmaster") is None:
        raise BatchError("rosmaster is not on PATH: run through ./magna or source devel/setup.bash (make setup)")
    program = config.launch_command[0]
    if shutil.which(program) is None and not Path(program).is_file():
        raise BatchError(f"the launch command {program!r} is not on PATH; run through ./magna (make setup)")
    if config.uses_default_launch():
        try:
            import rospkg

            package = Path(rospkg.RosPack().get_path("magna_gs"))
        except Exception:
            raise BatchError("package magna_gs is not found by ROS: run through ./magna or source "
                             "devel/setup.bash (make setup)") from None
        if not (package / "launch" / "simulation.launch").is_file():
            raise BatchError(f"{package}/launch/simulation.launch is missing: the ground station is not built "
                             "yet; update the workspace (make setup)")


# A running simulation is stopped when its disk has less than this many MB free (or less than
# --min-free-space, if smaller): its result.json and summary row still fit.
FULL_DISK_MB = 1.0

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
# what signal.signal takes and gives back: a function, SIG_DFL or SIG_IGN (ints), None (a handler not set by Python)
_SignalHandler = Callable[[int, FrameType | None], Any] | int | None


class _StopFlag:
    """Set by SIGINT/SIGTERM/SIGHUP while a batch runs (handlers only in the main thread)."""

    def __init__(self, out):
        self.event = threading.Event()
        self.out = out
        self._previous: dict[int, _SignalHandler] = {}

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in STOP_SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _handle(self, signum, _frame) -> None:
        first = not self.event.is_set()
        self.event.set()
        try:
            if first:
                print(f"\nmagna run: {signal.Signals(signum).name}: stopping the running simulation, keeping the "
                      "finished ones (wait for the clean-up)", file=self.out, flush=True)
            else:
                print("magna run: still cleaning up, please wait", file=self.out, flush=True)
        except (OSError, ValueError):  # a terminal that hung up: the stop matters, not the words
            pass

    def __bool__(self) -> bool:
        return self.event.is_set()


class JobSlot:
    """One job slot: the simulations it runs one after another, on a persistent stack of its own.

    A batch makes its slots and stops their stacks when it ends. A slot handed to `Batch.run` by its owner
    (`kept`) outlives the batch: its stack stays up for the owner's next batch, and the owner stops it (a
    cluster worker's runner, magna_master.cluster_task)."""

    def __init__(self, index: int, cold_reasons: list[str], kept: bool = False, stack_logs: Path | None = None):
        self.index = index
        self.kept = kept
        self.stack_logs = stack_logs  # where its stacks keep their logs (None: the first simulation's logs/stack)
        self.stacks_started = 0
        self.stack: Stack | None = None
        self.cold_reasons = list(cold_reasons)  # why its simulations start cold (empty: a warm stack)
        self.disk_full = ""  # why its running simulation was stopped for its disk (empty: it was not)

    def stop_stack(self) -> None:
        if self.stack is not None:
            self.stack.stop()
            self.stack = None


class _DiskWatch:
    """Looks at the free space under a running simulation's folder at most every `disk_check_period`."""

    def __init__(self, batch: Batch, slot: JobSlot, m: int, data_dir: Path | None):
        self.batch, self.slot, self.m, self.data_dir = batch, slot, m, data_dir
        self.next_check = 0.0

    def full(self) -> bool:
        batch, slot = self.batch, self.slot
        now = time.monotonic()
        if self.data_dir is not None and not slot.disk_full and now >= self.next_check:
            self.next_check = now + batch.disk_check_period
            slot.disk_full = batch._disk_full(self.m, self.data_dir)
        return bool(slot.disk_full)


@dataclasses.dataclass
class RunningBatch:
    """What the job slots of one batch share while it runs (under Batch._shared)."""

    plan: storage.StoragePlan
    bar: Any  # the tqdm progress bar
    pending: list[int] = dataclasses.field(default_factory=list)
    results: list[SimulationResult] = dataclasses.field(default_factory=list)
    halted: bool = False  # a simulation was interrupted: start no other
    error: BaseException | None = None  # what a slot raised; raised again by the batch

    def __post_init__(self):
        self.pending = list(self.plan.ids)


class _RunCold:
    """What _supervise_warm returns when the simulation must run cold instead."""


RUN_COLD = _RunCold()


class Batch:
    """One batch run; `run()` returns a BatchResult. Use `run_batch` unless you need the pieces."""

    # Seconds a supervisor may take beyond the simulation's own budgets (its start, rospy, the clean-up)
    # before the batch gives it up as hung and ends its process group.
    supervisor_margin = 60.0
    disk_check_period = 0.5  # wall s between two looks at the free space of a running simulation's disk

    def __init__(self, config: BatchConfig, ask: Callable[[storage.StorageConflict], str] | None = None,
                 progress: bool | None = None, out=None,
                 on_simulation: Callable[[SimulationResult], None] | None = None,
                 on_start: Callable[[int, str], None] | None = None):
        self.config = config
        self.ask = ask
        self.progress = progress
        self.out = out if out is not None else sys.stderr
        self.on_simulation = on_simulation
        self.on_start = on_start  # (simulation, its ROS master's URI) as it starts: for a watcher (--status-file)
        self.stop = _StopFlag(self.out)
        self.storage_error = ""  # why the batch stopped early for its storage (empty: it did not)
        self.cold_reasons = stack.cold_reasons(config)  # why each simulation starts cold (empty: a warm stack)
        self.policy = StackPolicy()
        # One lock for what the job slots share: summary.csv, the results, the progress bar, on_simulation.
        self._shared = threading.Lock()

    def run(self, plan: storage.StoragePlan | None = None, slot: JobSlot | None = None) -> BatchResult:
        """Run the batch; `plan`: the simulation ids and folder decided already (a cluster worker runs one
        simulation of a client's batch), instead of planning them here from the config; `slot`: the one job
        slot to run them on, kept by the caller (its stack is not stopped at the end)."""
        config = self.config
        preflight(config)
        lock = None
        # From here on a signal stops the batch in order (the dataset lock, the folders it made).
        self.stop.install()
        try:
            if config.save_data:
                lock = storage.DatasetLock(config.dataset_dir).acquire()
            if plan is None:
                plan = storage.plan_storage(config.dataset_dir, config.n_iter, config.policy, config.save_data,
                                            self.ask)
            if not plan.save and lock is not None:
                lock.release()  # skip-save: nothing will be written there
                lock = None
            if plan.save:
                storage.check_writable(config.dataset_dir, config.min_free_mb)
                repaired = storage.repair_summary(config.dataset_dir)
                if repaired:
                    print(f"magna run: summary.csv had no row for simulation(s) {', '.join(map(str, repaired))} "
                          "(their batch ended before writing it): added", file=self.out, flush=True)
            return self._loop(plan, slot) if slot is not None else self._loop(plan)
        finally:
            self.stop.restore()
            if lock is not None:
                lock.release()

    def _progress_bar(self, plan: storage.StoragePlan):
        """The batch's one progress bar (off when `progress` is False; by default only on a terminal)."""
        from tqdm import tqdm

        inputs = self.config.inputs
        return tqdm(total=len(plan.ids), unit="sim", desc=f"{inputs.mission}/{inputs.submission}", file=self.out,
                    disable=(None if self.progress is None else not self.progress), dynamic_ncols=True, leave=True)

    def _loop(self, plan: storage.StoragePlan, kept: JobSlot | None = None) -> BatchResult:
        config = self.config
        started = time.monotonic()
        bar = self._progress_bar(plan)
        run = RunningBatch(plan, bar)
        slots = [kept] if kept is not None else [JobSlot(i, self.cold_reasons)
                                                   for i in range(min(config.jobs, len(plan.ids)))]
        try:
            if len(slots) == 1:
                self._work(slots[0], run)
            else:
                self._work_in_threads(slots, run)
        finally:
            bar.close()
        if run.error is not None:
            raise run.error
        results = sorted(run.results, key=lambda r: r.id or 0)
        return BatchResult(config, plan, results, bool(self.stop), time.monotonic() - started, self.storage_error)

    def _work_in_threads(self, slots: list[JobSlot], run: RunningBatch) -> None:
        """Each slot in a thread of its own; this (main) thread keeps taking the stop signals meanwhile."""
        threads = [threading.Thread(target=self._work, args=(slot, run), name=f"magna-job-{slot.index + 1}",
                                    daemon=True) for slot in slots]
        for thread in threads:
            thread.start()
        for thread in threads:
            while thread.is_alive():
                thread.join(0.2)  # a short join: the signal handlers run in between

    def _work(self, slot: JobSlot, run: RunningBatch) -> None:
        """One slot's simulations, one after another, until none is left or the batch must stop."""
        try:
            while (m := self._next(run)) is not None:
                try:
                    if run.plan.dataset_dir is not None:  # the disk may have filled since the last simulation
                        storage.check_writable(run.plan.dataset_dir, self.config.min_free_mb)
                    result = self._simulation(slot, m, run.plan)
                except StorageError as err:
                    with self._shared:
                        self.storage_error = self.storage_error or f"simulation {m} was not started: {err}"
                    return
                if result is None:  # stopped before it started
                    return
                self._finished(result, run)
        except BaseException as error:  # noqa: BLE001 -- raised again by _loop, in the batch's thread
            with self._shared:
                run.error = run.error or error
        finally:
            if not slot.kept:
                self._stop_stack(slot)

    def _next(self, run: RunningBatch) -> int | None:
        """The next simulation to start, or None when the batch must not start another."""
        with self._shared:
            if self.stop or self.storage_error or run.halted or run.error is not None or not run.pending:
                return None
            return run.pending.pop(0)

    def _finished(self, result: SimulationResult, run: RunningBatch) -> None:
        config, bar = self.config, run.bar
        with self._shared:
            run.results.append(result)
            bar.update(1)
            done = [r for r in run.results if not r.interrupted]
            speed = BatchResult(config, run.plan, run.results, False, 0.0).speed
            bar.set_postfix_str(f"ok {sum(r.success for r in done)}/{len(done)}, {speed:.1f}x sim/wall")
            if bar.disable:
                print(f"simulation {result.id} ({len(run.results)}/{len(run.plan.ids)}): {status(result)}, "
                      f"{result.sim_duration:.1f} sim s in {result.wall_time:.1f} s", file=self.out, flush=True)
            if self.on_simulation is not None:
                self.on_simulation(result)
            if result.interrupted:
                run.halted = True

    def _simulation(self, slot: JobSlot, m: int, plan: storage.StoragePlan) -> SimulationResult | None:
        if plan.dataset_dir is not None:  # plan.save
            try:
                with self._shared:  # it may remove an old summary row
                    work_dir = storage.prepare_simulation_dir(plan, m)
            except OSError as err:
                raise StorageError(storage.describe_write_error(plan.dataset_dir, err)) from None
            data_dir: Path | None = work_dir
        else:
            work_dir = Path(tempfile.mkdtemp(prefix=f"magna_sim_{m}_"))
            data_dir = None
        try:
            try:
                result = self._supervise(slot, m, plan, work_dir, data_dir)
            except OSError as err:  # its logs folder or supervisor.log could not be made: nothing ran
                raise StorageError(storage.describe_write_error(work_dir, err)) from None
            if result is None:
                return None
            written = storage.read_result(work_dir / RESULT_FILE)
            if plan.dataset_dir is not None and written is not None and written.final:  # a row only beside it
                try:
                    with self._shared:
                        storage.update_summary(plan.dataset_dir, result)
                except OSError as err:  # the previous summary.csv stays whole (an atomic write)
                    self._storage_failed(m, f"its row of {SUMMARY_FILE} could not be written", plan.dataset_dir, err)
            return dataclasses.replace(result, directory=work_dir if plan.save else None)
        finally:
            if not plan.save:
                shutil.rmtree(work_dir, ignore_errors=True)

    def _supervise(self, slot: JobSlot, m: int, plan: storage.StoragePlan, work_dir: Path,
                   data_dir: Path | None) -> SimulationResult | None:
        if not slot.cold_reasons:
            result = self._supervise_warm(slot, m, plan, work_dir, data_dir)
            if not isinstance(result, _RunCold):
                return result
        return self._supervise_cold(slot, m, plan, work_dir, data_dir)

    def _known(self, m: int, plan: storage.StoragePlan, data_dir: Path | None, **extra) -> SimulationResult:
        """result.json's fields known before simulation m runs."""
        config = self.config
        return SimulationResult(id=m, seed=config.seed_of(m), hyperparameters=hyperparameters(config, m, plan),
                                world_file=config.inputs.world_file, mission_file=config.inputs.mission_file,
                                data_dir=data_dir, extra=extra)

    def _supervise_warm(self, slot: JobSlot, m: int, plan: storage.StoragePlan, work_dir: Path,
                        data_dir: Path | None) -> SimulationResult | None | _RunCold:
        """Simulation m on the slot's persistent stack (started now if there is none); RUN_COLD when the
        stack could not run it, so that it runs cold instead."""
        config = self.config
        logs = work_dir / LOGS_DIR
        logs.mkdir(exist_ok=True)
        fresh = slot.stack is None
        if slot.stack is None:
            stack_token = uuid.uuid4().hex
            try:
                slot.stacks_started += 1
                stack_logs = (slot.stack_logs / f"stack_{slot.stacks_started}" if slot.stack_logs is not None
                              else logs / "stack")
                slot.stack = Stack(stack.server_argv(config), stack_logs, stack_token).start()
            except StackError as err:
                slot.stack = None
                slot.cold_reasons.append(str(err))
                print(f"magna run: simulation {m}: {err}; the batch goes on with a cold start per simulation",
                      file=self.out, flush=True)
                return RUN_COLD
        if self.stop:
            self._discard(work_dir, plan)
            return None
        result_path = work_dir / RESULT_FILE
        token = uuid.uuid4().hex
        self._started(m, slot.stack.master_uri)
        known = self._known(m, plan, data_dir, stack={"start": "cold" if fresh else "warm",
                                                      "index": slot.stack.simulations + 1})
        request = stack.SimulationRequest(
            result=str(result_path), log=str(logs / "launch.log"), data_dir=str(data_dir or ""),
            ros_log_dir=str(logs / "ros"), seed=config.seed_of(m),
            world_record=str(data_dir / "world.json") if data_dir is not None else "",
            hyperparameters=hyperparameters(config, m, plan).to_param(),
            ground_station=stack.ground_station_params(config, data_dir, plan), known=known.to_dict(), token=token,
            time_limit=config.time_limit or 0.0, stop_grace=config.stop_grace, settle=config.settle,
            shutdown_timeout=config.shutdown_timeout)
        slot.disk_full = ""
        disk = _DiskWatch(self, slot, m, data_dir)
        reply = slot.stack.simulate(request, self._supervisor_budget(), lambda: bool(self.stop) or disk.full())
        leftovers = kill_tagged(token)
        if not reply.ran:
            self._stop_stack(slot)
            print(f"magna run: simulation {m}: the stack could not run it ({reply.reason}); it runs cold",
                  file=self.out, flush=True)
            return RUN_COLD
        result = self._settle_result(slot, m, work_dir, result_path, known, slot.stack.server, not reply.healthy,
                                     leftovers, its_log=f"{slot.stack.logs / 'stack_server.log'}")
        why = self.policy.why_restart(result, reply)
        if why:
            self._stop_stack(slot)
        return result

    def _started(self, m: int, master_uri: str) -> None:
        if self.on_start is not None:
            with self._shared:
                self.on_start(m, master_uri)

    @staticmethod
    def _stop_stack(slot: JobSlot) -> None:
        slot.stop_stack()

    def _supervise_cold(self, slot: JobSlot, m: int, plan: storage.StoragePlan, work_dir: Path,
                        data_dir: Path | None) -> SimulationResult | None:
        config = self.config
        logs = work_dir / LOGS_DIR
        logs.mkdir(exist_ok=True)
        result_path = work_dir / RESULT_FILE
        token = uuid.uuid4().hex
        hyper = hyperparameters(config, m, plan)
        command = launch_command(config, m, data_dir, plan)
        known = self._known(m, plan, data_dir)
        master = RosMaster(log_dir=logs / "ros")
        supervisor = None
        hung = False
        try:
            try:
                master.start()
            except (RosMasterError, OSError) as err:
                self._discard(work_dir, plan)
                raise BatchError(f"simulation {m}: cannot start a ROS master: {err}") from None
            xmlrpc.client.ServerProxy(master.uri).setParam("/magna_master", HYPERPARAMETERS, hyper.to_param())
            if self.stop:
                self._discard(work_dir, plan)
                return None
            self._started(m, master.uri)
            argv = self.supervisor_argv(result_path, logs, data_dir, known.to_dict(), command)
            env = dict(os.environ)
            env[TOKEN_ENV] = token
            package_parent = str(Path(__file__).resolve().parents[1])
            env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH", "")) if p)
            with open(logs / "supervisor.log", "ab") as supervisor_log:
                supervisor = master.spawn(argv, env=env, stdout=supervisor_log, stderr=supervisor_log,
                                          stdin=subprocess.DEVNULL)
            hung = self._wait_supervisor(slot, supervisor, m, data_dir)
        finally:
            if supervisor is not None and supervisor.poll() is None:
                end_process_group(supervisor, grace=2.0)
            leftovers = kill_tagged(token)
            master.stop()
        return self._settle_result(slot, m, work_dir, result_path, known, supervisor, hung, leftovers)

    def _settle_result(self, slot: JobSlot, m: int, work_dir: Path, result_path: Path, known: SimulationResult,
                       supervisor, hung: bool, leftovers: list[str],
                       its_log: str = "logs/supervisor.log") -> SimulationResult:
        """result.json as the supervisor left it, completed with what only the batch knows (a disk that
        filled, a supervisor that died or hung before writing it, leftovers killed), and written back."""
        result = storage.read_result(result_path)
        changed = False
        if slot.disk_full and result is not None and result.final and not result.reported:
            # the supervisor wrote its result (there was room for it): say why it was stopped
            result = dataclasses.replace(result, message=slot.disk_full)
            changed = True
        if result is None or not result.final:
            changed = True
            partial = result or known
            reported = partial.reported
            ended = ("the supervisor " + ("hung and was killed" if hung else
                                          f"exited with status {supervisor.returncode if supervisor else None}")
                     + f" before writing its result; see {its_log}")
            result = dataclasses.replace(partial, final=True, supervisor_pid=supervisor.pid if supervisor else None,
                                         message=(partial.message + "; " if reported else "") + ended)
            if not reported:
                termination = INTERRUPTED if self.stop or slot.disk_full else SUPERVISOR_FAILED
                result = dataclasses.replace(result, success=False, outcome=termination, termination=termination,
                                             sim_duration=0.0, collisions=0, reported=False)
                if slot.disk_full:
                    result = dataclasses.replace(result, message=f"{slot.disk_full}; {result.message}")
        if leftovers:
            result = dataclasses.replace(
                result, leftover_processes_killed=(*result.leftover_processes_killed, *leftovers))
            changed = True
        if changed:
            try:
                storage.write_result(work_dir, result)
            except OSError as err:
                self._storage_failed(m, f"its {RESULT_FILE} could not be written", work_dir, err)
                result = dataclasses.replace(result, message=f"{result.message}; {self.storage_error}")
        return result

    def _storage_failed(self, m: int, what: str, folder: Path, err: OSError) -> None:
        """A write of the batch failed (a full disk, a file system gone read-only): the batch stops."""
        failure = f"{what}: {storage.describe_write_error(folder, err)}"
        with self._shared:
            if self.storage_error:  # the disk filled during the simulation: that was said first
                self.storage_error = f"{self.storage_error}; {failure}"
            else:
                self.storage_error = (f"simulation {m}: {failure}; the batch stopped there, then continue it "
                                      "with --append")
        print(f"magna run: simulation {m}: {failure}", file=self.out, flush=True)

    def supervisor_argv(self, result_path: Path, logs: Path, data_dir: Path | None, known: dict,
                        command: list[str]) -> list[str]:
        """The command line of one simulation's supervisor process (`known`: result.json's fields known now)."""
        config = self.config
        return [sys.executable, "-m", "magna_master.supervisor", "--result", str(result_path),
                "--log", str(logs / "launch.log"), "--data-dir", str(data_dir or ""),
                "--time-limit", str(config.time_limit or 0), "--stop-grace", str(config.stop_grace),
                "--settle", str(config.settle), "--shutdown-timeout", str(config.shutdown_timeout),
                "--parent-pid", str(os.getpid()), "--extra", json.dumps(known), "--", *command]

    def _supervisor_budget(self) -> float:
        """Wall s a simulation's supervisor may take in all before it is given up as hung."""
        config = self.config
        return ((config.time_limit or math.inf) + config.stop_grace + config.settle
                + 3 * config.shutdown_timeout + self.supervisor_margin)

    def _wait_supervisor(self, slot: JobSlot, supervisor, m: int, data_dir: Path | None) -> bool:
        """Wait for the supervisor; on a stop request, or a disk that fills up under `data_dir`, forward SIGINT;
        True when it had to be given up as hung."""
        config = self.config
        deadline = time.monotonic() + self._supervisor_budget()
        stop_deadline = None
        slot.disk_full = ""
        disk = _DiskWatch(self, slot, m, data_dir)
        while supervisor.poll() is None:
            now = time.monotonic()
            if (self.stop or disk.full()) and stop_deadline is None:
                try:
                    os.killpg(supervisor.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
                stop_deadline = now + 3 * config.shutdown_timeout + 15.0
            if now > deadline or (stop_deadline is not None and now > stop_deadline):
                return True
            time.sleep(0.05)
        return False

    def _disk_full(self, m: int, data_dir: Path) -> str:
        """Why simulation m must stop for its disk (empty while there is room): below the last MB the nodes'
        writes fail, and the ground station may wait for them until the time limit."""
        try:
            free = shutil.disk_usage(data_dir).free
        except OSError:
            return ""
        if free >= min(FULL_DISK_MB, self.config.min_free_mb) * 1e6:
            return ""
        why = (f"simulation {m} was stopped: the disk of {data_dir} filled up while it ran ({free // 1000} kB free); "
               "free space there, then continue the dataset with --append")
        with self._shared:
            self.storage_error = self.storage_error or why
        print(f"magna run: {why}", file=self.out, flush=True)
        return f"stopped by the batch: the disk filled up ({free // 1000} kB free)"

    def _discard(self, work_dir: Path, plan: storage.StoragePlan) -> None:
        """Remove the folder of a simulation that never started (it holds only its empty logs)."""
        if plan.save:
            shutil.rmtree(work_dir, ignore_errors=True)


def run_batch(config: BatchConfig, ask: Callable[[storage.StorageConflict], str] | None = None,
              progress: bool | None = None, out=None,
              on_simulation: Callable[[SimulationResult], None] | None = None,
              on_start: Callable[[int, str], None] | None = None) -> BatchResult:
    """Run a batch (see the module doc). Raises a UserError (BatchError, StorageError, UsageError) before
    starting anything."""
    return Batch(config, ask=ask, progress=progress, out=out, on_simulation=on_simulation, on_start=on_start).run()
