"""One `magna run` started from the page, and the bridge node that lets the page watch it.

The studio writes the world and mission the page holds into the run's folder (so unsaved edits fly
too), starts `magna run ... --status-file` in a process group of its own, and follows the status file:
when a simulation's ROS master appears it starts `rosrun magna_studio bridge` against that master,
and moves the bridge when the next simulation brings another master. Stopping sends the batch Ctrl-C
(magna run then ends the simulation in order and keeps what finished), then ends the bridge.
Nothing here outlives the studio: `close()` ends both process groups.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from magna_common.files import write_text_atomically
from magna_common.processes import end_process_group
from magna_common.storage_tree import StorageError, check_component

RUN_STOP_GRACE = 30.0  # s magna run may take to end its simulation in order after Ctrl-C
LOG_LINES = 40  # last lines of magna run's output shown on the page
BRIDGE_LINE = re.compile(r"^bridge: (ws://\S+)")


class RunError(Exception):
    """A run the studio will not start; the message says why and what to do."""


@dataclass(frozen=True)
class RunRequest:
    world: dict  # {"data": the world document, "name": "Family/Name"}
    mission: dict  # {"data": the mission document, "name": "Family/Name"}
    n_iter: int = 1
    rtf: str = "1"
    seed: int = 0
    name: str = "studio"

    @classmethod
    def from_json(cls, body: Any) -> RunRequest:
        if not isinstance(body, dict):
            raise RunError("the run request is not a JSON object")
        for key in ("world", "mission"):
            part = body.get(key)
            if not isinstance(part, dict) or not isinstance(part.get("data"), dict) or \
                    not isinstance(part.get("name"), str):
                raise RunError(f"{key}: give {{'data': the {key} document, 'name': 'Family/Name'}}; open or "
                               f"create a {key} first")
        n_iter, seed = body.get("n_iter", 1), body.get("seed", 0)
        if isinstance(n_iter, bool) or not isinstance(n_iter, int) or not 1 <= n_iter <= 1000:
            raise RunError(f"n_iter is {n_iter!r}: give a whole number of simulations, 1..1000")
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise RunError(f"seed is {seed!r}: give a whole number")
        rtf = str(body.get("rtf", "1"))
        if rtf != "max":
            try:
                if not float(rtf) > 0:
                    raise ValueError
            except ValueError:
                raise RunError(f"rtf is {rtf!r}: give 'max' or a real-time factor > 0, e.g. 1") from None
        name = str(body.get("name", "studio"))
        try:
            check_component(name, "name")
        except StorageError as err:  # a name that is not one folder
            raise RunError(str(err)) from None
        return cls(body["world"], body["mission"], n_iter, rtf, seed, name)


def _family_and_name(name: str, what: str) -> tuple[str, str]:
    parts = name.split("/")
    if len(parts) != 2:
        raise RunError(f"{what} name {name!r}: give Family/Name, e.g. Gym/My_World (magna run files the "
                       "dataset under these names)")
    for part in parts:
        try:
            check_component(part, f"{what} name")
        except StorageError as err:
            raise RunError(str(err)) from None
    return parts[0], parts[1]


@dataclass
class _Process:
    process: subprocess.Popen
    log: deque[str] = field(default_factory=lambda: deque(maxlen=LOG_LINES))


class StudioRun:
    """At most one run at a time; every method is safe from any thread."""

    def __init__(self, magna: Path, runs_dir: Path, data_root: Path, search_path: list[Path], origin: str,
                 bridge_command: list[str] | None = None):
        self.magna, self.runs_dir, self.data_root = magna, runs_dir, data_root
        self.search_path, self.origin = search_path, origin
        self.bridge_command = bridge_command or ["rosrun", "magna_studio", "bridge"]
        self._lock = threading.RLock()
        self._run: _Process | None = None
        self._folder: Path | None = None
        self._bridge: _Process | None = None
        self._bridge_master: str | None = None
        self._bridge_url: str | None = None
        self._bridge_error = ""
        self._stopping = False
        self._exit_status: int | None = None
        self._ending: list[threading.Thread] = []  # bridges being ended off the event loop; close() waits for them

    # --- the run -------------------------------------------------------------------------------------------
    def start(self, request: RunRequest) -> dict:
        world_family, world_name = _family_and_name(request.world["name"], "world")
        mission_family, mission_name = _family_and_name(request.mission["name"], "mission")
        with self._lock:
            if self._run is not None and self._run.process.poll() is None:
                raise RunError("a run is going on; stop it first, or wait for it to end")
            self._end_bridge()
            folder = self.runs_dir / time.strftime("%Y%m%d-%H%M%S")
            suffix = 1
            while folder.exists():
                suffix += 1
                folder = self.runs_dir / f"{time.strftime('%Y%m%d-%H%M%S')}_{suffix}"
            world_file = folder / "worlds" / world_family / f"{world_name}.json"
            mission_file = folder / "missions" / mission_family / f"{mission_name}.json"
            for path, data in ((world_file, request.world["data"]), (mission_file, request.mission["data"])):
                path.parent.mkdir(parents=True, exist_ok=True)
                write_text_atomically(path, json.dumps(data, indent=4) + "\n")
            argv = [str(self.magna), "run", "--world", str(world_file), "--mission", str(mission_file),
                    "--n-iter", str(request.n_iter), "--rtf", request.rtf, "--seed", str(request.seed),
                    "--name", request.name, "--data-root", str(self.data_root), "--append",
                    "--button-timeout", "0", "--status-file", str(folder / "status.json"),
                    *[arg for d in self.search_path for arg in ("--search-path", str(d))]]
            log = open(folder / "magna_run.log", "w")  # noqa: SIM115 - the reader thread closes it
            process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                       text=True, bufsize=1, start_new_session=True)
            self._run = _Process(process)
            self._folder, self._stopping, self._exit_status = folder, False, None
            threading.Thread(target=self._read_run, args=(self._run, log), daemon=True).start()
            return {"folder": str(folder), "command": argv}

    def _read_run(self, run: _Process, log) -> None:
        with log:
            assert run.process.stdout is not None
            for line in run.process.stdout:
                log.write(line)
                log.flush()
                run.log.append(line.rstrip("\n"))
        code = run.process.wait()
        with self._lock:
            if self._run is run:
                self._exit_status = code
                self._end_bridge()

    def stop(self) -> None:
        """Ctrl-C to the batch (it ends its simulation in order), then the bridge. Blocks: call it off the loop."""
        with self._lock:
            run = self._run
            self._stopping = True
        if run is not None:
            end_process_group(run.process, grace=RUN_STOP_GRACE)
        with self._lock:
            self._end_bridge()

    def close(self) -> None:
        """End the run and every bridge; waits until they are gone."""
        self.stop()
        for thread in self._ending:
            thread.join()

    # --- what the page polls ----------------------------------------------------------------------------------
    def status(self) -> dict:
        with self._lock:
            if self._run is None:
                return {"state": "idle"}
            written = self._read_status()
            running = self._run.process.poll() is None
            if running:
                self._follow_master(written)
            state = "stopping" if running and self._stopping else "running" if running else "finished"
            return {"state": state, "folder": str(self._folder), "batch": written,
                    "exit_status": self._exit_status, "log": list(self._run.log),
                    "bridge_url": self._bridge_url, "bridge_error": self._bridge_error,
                    "bridge_pid": self._bridge.process.pid if self._bridge is not None else None,
                    "master_uri": self._bridge_master}

    def _read_status(self) -> dict | None:
        assert self._folder is not None
        try:
            return json.loads((self._folder / "status.json").read_text())
        except (OSError, ValueError):  # not written yet (magna run is starting)
            return None

    # --- the bridge ---------------------------------------------------------------------------------------------
    def _follow_master(self, written: dict | None) -> None:
        running = (written or {}).get("running") or []
        master = running[-1]["master_uri"] if running else None
        if master is None or master == self._bridge_master:
            return
        self._end_bridge()
        self._bridge_master = master
        env = dict(os.environ, ROS_MASTER_URI=master, ROS_IP="127.0.0.1")
        env.pop("ROS_HOSTNAME", None)
        argv = [*self.bridge_command, "--port", "0", "--allow-origin", self.origin]
        process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                   text=True, bufsize=1, env=env, start_new_session=True)
        self._bridge = _Process(process)
        threading.Thread(target=self._read_bridge, args=(self._bridge,), daemon=True).start()

    def _read_bridge(self, bridge: _Process) -> None:
        assert bridge.process.stdout is not None
        for line in bridge.process.stdout:
            bridge.log.append(line.rstrip("\n"))
            found = BRIDGE_LINE.match(line)
            if found:
                with self._lock:
                    if self._bridge is bridge:
                        self._bridge_url = found.group(1)
        code = bridge.process.wait()
        with self._lock:
            if self._bridge is bridge and code not in (0, -2, -15):
                self._bridge_error = f"the bridge node ended with status {code}: " + " | ".join(bridge.log)

    def _end_bridge(self) -> None:
        bridge, self._bridge = self._bridge, None
        self._bridge_url, self._bridge_master, self._bridge_error = None, None, ""
        if bridge is not None:
            ending = threading.Thread(target=end_process_group, args=(bridge.process, 5.0))
            ending.start()
            self._ending = [t for t in self._ending if t.is_alive()] + [ending]
