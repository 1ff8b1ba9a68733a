"""Pickler: recorded simulations -> input vectors and labels for one teacher.

It walks the storage tree (`DATA_ROOT/Simulations/WORLD/SUBWORLD/MISSION/SUBMISSION/NAME/
dataset_N/simulation_M/`), keeps the simulations whose `world.json` and `result.json` exist
and whose result says success, and reads every UAV's recorder CSV (or, with
`source="bag"`, rebuilds the same steps from `simulation.bag`, see `mlr.bags`).

A sample is one control step of a UAV flying the teacher role with the teacher algorithm:
- inputs: the vector `magna_uav.nai.inputs.assemble_inputs` builds (THE order the NAI flies
  with), from the step's own velocity, goal, neighbours and obstacles;
- label: the velocity the teacher chose `fvi` steps later (FVI, future velocity instant;
  0 = this step's choice), taken only within the same run of the role (a label never comes
  from the next role or the next goal sequence). With `label="teacher"` (DAgger) the steps are
  those a network flew (`algorithm` neural_network) and the label is the answer ORCA-3D gave
  from the same inputs at that step (the recorder's teacher_vel), not what the network chose.

Neighbours are chosen as the NAI chooses them (`select_neighbors`): the `n_neighbors` UAVs
and `n_obstacles` obstacles whose gap is below `neighbor_dist`, nearest first (UAV ties by
id), padded as `inputs.pad_position` says.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, get_args

import numpy as np

from magna_common.airframes import AirframeError, load_airframe
from magna_common.records import NOT_FLOWN, RecordError, SimulationResult
from magna_common.storage_tree import MISSION_FILE, RESULT_FILE, WORLD_FILE, StorageKey
from magna_uav.nai.inputs import ROLE_BLOCKS, assemble_inputs, input_names
from magna_uav.nai.neural import prepare_depth
from magna_uav.recorder import depth_path, read_csv, read_depth
from mlr.steps import PicklerError, UavSteps

XYZ = ("x", "y", "z")
Source = Literal["csv", "bag"]  # the recorder CSVs, or simulation.bag (mlr.bags)
SOURCES: tuple[str, ...] = get_args(Source)
Label = Literal["chosen", "teacher"]  # what the algorithm flown chose (sel_vel), or the teacher's answer (teacher_vel)
LABELS: tuple[str, ...] = get_args(Label)


@dataclass(frozen=True)
class Selection:
    """Which simulations to learn from: a dataset series of one world and one mission."""

    data_root: Path
    world: str
    subworld: str
    mission: str
    submission: str
    name: str = "default"
    datasets: tuple[int, ...] = (1,)

    @property
    def key(self) -> StorageKey:
        return StorageKey(self.world, self.subworld, self.mission, self.submission, self.name)

    @property
    def series_dir(self) -> Path:
        return self.key.base_dir(self.data_root)

    def dataset_dirs(self) -> list[Path]:
        return [self.key.dataset_dir(self.data_root, n) for n in self.datasets]


@dataclass(frozen=True)
class Teacher:
    """Whose steps become samples, and how they are turned into vectors."""

    role: str = "path"
    algorithm: str = "orca3d"
    n_neighbors: int = 1
    n_obstacles: int = 0
    neighbor_dist: float = 6.0
    fvi: int = 0
    image: tuple[int, int] | None = None  # (height, width) of the depth image for CNN models, or None
    label: Label = "chosen"

    def __post_init__(self):
        if self.role not in ROLE_BLOCKS:
            raise PicklerError(f"teacher role {self.role!r} has no network inputs: give one of "
                               f"{', '.join(ROLE_BLOCKS)}")
        if isinstance(self.fvi, bool) or not isinstance(self.fvi, int) or self.fvi < 0:
            raise PicklerError(f"fvi is {self.fvi!r}: give a whole number of control steps >= 0")
        input_names(self.role, self.n_neighbors, self.n_obstacles)  # checks the counts
        if self.label not in LABELS:
            raise PicklerError(f"label is {self.label!r}: give chosen (what the flown algorithm chose) or teacher "
                               "(ORCA-3D's answer recorded while a network flew)")


@dataclass
class Samples:
    """Inputs `x` [k, d], labels `y` [k, 3], each sample's max speed and where it came from."""

    x: np.ndarray
    y: np.ndarray
    max_speed: np.ndarray  # (k,) m/s
    origin: np.ndarray  # (k,) int: index into `sources`
    step: np.ndarray  # (k,) int: the step (CSV data row, 0-based) the inputs come from
    sources: list[str] = field(default_factory=list)
    images: np.ndarray | None = None  # (k, H, W) float32 depth, for image models

    def __len__(self) -> int:
        return len(self.x)

    @staticmethod
    def concatenate(parts: Sequence[Samples], d: int, image: tuple[int, int] | None) -> Samples:
        sources: list[str] = []
        origins = []
        for part in parts:
            origins.append(part.origin + len(sources))
            sources.extend(part.sources)
        images = None
        if image is not None:
            images = np.concatenate([p.images for p in parts]) if parts else np.zeros((0, *image), np.float32)
        return Samples(
            np.concatenate([p.x for p in parts]) if parts else np.zeros((0, d)),
            np.concatenate([p.y for p in parts]) if parts else np.zeros((0, 3)),
            np.concatenate([p.max_speed for p in parts]) if parts else np.zeros(0),
            np.concatenate(origins) if parts else np.zeros(0, dtype=np.int64),
            np.concatenate([p.step for p in parts]) if parts else np.zeros(0, dtype=np.int64),
            sources, images)


# --- choosing simulations -----------------------------------------------------------------------


@dataclass(frozen=True)
class Simulation:
    directory: Path
    uav_models: dict[int, str]  # UAV id -> airframe model, from the simulation's mission.json


def find_simulations(selection: Selection, failures: bool = False) -> tuple[list[Simulation], list[str]]:
    """(usable simulations, why each other one was left out), in dataset and simulation order.

    A teacher's demonstrations come from its successful simulations only. With `failures` a
    simulation that ran to any mission outcome is kept too (DAgger: a network's collisions are
    exactly the states the teacher must relabel); interrupted or crashed ones never are."""
    kept, skipped = [], []
    for dataset in selection.dataset_dirs():
        if not dataset.is_dir():
            raise PicklerError(f"{dataset}: no such dataset; run it first (magna run --world "
                               f"{selection.world}/{selection.subworld} --mission {selection.mission}/"
                               f"{selection.submission} --name {selection.name} --dataset "
                               f"{dataset.name.split('_')[-1]} ...) or fix 'datasets' in the config")
        sims = sorted((p for p in dataset.glob("simulation_*") if p.name.split("_")[-1].isdigit()),
                      key=lambda p: int(p.name.split("_")[-1]))
        for sim in sims:
            reason = _unusable(sim, failures)
            if reason:
                skipped.append(f"{sim}: {reason}")
            else:
                kept.append(Simulation(sim, _uav_models(sim / MISSION_FILE)))
    return kept, skipped


def _unusable(sim: Path, failures: bool = False) -> str:
    if not (sim / WORLD_FILE).is_file():
        return f"no {WORLD_FILE} (the resolved world)"
    result_path = sim / RESULT_FILE
    if not result_path.is_file():
        return f"no {RESULT_FILE}"
    try:
        result = SimulationResult.read(result_path)
    except RecordError as err:
        return f"{RESULT_FILE} unreadable ({err})"
    if not result.success and not (failures and result.termination not in NOT_FLOWN):
        return f"not a success ({result.outcome or '?'}: {result.message})"
    if not (sim / MISSION_FILE).is_file():
        return f"no {MISSION_FILE} (the UAV models come from it)"
    return ""


def _uav_models(mission_json: Path) -> dict[int, str]:
    try:
        raw = json.loads(mission_json.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise PicklerError(f"{mission_json}: not a readable mission JSON: {err}") from None
    agents = raw.get("Agents_Config", raw.get("UAVs_Config")) if isinstance(raw, dict) else None
    if not isinstance(agents, list):
        raise PicklerError(f"{mission_json}: Agents_Config is missing: the UAV models (hence max speeds) come from it")
    models = {}
    for k, agent in enumerate(agents):
        try:
            models[int(agent["ID"])] = str(agent.get("model", "iris"))
        except (KeyError, TypeError, ValueError):
            raise PicklerError(f"{mission_json}: Agents_Config[{k}].ID is missing or not a number") from None
    return models


def max_speed_of(model: str, where: Path) -> float:
    try:
        return float(load_airframe(model).max_speed)
    except (AirframeError, FileNotFoundError, ValueError) as err:
        raise PicklerError(f"{where}: UAV model {model!r}: {err}") from None


# --- reading a recorder CSV ---------------------------------------------------------------------


def _block(rows: list[dict], prefix: str, optional: bool = False) -> np.ndarray:
    if optional and rows and f"{prefix}.x" not in rows[0]:
        return np.full((len(rows), 3), np.nan)
    return np.array([[row[f"{prefix}.{a}"] for a in XYZ] for row in rows], dtype=float).reshape(len(rows), 3)


def steps_from_csv(csv_path: str | Path, max_speed: float) -> UavSteps:
    """The steps of the recorder CSV at `csv_path` (columns: magna_uav README, "Recorder CSV columns")."""
    csv_path = Path(csv_path)
    try:
        header, rows = read_csv(csv_path)
    except OSError as err:
        raise PicklerError(f"{csv_path}: cannot read: {err}") from None
    except ValueError as err:
        raise PicklerError(str(err)) from None
    others = sorted(int(name[3:-6]) for name in header if name.startswith("uav") and name.endswith(".pos.x"))
    n_obs = sum(1 for name in header if name.startswith("obs") and name.endswith(".name"))
    n = len(rows)
    uav_ids = {row["uav_id"] for row in rows}
    if len(uav_ids) > 1:
        raise PicklerError(f"{csv_path}: rows of several UAVs {sorted(uav_ids)}: a recorder CSV holds one UAV")
    steps = UavSteps(
        source=csv_path,
        uav_id=uav_ids.pop() if uav_ids else -1,
        max_speed=float(max_speed),
        time=np.array([row["time"] for row in rows], dtype=float),
        role=np.array([row["role"] for row in rows], dtype=object),
        algorithm=np.array([row["algorithm"] for row in rows], dtype=object),
        position=_block(rows, "pos"),
        velocity=_block(rows, "vel"),
        goal=_block(rows, "goal"),
        goal_vel=_block(rows, "goal_vel", optional=True),
        goal_dist=np.array([row.get("goal_dist", math.nan) for row in rows], dtype=float),
        sel_vel=_block(rows, "sel_vel"),
        teacher_vel=_block(rows, "teacher_vel"),
        role_end=np.array([bool(row["outcome"]) for row in rows], dtype=bool),
        others={j: (_block(rows, f"uav{j}.pos"), _block(rows, f"uav{j}.vel"),
                    np.array([row[f"uav{j}.gap"] for row in rows], dtype=float)) for j in others},
        obstacle_pos=np.stack([_block(rows, f"obs{k}.pos") for k in range(n_obs)], axis=1) if n_obs
        else np.zeros((n, 0, 3)),
        obstacle_gap=np.array([[row[f"obs{k}.gap"] for k in range(n_obs)] for row in rows], dtype=float)
        .reshape(n, n_obs),
    )
    if depth_path(csv_path).is_file():
        steps.depth_frames, steps.depth_rows = read_depth(csv_path)
    return steps


# --- steps -> samples ---------------------------------------------------------------------------


def runs(steps: UavSteps, role: str, algorithm: str) -> list[tuple[int, int]]:
    """[start, stop) index ranges of consecutive steps flying `role` with `algorithm`.

    A run ends where the role wrote its outcome, or where another role or algorithm starts.
    """
    match = (steps.role == role) & (steps.algorithm == algorithm)
    out, start = [], None
    for i in range(len(steps)):
        if match[i] and start is None:
            start = i
        if start is not None and (not match[i] or steps.role_end[i]):
            out.append((start, i + 1 if match[i] else i))
            start = None
    if start is not None:
        out.append((start, len(steps)))
    return out


def _neighbors_at(steps: UavSteps, i: int, teacher: Teacher) -> tuple[list, list, list]:
    own = steps.position[i]
    gaps = [(gap[i], j) for j, (_, _, gap) in steps.others.items()
            if math.isfinite(gap[i]) and gap[i] < teacher.neighbor_dist]
    chosen = [j for _, j in sorted(gaps)[:teacher.n_neighbors]]
    pos_rel = [steps.others[j][0][i] - own for j in chosen]
    vel = [steps.others[j][1][i] for j in chosen]
    obstacles = []
    if teacher.n_obstacles and steps.obstacle_gap is not None:
        assert steps.obstacle_pos is not None  # the CSV and bag readers give positions and gaps together
        for k in range(steps.obstacle_gap.shape[1]):
            gap = steps.obstacle_gap[i, k]
            if math.isfinite(gap) and gap < teacher.neighbor_dist:
                obstacles.append(steps.obstacle_pos[i, k] - own)
            if len(obstacles) == teacher.n_obstacles:
                break
    return pos_rel, vel, obstacles


def samples(steps: UavSteps, teacher: Teacher) -> Samples:
    """The samples of one UAV's steps for `teacher` (module docstring)."""
    if teacher.n_obstacles and steps.obstacle_gap is not None and steps.obstacle_gap.shape[1] < teacher.n_obstacles:
        raise PicklerError(f"{steps.source}: {steps.obstacle_gap.shape[1]} obstacles were recorded per step but "
                           f"n_obstacles is {teacher.n_obstacles}: give at most {steps.obstacle_gap.shape[1]}")
    xs, ys, rows, images = [], [], [], []
    d = len(input_names(teacher.role, teacher.n_neighbors, teacher.n_obstacles))
    labels = steps.teacher_vel if teacher.label == "teacher" else steps.sel_vel
    for start, stop in runs(steps, teacher.role, teacher.algorithm):
        for i in range(start, stop - teacher.fvi):
            label = labels[i + teacher.fvi]
            if not (np.all(np.isfinite(label)) and np.all(np.isfinite(steps.position[i]))
                    and np.all(np.isfinite(steps.velocity[i])) and np.all(np.isfinite(steps.goal[i]))):
                continue
            pos_rel, vel, obstacles = _neighbors_at(steps, i, teacher)
            goal_vel = steps.goal_vel[i] if np.all(np.isfinite(steps.goal_vel[i])) else None
            distance = steps.goal_dist[i] if math.isfinite(steps.goal_dist[i]) else None
            if "distance" in ROLE_BLOCKS[teacher.role] and distance is None:
                raise PicklerError(f"{steps.source}: step {i} of role {teacher.role} has no goal_dist: record the "
                                   "run again with a recorder that writes goal_dist")
            x = assemble_inputs(teacher.role, steps.velocity[i], steps.goal[i] - steps.position[i], pos_rel, vel,
                                obstacles, teacher.n_neighbors, teacher.n_obstacles, teacher.neighbor_dist,
                                goal_vel=goal_vel, distance=distance)
            if teacher.image is not None:
                frame = steps.depth_at(i)
                if frame is None:
                    continue  # no image yet: an image model cannot learn from this step
                images.append(prepare_depth(frame, *teacher.image))
            xs.append(x)
            ys.append(label)
            rows.append(i)
    k = len(xs)
    return Samples(np.asarray(xs, dtype=float).reshape(k, d), np.asarray(ys, dtype=float).reshape(k, 3),
                   np.full(k, steps.max_speed), np.zeros(k, dtype=np.int64), np.asarray(rows, dtype=np.int64),
                   [str(steps.source)],
                   None if teacher.image is None else np.asarray(images, np.float32).reshape(k, *teacher.image))


def simulation_steps(sim: Simulation, source: Source = "csv") -> list[UavSteps]:
    """Every UAV's steps of one simulation, read from its CSVs or its bag."""
    if source not in SOURCES:
        raise PicklerError(f"source is {source!r}: give csv (the recorder CSVs) or bag (simulation.bag)")
    speeds = {uav: max_speed_of(model, sim.directory / MISSION_FILE) for uav, model in sim.uav_models.items()}
    if source == "bag":
        from mlr.bags import steps_from_bag  # rosbags, only when asked for

        return steps_from_bag(sim.directory, speeds)
    out = []
    for csv_path in sorted(sim.directory.glob("uav_*.csv")):
        uav = csv_path.stem.split("_")[-1]
        if not uav.isdigit() or int(uav) not in speeds:
            raise PicklerError(f"{csv_path}: UAV {uav} is not in the simulation's mission.json Agents_Config")
        out.append(steps_from_csv(csv_path, speeds[int(uav)]))
    return out


def pickle_simulations(sims: Iterable[Simulation], teacher: Teacher, source: Source = "csv",
                       progress: Callable[[Iterable], Iterable] = lambda it: it) -> Samples:
    """Samples of every UAV of every simulation, in order."""
    parts = [samples(steps, teacher) for sim in progress(list(sims)) for steps in simulation_steps(sim, source)]
    d = len(input_names(teacher.role, teacher.n_neighbors, teacher.n_obstacles))
    return Samples.concatenate(parts, d, teacher.image)
