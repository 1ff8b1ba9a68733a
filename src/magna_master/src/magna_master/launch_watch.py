"""Reads a simulation's launch log as it grows, for roslaunch's word that a required node died.

simulation.launch marks the simulator (magna_sim), the world node and the ground station required:
when one dies roslaunch prints `REQUIRED process [magna_sim-2] has died!` with the exit description
(`process has died [pid N, exit code -9, cmd ...]`) and shuts the launch down. The supervisor polls
`RequiredDeathWatch` while it waits, so it knows which node died, and when, within its poll period,
however long the rest of the launch then takes to stop. No ROS here.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

# What each required node of simulation.launch is, for a result message people read.
COMPONENTS = {
    "magna_sim": "the simulator (magna_sim)",
    "ground_station": "the ground station",
    "magna_world": "the world node (magna_world)",
}

_REQUIRED_DIED = re.compile(r"REQUIRED process \[(?P<process>[^\]]+)\] has died!\s*\n(?P<detail>[^\n]*)")
_EXIT_CODE = re.compile(r"exit code (-?\d+)")
_READ_LIMIT = 1 << 20  # bytes read per poll at most: a log that floods is read over several polls


@dataclass(frozen=True)
class RequiredDeath:
    node: str  # the node's name (magna_sim), roslaunch's process name without its -N
    detail: str  # roslaunch's exit description
    exit_code: int | None

    @property
    def component(self) -> str:
        return COMPONENTS.get(self.node, f"the required node {self.node}")

    def describe(self) -> str:
        return f"{self.component} died ({self.detail.strip() or 'no exit description'})"


class RequiredDeathWatch:
    """`poll()` reads what the log gained since the last call; the first required node's death found, or None."""

    def __init__(self, log_path: Path):
        self.log_path = Path(log_path)
        self._offset = 0
        self._pending = ""  # text after the last complete line, kept for the next poll
        self.death: RequiredDeath | None = None

    def poll(self) -> RequiredDeath | None:
        if self.death is not None:
            return self.death
        try:
            with open(self.log_path, "rb") as log:
                log.seek(self._offset)
                chunk = log.read(_READ_LIMIT)
        except OSError:
            return None
        if not chunk:
            return None
        self._offset += len(chunk)
        text = self._pending + chunk.decode(errors="replace")
        match = _REQUIRED_DIED.search(text)
        if match is None:
            # keep an unfinished REQUIRED line (and the line after it) for the next poll
            start = text.rfind("REQUIRED process [")
            self._pending = text[start:] if start >= 0 else text[-200:]
            return None
        detail = match["detail"].strip()
        code = _EXIT_CODE.search(detail)
        self.death = RequiredDeath(re.sub(r"-\d+$", "", match["process"]), detail,
                                   int(code.group(1)) if code else None)
        return self.death
