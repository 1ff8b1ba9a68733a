"""Each simulation's report.html, written while the batch goes on, then the dataset's index.

Drawing a report (reading the bag, six matplotlib figures) takes one to two wall seconds, and the
next simulation does not need it: `magna run` hands each finished simulation to one worker thread
and starts the next at once. The simulation's processes leave part of the two cores idle while they
fly (the simulator waits on its managers), which is where the drawing runs. The reports are written
in the order the simulations ended; `wait` returns when all are written, and `finish` writes the
index after them.

One worker, never more: pyplot keeps global state and must be used by one thread at a time, so the
caller waits (`wait`) before drawing anything else itself.

A report is a view of the data: when one cannot be drawn the batch goes on, and the error is said
with the command that draws it again.
"""
from __future__ import annotations

import queue
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

_DONE = None  # put on the queue by `wait`: the worker ends after the reports before it


def _write_report(directory: Path) -> Path:
    from magna_viz.report import write_report

    return write_report(directory, overwrite=True).path


def _write_index(dataset_dir: Path) -> Path:
    from magna_viz.index import write_index

    return write_index(dataset_dir)


class Reports:
    """`reports(result)` after each simulation (batch's on_simulation); `finish(dataset_dir)` at the end."""

    def __init__(self, write_report: Callable[[Path], Path] = _write_report,
                 write_index: Callable[[Path], Path] = _write_index, out: TextIO | None = None):
        self._write_report, self._write_index = write_report, write_index
        self._out = out
        self._queue: queue.Queue = queue.Queue()
        self._worker: threading.Thread | None = None
        self.written: list[Path] = []
        self.failed: list[int] = []  # simulation ids whose report could not be drawn

    def __call__(self, result) -> None:
        if result.directory is None or result.interrupted:
            return
        if self._worker is None:
            # a daemon: an interrupted `magna run` is not held up by a drawing; write_page writes atomically,
            # so a report cut short leaves no half-written file
            self._worker = threading.Thread(target=self._work, name="magna-reports", daemon=True)
            self._worker.start()
        self._queue.put((result.id, Path(result.directory)))

    def pending(self) -> int:
        """Reports handed over and not yet written (or failed)."""
        return self._queue.unfinished_tasks

    def wait(self) -> None:
        """Return once every report handed over so far is written (or has failed); the worker then ends."""
        worker, self._worker = self._worker, None
        if worker is None:
            return
        self._queue.put(_DONE)
        worker.join()

    def finish(self, dataset_dir: Path) -> None:
        self.wait()
        try:
            index = self._write_index(dataset_dir)
        except Exception as error:  # the data is safe; only the page is missing
            self._say(f"magna run: no index page: {error}; try `magna report {dataset_dir}`", sys.stderr)
            return
        if self.written:
            self._say(f"report:  {self.written[-1]} (the last simulation's)")
        self._say(f"index:   {index} (every simulation, linked to its report)")

    def _work(self) -> None:
        while True:
            item = self._queue.get()
            try:
                if item is _DONE:
                    return
                sim_id, directory = item
                try:
                    self.written.append(self._write_report(directory))
                except Exception as error:  # noqa: BLE001 -- the simulation's data is safe; only its page is missing
                    self.failed.append(sim_id)
                    self._say(f"magna run: simulation {sim_id}: no report: {error}; try `magna report {directory}`",
                              sys.stderr)
            finally:
                self._queue.task_done()

    def _say(self, line: str, default: TextIO | None = None) -> None:
        print(line, file=self._out or default or sys.stdout, flush=True)
