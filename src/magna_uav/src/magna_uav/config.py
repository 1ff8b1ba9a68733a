"""A UAV's configuration (UAV-C): its mission entry merged with its airframe, parsed once.

A mission's "Agents_Config" (legacy name "UAVs_Config") holds one entry per UAV, as in the
original ROS-MAGNA missions:

    {"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5],
     "ual_use": true, "agent_manager_on_gs": true}

ID, model, mode and marker_color are required; ual_use (default: the airframe's) and
agent_manager_on_gs (legacy uav_manager_on_gs, default true) are optional. The model names
an airframe file, src/magna_common/airframes/<model>.json. Every error names the file, the
JSON path and what would be accepted (magna_common.json_fields, stopping at the first).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Never, get_args

from magna_common.airframes import AIRFRAME_DIR, Airframe, AirframeError, available_models, load_airframe
from magna_common.json_fields import FieldError, JsonFields, closest, is_number, join_path

Mode = Literal["sitl", "hil", "real"]  # simulated, hardware in the loop, or a real flight
MODES: tuple[Mode, ...] = get_args(Mode)
AGENTS_KEY = "Agents_Config"
LEGACY_AGENTS_KEY = "UAVs_Config"
GS_KEY = "agent_manager_on_gs"
LEGACY_GS_KEY = "uav_manager_on_gs"
REQUIRED_KEYS = ("ID", "model", "mode", "marker_color")
OPTIONAL_KEYS = ("ual_use", GS_KEY, LEGACY_GS_KEY)
ALLOWED_KEYS = REQUIRED_KEYS + OPTIONAL_KEYS


class ConfigError(FieldError):
    """A bad agent entry; the message is `<file>: <JSON path>: <what is wrong and what is accepted>`."""


@dataclass(frozen=True)
class UavConfig:
    """One UAV of a mission: its mission entry and its airframe."""

    id: int
    model: str
    mode: Mode
    marker_color: tuple[float, float, float, float]  # r, g, b in 0..255 as the files write them; alpha 0..1
    ual_use: bool
    manager_on_gs: bool
    airframe: Airframe = field(repr=False)  # its model is in `model`

    @property
    def name(self) -> str:
        """The UAV's namespace and frame prefix: uav_{id}."""
        return f"uav_{self.id}"

    @property
    def safety_radius(self) -> float:
        return self.airframe.safety_radius

    @property
    def max_speed(self) -> float:
        return self.airframe.max_speed

    @property
    def accepted_target_radius(self) -> float:
        return self.airframe.accepted_target_radius

    @property
    def autopilot(self) -> str:
        return self.airframe.autopilot

    @property
    def marker_rgba(self) -> tuple[float, float, float, float]:
        """The marker colour as rviz wants it: every channel 0..1."""
        r, g, b, a = self.marker_color
        return (r / 255.0, g / 255.0, b / 255.0, a)


def configs_from_mission(agents_config: Any, source: str, key: str = AGENTS_KEY,
                         airframe_dir: Path = AIRFRAME_DIR) -> list[UavConfig]:
    """One UavConfig per entry of a mission's agent list, in file order; ConfigError at the first bad field."""
    fields = JsonFields.first_error(source, ConfigError)
    entries = fields.list(agents_config, key, "a list of agent entries ({\"ID\": 1, \"model\": \"iris\", ...})")
    airframes: dict[str, Airframe] = {}
    first_use: dict[int, int] = {}
    configs = []
    for index, entry in enumerate(entries):
        config = _parse_entry(fields, entry, join_path(key, index), airframes, Path(airframe_dir))
        if config.id in first_use:
            fields.fail(f"{key}[{index}].ID", f"{config.id} is already the ID of {key}[{first_use[config.id]}]; "
                                              "every agent needs its own ID")
        first_use[config.id] = index
        configs.append(config)
    return configs


def configs_from_mission_file(path: str | Path, airframe_dir: Path = AIRFRAME_DIR) -> list[UavConfig]:
    """The agents of a mission file, under "Agents_Config" or the legacy "UAVs_Config"."""
    path = Path(path)
    try:
        raw = json.loads(path.read_text())
    except OSError as err:
        raise ConfigError(str(path), "", f"cannot read the mission: {err.strerror or err}") from None
    except json.JSONDecodeError as err:
        raise ConfigError(str(path), "", f"not valid JSON: {err}") from None
    if not isinstance(raw, dict):
        raise ConfigError(str(path), "", f"the top level must be a JSON object with {AGENTS_KEY} and State_Machine")
    present = [k for k in (AGENTS_KEY, LEGACY_AGENTS_KEY) if k in raw]
    if not present:
        raise ConfigError(str(path), AGENTS_KEY, f"missing; a mission lists its agents under {AGENTS_KEY} "
                                                 f"(or the legacy {LEGACY_AGENTS_KEY})")
    if len(present) == 2:
        raise ConfigError(str(path), LEGACY_AGENTS_KEY, f"give the agents once, under {AGENTS_KEY} "
                                                        f"(the legacy name {LEGACY_AGENTS_KEY} as well is ambiguous)")
    return configs_from_mission(raw[present[0]], str(path), present[0], airframe_dir)


def _parse_entry(fields: JsonFields[Never], raw: Any, where: str, airframes: dict[str, Airframe],
                 airframe_dir: Path) -> UavConfig:
    entry = fields.object(raw, where, f"an object with {', '.join(REQUIRED_KEYS)}")
    for key in entry:
        if key not in ALLOWED_KEYS:
            close = closest(key, ALLOWED_KEYS, cutoff=0.5)
            hint = f"did you mean '{close}'? " if close else ""
            fields.fail(join_path(where, key), f"unknown key; {hint}allowed: {', '.join(ALLOWED_KEYS)}")
    for key in REQUIRED_KEYS:
        if key not in entry:
            fields.fail(join_path(where, key), f"missing (every agent has {', '.join(REQUIRED_KEYS)})")
    if GS_KEY in entry and LEGACY_GS_KEY in entry:
        fields.fail(join_path(where, LEGACY_GS_KEY), f"give {GS_KEY} or its legacy name {LEGACY_GS_KEY}, not both")

    agent_id = fields.integer(entry["ID"], join_path(where, "ID"), "a whole number 0 or more", minimum=0)
    model = fields.text(entry["model"], join_path(where, "model"), "an airframe name (a string)", allow_empty=True)
    airframe = _airframe(fields, model, join_path(where, "model"), airframes, airframe_dir)
    mode = fields.choice(entry["mode"], join_path(where, "mode"), MODES)
    color = _color(fields, entry["marker_color"], join_path(where, "marker_color"))
    if "ual_use" in entry:
        ual_use = fields.flag(entry["ual_use"], join_path(where, "ual_use"), zero_one=True)
    else:
        ual_use = bool(airframe.ual_use)
    gs_key = LEGACY_GS_KEY if LEGACY_GS_KEY in entry else GS_KEY
    manager_on_gs = fields.flag(entry[gs_key], join_path(where, gs_key), zero_one=True) if gs_key in entry else True

    return UavConfig(id=agent_id, model=model, mode=mode, marker_color=color, ual_use=ual_use,
                     manager_on_gs=manager_on_gs, airframe=airframe)


def _airframe(fields: JsonFields[Never], model: str, where: str, cache: dict[str, Airframe],
              directory: Path) -> Airframe:
    if model in cache:
        return cache[model]
    known = available_models(directory)
    if model not in known:
        close = closest(model, known)
        hint = f"did you mean '{close}'? " if close else ""
        fields.fail(where, f"{model!r} is not a known airframe; {hint}known: {', '.join(known)} "
                           f"(files {directory}/<model>.json)")
    try:
        cache[model] = load_airframe(model, directory)
    except AirframeError as err:
        raise ConfigError(fields.source, where, f"airframe {model!r} does not load: {err}") from None
    return cache[model]


def _color(fields: JsonFields[Never], value: Any, where: str) -> tuple[float, float, float, float]:
    usage = "expected [r, g, b, a] with r, g, b 0-255 and alpha 0-1"
    if not isinstance(value, list) or len(value) != 4:
        fields.fail(where, f"{usage}, got {value!r}")
    for i, channel in enumerate(value):
        if not is_number(channel):
            fields.fail(join_path(where, i), f"{usage}; {channel!r} is not a number")
        top = 1 if i == 3 else 255
        if not 0 <= channel <= top:
            name = "alpha" if i == 3 else "rgb"[i]
            fields.fail(join_path(where, i), f"{channel!r} is outside 0..{top} ({name}); {usage}")
    r, g, b, a = (float(c) for c in value)
    return (r, g, b, a)
