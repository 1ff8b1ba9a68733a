"""`magna run --status-file FILE`: where a batch is, in a small JSON file a watching program reads.

A program that starts `magna run` and wants to follow it (magna studio) cannot guess the ROS master of
the running simulation: every simulation, or every warm stack, has its own on a free port. This file
says it, and how far the batch has come. It is rewritten whole (atomically) at every change:

    {"pid": the magna run process, "state": "running" | "finished", "total": simulations planned,
     "done": simulations ended, "succeeded": of them, "running": [{"simulation": m, "master_uri": URI}]
     (one per job slot, --jobs), "results": [{"id", "success", "outcome", "sim_duration", "directory",
     "master_uri"}], "dataset_dir": the dataset's folder or null, "exit_status": at "finished"}
"""
from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from typing import Any

from magna_common.files import write_text_atomically


class RunStatus:
    def __init__(self, path: Path, total: int, dataset_dir: Path | None):
        self.path = path
        self._lock = threading.Lock()  # job slots report from their own threads
        self._status: dict[str, Any] = {"pid": os.getpid(), "state": "running", "total": total, "done": 0,
                                        "succeeded": 0, "running": [], "results": [],
                                        "dataset_dir": str(dataset_dir) if dataset_dir is not None else None}
        self._write()

    def started(self, simulation: int, master_uri: str) -> None:
        with self._lock:
            self._status["running"].append({"simulation": simulation, "master_uri": master_uri})
            self._write()

    def finished(self, result) -> None:
        """A SimulationResult, as `magna run` hands it to on_simulation."""
        with self._lock:
            ran = [r for r in self._status["running"] if r["simulation"] == result.id]
            self._status["running"] = [r for r in self._status["running"] if r["simulation"] != result.id]
            self._status["done"] += 1
            self._status["succeeded"] += int(bool(result.success))
            self._status["results"].append({
                "id": result.id, "success": bool(result.success), "outcome": result.outcome,
                "sim_duration": result.sim_duration,
                "directory": str(result.directory) if result.directory is not None else None,
                "master_uri": ran[0]["master_uri"] if ran else None})
            self._write()

    def ended(self, exit_status: int) -> None:
        with self._lock:
            self._status.update(state="finished", running=[], exit_status=exit_status)
            self._write()

    def _write(self) -> None:
        write_text_atomically(self.path, json.dumps(self._status, indent=2) + "\n", overwrite=True)
