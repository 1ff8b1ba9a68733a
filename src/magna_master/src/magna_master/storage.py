"""Where simulation batches keep their data, and what happens when a run would meet older data.

The tree (its paths in magna_common.storage_tree; result.json and a summary.csv row are
magna_common.records' SimulationResult and SummaryRow)::

    <data root>/Simulations/<world>/<subworld>/<mission>/<submission>/<name>/dataset_<n>/
        summary.csv                  one row per simulation, rewritten atomically after each one
        simulation_<m>/              m counts from 1
            result.json              what the Master recorded (written atomically)
            world.json mission.json uav_<id>.csv simulation.bag    written by the ground station
            logs/                    launch.log, supervisor.log and the ROS node logs

The data root defaults to `~/magna_data`. A batch checks before it starts, and again before each
simulation, that it can write in the dataset folder and that its disk keeps a floor of free space
(`check_writable`); a folder without a summary row (its batch was killed, or the disk filled before
the row was written) gets one from the next batch (`repair_summary`). A simulation folder that already exists
is a *conflict*; the policy says what to do with it:

- ``append``: number the new simulations after the last existing one (nothing is touched);
- ``overwrite``: the only way anything is deleted: each folder that will be rewritten is
  deleted just before its simulation starts, and its summary row with it; other folders stay;
- ``skip-save``: run the simulations without writing anything (`magna run --skip-save` asks for it
  whether or not the dataset holds data);
- ``abort`` (no policy given and nobody to ask): stop before starting anything, with a
  message that lists the three options.

Nothing here imports ROS: the batch loop and the tests use it directly.
"""
from __future__ import annotations

import dataclasses
import datetime
import errno
import fcntl
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.records import INTERRUPTED, RecordError, SimulationResult, SummaryRow
from magna_common.storage_tree import (
    RESULT_FILE,
    SUMMARY_FILE,
    StorageError,
    existing_simulations,
    simulation_dir,
)

APPEND, OVERWRITE, SKIP_SAVE, ABORT = "append", "overwrite", "skip-save", "abort"
POLICIES = (APPEND, OVERWRITE, SKIP_SAVE, ABORT)


class StorageConflict(StorageError):
    """Planned simulation folders exist already and no policy says what to do."""

    def __init__(self, dataset_dir: Path, existing: list[int], planned: list[int]):
        self.dataset_dir, self.existing, self.planned = dataset_dir, existing, planned
        clash = sorted(set(existing) & set(planned))
        super().__init__(
            f"{dataset_dir} already holds {_id_ranges(clash, 'simulation_')} "
            f"({len(existing)} simulation folder(s) in all, last simulation_{max(existing)}); "
            "nothing was started. Choose: --append (number the new simulations from "
            f"{max(existing) + 1}), --overwrite (delete and rewrite {_id_ranges(clash, 'simulation_')}), "
            "--skip-save (run without saving), or another --name/--dataset")


def _id_ranges(ids: Iterable[int], prefix: str = "") -> str:
    """[1, 2, 3, 5] -> 'simulation_1..3, simulation_5'."""
    ids = sorted(ids)
    parts, start = [], None
    for i, value in enumerate(ids):
        if start is None:
            start = value
        if i + 1 == len(ids) or ids[i + 1] != value + 1:
            parts.append(f"{prefix}{start}" if start == value else f"{prefix}{start}..{value}")
            start = None
    return ", ".join(parts) or "nothing"


# --- result.json and summary.csv ---------------------------------------------------------------------------

def write_result(sim_dir: Path, result: SimulationResult) -> Path:
    """result.json of one simulation, atomically."""
    return result.write(Path(sim_dir) / RESULT_FILE)


def read_result(path: Path) -> SimulationResult | None:
    """A result.json, or None when missing or unreadable (a simulation that never finished writing it)."""
    try:
        return SimulationResult.read(path)
    except RecordError:
        return None


def read_summary(dataset_dir: Path) -> list[SummaryRow]:
    """The rows of a dataset's summary.csv (none when it does not exist)."""
    try:
        return SummaryRow.read(Path(dataset_dir) / SUMMARY_FILE)
    except RecordError as err:
        if err.missing:
            return []
        raise


def update_summary(dataset_dir: Path, result: SimulationResult) -> Path:
    """Put (or replace) the row of `result` in summary.csv, keeping every other row; rows in id order."""
    row = SummaryRow.of(result)
    rows = [r for r in read_summary(dataset_dir) if r.id != row.id]
    # in id order: simulations run at once (--jobs, --cluster) end in any order
    return SummaryRow.write(Path(dataset_dir) / SUMMARY_FILE, sorted([*rows, row], key=lambda r: r.id or 0))


def remove_summary_row(dataset_dir: Path, m: int) -> None:
    rows = read_summary(dataset_dir)
    kept = [r for r in rows if r.id != m]
    if len(kept) != len(rows):
        SummaryRow.write(Path(dataset_dir) / SUMMARY_FILE, kept)


def repair_summary(dataset_dir: Path) -> list[int]:
    """Give each simulation folder without a summary row its row; returns the ids given one.

    A batch that was killed (SIGKILL, a power cut) or met a full disk cannot write the row of the
    simulation it was running. Its supervisor may still have written a final result.json: that is the
    row. Without one, the simulation did not finish: its result.json says so (termination
    'interrupted', success false, what was known kept) and its row follows. Rows already written and
    finished simulations are never touched.
    """
    dataset_dir = Path(dataset_dir)
    listed = {row.id for row in read_summary(dataset_dir)}
    repaired = []
    for m in existing_simulations(dataset_dir):
        if m in listed:
            continue
        folder = simulation_dir(dataset_dir, m)
        result = read_result(folder / RESULT_FILE)
        if result is None or not result.final:
            now = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
            note = f"its batch ended before this simulation finished (found by the next batch, {now})"
            if result is not None and result.reported:  # the ground station's verdict stands
                result = dataclasses.replace(result, final=True, message=f"{result.message}; {note}")
            else:
                result = dataclasses.replace(result or SimulationResult(), id=m, final=True, success=False,
                                             termination=INTERRUPTED, outcome=INTERRUPTED, message=note)
            write_result(folder, result)
        update_summary(dataset_dir, result)
        repaired.append(m)
    return repaired


# --- room to write --------------------------------------------------------------------------------------------

DEFAULT_MIN_FREE_MB = 100.0  # a batch keeps at least this much free on the disk of its dataset


def describe_write_error(folder: Path, err: OSError) -> str:
    """What a failed write in `folder` means for the user, and the fix."""
    reason = err.strerror or str(err)
    if err.errno in (errno.ENOSPC, errno.EDQUOT):
        return (f"no space left on the disk of {folder} ({reason}); free space there, or choose another "
                "--data-root")
    if err.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
        return (f"{folder} is not writable ({reason}); make it writable (its owner and permissions, or a "
                "read-only mount) or choose another --data-root")
    return f"cannot write in {folder} ({reason}); check that disk, or choose another --data-root"


def check_writable(folder: Path, min_free_mb: float = DEFAULT_MIN_FREE_MB) -> None:
    """StorageError unless a file can be written in `folder` and its disk has `min_free_mb` MB free.

    The probe is a small file, written, synced and removed: on file systems that allocate late, only
    the sync meets a full disk.
    """
    folder = Path(folder)
    try:
        fd, probe = tempfile.mkstemp(prefix=".magna_write_probe.", dir=folder)
        try:
            os.write(fd, b"\0" * 4096)
            os.fsync(fd)
        finally:
            os.close(fd)
            os.unlink(probe)
    except OSError as err:
        raise StorageError(describe_write_error(folder, err)) from None
    free = shutil.disk_usage(folder).free
    if free < min_free_mb * 1e6:
        raise StorageError(f"only {free / 1e6:.1f} MB free on the disk of {folder}, less than the "
                           f"{min_free_mb:g} MB a batch keeps free (--min-free-space); free space there, or "
                           "choose another --data-root")


# --- planning a batch -------------------------------------------------------------------------------------------

@dataclass
class StoragePlan:
    """Which simulation ids a batch runs and where (if anywhere) it saves them."""

    dataset_dir: Path | None  # None: nothing is written
    ids: list[int]
    policy: str | None = None  # the conflict policy applied, None when there was no conflict
    overwrite: list[int] = field(default_factory=list)  # ids whose existing folder is deleted before rewriting
    reason: str = ""  # why nothing is saved, when dataset_dir is None

    @property
    def save(self) -> bool:
        return self.dataset_dir is not None

    def simulation_dir(self, m: int) -> Path | None:
        return simulation_dir(self.dataset_dir, m) if self.dataset_dir is not None else None


def ask_policy(conflict: StorageConflict, input_fn: Callable[[str], str] = input) -> str:
    """Ask on the terminal what to do about a conflict; returns one of POLICIES."""
    clash = _id_ranges(sorted(set(conflict.existing) & set(conflict.planned)), "simulation_")
    prompt = (f"{conflict.dataset_dir} already holds {clash}.\n"
              f"  [a]ppend (new simulations from {max(conflict.existing) + 1}), [o]verwrite ({clash}), "
              "[s]kip-save (run without saving), [q]uit? ")
    answers = {"a": APPEND, "append": APPEND, "o": OVERWRITE, "overwrite": OVERWRITE, "s": SKIP_SAVE,
               "skip-save": SKIP_SAVE, "q": ABORT, "quit": ABORT, "abort": ABORT, "": ABORT}
    for _ in range(3):
        try:
            answer = input_fn(prompt).strip().lower()
        except EOFError:
            return ABORT
        if answer in answers:
            return answers[answer]
    return ABORT


def plan_storage(dataset_dir: Path, n_iter: int, policy: str | None = None, save: bool = True,
                 ask: Callable[[StorageConflict], str] | None = None) -> StoragePlan:
    """Decide the simulation ids and what to do with older folders. Touches nothing on disk.

    Without a conflict the ids are 1..n_iter (`append` numbers after the last existing folder
    even then). With one, `policy` decides; without a policy `ask` is called when given (a
    terminal), else StorageConflict is raised.
    """
    if n_iter < 1:
        raise StorageError(f"the number of simulations must be >= 1, got {n_iter}")
    if policy is not None and policy not in POLICIES:
        raise StorageError(f"unknown conflict policy {policy!r}; use one of {', '.join(POLICIES)}")
    planned = list(range(1, n_iter + 1))
    if not save:
        return StoragePlan(None, planned, reason="saving is off (--skip-save)")
    existing = existing_simulations(dataset_dir)
    if policy == APPEND:
        start = (max(existing) if existing else 0) + 1
        return StoragePlan(Path(dataset_dir), list(range(start, start + n_iter)), APPEND if existing else None)
    clash = sorted(set(existing) & set(planned))
    if not clash:
        return StoragePlan(Path(dataset_dir), planned)
    conflict = StorageConflict(Path(dataset_dir), existing, planned)
    if policy is None and ask is not None:
        policy = ask(conflict)
        if policy == APPEND:
            return plan_storage(dataset_dir, n_iter, APPEND, save)
    if policy == OVERWRITE:
        return StoragePlan(Path(dataset_dir), planned, OVERWRITE, clash)
    if policy == SKIP_SAVE:
        return StoragePlan(None, planned, SKIP_SAVE, reason=f"{dataset_dir} holds data already (--skip-save)")
    raise conflict


def prepare_simulation_dir(plan: StoragePlan, m: int) -> Path:
    """Create the folder of simulation `m`; with `overwrite` first delete the old one and its summary row.

    Only a folder named in `plan.overwrite` is ever deleted; any other existing folder is an error.
    """
    if plan.dataset_dir is None:
        raise StorageError("this batch saves nothing; there is no simulation folder to prepare")
    path = simulation_dir(plan.dataset_dir, m)
    if path.exists() or path.is_symlink():
        if m not in plan.overwrite:
            raise StorageError(f"{path} appeared while the batch ran; it was left as it is. Run again with "
                               "--append or another --name/--dataset")
        if path.is_symlink() or not path.is_dir():
            path.unlink()
        else:
            shutil.rmtree(path)
        remove_summary_row(plan.dataset_dir, m)
    path.mkdir(parents=True)
    return path


class DatasetLock:
    """An exclusive lock on a dataset folder, so that two batches never write into the same one.

    The folder is created if needed; on release, the folders the lock created are removed
    again if they stayed empty.
    """

    def __init__(self, dataset_dir: Path):
        self.dataset_dir = Path(dataset_dir)
        self._fd: int | None = None
        self._created: list[Path] = []  # the folders this lock made, deepest first

    def acquire(self) -> DatasetLock:
        if not self.dataset_dir.exists():
            missing = [self.dataset_dir]
            missing.extend(p for p in self.dataset_dir.parents if not p.exists())
            try:
                self.dataset_dir.mkdir(parents=True)
                self._created = missing
            except FileExistsError:
                pass
            except OSError as err:
                raise StorageError(f"cannot create {self.dataset_dir}: {describe_write_error(missing[-1].parent, err)}"
                                   ) from None
        self._fd = os.open(self.dataset_dir, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(self._fd)
            self._fd = None
            if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise StorageError(f"another magna run is writing to {self.dataset_dir}; wait for it to end "
                                   "or choose another --name/--dataset") from None
            raise
        return self

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
        for folder in self._created:
            try:
                folder.rmdir()  # only when still empty: a batch that wrote nothing leaves no folders
            except OSError:
                break
        self._created = []

    def __enter__(self) -> DatasetLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
