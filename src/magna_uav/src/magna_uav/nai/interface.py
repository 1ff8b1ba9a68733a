"""The navigation algorithms interface (NAI): one UAV's velocity command from its WorldView and Goal.

Algorithms, switched and tuned by the mission's `algorithm_control` state (or the
magna_msgs/AlgorithmControl service) through `NavigationInterface.control`:

- "simple" (the default): `simple.simple_velocity`. Parameter: brakingDistance (m,
  default max_speed * 1 s).
- "orca3d" (also "orca3", the original name): ORCA-3D around the simple-guidance velocity
  (`orca`). Parameters: N_neighbors_aware (10), N_obstacles_aware (follows
  N_neighbors_aware until set), timeStep (1/60 s), neighborDist (6 m), timeHorizon (5 s),
  agent_radius (0.5 m), maxSpeed (2 m/s).
- "neural_network": the model of the goal's role (`neural`). Parameters: model (the path
  of a TorchScript file; or the request's text_value), neighborDist (6 m: selection and
  padding of the inputs, `inputs`), fallback (0: off, the default; 1: on, see below), teacher
  (1, the default: solve the teacher's answer at every step; 0: do not, see below).

The teacher (DAgger): while a network flies, every command also carries ORCA-3D's answer from the
same WorldView and goal, with the ORCA-3D parameters as they stand (`Command.teacher_velocity`,
saturated like any command). The recorder writes it beside the network's, so a flight of the
network is relabelled by its teacher (mlr's DAgger). With fallback 1 the teacher also takes over a
step whose network command would collide within ORCA-3D's timeHorizon (`would_collide`: the
command inside a velocity obstacle of a UAV or obstacle ORCA-3D considers); `Command.fallback` says
so. The plain network is fallback 0. The teacher's solve costs one ORCA-3D step per command; a flight
that records nothing for DAgger (a real UAV with a slow companion computer) may turn it off with
teacher 0, and then `teacher_velocity` is None, unless fallback 1 needs the answer anyway.

ORCA-3D's agent_radius is the radius every UAV has in ORCA when its safety radius is
smaller: the margin that absorbs the autopilot's lag (`orca`). maxSpeed is kept but changes
nothing: the NAI always gives the UAV's own max speed.

Actions: "set" selects the algorithm and applies the parameters given; "configure" only
applies them (to the named algorithm, selected or not). Parameters not given keep their
value. A request is checked as a whole before anything changes: an unknown name, action
or parameter, a bad value or a model that does not load raises ValueError naming it, and
the NAI stays as it was.

Neural networks: each model has a role (its spec); loading one ("set" or "configure"
with a model) keeps it for that role, replacing an earlier one of the same role, so a
mission may load a "path" and an "agent_ad" model. A goal whose role has no model is an
error (hover); "basic_move" goals, which no network is trained for, fly with ORCA-3D and
the command says so (`Command.algorithm` "orca3d"). Relative model paths are taken from
`model_dir` (default: the working directory).

ORCA-3D's solver (constructor): `solver`, or a ready `orca` navigator (orca.OrcaNavigator), e.g. one
sharing an OrcaBatcher with the other managers of a process so that one call per control step
serves them all, with the same answers. `release()` tells the NAI that the control loop stopped
stepping (a role ended), so a shared batcher does not wait for this UAV.

Heading (constructor: heading "none" | "goal" | "travel", yaw_gain, max_yaw_rate): the yaw
rate of `simple.heading_rate`, for every algorithm, from its final velocity.

Every command is saturated to `max_speed` (norm). An algorithm that fails or answers a
non-finite velocity gives a hover command (zero velocity, `feasible` False, `error` set)
and one error on the `magna_uav.nai` logger (repeated only when the reason changes).
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from magna_orca_cpp.model import ALGORITHM_CONTROL_NAMES, Params
from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import DEFAULT_NEIGHBOR_DIST
from magna_uav.nai.neural import NeuralModel, load_model
from magna_uav.nai.orca import OrcaNavigator, OrcaResult, would_collide
from magna_uav.nai.simple import DEFAULT_BRAKING_TIME, HEADING_MODES, heading_rate, saturate, simple_velocity
from magna_uav.world_view import WorldView

logger = logging.getLogger("magna_uav.nai")

ALGORITHMS = ("simple", "orca3d", "neural_network")
ALIASES = {"orca3": "orca3d"}
ACTIONS = ("set", "configure")
ORCA_OBSTACLES = "N_obstacles_aware"

ParamValue = float | str  # a number (an int for the whole ones) or neural_network's model path
_Checker = Callable[[object], ParamValue]


def _number(value) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeError
    return float(value)


def _positive(value) -> float:
    number = _number(value)
    if not math.isfinite(number) or number <= 0.0:
        raise ValueError
    return number


def _not_negative(value) -> float:
    number = _number(value)
    if not math.isfinite(number) or number < 0.0:
        raise ValueError
    return number


def _whole(value) -> int:
    number = _not_negative(value)
    if number != int(number):
        raise ValueError
    return int(number)


def _flag(value) -> int:
    number = _whole(value)
    if number not in (0, 1):
        raise ValueError
    return number


def _path(value) -> str:
    if not isinstance(value, str | Path) or not str(value).strip():
        raise TypeError
    return str(value).strip()


# name -> (check, what to give) per algorithm; values arrive as floats (service) or JSON numbers / strings
PARAMETERS: dict[str, dict[str, tuple[_Checker, str]]] = {
    "simple": {
        "brakingDistance": (_positive, "a positive distance in metres"),
    },
    "orca3d": {
        "N_neighbors_aware": (_whole, "a whole number >= 0"),
        ORCA_OBSTACLES: (_whole, "a whole number >= 0"),
        "timeStep": (_positive, "a positive number of seconds"),
        "neighborDist": (_not_negative, "a finite distance >= 0 in metres"),
        "timeHorizon": (_positive, "a positive number of seconds"),
        "agent_radius": (_not_negative, "a finite radius >= 0 in metres"),
        "maxSpeed": (_not_negative, "a finite speed >= 0 in m/s"),
    },
    "neural_network": {
        "model": (_path, "the path of a TorchScript file (its .json spec beside it)"),
        "neighborDist": (_positive, "a finite positive distance in metres"),
        "fallback": (_flag, "0 (the network alone) or 1 (the teacher takes over a colliding command)"),
        "teacher": (_flag, "1 (ORCA-3D's answer is solved beside the network's) or 0 (it is not)"),
    },
}


@dataclass
class Command:
    """One velocity command (map frame) and how it was made."""

    velocity: np.ndarray  # (3,) m/s, norm <= max_speed, never NaN
    yaw_rate: float  # rad/s
    algorithm: str  # the algorithm that produced it ("orca3d" for basic moves under neural_network)
    feasible: bool = True  # ORCA-3D: every constraint met; False also for a hover after an error
    neighbors: tuple[int, ...] = ()  # ids of the UAVs taken into account, nearest first
    obstacles: tuple[str, ...] = ()  # names of the obstacles taken into account, nearest first
    error: str = ""  # why this is a hover command, or ""
    # ORCA-3D's answer from the same inputs while a network flies (module docstring), else None
    teacher_velocity: np.ndarray | None = None
    fallback: bool = False  # the network's command would have collided and the teacher's was sent


def canonical_name(name: str) -> str:
    name = ALIASES.get(name, name)
    if name not in ALGORITHMS:
        raise ValueError(f"algorithm_control name {name!r} is unknown: give one of simple, orca3d (or orca3), "
                         "neural_network")
    return name


def _state_list(parameters: Mapping[str, object], key: str) -> Sequence[object]:
    value = parameters.get(key, [])
    if not isinstance(value, list | tuple):
        raise ValueError(f"algorithm_control parameters.{key} is {value!r}: give a list")
    return value


class NavigationInterface:
    """Velocity commands for one UAV; `control` switches and tunes the algorithm."""

    def __init__(self, max_speed: float, safety_radius: float, solver=None, max_yaw_rate: float = 1.0,
                 heading: str = "goal", yaw_gain: float = 1.0, model_dir: str | Path | None = None,
                 model_loader: Callable[[Path], NeuralModel] = load_model, orca: OrcaNavigator | None = None):
        for name, value in (("max_speed", max_speed), ("safety_radius", safety_radius),
                            ("max_yaw_rate", max_yaw_rate), ("yaw_gain", yaw_gain)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
                    or value <= 0:
                raise ValueError(f"NavigationInterface {name} is {value!r}: give a positive finite number "
                                 "(from the UAV's airframe)")
        if orca is not None and solver is not None:
            raise ValueError("NavigationInterface takes a solver or an orca navigator, not both: give the solver to "
                             "the navigator")
        if heading not in HEADING_MODES:
            raise ValueError(f"NavigationInterface heading is {heading!r}: give one of {', '.join(HEADING_MODES)}")
        self.max_speed = float(max_speed)
        self.safety_radius = float(safety_radius)
        self.max_yaw_rate = float(max_yaw_rate)
        self.heading = heading
        self.yaw_gain = float(yaw_gain)
        self.model_dir = Path(model_dir) if model_dir is not None else None
        self._load_model = model_loader
        self._orca = orca if orca is not None else OrcaNavigator(solver)
        self._algorithm = "simple"
        self._params: dict[str, dict[str, ParamValue]] = {
            "simple": {"brakingDistance": self.max_speed * DEFAULT_BRAKING_TIME},
            "orca3d": {name: getattr(Params(), field) for name, field in ALGORITHM_CONTROL_NAMES.items()},
            "neural_network": {"model": "", "neighborDist": DEFAULT_NEIGHBOR_DIST, "fallback": 0, "teacher": 1},
        }
        self._models: dict[str, NeuralModel] = {}  # by role
        self._last_error = ""

    # --- algorithm_control -------------------------------------------------------------------

    @property
    def algorithm(self) -> str:
        return self._algorithm

    def params(self, name: str | None = None) -> dict[str, ParamValue]:
        """A copy of the parameters of algorithm `name` (default: the current one)."""
        name = canonical_name(name) if name is not None else self._algorithm
        params = dict(self._params[name])
        if name == "orca3d" and ORCA_OBSTACLES not in params:
            params[ORCA_OBSTACLES] = params["N_neighbors_aware"]
        return params

    @property
    def models(self) -> dict[str, NeuralModel]:
        """The loaded neural networks by role."""
        return dict(self._models)

    def orca_params(self) -> Params:
        return Params.from_algorithm_control({k: self._number_param("orca3d", k) for k in self._params["orca3d"]
                                              if k != ORCA_OBSTACLES})

    def _number_param(self, name: str, param: str) -> float:
        value = self._params[name][param]
        assert not isinstance(value, str), f"{name} {param} is {value!r}"  # only neural_network's model is a path
        return value

    def control(self, name: str, action: str, params: Sequence[str] = (), values: Sequence[object] = (),
                text_value: str = "") -> str:
        """Apply one algorithm_control request (module docstring); returns what was done."""
        name = canonical_name(name)
        if action not in ACTIONS:
            raise ValueError(f"algorithm_control action {action!r} is unknown: give 'set' (select and configure) or "
                             "'configure' (only change parameters)")
        params, values = list(params), list(values)
        if len(params) != len(values):
            raise ValueError(f"algorithm_control params has {len(params)} names but values has {len(values)}: "
                             "give one value per name")
        known = PARAMETERS[name]
        updates: dict[str, ParamValue] = {}
        for param, value in zip(params, values, strict=True):
            if param not in known:
                raise ValueError(f"algorithm_control parameter {param!r} is not a parameter of {name}; known: "
                                 f"{', '.join(known)}")
            if param in updates:
                raise ValueError(f"algorithm_control parameter {param!r} is given twice: give it once")
            check, what = known[param]
            try:
                updates[param] = check(value)
            except (TypeError, ValueError):
                raise ValueError(f"algorithm_control {name} parameter {param} is {value!r}: give {what}") from None
        done = []
        if name == "neural_network":
            model = self._model_request(updates, text_value, action)
            if model is not None:
                updates["model"] = str(model.path)
                self._models[model.role] = model
                done.append(f"loaded {model.path} for role {model.role!r} ({model.spec.n_neighbors} neighbours, "
                            f"{model.spec.n_obstacles} obstacles{', depth image' if model.spec.image else ''})")
        elif text_value:
            raise ValueError(f"algorithm_control text_value {text_value!r} means nothing to {name}: leave it empty")
        self._params[name].update(updates)
        if updates:
            done.insert(0, f"{name} parameters " + ", ".join(f"{k}={v}" for k, v in updates.items()))
        if action == "set":
            self._algorithm = name
            done.insert(0, f"{name} selected")
        return "; ".join(done) if done else f"{name}: nothing to change"

    def control_from_state(self, parameters: Mapping[str, object]) -> str:
        """Apply a mission algorithm_control state's `parameters` ({"name", "action", "params", "values"})."""
        if not isinstance(parameters, Mapping):
            raise ValueError(f"algorithm_control parameters is {parameters!r}: give an object with name, action, "
                             "params, values")
        for key in ("name", "action"):
            if key not in parameters:
                raise ValueError(f"algorithm_control parameters.{key} is missing: give it (e.g. \"name\": \"orca3\", "
                                 "\"action\": \"set\")")
        unknown = sorted(set(parameters) - {"name", "action", "params", "values", "text_value"})
        if unknown:
            raise ValueError(f"algorithm_control parameters.{unknown[0]} is unknown: known keys are name, action, "
                             "params, values, text_value")
        name, action = parameters["name"], parameters["action"]
        if not isinstance(name, str):
            raise ValueError(f"algorithm_control parameters.name is {name!r}: give one of simple, orca3d (or orca3), "
                             "neural_network")
        if not isinstance(action, str):
            raise ValueError(f"algorithm_control parameters.action is {action!r}: give 'set' or 'configure'")
        params, values = _state_list(parameters, "params"), _state_list(parameters, "values")
        names = [param for param in params if isinstance(param, str)]
        if len(names) != len(params):
            raise ValueError(f"algorithm_control parameters.params is {params!r}: give a list of parameter names")
        return self.control(name, action, names, values, str(parameters.get("text_value", "") or ""))

    def _model_request(self, updates: dict, text_value: str, action: str) -> NeuralModel | None:
        path = updates.get("model")
        text = text_value.strip()
        if path is not None and text and path != text:
            raise ValueError(f"algorithm_control neural_network has model {path!r} and text_value {text!r}: give "
                             "the model path once")
        path = path or text
        if not path:
            if action == "set" and not self._models:
                raise ValueError("algorithm_control neural_network needs a model: give its path in text_value or "
                                 "as the parameter 'model'")
            return None
        path = Path(path).expanduser()
        if not path.is_absolute() and self.model_dir is not None:
            path = self.model_dir / path
        try:
            return self._load_model(path)
        except ValueError:
            raise
        except ImportError as err:
            raise ValueError(f"algorithm_control neural_network: {path} needs torch, which does not import: "
                             f"{err}") from None

    # --- commands -----------------------------------------------------------------------------

    def release(self) -> None:
        """The control loop stopped stepping (a role ended): nobody sharing ORCA-3D's batcher waits for this UAV
        until its next ORCA-3D step."""
        self._orca.release()

    def velocity(self, view: WorldView, goal: Goal) -> Command:
        """The command for the UAV `view.own` towards `goal` with the current algorithm (module docstring)."""
        try:
            command = self._command(view, goal)
            if not (np.all(np.isfinite(command.velocity)) and math.isfinite(command.yaw_rate)):
                raise FloatingPointError(f"{command.algorithm} answered velocity {command.velocity.tolist()}, "
                                         f"yaw rate {command.yaw_rate}")
        except Exception as err:  # never let a control step die in flight: hover and say why
            message = f"{type(err).__name__}: {err}"
            if message != self._last_error:
                logger.error("UAV %s: navigation with %s failed, hovering: %s", view.own_id, self._algorithm,
                             message)
                self._last_error = message
            return Command(np.zeros(3), 0.0, self._algorithm, feasible=False, error=message)
        self._last_error = ""
        command.velocity = saturate(command.velocity, self.max_speed)  # the direction, hence the yaw rate, stays
        if command.teacher_velocity is not None:
            command.teacher_velocity = saturate(command.teacher_velocity, self.max_speed)
        return command

    def _preferred(self, view: WorldView, goal: Goal) -> np.ndarray:
        velocity, _ = simple_velocity(view.own, goal, self.max_speed, self._number_param("simple", "brakingDistance"),
                                      "none")
        return velocity

    def _yaw_rate(self, view: WorldView, goal: Goal, velocity: np.ndarray) -> float:
        return heading_rate(view.own.yaw, goal.yaw, velocity, self.heading, self.yaw_gain, self.max_yaw_rate)

    def _command(self, view: WorldView, goal: Goal) -> Command:
        algorithm = self._algorithm
        if algorithm == "neural_network" and goal.role == "basic_move":
            algorithm = "orca3d"
        if algorithm == "simple":
            velocity = self._preferred(view, goal)
            return Command(velocity, self._yaw_rate(view, goal, velocity), "simple")
        if algorithm == "orca3d":
            result = self._orca_result(view, goal)
            velocity = result.velocity
            return Command(velocity, self._yaw_rate(view, goal, velocity), "orca3d", result.feasible,
                           result.neighbors.ids, result.neighbors.obstacle_names)
        model = self._models.get(goal.role)
        if model is None:
            loaded = ", ".join(sorted(self._models)) or "none"
            raise LookupError(f"neural_network has no model for role {goal.role!r} (loaded: {loaded}); load one "
                              "with algorithm_control configure neural_network and the model path")
        velocity, neighbors = model.velocity(view, goal, self._number_param("neural_network", "neighborDist"))
        wanted = self._params["neural_network"]
        if not (wanted["teacher"] or wanted["fallback"]):
            return Command(velocity, self._yaw_rate(view, goal, velocity), "neural_network", True, neighbors.ids,
                           neighbors.obstacle_names)
        params = self.orca_params()
        teacher = self._orca_result(view, goal, params)
        fallback = bool(wanted["fallback"]) and self._collides(velocity, view, teacher, params)
        if fallback:
            velocity = teacher.velocity
        return Command(velocity, self._yaw_rate(view, goal, velocity), "neural_network", True, neighbors.ids,
                       neighbors.obstacle_names, teacher_velocity=teacher.velocity.copy(), fallback=fallback)

    def _orca_result(self, view: WorldView, goal: Goal, params: Params | None = None) -> OrcaResult:
        """ORCA-3D's step with its parameters as they stand (`params`: those, built already): what it flies,
        or the teacher's answer."""
        n_obstacles = self.params("orca3d")[ORCA_OBSTACLES]
        assert isinstance(n_obstacles, int)  # from _whole, or N_neighbors_aware's default, which is an int too
        if params is None:
            params = self.orca_params()
        return self._orca.velocity(view, self._preferred(view, goal), params, n_obstacles, self.safety_radius,
                                   self.max_speed)

    def _collides(self, velocity: np.ndarray, view: WorldView, teacher: OrcaResult, params: Params) -> bool:
        """Would `velocity` (saturated as it would be sent) collide within ORCA-3D's horizon (`params`, the
        teacher's) with what the teacher avoided?"""
        return would_collide(view, saturate(velocity, self.max_speed), teacher.neighbors, self.safety_radius,
                             params.agent_radius, params.time_horizon)


__all__ = ["ACTIONS", "ALGORITHMS", "Command", "NavigationInterface", "PARAMETERS", "canonical_name"]
