"""Typed records of the files and parameters MAGNA writes and reads back, one `read` and one `write` each.

- `SimulationResult`: a simulation's result.json (the Master's supervisor and batch write it; the
  batch, the reports, the replay and mlr read it);
- `Hyperparameters`: the parameter /magna/hyperparameters of one simulation (`to_param`/`from_param`),
  also kept in result.json;
- `SummaryRow`: one row of a dataset's summary.csv;
- `WorldRecord`: the world.json the world node writes into a simulation folder (every world part
  the run had, as `magna_worlds.generate.world_record` gives it).

Readers use attributes. Files written by earlier MAGNA versions still read: a missing field takes
its default, and keys this version does not know are kept in `extra` and written back unchanged.
A file that cannot be read, or a field of the wrong type, raises `RecordError` naming the file
(and the field).
"""
from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from magna_common.errors import UserError
from magna_common.files import write_text_atomically
from magna_common.ros_names import HYPERPARAMETERS
from magna_common.storage_tree import SUMMARY_COLUMNS

# How a simulation ended (result.json "termination").
GROUND_STATION = "ground_station"  # the ground station called the termination service
TIME_LIMIT = "time_limit"  # the wall-clock limit passed first
CRASHED = "crashed"  # the launch ended without calling the service
INTERRUPTED = "interrupted"  # Ctrl-C / SIGTERM reached the batch or the supervisor
START_FAILED = "start_failed"  # the launch command could not be started
SUPERVISOR_FAILED = "supervisor_failed"  # the supervisor ended without a result (written by the batch)
NOT_RUN_TO_AN_OUTCOME = (CRASHED, START_FAILED, SUPERVISOR_FAILED)
# Terminations that say nothing of how the mission flew: mlr leaves such simulations out.
NOT_FLOWN = (INTERRUPTED, *NOT_RUN_TO_AN_OUTCOME)


class RecordError(UserError, ValueError):
    """A record file (or parameter) that cannot be read: it names the file and, when one is wrong, the field."""

    def __init__(self, message: str, missing: bool = False):
        super().__init__(message)
        self.missing = missing  # the file is not there at all


class _Bad(ValueError):
    """A value of the wrong type; the record reader adds the file and the field."""


# --- converters: a JSON value to the field's type (_Bad when it is not one) ---------------------------------------

def _str(value: Any) -> str:
    if not isinstance(value, str):
        raise _Bad(f"expected a string, got {value!r}")
    return value


def _bool(value: Any) -> bool:
    if not isinstance(value, bool):
        raise _Bad(f"expected true or false, got {value!r}")
    return value


def _int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or not float(value).is_integer():
        raise _Bad(f"expected a whole number, got {value!r}")
    return int(value)


def _float(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _Bad(f"expected a number, got {value!r}")
    return float(value)


def _path(value: Any) -> Path:
    return Path(_str(value))


def _optional(convert: Callable[[Any], Any]) -> Callable[[Any], Any]:
    return lambda value: None if value is None else convert(value)


def _tuple_of(convert: Callable[[Any], Any]) -> Callable[[Any], tuple]:
    def read(value: Any) -> tuple:
        if not isinstance(value, list | tuple):
            raise _Bad(f"expected a list, got {value!r}")
        return tuple(convert(item) for item in value)
    return read


_floats = _tuple_of(_float)
_strs = _tuple_of(_str)


def _key(name: str | None = None, read: Callable[[Any], Any] = _str, default: Any = None,
         factory: Callable[[], Any] | None = None):
    """A record field: its JSON key (default: the attribute's name) and how a value is read; a field whose
    default is None reads null as None."""
    metadata = {"key": name, "read": _optional(read) if default is None and factory is None else read}
    if factory is not None:
        return field(default_factory=factory, metadata=metadata)
    return field(default=default, metadata=metadata)


def _extra():
    return field(default_factory=dict, compare=False, repr=False)


R = TypeVar("R", bound="_Record")


class _Record:
    """from_dict/to_dict over the dataclass fields declared with `_key`; other keys go to `extra`."""

    extra: dict[str, Any]
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]  # every subclass is a dataclass

    @classmethod
    def _keyed_fields(cls) -> list[tuple[dataclasses.Field, str]]:
        return [(f, f.metadata["key"] or f.name) for f in dataclasses.fields(cls) if "read" in f.metadata]

    @classmethod
    def from_dict(cls: type[R], data: Any, source: str) -> R:
        """The record of a JSON object; RecordError naming `source` and the field when one is wrong."""
        if not isinstance(data, Mapping):
            raise RecordError(f"{source}: expected a JSON object, got {type(data).__name__}")
        values: dict[str, Any] = {}
        known = set()
        for f, key in cls._keyed_fields():
            known.add(key)
            if key not in data:
                continue
            try:
                values[f.name] = f.metadata["read"](data[key])
            except _Bad as err:
                raise RecordError(f"{source}: field {key!r}: {err}") from None
            except RecordError as err:  # a nested record names its own part
                raise RecordError(f"{source}: {err}") from None
        extra = {k: v for k, v in data.items() if k not in known}
        return cls(**values, extra=extra)  # type: ignore[call-arg]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: every field (None as null), then the unknown keys it was read with."""
        out = {k: v for k, v in self.extra.items()}
        for f, key in self._keyed_fields():
            out[key] = _to_json(getattr(self, f.name))
        return out


def _to_json(value: Any) -> Any:
    if isinstance(value, _Record):
        return value.to_dict()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, Mapping):
        return {str(k): _to_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_to_json(v) for v in value]
    return value


def _read_json(path: Path, what: str) -> Any:
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise RecordError(f"{path}: no such file ({what})", missing=True) from None
    except OSError as err:
        raise RecordError(f"{path}: cannot read it ({what}): {err.strerror or err}") from None
    try:
        return json.loads(text)
    except ValueError as err:
        raise RecordError(f"{path}: not JSON ({what}): {err}") from None


def _write_json(path: Path, data: dict) -> Path:
    text = json.dumps(data, indent=2, sort_keys=True, default=str) + "\n"
    return write_text_atomically(path, text, overwrite=True)


# --- /magna/hyperparameters --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Hyperparameters(_Record):
    """What one simulation of a batch is: its world, mission, place in the dataset, seed and what it saves.

    The numbers are None when not given (a hand-made file); `to_param` leaves those out.
    """

    world: str = _key(default="")
    subworld: str = _key(default="")
    mission: str = _key(default="")
    submission: str = _key(default="")
    n_dataset: int | None = _key(read=_int)
    n_simulation: int | None = _key(read=_int)
    n_iter: int | None = _key("N_iter", read=_int)  # simulations in the batch
    sm_view: bool = _key(read=_bool, default=False)
    save_data: bool = _key(read=_bool, default=True)
    save_bag: bool = _key(read=_bool, default=True)
    rviz: bool = _key(read=_bool, default=False)
    seed: int | None = _key(read=_int)
    extra: dict[str, Any] = _extra()

    @classmethod
    def from_param(cls, value: Any, source: str = HYPERPARAMETERS) -> Hyperparameters:
        """From the parameter's value (None or {} when it is not set: every default)."""
        return cls.from_dict(value or {}, source)

    def to_param(self) -> dict[str, Any]:
        """The parameter's value: XML-RPC has no null, so numbers not given are left out."""
        return {k: v for k, v in self.to_dict().items() if v is not None}


# --- result.json -------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SimulationResult(_Record):
    """A simulation's result.json: the ground station's verdict and how the run went.

    `directory` is the simulation folder the file was read from (not written; None when the
    batch saved nothing).
    """

    id: int | None = _key(read=_int)
    seed: int | None = _key(read=_int)
    success: bool = _key(read=_bool, default=False)
    outcome: str = _key(default="")
    message: str = _key(default="")
    termination: str = _key(default="")  # one of GROUND_STATION ... SUPERVISOR_FAILED
    sim_duration: float = _key(read=_float, default=0.0)
    wall_time: float = _key(read=_float, default=0.0)
    collisions: int | None = _key(read=_int)  # None: not in the file
    mission_wall_time: float = _key(read=_float, default=0.0)
    setup_wall_time: float = _key(read=_float, default=0.0)
    reported: bool = _key(read=_bool, default=False)  # the ground station called the termination service
    final: bool = _key(read=_bool, default=False)  # False: written on the report, before the launch was down
    hyperparameters: Hyperparameters | None = _key(read=lambda v: Hyperparameters.from_dict(v, "hyperparameters"))
    world_file: Path | None = _key(read=_path)
    mission_file: Path | None = _key(read=_path)
    data_dir: Path | None = _key(read=_path)
    time_limit: float | None = _key(read=_float)
    timed_out: bool = _key(read=_bool, default=False)
    gs_stop_called: bool = _key(read=_bool, default=False)
    launch_command: tuple[str, ...] = _key(read=_strs, default=())
    launch_pid: int | None = _key(read=_int)
    launch_exit_code: int | None = _key(read=_int)
    supervisor_pid: int | None = _key(read=_int)
    leftover_processes_killed: tuple[str, ...] = _key(read=_strs, default=())
    started_at: str = _key(default="")
    ended_at: str = _key(default="")
    files: tuple[str, ...] = _key(read=_strs, default=())  # the simulation folder's files, logs/ left out
    extra: dict[str, Any] = _extra()
    directory: Path | None = field(default=None, compare=False)

    @property
    def interrupted(self) -> bool:
        return self.termination == INTERRUPTED

    @property
    def failed_to_run(self) -> bool:
        """The simulation did not run to a mission outcome (crash, start failure, supervisor failure)."""
        return self.termination in NOT_RUN_TO_AN_OUTCOME

    @classmethod
    def read(cls, path: Path) -> SimulationResult:
        path = Path(path)
        return dataclasses.replace(cls.from_dict(_read_json(path, "a simulation's result.json"), str(path)),
                                   directory=path.parent)

    def write(self, path: Path) -> Path:
        """Write it atomically (replacing an older one)."""
        return _write_json(Path(path), self.to_dict())


# --- summary.csv -------------------------------------------------------------------------------------------------

def _csv_bool(text: str) -> bool:
    if text.lower() not in ("true", "false"):
        raise _Bad(f"expected True or False, got {text!r}")
    return text.lower() == "true"


def _csv_number(convert: Callable[[str], Any]) -> Callable[[str], Any]:
    def read(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise _Bad(f"expected a number, got {text!r}") from None
        if isinstance(value, float) and math.isnan(value):
            raise _Bad(f"expected a number, got {text!r}")
        return value
    return read


@dataclass(frozen=True)
class SummaryRow:
    """One row of summary.csv (columns storage_tree.SUMMARY_COLUMNS; unknown columns kept in `extra`)."""

    id: int
    success: bool = False
    outcome: str = ""
    message: str = ""  # on one line
    duration: float = 0.0  # simulated seconds
    wall_time: float = 0.0
    collisions: int = 0
    extra: dict[str, str] = field(default_factory=dict, compare=False)

    _READ: ClassVar[dict[str, Callable[[str], Any]]] = {
        "id": _csv_number(int), "success": _csv_bool, "outcome": str, "message": str,
        "duration": _csv_number(float), "wall_time": _csv_number(float), "collisions": _csv_number(int)}

    @classmethod
    def of(cls, result: SimulationResult) -> SummaryRow:
        if result.id is None:
            raise ValueError("a summary row needs the simulation's id, and this result has none")
        return cls(result.id, result.success, result.outcome, " ".join(result.message.split()),
                   result.sim_duration, result.wall_time, result.collisions or 0)

    def cells(self) -> dict[str, str]:
        return {**self.extra, "id": str(self.id), "success": str(self.success), "outcome": self.outcome,
                "message": " ".join(self.message.split()), "duration": f"{self.duration:.3f}",
                "wall_time": f"{self.wall_time:.3f}", "collisions": str(self.collisions)}

    @classmethod
    def read(cls, path: Path) -> list[SummaryRow]:
        """The rows of a summary.csv; an empty cell (or a column an older file lacks) takes the default."""
        path = Path(path)
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise RecordError(f"{path}: no such file (a dataset's summary.csv)", missing=True) from None
        except OSError as err:
            raise RecordError(f"{path}: cannot read it: {err.strerror or err}") from None
        rows = []
        for line, cells in enumerate(csv.DictReader(io.StringIO(text)), start=2):
            values: dict[str, Any] = {}
            for column, read in cls._READ.items():
                cell = cells.get(column) or ""
                if cell == "" and column != "id":
                    continue
                try:
                    values[column] = read(cell)
                except _Bad as err:
                    raise RecordError(f"{path}: line {line}, column {column!r}: {err}") from None
            extra = {k: v or "" for k, v in cells.items() if k is not None and k not in cls._READ}
            rows.append(cls(**values, extra=extra))
        return rows

    @staticmethod
    def write(path: Path, rows: Iterable[SummaryRow]) -> Path:
        """Write summary.csv atomically, rows sorted by id; unknown columns are kept after SUMMARY_COLUMNS."""
        rows = sorted(rows, key=lambda row: row.id)
        columns = list(SUMMARY_COLUMNS)
        for row in rows:
            columns.extend(k for k in row.extra if k not in columns)
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        for row in rows:
            cells = row.cells()
            writer.writerow({k: cells.get(k, "") for k in columns})
        return write_text_atomically(Path(path), out.getvalue(), overwrite=True)


# --- world.json --------------------------------------------------------------------------------------------------

_vector = _floats
_vectors = _tuple_of(_floats)


def _boundaries(value: Any) -> tuple[tuple[float, float], ...]:
    box = _vectors(value)
    if len(box) != 3 or any(len(axis) != 2 for axis in box):
        raise _Bad(f"expected [[xmin, xmax], [ymin, ymax], [zmin, zmax]], got {value!r}")
    return box


def _records_of(cls: type[R], what: str) -> Callable[[Any], tuple]:
    return _tuple_of(lambda item: cls.from_dict(item, what))


@dataclass(frozen=True)
class RecordedPoseSet(_Record):
    type: str = _key(default="")
    path: str | None = _key(read=_str)  # the zigzag path's name; None for other pose sets
    frames: tuple[str, ...] = _key(read=_strs, default=())
    cells: tuple[tuple[float, ...], ...] | None = _key(read=_vectors)
    positions: tuple[tuple[float, ...], ...] = _key(read=_vectors, default=())
    orientations: tuple[tuple[float, ...], ...] = _key(read=_vectors, default=())  # quaternions x, y, z, w
    extra: dict[str, Any] = _extra()


@dataclass(frozen=True)
class RecordedGeometry(_Record):
    """A geometry of a world part: its shape and pose in map."""

    volume: str = _key(default="")
    geometry: str = _key(default="")
    frame: str = _key(default="")
    shape: str = _key(default="")
    dimensions: tuple[float, ...] = _key(read=_vector, default=())
    polygon: tuple[tuple[float, ...], ...] = _key(read=_vectors, default=())
    position: tuple[float, ...] = _key(read=_vector, default=(0.0, 0.0, 0.0))
    orientation: tuple[float, ...] = _key(read=_vector, default=(0.0, 0.0, 0.0, 1.0))  # x, y, z, w
    pose_sets: tuple[RecordedPoseSet, ...] = _key(read=_records_of(RecordedPoseSet, "pose set"), default=())
    extra: dict[str, Any] = _extra()


@dataclass(frozen=True)
class RecordedObstacle(_Record):
    name: str = _key(default="")
    shape: str = _key(default="")
    dimensions: tuple[float, ...] = _key(read=_vector, default=())
    polygon: tuple[tuple[float, ...], ...] = _key(read=_vectors, default=())
    position: tuple[float, ...] = _key(read=_vector, default=(0.0, 0.0, 0.0))
    orientation: tuple[float, ...] = _key(read=_vector, default=(0.0, 0.0, 0.0, 1.0))  # x, y, z, w
    extra: dict[str, Any] = _extra()


@dataclass(frozen=True)
class RecordedWorldPart(_Record):
    """One world part as the simulation flew in it (magna_worlds.generate.world_record)."""

    source: str = _key(default="")  # the world file, or what made the part
    included: tuple[str, ...] = _key(read=_strs, default=())
    seed: int = _key(read=_int, default=0)
    world_boundaries: tuple[tuple[float, float], ...] | None = _key(read=_boundaries)
    origin_geo: tuple[float, ...] | None = _key(read=_vector)
    geometries: tuple[RecordedGeometry, ...] = _key(read=_records_of(RecordedGeometry, "geometry"), default=())
    obstacles: tuple[RecordedObstacle, ...] = _key(read=_records_of(RecordedObstacle, "obstacle"), default=())
    deleted: bool = _key(read=_bool, default=False)  # deleted during the run (missions delete their world)
    extra: dict[str, Any] = _extra()


def _parts(value: Any) -> dict[str, RecordedWorldPart]:
    if not isinstance(value, Mapping):
        raise _Bad(f"expected an object of world parts by id, got {type(value).__name__}")
    return {str(k): RecordedWorldPart.from_dict(v, f"part {k!r}") for k, v in value.items()}


@dataclass(frozen=True)
class WorldRecord(_Record):
    """A simulation's world.json: every world part the run had, deleted ones too, by part id."""

    seed: int | None = _key(read=_int)
    parts: dict[str, RecordedWorldPart] = _key(read=_parts, factory=dict)
    extra: dict[str, Any] = _extra()

    @classmethod
    def read(cls, path: Path) -> WorldRecord:
        path = Path(path)
        data = _read_json(path, "a simulation's world record")
        if isinstance(data, Mapping) and "parts" not in data:
            raise RecordError(f"{path}: not a world record: expected {{\"seed\", \"parts\": {{id: part}}}}")
        return cls.from_dict(data, str(path))

    def write(self, path: Path) -> Path:
        """Write it atomically (replacing an older one)."""
        return _write_json(Path(path), self.to_dict())
