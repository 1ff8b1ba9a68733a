"""What a batch runs: the world and mission found (magna_gs.inputs), how many simulations, where their data
goes, and the launch command and /magna/hyperparameters of each simulation."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from magna_common.errors import UserError
from magna_common.records import Hyperparameters
from magna_common.storage_tree import DEFAULT_DATA_ROOT, DEFAULT_NAME, StorageKey
from magna_gs.inputs import Inputs
from magna_master.storage import DEFAULT_MIN_FREE_MB, StoragePlan

# The launch of one simulation (magna_gs). {name} placeholders are filled per simulation.
DEFAULT_LAUNCH_COMMAND: tuple[str, ...] = (
    "roslaunch", "--sigint-timeout=5", "--sigterm-timeout=2", "magna_gs", "simulation.launch",
    "mission_file:={mission_file}", "world:={world}", "subworld:={subworld}", "worlds_path:={worlds_path}",
    "data_dir:={data_dir}", "rtf:={rtf}", "seed:={seed}", "bag:={bag}", "save_data:={save_data}",
    "output:={output}", "button_timeout:={button_timeout}", "managers:={managers}",
)
PLACEHOLDERS = ("mission_file", "world", "subworld", "worlds_path", "data_dir", "rtf", "seed", "bag", "save_data",
                "output", "mission", "submission", "n_simulation", "button_timeout", "rviz", "utm_plan",
                "battery_floor", "fleet", "managers")


class BatchError(UserError):
    """A batch that cannot start (bad option, missing launch file, ...): say what and the fix; exit status 2."""


@dataclass
class BatchConfig:
    """Everything one batch needs; `run_batch` checks it before starting anything."""

    inputs: Inputs
    n_iter: int = 1
    name: str = DEFAULT_NAME
    n_dataset: int = 1
    rtf: str = "max"
    seed: int = 0
    bag: bool = True
    save_data: bool = True
    data_root: Path = DEFAULT_DATA_ROOT
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
    min_free_mb: float = DEFAULT_MIN_FREE_MB  # MB the dataset's disk keeps free; checked before each simulation
    # a fresh master and launch for every simulation, instead of one stack kept up across the batch
    cold_start: bool = False
    # host: the UAV managers of the ground station share one process (a thread each); process: one each
    managers: str = "host"
    jobs: int = 1  # simulations run at once, each with its own master, simulator and stack

    @property
    def key(self) -> StorageKey:
        i = self.inputs
        return StorageKey(i.world, i.subworld, i.mission, i.submission, self.name)

    @property
    def dataset_dir(self) -> Path:
        return self.key.dataset_dir(self.data_root, self.n_dataset)

    def seed_of(self, m: int) -> int:
        return self.seed + m

    def uses_default_launch(self) -> bool:
        return tuple(self.launch_command) == DEFAULT_LAUNCH_COMMAND


def hyperparameters(config: BatchConfig, m: int, plan: StoragePlan) -> Hyperparameters:
    """The /magna/hyperparameters of simulation m."""
    i = config.inputs
    return Hyperparameters(
        world=i.world, subworld=i.subworld, mission=i.mission, submission=i.submission,
        n_dataset=config.n_dataset, n_simulation=m, n_iter=config.n_iter,
        sm_view=False, save_data=plan.save, save_bag=plan.save and config.bag, rviz=config.rviz,
        seed=config.seed_of(m),
    )


def launch_command(config: BatchConfig, m: int, data_dir: Path | None, plan: StoragePlan) -> list[str]:
    """The launch command of simulation m, its {placeholders} filled."""
    i = config.inputs
    values = {
        "mission_file": str(i.mission_file), "world": i.world, "subworld": i.subworld,
        "worlds_path": str(i.worlds_path), "data_dir": str(data_dir) if data_dir is not None else "",
        "rtf": config.rtf, "seed": str(config.seed_of(m)), "bag": _bool(plan.save and config.bag),
        "save_data": _bool(plan.save), "output": config.output, "mission": i.mission, "submission": i.submission,
        "n_simulation": str(m), "button_timeout": f"{config.button_timeout:g}", "rviz": _bool(config.rviz),
        "utm_plan": str(config.utm_plan) if config.utm_plan else "", "battery_floor": f"{config.battery_floor:g}",
        "fleet": str(config.fleet) if config.fleet else "", "managers": config.managers,
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
