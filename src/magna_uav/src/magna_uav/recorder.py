"""The recorder: one row per control step of one UAV, kept in memory and written at save_csv /
end of mission to one CSV per UAV (and, with the depth camera, one compressed npz of frames).

With `stream_to(path)` the rows also go to a CSV as the UAV flies, so a manager that is killed
leaves its rows up to the kill. Flush policy: a row is written (one write(2), nothing buffered in the
process) as soon as it is final: at the next control step, or when its role ends and the role's
outcome is in it. A SIGKILL loses at most the row of the step in progress; the kernel keeps the rest
(no fsync: a power cut may lose the last seconds). save_csv to the same path rewrites the file whole,
then streaming goes on appending to it. The depth frames are written at save_csv only.

The column set is defined once, by `columns(other_ids, n_obstacles)`, and documented in the
package README ("Recorder CSV columns"); mlr trains from these files, so change both together.
Values: floats in shortest round-trip form ("nan" when unknown), flags 0/1, ids and UAL states
as integers, text as is; `feasible` is empty when the algorithm did not say.

`read_csv` also reads files written before the goal's target velocity and distance, or the
teacher's answer, were recorded (`LEGACY_GENERATIONS`): those columns come back NaN (the
fallback flag: unknown).
"""
from __future__ import annotations

import csv
import io
import math
import os
import re
import threading
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from magna_common.files import write_atomically
from magna_uav.world_view import WorldView

DEFAULT_OBSTACLES = 5
NAN = math.nan

XYZ = ("x", "y", "z")
# goal_vel / goal_dist: what a follower role knows of its target (Goal.velocity, Goal.distance); the
# network inputs of agent_ad / agent_ap need them, so mlr must find them in the rows.
GOAL_TARGET = (*(f"goal_vel.{a}" for a in XYZ), "goal_dist")
# teacher_vel: ORCA-3D's answer from the same inputs while a network flies (DAgger relabels with it);
# fallback: the teacher's answer was sent because the network's would have collided (NAI docstring).
TEACHER = (*(f"teacher_vel.{a}" for a in XYZ), "fallback")
_HEAD = (["time", "uav_id", "role", "algorithm"] + [f"goal.{a}" for a in XYZ] + list(GOAL_TARGET)
         + [f"sel_vel.{a}" for a in XYZ] + list(TEACHER) + [f"pos.{a}" for a in XYZ]
         + [f"ori.{a}" for a in (*XYZ, "w")] + [f"vel.{a}" for a in XYZ] + ["yaw_rate"])
# The columns that files of older recorders lack, newest generation first; read_csv gives them NaN.
LEGACY_GENERATIONS = (TEACHER, GOAL_TARGET + TEACHER)
_TAIL = ["collision", "collided_with", "out_of_bounds", "low_battery", "battery", "ual_state", "feasible", "outcome"]

TEXT_COLUMNS = frozenset({"role", "algorithm", "collided_with", "outcome"})  # and every obs{k}.name
INT_COLUMNS = frozenset({"uav_id", "collision", "out_of_bounds", "low_battery", "ual_state"})
OPTIONAL_FLAG_COLUMNS = frozenset({"feasible", "fallback"})  # 0/1, or empty (None) when unknown


def columns(other_ids: Iterable[int], n_obstacles: int = DEFAULT_OBSTACLES) -> list[str]:
    """Every column of a recorder CSV, in order, for these other UAV ids (sorted) and obstacle slots."""
    others = _other_ids(other_ids)
    n_obstacles = _n_obstacles(n_obstacles)
    names = list(_HEAD)
    for j in others:
        names += [f"uav{j}.pos.{a}" for a in XYZ] + [f"uav{j}.vel.{a}" for a in XYZ]
    names += ["nearest_uav_gap", "nearest_obstacle_gap"]
    names += [f"uav{j}.gap" for j in others]
    for k in range(n_obstacles):
        names += [f"obs{k}.name"] + [f"obs{k}.pos.{a}" for a in XYZ] + [f"obs{k}.gap"]
    return names + _TAIL


def column_kind(name: str) -> str:
    """'text', 'int', 'flag?' (0/1 or unknown) or 'float': how a column's cells are read back."""
    if name in TEXT_COLUMNS or re.fullmatch(r"obs\d+\.name", name):
        return "text"
    if name in INT_COLUMNS:
        return "int"
    if name in OPTIONAL_FLAG_COLUMNS:
        return "flag?"
    return "float"


def depth_path(csv_path: str | os.PathLike) -> Path:
    """Where the depth frames of the CSV at `csv_path` go: `<stem>_depth.npz` next to it."""
    csv_path = Path(csv_path)
    return csv_path.with_name(f"{csv_path.stem}_depth.npz")


class RowStream:
    """A recorder CSV that grows as rows become final: each `append` is one write(2) of whole lines, so
    the file always ends on a complete row, whatever happens to the process afterwards."""

    def __init__(self, path: str | os.PathLike, header: Sequence[str], overwrite: bool = False):
        self.path = Path(path)
        flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | (os.O_TRUNC if overwrite else os.O_EXCL)
        try:
            self._fd: int | None = os.open(self.path, flags, 0o666)  # the umask decides the mode
        except FileExistsError:
            raise FileExistsError(f"{self.path}: already exists; not streaming rows into it") from None
        self.written = 0  # rows written so far, the header not counted
        self.error = ""  # why streaming stopped (a write failed), "" while it goes on
        self._lock = threading.Lock()
        self._write_lines([list(header)])

    def append(self, rows: Sequence[Sequence]) -> None:
        with self._lock:
            if self._fd is not None and rows:
                self._write_lines([[_cell(v) for v in row] for row in rows])
                self.written += len(rows)

    def restart(self, written: int) -> None:
        """The file was replaced whole (save_csv) holding `written` rows: go on appending to the new file."""
        with self._lock:
            if self._fd is None:
                return
            os.close(self._fd)
            self._fd = None
            try:
                self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
            except OSError as error:
                self.error = f"{self.path}: cannot reopen it to go on streaming: {error.strerror or error}"
                return
            self.written = written

    def close(self) -> None:
        with self._lock:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None

    def _write_lines(self, lines: list[list]) -> None:
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows(lines)
        data = memoryview(text.getvalue().encode("utf-8"))
        assert self._fd is not None
        try:
            while data:
                data = data[os.write(self._fd, data):]
        except OSError as error:  # a full disk: the rows stay in memory for save_csv; streaming stops here
            self.error = f"{self.path}: writing a row failed, streaming stopped: {error.strerror or error}"
            os.close(self._fd)
            self._fd = None


class HeardStamps(NamedTuple):
    """One UAV's messages a row came from, by stamp (ns; `AgentState.pose_stamp_ns`, `velocity_stamp_ns`)."""

    uav_id: int
    pose_ns: int
    velocity_ns: int


def heard_stamps(view: WorldView, other_ids: Sequence[int]) -> list[HeardStamps]:
    """The UAVs in `view` (own first, then `other_ids` in order) with the stamps of the messages the view holds."""
    ids = [view.own_id, *other_ids]
    return [HeardStamps(state.id, state.pose_stamp_ns, state.velocity_stamp_ns)
            for state in (view.agent(i) for i in ids) if state is not None]


class Recorder:
    """Rows of one UAV's control steps; see `columns` for what a row holds."""

    def __init__(self, uav_id: int, other_ids: Iterable[int], n_obstacles: int = DEFAULT_OBSTACLES,
                 depth: bool = False, on_row: Callable[[int, dict, list[HeardStamps]], None] | None = None):
        self.uav_id = int(uav_id)
        self.other_ids = _other_ids(other_ids)
        if self.uav_id in self.other_ids:
            raise ValueError(f"recorder of UAV {self.uav_id}: its own id is among the other UAVs {self.other_ids}")
        self.n_obstacles = _n_obstacles(n_obstacles)
        self.depth = bool(depth)
        self.columns = columns(self.other_ids, self.n_obstacles)
        self._rows: list[list] = []
        self._frames: list[np.ndarray] = []
        self._frame_rows: list[int] = []
        # the view's depth array last stored: a frame is kept once, on the row it arrived
        self._last_depth: np.ndarray | None = None
        # Called with each new row's index, {column: value} and the stamps of the messages the row came
        # from (`heard_stamps`): the node publishes it as a NavigationStep, so a bag carries the same
        # numbers as the CSV and names the poses to rebuild the rest from.
        self.on_row = on_row
        self.stream: RowStream | None = None  # the CSV the rows go to as they are final (stream_to)

    def stream_to(self, path: str | os.PathLike, overwrite: bool = False) -> RowStream:
        """Write rows to the CSV at `path` as they become final (see the module's flush policy), starting
        with the header and the final rows already recorded. An existing file is refused (FileExistsError)
        unless `overwrite`."""
        if self.stream is not None:
            self.stream.close()
        self.stream = RowStream(path, self.columns, overwrite=overwrite)
        self._stream_rows(final=False)
        return self.stream

    def _stream_rows(self, final: bool) -> None:
        """Stream the rows not written yet; the last one only when `final` (its role has ended)."""
        stream = self.stream
        if stream is None:
            return
        end = len(self._rows) if final else len(self._rows) - 1
        if end > stream.written:
            stream.append(self._rows[stream.written:end])

    @property
    def rows(self) -> int:
        return len(self._rows)

    @property
    def depth_frames(self) -> int:
        return len(self._frames)

    def row(self, index: int) -> dict:
        """One recorded row as {column: value} (values as they will be written, before formatting)."""
        return dict(zip(self.columns, self._rows[index], strict=True))

    def record(self, time: float, role: str, algorithm: str, goal_position: Sequence[float] | None,
               chosen_velocity: Sequence[float] | None, view: WorldView, evaluation=None,
               feasible: bool | None = None, outcome: str = "", goal_velocity: Sequence[float] | None = None,
               goal_distance: float | None = None, teacher_velocity: Sequence[float] | None = None,
               fallback: bool | None = None) -> int:
        """Append the row of this control step; returns its index.

        goal_velocity / goal_distance: the goal's target velocity and kept distance (follower
        roles); None gives NaN. teacher_velocity / fallback: the teacher's answer while a network
        flies, and whether it was sent; None gives NaN / unknown.

        Positions, velocities and which obstacles are nearest come from `view`; gaps, collisions,
        out_of_bounds and low_battery come from `evaluation` (duck-typed: nearest_agent_gap,
        nearest_obstacle_gap, agent_gaps {id: gap}, obstacle_gaps {name: gap}, collided_with,
        out_of_bounds, low_battery) where it has them, else from the view's safety-sphere gaps.
        A UAV not heard of yet, or the own UAV before its first pose, gives NaN. With depth on, the
        own depth image is kept with this row when it is a new image (not the one already kept).
        """
        own = view.own if view.has_own else None
        agent_gaps = _view_agent_gaps(view) if own is not None else {}
        agent_gaps.update(_mapping(getattr(evaluation, "agent_gaps", None)))
        obstacles = _ranked_obstacles(view, _mapping(getattr(evaluation, "obstacle_gaps", None)), own is not None)

        row: list = [float(time), self.uav_id, str(role), str(algorithm)]
        row += _vector(goal_position, 3) + _vector(goal_velocity, 3)
        row.append(NAN if goal_distance is None else float(goal_distance))
        row += _vector(chosen_velocity, 3) + _vector(teacher_velocity, 3)
        row.append(None if fallback is None else int(bool(fallback)))
        if own is not None:
            row += _vector(own.position, 3) + _vector(own.orientation, 4) + _vector(own.velocity, 3)
            row.append(float(own.yaw_rate))
        else:
            row += [NAN] * 11
        for j in self.other_ids:
            other = view.agent(j)
            row += [NAN] * 6 if other is None else _vector(other.position, 3) + _vector(other.velocity, 3)

        nearest_uav = _gap(getattr(evaluation, "nearest_agent_gap", None),
                           min((g for j, g in agent_gaps.items() if j != self.uav_id), default=NAN))
        nearest_obstacle = _gap(getattr(evaluation, "nearest_obstacle_gap", None),
                                min((g for _, g in obstacles), default=NAN))
        row += [nearest_uav, nearest_obstacle]
        row += [_gap(agent_gaps.get(j), NAN) for j in self.other_ids]
        for k in range(self.n_obstacles):
            if k < len(obstacles):
                obstacle, gap = obstacles[k]
                row += [obstacle.name] + _vector(obstacle.position, 3) + [gap]
            else:
                row += ["", NAN, NAN, NAN, NAN]

        collided_with = [str(c) for c in (getattr(evaluation, "collided_with", None) or ())]
        out_of_bounds = getattr(evaluation, "out_of_bounds", None)
        if out_of_bounds is None:
            out_of_bounds = own is not None and not view.inside_boundaries()
        row += [int(bool(collided_with)), ";".join(collided_with), int(bool(out_of_bounds)),
                int(bool(getattr(evaluation, "low_battery", False))),
                NAN if own is None else float(own.battery), 0 if own is None else int(own.ual_state),
                None if feasible is None else int(bool(feasible)), str(outcome)]
        assert len(row) == len(self.columns)

        depth = own.depth if self.depth and own is not None else None
        frame = None
        if depth is not None and depth is not self._last_depth:
            frame = np.array(depth, dtype=np.float32, copy=True)
            if frame.ndim != 2:
                raise ValueError(f"recorder of UAV {self.uav_id}: depth frame must be 2-D, got shape {frame.shape}")
            if self._frames and frame.shape != self._frames[0].shape:
                raise ValueError(f"recorder of UAV {self.uav_id}: depth frame shape {frame.shape} differs from "
                                 f"the first one {self._frames[0].shape}")
        self._rows.append(row)
        index = len(self._rows) - 1
        if frame is not None:
            self._last_depth = depth
            self._frames.append(frame)
            self._frame_rows.append(index)
        self._stream_rows(final=False)  # the previous row is final now
        if self.on_row is not None:
            self.on_row(index, self.row(index), heard_stamps(view, self.other_ids))
        return index

    def set_outcome(self, outcome: str) -> None:
        """Write the role's outcome into the last row (the role ends after its last step)."""
        if not self._rows:
            raise LookupError(f"recorder of UAV {self.uav_id}: no row to give the outcome {outcome!r}")
        self._rows[-1][-1] = str(outcome)
        self._stream_rows(final=True)

    def save_csv(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write every row to `path` (and the depth frames to `depth_path(path)` when depth is on).

        All or nothing per file; an existing file is refused (FileExistsError, nothing written)
        unless `overwrite`. The rows stay in memory; `clear()` drops them.
        """
        path = Path(path)
        targets = [path] + ([depth_path(path)] if self.depth else [])
        if not overwrite:
            for target in targets:
                if target.exists():
                    raise FileExistsError(f"{target}: already exists (pass overwrite=True to replace it)")
        created_depth = None
        if self.depth:
            created_depth = None if depth_path(path).exists() else depth_path(path)
            write_atomically(depth_path(path), self._write_depth, overwrite=overwrite, binary=True)
        try:
            write_atomically(path, self._write_csv, overwrite=overwrite)
        except BaseException:
            if created_depth is not None:  # do not leave frames without their rows
                created_depth.unlink(missing_ok=True)
            raise
        if self.stream is not None and os.path.abspath(path) == os.path.abspath(self.stream.path):
            self.stream.restart(len(self._rows))  # the file holds every row now; go on after them
        return path

    def clear(self) -> None:
        """Drop every row and frame; a stream stops (its file keeps the rows it has)."""
        if self.stream is not None:
            self.stream.close()
            self.stream = None
        self._rows.clear()
        self._frames.clear()
        self._frame_rows.clear()
        self._last_depth = None

    def _write_csv(self, out) -> None:
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(self.columns)
        for row in self._rows:
            writer.writerow([_cell(v) for v in row])

    def _write_depth(self, out) -> None:
        if self._frames:
            frames = np.stack(self._frames).astype(np.float32, copy=False)
        else:
            frames = np.zeros((0, 0, 0), dtype=np.float32)
        np.savez_compressed(out, frames=frames, rows=np.asarray(self._frame_rows, dtype=np.int64))


def read_csv(path: str | os.PathLike) -> tuple[list[str], list[dict]]:
    """(columns, rows) of a recorder CSV, each row {column: value} with the types of `column_kind`.

    A file of an older recorder, whose header lacks only the columns of one `LEGACY_GENERATIONS`
    entry (teacher_vel.* and fallback; and before them goal_vel.* and goal_dist), is read too: the
    returned columns are the current set and those cells are NaN (fallback: None) in every row, so
    callers see one layout. ValueError naming the file when the header is not a
    recorder column set.
    """
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as source:
        reader = csv.reader(source)
        try:
            header = next(reader)
        except StopIteration:
            raise ValueError(f"{path}: empty, no header") from None
        others = [int(m.group(1)) for name in header if (m := re.fullmatch(r"uav(\d+)\.pos\.x", name))]
        n_obstacles = sum(1 for name in header if re.fullmatch(r"obs\d+\.name", name))
        expected = columns(others, n_obstacles)
        layouts = [expected] + [[name for name in expected if name not in missing] for missing in LEGACY_GENERATIONS]
        if header not in layouts:
            missing = [c for c in expected if c not in header]
            extra = [c for c in header if c not in expected]
            raise ValueError(f"{path}: not a recorder CSV header (missing {missing}, unexpected {extra}"
                             f"{', or out of order' if not missing and not extra else ''})")
        kinds = [column_kind(name) for name in header]
        rows = []
        for line, cells in enumerate(reader, start=2):
            if len(cells) != len(header):
                raise ValueError(f"{path}:{line}: {len(cells)} cells for {len(header)} columns")
            try:
                rows.append({name: _parse(cell, kind) for name, cell, kind in zip(header, cells, kinds, strict=True)})
            except ValueError as error:
                raise ValueError(f"{path}:{line}: {error}") from None
    if header != expected:  # a legacy file: the missing columns are unknown, in their place
        unknown = {name: None if column_kind(name) == "flag?" else NAN for name in expected}
        rows = [{name: row.get(name, unknown[name]) for name in expected} for row in rows]
    return expected, rows


def read_depth(csv_path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(frames [n, H, W] float32 in metres, row index [n]) saved next to the CSV at `csv_path`."""
    with np.load(depth_path(csv_path)) as data:
        return data["frames"], data["rows"]


def _other_ids(other_ids: Iterable[int]) -> list[int]:
    ids = [int(j) for j in other_ids]
    if len(set(ids)) != len(ids):
        raise ValueError(f"other UAV ids repeat: {ids}")
    if any(j < 0 for j in ids):
        raise ValueError(f"UAV ids must be >= 0: {ids}")
    return sorted(ids)


def _n_obstacles(n: int) -> int:
    if isinstance(n, bool) or int(n) != n or n < 0:
        raise ValueError(f"n_obstacles must be an integer >= 0, got {n!r}")
    return int(n)


def _vector(values, size: int) -> list[float]:
    if values is None:
        return [NAN] * size
    array = np.asarray(values, dtype=float).reshape(-1)
    if array.size != size:
        raise ValueError(f"expected {size} values, got {array.size}")
    return [float(v) for v in array]


def _gap(value, default: float) -> float:
    """A gap to write: `default` when not given; an infinite gap ("nothing there") is unknown, NaN."""
    if value is None:
        return default
    value = float(value)
    return value if math.isfinite(value) else NAN


def _mapping(value) -> dict:
    return dict(value) if value else {}


def _view_agent_gaps(view: WorldView) -> dict[int, float]:
    return {state.id: gap for state, gap in view.nearest_agents()}


def _ranked_obstacles(view: WorldView, gaps: dict, has_own: bool) -> list:
    """(Obstacle, gap) for every obstacle of the view, nearest first (ties by the view's order).

    The evaluation's gap for a name is used when that name is unique in the view (a gap by name
    cannot tell two obstacles of one name apart); otherwise the view's gap (to the obstacle's real shape).
    """
    sphere = {id(o): g for o, g in view.nearest_obstacles()} if has_own else {}
    names = Counter(o.name for o in view.obstacles)
    ranked = []
    for n, obstacle in enumerate(view.obstacles):
        given = gaps.get(obstacle.name) if names[obstacle.name] == 1 else None
        gap = _gap(given, sphere.get(id(obstacle), NAN))
        ranked.append((math.inf if math.isnan(gap) else gap, n, obstacle, gap))
    ranked.sort(key=lambda item: item[:2])
    return [(obstacle, gap) for _, _, obstacle, gap in ranked]


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _parse(cell: str, kind: str):
    if kind == "text":
        return cell
    if kind == "int":
        return int(cell)
    if kind == "flag?":
        return None if cell == "" else int(cell)
    return float(cell)


__all__ = ["DEFAULT_OBSTACLES", "GOAL_TARGET", "LEGACY_GENERATIONS", "TEACHER", "HeardStamps", "Recorder", "RowStream",
           "column_kind", "columns", "depth_path", "heard_stamps", "read_csv", "read_depth"]
