"""The UAV manager node's private parameters, read and checked without ROS: the node passes
rospy.get_param, tests a dict's get."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from magna_uav.config import ConfigError, UavConfig, configs_from_mission, configs_from_mission_file


class SettingsError(ValueError):
    """A bad private parameter; the message names it."""


def _default_data_dir() -> Path:
    return Path.home() / ".ros" / "magna"


@dataclass
class Settings:
    uav_id: int
    configs: list[UavConfig]
    control_rate: float = 10.0
    data_dir: Path = field(default_factory=_default_data_dir)
    depth: bool = False
    low_battery: float = 0.15
    algorithm: str = "simple"
    flies_networks: bool = False  # the mission names neural_network: torch is imported at start-up
    csv_stream: Path | None = None  # the CSV the rows go to as the UAV flies (Recorder.stream_to); None: none

    @property
    def own(self) -> UavConfig:
        return next(c for c in self.configs if c.id == self.uav_id)


def _whole(name: str, value: object) -> int:
    # numbers may come as text (a launch file's <param type="str">)
    if isinstance(value, int | float | str):
        try:
            return int(value)
        except ValueError:
            pass
    raise SettingsError(f"{name} is {value!r}: give a whole number")


def _number(name: str, value: object) -> float:
    if isinstance(value, int | float | str):
        try:
            return float(value)
        except ValueError:
            pass
    raise SettingsError(f"{name} is {value!r}: give a number")


def _path(name: str, value: object) -> str:
    if not isinstance(value, str):
        raise SettingsError(f"{name} is {value!r}: give a path")
    return value


def read_settings(param: Callable[[str, object], object]) -> Settings:
    """The node's private parameters (`param(name, default)`), checked; SettingsError names the bad one."""
    raw_id = param("~id", None)
    if raw_id is None:
        raise SettingsError("~id is missing: give this UAV's id, e.g. _id:=1")
    uav_id = _whole("~id", raw_id)
    mission_file = _path("~mission_file", param("~mission_file", ""))
    try:
        if mission_file:
            configs = configs_from_mission_file(mission_file)
        else:
            raw_ids = param("~uav_ids", [uav_id])
            if not isinstance(raw_ids, list | tuple):
                raise SettingsError(f"~uav_ids is {raw_ids!r}: give a list of UAV ids")
            ids = [_whole("~uav_ids", i) for i in raw_ids]
            model = param("~model", "iris")
            entries = [{"ID": i, "model": model, "mode": "sitl", "marker_color": [255, 255, 255, 1.0]} for i in ids]
            configs = configs_from_mission(entries, "~uav_ids/~model")
    except ConfigError as error:
        raise SettingsError(str(error)) from None
    if uav_id not in [c.id for c in configs]:
        raise SettingsError(f"~id is {uav_id} but the mission's UAVs are {[c.id for c in configs]}")
    rate = _number("~control_rate", param("~control_rate", 10.0))
    if not 0.5 <= rate <= 200.0:
        raise SettingsError(f"~control_rate is {rate}: give 0.5 to 200 steps per second")
    low = _number("~low_battery", param("~low_battery", 0.15))
    if not 0.0 <= low < 1.0:
        raise SettingsError(f"~low_battery is {low}: give a battery fraction in [0, 1)")
    flies_networks = bool(mission_file) and "neural_network" in Path(mission_file).read_text(errors="replace")
    data_dir = Path(_path("~data_dir", param("~data_dir", str(_default_data_dir())))).expanduser()
    stream = _path("~csv_stream", param("~csv_stream", ""))
    return Settings(uav_id, configs, rate, data_dir, bool(param("~depth_camera", False)), low,
                    str(param("~algorithm", "simple")), flies_networks,
                    Path(stream).expanduser() if stream else None)
