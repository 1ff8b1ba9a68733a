"""The batch loop: N simulations of one mission in one world, each on a ROS master of its own.

Per simulation m (ids from storage.plan_storage, 1..N unless appending):

1. a fresh `RosMaster` on a free port: nothing of the previous simulation (/ual_ids, /clock,
   /use_sim_time, ...) can leak into this one;
2. the parameter `/magna/hyperparameters` (world, subworld, mission, submission, n_dataset,
   n_simulation=m, N_iter, sm_view, save_data, save_bag, rviz, seed=S+m);
3. a supervisor process (`python -m magna_master.supervisor`, see there) that serves
   `/magna/master/simulation_termination`, starts the launch command and writes result.json;
4. when the supervisor is done (or hangs past every budget: then its process group is ended),
   every process still carrying the simulation's token is killed, the master is stopped, and
   the summary row is written.

Seeds: simulation m runs with seed S+m (S from --seed, default 0), so appended simulations
get new seeds and a dataset can be re-run exactly.

Ctrl-C (SIGINT) or SIGTERM during a batch: the running simulation is stopped (its supervisor
ends the launch), *marked* as interrupted (result.json termination/outcome "interrupted",
success false, and its summary row), every process it started is ended, and no further
simulation starts. Finished simulations and summary.csv are untouched. `BatchResult.interrupted`
says so; `magna run` then exits with status 130.
"""
from __future__ import annotations

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
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.processes import TOKEN_ENV, end_process_group, kill_tagged
from magna_common.ros_master import RosMaster, RosMasterError
from magna_master import storage
from magna_master.supervisor import (
    CRASHED,
    GROUND_STATION,
    INTERRUPTED,
    START_FAILED,
    SUPERVISOR_FAILED,
)

HYPERPARAMETERS_PARAM = "/magna/hyperparameters"

# The launch of one simulation (magna_gs). {name} placeholders are filled per simulation.
DEFAULT_LAUNCH_COMMAND: tuple[str, ...] = (
    "roslaunch", "--sigint-timeout=5", "--sigterm-timeout=2", "magna_gs", "simulation.launch",
    "mission_file:={mission_file}", "world:={world}", "subworld:={subworld}", "worlds_path:={worlds_path}",
    "data_dir:={data_dir}", "rtf:={rtf}", "seed:={seed}", "bag:={bag}", "save_data:={save_data}",
    "output:={output}", "button_timeout:={button_timeout}",
)
PLACEHOLDERS = ("mission_file", "world", "subworld", "worlds_path", "data_dir", "rtf", "seed", "bag", "save_data",
                "output", "mission", "submission", "n_simulation", "button_timeout", "rviz", "utm_plan",
                "battery_floor", "fleet")


class BatchError(RuntimeError):
    """A batch that cannot start (bad input, missing launch file, ...): say what and the fix; exit status 2."""


# --- finding worlds and missions ------------------------------------------------------------------------------

def project_root() -> Path | None:
    from magna_common.workspace import WorkspaceNotFound, find_root

    try:
        return find_root()
    except WorkspaceNotFound:
        return None


def _roots(search_dirs: Iterable[Path], names: tuple[str, str], project_dir: str) -> list[Path]:
    """For each search dir D: D/<lower>, D/<Capitalised> (when present) and D itself; then the project's folder."""
    roots: list[Path] = []
    for directory in search_dirs:
        directory = Path(directory).expanduser()
        for name in names:
            if (directory / name).is_dir():
                roots.append(directory / name)
        roots.append(directory)
    root = project_root()
    if root is not None:
        roots.append(root / project_dir)
    unique: list[Path] = []
    for r in roots:
        if r not in unique:
            unique.append(r)
    return unique


def world_roots(search_dirs: Iterable[Path] = ()) -> list[Path]:
    """Where worlds are looked for: the search dirs (their worlds/ or Worlds/ first), $MAGNA_WORLDS_PATH, worlds/."""
    from magna_worlds.loader import default_search_path

    roots = _roots(search_dirs, ("worlds", "Worlds"), "worlds")
    for extra in default_search_path():
        if extra not in roots:
            roots.append(extra)
    return roots


def mission_roots(search_dirs: Iterable[Path] = ()) -> list[Path]:
    """Where missions are looked for: the search dirs (their missions/ or Missions/ first), $MAGNA_MISSIONS_PATH,
    then missions/."""
    roots = _roots(search_dirs, ("missions", "Missions"), "missions")
    extra = [Path(p) for p in os.environ.get("MAGNA_MISSIONS_PATH", "").split(os.pathsep) if p]
    return [*roots[:-1], *[e for e in extra if e not in roots], *roots[-1:]] if roots else extra


def split_spec(value: str, what: str, example: str) -> tuple[str, str]:
    """'Gym/1Obs_Central_Cylinder' -> ('Gym', '1Obs_Central_Cylinder'); a trailing .json is dropped."""
    parts = value.strip().removesuffix(".json").split("/")
    if len(parts) != 2 or not all(p.strip() for p in parts) or any(p in (".", "..") for p in parts):
        raise BatchError(f"--{what} {value!r}: expected {what.upper()}/SUB{what.upper()}, e.g. {example}")
    return parts[0], parts[1]


def find_mission_file(mission: str, submission: str, roots: Iterable[Path]) -> Path | None:
    for root in roots:
        candidate = Path(root) / mission / f"{submission}.json"
        if candidate.is_file():
            return candidate
    return None


@dataclass(frozen=True)
class Inputs:
    world: str
    subworld: str
    mission: str
    submission: str
    world_file: Path
    mission_file: Path

    @property
    def worlds_path(self) -> Path:
        """The folder that holds <world>/<subworld>.json (simulation.launch's worlds_path)."""
        return self.world_file.parent.parent


def _as_file(spec: str) -> Path | None:
    """A --world/--mission value that is a path to an existing .json file (its folder names the world/mission)."""
    path = Path(spec).expanduser()
    return path if spec.endswith(".json") and path.is_file() else None


def resolve_inputs(world_spec: str, mission_spec: str, search_dirs: Sequence[Path] = (), check: bool = True,
                   strict: bool = False) -> Inputs:
    """Find and (with `check`) load the world and the mission (`strict`: refuse what only warns); BatchError names
    what was searched.

    Each spec is NAME/SUBNAME (looked up) or the path of a .json file (<world>/<subworld>.json).
    """
    for directory in search_dirs:
        if not Path(directory).expanduser().is_dir():
            raise BatchError(f"--search-path {directory}: no such folder; give a folder holding worlds/ and "
                             "missions/ (or Worlds/ and Missions/)")
    from magna_worlds.loader import candidate_paths, find_world_file

    wroots = world_roots(search_dirs)
    world_file = _as_file(world_spec)
    if world_file is not None:
        world, subworld = world_file.resolve().parent.name, world_file.stem
    else:
        world, subworld = split_spec(world_spec, "world", "Gym/1Obs_Central_Cylinder")
        world_file = find_world_file(world, subworld, wroots)
        if world_file is None:
            raise BatchError(f"world {world}/{subworld} not found; looked at "
                             f"{candidate_paths(world, subworld, wroots)}. "
                             "Fix --world WORLD/SUBWORLD or add the folder holding it with --search-path DIR")
    mission_file = _as_file(mission_spec)
    if mission_file is not None:
        mission, submission = mission_file.resolve().parent.name, mission_file.stem
    else:
        mission, submission = split_spec(mission_spec, "mission", "Gym/2UAVs_2paths_Central_Cylinder")
        mission_file = find_mission(mission, submission, search_dirs)
    inputs = Inputs(world, subworld, mission, submission, world_file.resolve(), mission_file.resolve())
    if check:
        check_inputs(inputs, wroots, strict)
    return inputs


def find_mission(mission: str, submission: str, search_dirs: Sequence[Path] = ()) -> Path:
    """The file of MISSION/SUBMISSION; BatchError naming every place looked at.

    Uses the ground station's finder (magna_gs.mission.loader.find_mission) when it is installed,
    else looks in `mission_roots(search_dirs)` itself.
    """
    try:
        from magna_gs.mission import loader as gs_loader
        from magna_gs.mission.model import MissionError
    except ImportError:
        gs_loader = None
    hint = "Fix --mission MISSION/SUBMISSION or add the folder holding it with --search-path DIR"
    if gs_loader is not None and hasattr(gs_loader, "find_mission"):
        folders: list[Path] = []
        for directory in search_dirs:  # its finder looks in each folder and in its Missions/ subfolder
            directory = Path(directory).expanduser()
            if (directory / "missions").is_dir():
                folders.append(directory / "missions")
            folders.append(directory)
        folders += [f for f in gs_loader.default_search_path() if f not in folders]
        try:
            return Path(gs_loader.find_mission(f"{mission}/{submission}", folders))
        except MissionError as err:
            raise BatchError(f"mission {' '.join(str(err).split())}") from None
    roots = mission_roots(search_dirs)
    found = find_mission_file(mission, submission, roots)
    if found is None:
        looked = ", ".join(str(r / mission / f"{submission}.json") for r in roots) or "nowhere"
        raise BatchError(f"mission {mission}/{submission} not found; looked at {looked}. {hint}")
    return found


def check_inputs(inputs: Inputs, world_search: Sequence[Path], strict: bool = False) -> None:
    """Load the world (magna_worlds) and the mission, and check the mission in the world, so bad files stop the
    batch before it starts. With `strict`, what would be a warning (what the original tolerated) stops it too."""
    from magna_worlds.errors import WorldError
    from magna_worlds.loader import load_world_checked

    try:
        world = load_world_checked(inputs.world_file, search_path=world_search, strict=strict)
    except WorldError as err:
        raise BatchError(" ".join(str(err).split())) from None
    try:
        from magna_gs.mission.loader import load_mission
        from magna_gs.mission.model import MissionError
        from magna_gs.mission.world_check import check_in_world
    except ImportError:
        load_mission = None
    if load_mission is not None:  # the ground station's own checks: what it would refuse, refused now
        try:
            loaded = load_mission(inputs.mission_file, strict=strict)
        except MissionError as err:
            raise BatchError(_first_of(err.problems)) from None
        problems = check_in_world(loaded.mission, world.resolved, search_path=world_search, strict=strict).problems
        if problems:
            raise BatchError(_first_of(problems) + f"; in the world {inputs.world_file}") from None
        return
    try:
        data = json.loads(inputs.mission_file.read_text())
    except (OSError, ValueError) as err:
        raise BatchError(f"{inputs.mission_file}: cannot read it as JSON: {err}; fix the file") from None
    if not isinstance(data, dict) or "State_Machine" not in data or not (
            "Agents_Config" in data or "UAVs_Config" in data):
        raise BatchError(f"{inputs.mission_file}: not a mission: expected an object with Agents_Config (or "
                         "UAVs_Config), a list of agents, and State_Machine, a list of states")


def _first_of(problems: Sequence[str]) -> str:
    more = f" (and {len(problems) - 1} more problem(s))" if len(problems) > 1 else ""
    return " ".join(problems[0].split()) + more


# --- configuration and results --------------------------------------------------------------------------------

def parse_rtf(value: str) -> str:
    text = str(value).strip().lower()
    if text == "max":
        return "max"
    try:
        factor = float(text)
    except ValueError:
        factor = math.nan
    if not math.isfinite(factor) or factor <= 0:
        raise BatchError(f"--rtf {value!r}: give 'max' (as fast as possible) or a factor > 0 such as 1.0 or 10")
    return f"{factor:g}"


@dataclass
class BatchConfig:
    """Everything one batch needs; `run_batch` checks it before starting anything."""

    inputs: Inputs
    n_iter: int = 1
    name: str = storage.DEFAULT_NAME
    n_dataset: int = 1
    rtf: str = "max"
    seed: int = 0
    bag: bool = True
    save_data: bool = True
    data_root: Path = storage.DEFAULT_DATA_ROOT
    policy: str | None = None  # append, overwrite, skip-save, abort, or None (ask on a terminal, else abort)
    time_limit: float | None = 600.0  # wall-clock seconds per simulation; None or 0: none
    # Nobody presses the operator's button in a batch: a `wait` on it goes on after this many
    # simulated seconds (0: wait for /magna/gs/continue).
    button_timeout: float = 10.0
    stop_grace: float = 15.0  # after /magna/gs/stop, before the launch is ended
    settle: float = 5.0  # after the termination call, for the launch to exit by itself
    shutdown_timeout: float = 10.0  # between SIGINT, SIGTERM and SIGKILL to the launch
    launch_command: Sequence[str] = DEFAULT_LAUNCH_COMMAND
    output: str = "log"  # roslaunch output of the nodes: log or screen
    rviz: bool = False  # rviz on the display for each simulation (magna_viz rviz.launch); needs DISPLAY
    utm_plan: Path | None = None  # a UTM flight-plan file (magna_gs.utm format) the UTM node issues
    battery_floor: float = 0.0  # % of charge simulated batteries keep (PX4 SITL's SIM_BAT_MIN_PCT); 0: run empty
    fleet: Path | None = None  # the fleet file of the mission's hil and real UAVs (magna_mavlink.fleet)

    @property
    def key(self) -> storage.StorageKey:
        i = self.inputs
        return storage.StorageKey(i.world, i.subworld, i.mission, i.submission, self.name)

    @property
    def dataset_dir(self) -> Path:
        return self.key.dataset_dir(self.data_root, self.n_dataset)

    def seed_of(self, m: int) -> int:
        return self.seed + m

    def uses_default_launch(self) -> bool:
        return tuple(self.launch_command) == DEFAULT_LAUNCH_COMMAND


@dataclass
class SimulationResult:
    id: int
    seed: int
    success: bool
    outcome: str
    message: str
    sim_duration: float
    wall_time: float
    collisions: int
    termination: str
    directory: Path | None
    data: dict = field(default_factory=dict, repr=False)  # the whole result.json

    @property
    def interrupted(self) -> bool:
        return self.termination == INTERRUPTED

    @property
    def failed_to_run(self) -> bool:
        """The simulation did not run to a mission outcome (crash, start failure, supervisor failure)."""
        return self.termination in (CRASHED, START_FAILED, SUPERVISOR_FAILED)

    @classmethod
    def from_result(cls, result: dict, directory: Path | None) -> SimulationResult:
        return cls(int(result["id"]), int(result.get("seed", 0)), bool(result.get("success")),
                   str(result.get("outcome", "")), str(result.get("message", "")),
                   float(result.get("sim_duration") or 0.0), float(result.get("wall_time") or 0.0),
                   int(result.get("collisions") or 0), str(result.get("termination", "")), directory, result)


@dataclass
class BatchResult:
    config: BatchConfig
    plan: storage.StoragePlan
    simulations: list[SimulationResult]
    interrupted: bool
    wall_time: float

    @property
    def dataset_dir(self) -> Path | None:
        return self.plan.dataset_dir

    @property
    def successes(self) -> int:
        return sum(s.success for s in self.simulations)

    @property
    def sim_time(self) -> float:
        return sum(s.sim_duration for s in self.simulations)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second over the simulations the ground station reported."""
        reported = [s for s in self.simulations if s.data.get("reported")]
        wall = sum(s.wall_time for s in reported)
        return sum(s.sim_duration for s in reported) / wall if wall > 0 else 0.0

    @property
    def failed_to_run(self) -> list[SimulationResult]:
        return [s for s in self.simulations if s.failed_to_run]

    def bags(self) -> list[Path]:
        return sorted(s.directory / "simulation.bag" for s in self.simulations
                      if s.directory is not None and (s.directory / "simulation.bag").is_file())


def hyperparameters(config: BatchConfig, m: int, plan: storage.StoragePlan) -> dict:
    """The /magna/hyperparameters of simulation m."""
    i = config.inputs
    return {
        "world": i.world, "subworld": i.subworld, "mission": i.mission, "submission": i.submission,
        "n_dataset": config.n_dataset, "n_simulation": m, "N_iter": config.n_iter,
        "sm_view": False, "save_data": plan.save, "save_bag": plan.save and config.bag, "rviz": config.rviz,
        "seed": config.seed_of(m),
    }


def launch_command(config: BatchConfig, m: int, data_dir: Path | None, plan: storage.StoragePlan) -> list[str]:
    """The launch command of simulation m, its {placeholders} filled."""
    i = config.inputs
    values = {
        "mission_file": str(i.mission_file), "world": i.world, "subworld": i.subworld,
        "worlds_path": str(i.worlds_path), "data_dir": str(data_dir) if data_dir is not None else "",
        "rtf": config.rtf, "seed": str(config.seed_of(m)), "bag": _bool(plan.save and config.bag),
        "save_data": _bool(plan.save), "output": config.output, "mission": i.mission, "submission": i.submission,
        "n_simulation": str(m), "button_timeout": f"{config.button_timeout:g}", "rviz": _bool(config.rviz),
        "utm_plan": str(config.utm_plan) if config.utm_plan else "", "battery_floor": f"{config.battery_floor:g}",
        "fleet": str(config.fleet) if config.fleet else "",
    }
    argv = []
    for arg in config.launch_command:
        for key, value in values.items():
            arg = arg.replace("{" + key + "}", value)
        argv.append(arg)
    if config.rviz and config.uses_default_launch():
        argv.append("rviz:=true")
    if config.utm_plan and config.uses_default_launch():
        argv.append(f"utm_plan:={config.utm_plan}")
    if config.battery_floor and config.uses_default_launch():
        argv.append(f"battery_floor:={config.battery_floor:g}")
    if config.fleet and config.uses_default_launch():
        argv.append(f"fleet:={config.fleet}")
    return argv


def _bool(value: bool) -> str:
    return "true" if value else "false"


# --- the loop --------------------------------------------------------------------------------------------------

def preflight(config: BatchConfig) -> None:
    """Check what the batch needs before anything is created or started."""
    if config.n_iter < 1:
        raise BatchError(f"--n-iter must be >= 1, got {config.n_iter}")
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


class _StopFlag:
    """Set by SIGINT/SIGTERM while a batch runs (handlers only in the main thread)."""

    def __init__(self, out):
        self.event = threading.Event()
        self.out = out
        self._previous: dict[int, object] = {}

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._handle)

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _handle(self, signum, _frame) -> None:
        if not self.event.is_set():
            print(f"\nmagna run: {signal.Signals(signum).name}: stopping the running simulation, keeping the "
                  "finished ones (wait for the clean-up)", file=self.out, flush=True)
        else:
            print("magna run: still cleaning up, please wait", file=self.out, flush=True)
        self.event.set()

    def __bool__(self) -> bool:
        return self.event.is_set()


class Batch:
    """One batch run; `run()` returns a BatchResult. Use `run_batch` unless you need the pieces."""

    # Seconds a supervisor may take beyond the simulation's own budgets (its start, rospy, the clean-up)
    # before the batch gives it up as hung and ends its process group.
    supervisor_margin = 60.0

    def __init__(self, config: BatchConfig, ask: Callable[[storage.StorageConflict], str] | None = None,
                 progress: bool | None = None, out=None,
                 on_simulation: Callable[[SimulationResult], None] | None = None):
        self.config = config
        self.ask = ask
        self.progress = progress
        self.out = out if out is not None else sys.stderr
        self.on_simulation = on_simulation
        self.stop = _StopFlag(self.out)

    def run(self) -> BatchResult:
        config = self.config
        preflight(config)
        lock = None
        if config.save_data:
            lock = storage.DatasetLock(config.dataset_dir).acquire()
        try:
            plan = storage.plan_storage(config.dataset_dir, config.n_iter, config.policy, config.save_data, self.ask)
            if not plan.save and lock is not None:
                lock.release()  # skip-save: nothing will be written there
                lock = None
            return self._loop(plan)
        finally:
            if lock is not None:
                lock.release()

    def _loop(self, plan: storage.StoragePlan) -> BatchResult:
        from tqdm import tqdm

        config = self.config
        results: list[SimulationResult] = []
        started = time.monotonic()
        self.stop.install()
        bar = tqdm(total=len(plan.ids), unit="sim", desc=f"{config.inputs.mission}/{config.inputs.submission}",
                   file=self.out, disable=(None if self.progress is None else not self.progress),
                   dynamic_ncols=True, leave=True)
        try:
            for m in plan.ids:
                if self.stop:
                    break
                result = self._simulation(m, plan)
                if result is None:  # stopped before it started
                    break
                results.append(result)
                bar.update(1)
                done = [r for r in results if not r.interrupted]
                speed = BatchResult(config, plan, results, False, 0.0).speed
                bar.set_postfix_str(f"ok {sum(r.success for r in done)}/{len(done)}, {speed:.1f}x sim/wall")
                if bar.disable:
                    print(f"simulation {m} ({len(results)}/{len(plan.ids)}): {_status(result)}, "
                          f"{result.sim_duration:.1f} sim s in {result.wall_time:.1f} s", file=self.out, flush=True)
                if self.on_simulation is not None:
                    self.on_simulation(result)
                if result.interrupted:
                    break
        finally:
            bar.close()
            self.stop.restore()
        return BatchResult(config, plan, results, bool(self.stop), time.monotonic() - started)

    def _simulation(self, m: int, plan: storage.StoragePlan) -> SimulationResult | None:
        if plan.save:
            work_dir = storage.prepare_simulation_dir(plan, m)
            data_dir: Path | None = work_dir
        else:
            work_dir = Path(tempfile.mkdtemp(prefix=f"magna_sim_{m}_"))
            data_dir = None
        try:
            result = self._supervise(m, plan, work_dir, data_dir)
            if result is None:
                return None
            if plan.save:
                storage.update_summary(plan.dataset_dir, result)
            return SimulationResult.from_result(result, work_dir if plan.save else None)
        finally:
            if not plan.save:
                shutil.rmtree(work_dir, ignore_errors=True)

    def _supervise(self, m: int, plan: storage.StoragePlan, work_dir: Path, data_dir: Path | None) -> dict | None:
        config = self.config
        logs = work_dir / "logs"
        logs.mkdir(exist_ok=True)
        result_path = work_dir / storage.RESULT_FILE
        token = uuid.uuid4().hex
        hyper = hyperparameters(config, m, plan)
        command = launch_command(config, m, data_dir, plan)
        extra = {"id": m, "seed": config.seed_of(m), "hyperparameters": hyper,
                 "world_file": str(config.inputs.world_file), "mission_file": str(config.inputs.mission_file),
                 "data_dir": str(data_dir) if data_dir is not None else None}
        master = RosMaster(log_dir=logs / "ros")
        supervisor = None
        hung = False
        try:
            try:
                master.start()
            except (RosMasterError, OSError) as err:
                self._discard(work_dir, plan)
                raise BatchError(f"simulation {m}: cannot start a ROS master: {err}") from None
            xmlrpc.client.ServerProxy(master.uri).setParam("/magna_master", HYPERPARAMETERS_PARAM, hyper)
            if self.stop:
                self._discard(work_dir, plan)
                return None
            argv = self.supervisor_argv(result_path, logs, data_dir, extra, command)
            env = dict(os.environ)
            env[TOKEN_ENV] = token
            package_parent = str(Path(__file__).resolve().parents[1])
            env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH", "")) if p)
            with open(logs / "supervisor.log", "ab") as supervisor_log:
                supervisor = master.spawn(argv, env=env, stdout=supervisor_log, stderr=supervisor_log,
                                          stdin=subprocess.DEVNULL)
            hung = self._wait_supervisor(supervisor)
        finally:
            if supervisor is not None and supervisor.poll() is None:
                end_process_group(supervisor, grace=2.0)
            leftovers = kill_tagged(token)
            master.stop()
        result = storage.read_result(result_path)
        changed = result is None or not result.get("final", False)
        if changed:
            partial = result or {}
            result = {**extra, **partial, "final": True, "supervisor_pid": supervisor.pid if supervisor else None}
            reported = bool(partial.get("reported"))
            if not reported:
                interrupted = bool(self.stop)
                result.update(success=False, outcome=INTERRUPTED if interrupted else SUPERVISOR_FAILED,
                              termination=INTERRUPTED if interrupted else SUPERVISOR_FAILED,
                              sim_duration=0.0, collisions=0, reported=False)
            result.setdefault("wall_time", 0.0)
            result["message"] = ((partial.get("message", "") + "; ") if reported else "") + (
                "the supervisor " + ("hung and was killed" if hung else
                                     f"exited with status {supervisor.returncode if supervisor else None}")
                + " before writing its result; see logs/supervisor.log")
        if leftovers:
            result["leftover_processes_killed"] = [*result.get("leftover_processes_killed", []), *leftovers]
            changed = True
        if changed:
            storage.write_result(work_dir, result)
        return result

    def supervisor_argv(self, result_path: Path, logs: Path, data_dir: Path | None, extra: dict,
                        command: list[str]) -> list[str]:
        """The command line of one simulation's supervisor process."""
        config = self.config
        return [sys.executable, "-m", "magna_master.supervisor", "--result", str(result_path),
                "--log", str(logs / "launch.log"), "--data-dir", str(data_dir or ""),
                "--time-limit", str(config.time_limit or 0), "--stop-grace", str(config.stop_grace),
                "--settle", str(config.settle), "--shutdown-timeout", str(config.shutdown_timeout),
                "--parent-pid", str(os.getpid()), "--extra", json.dumps(extra), "--", *command]

    def _wait_supervisor(self, supervisor) -> bool:
        """Wait for the supervisor; on a stop request forward SIGINT; True when it had to be given up as hung."""
        config = self.config
        budget = ((config.time_limit or math.inf) + config.stop_grace + config.settle
                  + 3 * config.shutdown_timeout + self.supervisor_margin)
        deadline = time.monotonic() + budget
        stop_deadline = None
        while supervisor.poll() is None:
            now = time.monotonic()
            if self.stop and stop_deadline is None:
                try:
                    os.killpg(supervisor.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
                stop_deadline = now + 3 * config.shutdown_timeout + 15.0
            if now > deadline or (stop_deadline is not None and now > stop_deadline):
                return True
            time.sleep(0.05)
        return False

    def _discard(self, work_dir: Path, plan: storage.StoragePlan) -> None:
        """Remove the folder of a simulation that never started (it holds only its empty logs)."""
        if plan.save:
            shutil.rmtree(work_dir, ignore_errors=True)


def _status(result: SimulationResult) -> str:
    if result.termination == GROUND_STATION:
        return ("success" if result.success else "failure") + f" ({result.outcome})"
    return result.termination.replace("_", " ")


def run_batch(config: BatchConfig, ask: Callable[[storage.StorageConflict], str] | None = None,
              progress: bool | None = None, out=None,
              on_simulation: Callable[[SimulationResult], None] | None = None) -> BatchResult:
    """Run a batch (see the module doc). Raises BatchError / storage.StorageError before starting anything."""
    return Batch(config, ask=ask, progress=progress, out=out, on_simulation=on_simulation).run()


# --- reporting --------------------------------------------------------------------------------------------------

def format_summary(batch: BatchResult) -> str:
    """The table `magna run` prints at the end, and where the data is."""
    rows = [("id", "seed", "success", "outcome", "sim s", "wall s", "collisions", "message")]
    for s in batch.simulations:
        message = s.message if len(s.message) <= 70 else s.message[:67] + "..."
        rows.append((str(s.id), str(s.seed), "yes" if s.success else "no", s.outcome, f"{s.sim_duration:.1f}",
                     f"{s.wall_time:.1f}", str(s.collisions), message))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:-1], widths, strict=True)) + "  " + row[-1]
             for row in rows]
    done = [s for s in batch.simulations if not s.interrupted]
    lines.append("")
    lines.append(f"{len(done)} of {len(batch.plan.ids)} simulation(s) run, {batch.successes} succeeded; "
                 f"{batch.sim_time:.1f} simulated s in {batch.wall_time:.1f} wall s "
                 f"({batch.speed:.1f}x faster than real time while simulating)")
    if batch.interrupted:
        lines.append("interrupted: the running simulation is marked 'interrupted'; no further simulation started")
    if batch.plan.save:
        lines.append(f"data:    {batch.dataset_dir} (summary.csv, simulation_<m>/)")
        bags = batch.bags()
        if bags:
            lines.append(f"bags:    {len(bags)} in {batch.dataset_dir}/simulation_<m>/simulation.bag")
        else:
            lines.append("bags:    none" + (" (--no-bag)" if not batch.config.bag else ""))
    else:
        lines.append(f"data:    not saved: {batch.plan.reason}")
    return "\n".join(lines)
