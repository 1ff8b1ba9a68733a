"""The storage tree of simulation batches: where each dataset and simulation lives, and its files' names.

    <data root>/Simulations/<world>/<subworld>/<mission>/<submission>/<name>/dataset_<n>/
        summary.csv        one row per simulation
        simulation_<m>/    result.json, world.json, mission.json, uav_<id>.csv, simulation.bag, logs/

The Master writes this tree (magna_master.storage adds the conflict policies and the dataset lock);
the replay, the reports and mlr read it. Paths only: nothing here reads or writes a file's content.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from magna_common.errors import UserError

DEFAULT_DATA_ROOT = Path("~/magna_data")
DEFAULT_NAME = "default"
SUMMARY_FILE = "summary.csv"
RESULT_FILE = "result.json"
SUMMARY_COLUMNS = ("id", "success", "outcome", "message", "duration", "wall_time", "collisions")
BAG_FILE = "simulation.bag"
WORLD_FILE = "world.json"
MISSION_FILE = "mission.json"
LOGS_DIR = "logs"

_SIMULATION_DIR = re.compile(r"^simulation_(\d+)$")


class StorageError(UserError, RuntimeError):
    """A storage problem the user can fix (bad name, conflict, locked dataset); exit status 2."""


def check_component(value: str, what: str) -> str:
    """A name used as one folder of the tree: no separators, not '.' or '..', not empty."""
    if not value or value in (".", "..") or "/" in value or "\0" in value or value != value.strip():
        raise StorageError(f"{what} {value!r} cannot name a folder: use a plain name without '/' "
                           "or surrounding spaces (e.g. 'default')")
    return value


@dataclass(frozen=True)
class StorageKey:
    """What a batch simulates and under which name; it decides the folder of its datasets."""

    world: str
    subworld: str
    mission: str
    submission: str
    name: str = DEFAULT_NAME

    def __post_init__(self):
        for what in ("world", "subworld", "mission", "submission", "name"):
            check_component(getattr(self, what), what)

    def base_dir(self, data_root: Path) -> Path:
        return (Path(data_root).expanduser() / "Simulations" / self.world / self.subworld / self.mission
                / self.submission / self.name)

    def dataset_dir(self, data_root: Path, n_dataset: int) -> Path:
        if n_dataset < 0:
            raise StorageError(f"dataset number must be >= 0, got {n_dataset}")
        return self.base_dir(data_root) / f"dataset_{n_dataset}"


def simulation_dir(dataset_dir: Path, m: int) -> Path:
    return Path(dataset_dir) / f"simulation_{m}"


def existing_simulations(dataset_dir: Path) -> list[int]:
    """Ids of the `simulation_<m>` folders in a dataset, sorted (none when it does not exist)."""
    try:
        entries = list(Path(dataset_dir).iterdir())
    except FileNotFoundError:
        return []
    ids = []
    for entry in entries:
        match = _SIMULATION_DIR.match(entry.name)
        if match and entry.is_dir():
            ids.append(int(match.group(1)))
    return sorted(ids)
