"""algorithm_control on the NAI: names, actions, parameters, the corpus missions, and commands."""
import json
import logging

import numpy as np
import pytest

from magna_orca_cpp.model import ALGORITHM_CONTROL_NAMES, Params
from magna_uav.nai import Goal, NavigationInterface
from magna_uav.nai.interface import PARAMETERS, canonical_name
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, WorldView
from tests.support import CORPUS


def nai(**kwargs):
    return NavigationInterface(2.0, 0.3, solver=ReferenceSolver(), **kwargs)


def corpus_controls():
    """(file name, parameters) of every algorithm_control state in the corpus missions."""
    found = []

    def walk(node, source):
        if isinstance(node, dict):
            if node.get("state_type") == "algorithm_control":
                found.append((source, node["parameters"]))
            for value in node.values():
                walk(value, source)
        elif isinstance(node, list):
            for value in node:
                walk(value, source)

    for path in sorted((CORPUS / "Missions").rglob("*.json")):
        walk(json.loads(path.read_text()), path.name)
    return found


def test_the_corpus_algorithm_controls_apply():
    controls = corpus_controls()
    assert len(controls) >= 5, f"expected the corpus' algorithm_control states under {CORPUS / 'Missions'}"
    seen = set()
    for source, parameters in controls:
        nav = nai()
        message = nav.control_from_state(parameters)
        assert nav.algorithm == "orca3d", source
        assert message.startswith("orca3d selected"), message
        params = nav.params()
        for name, value in zip(parameters["params"], parameters["values"], strict=True):
            assert params[name] == value, (source, name)
        seen.add(tuple(parameters["params"]))
    assert ("N_neighbors_aware",) in seen
    assert ("N_neighbors_aware", "timeStep", "neighborDist", "timeHorizon", "agent_radius", "maxSpeed") in seen


def test_corpus_values_reach_the_solver_parameters():
    nav = nai()
    nav.control("orca3", "set", ["N_neighbors_aware", "timeStep", "neighborDist", "timeHorizon", "agent_radius",
                                 "maxSpeed"], [2, 0.01666, 6.0, 5.0, 0.5, 2.0])
    assert nav.orca_params() == Params(max_neighbors=2, time_step=0.01666, neighbor_dist=6.0, time_horizon=5.0,
                                       agent_radius=0.5, max_speed=2.0)
    assert isinstance(nav.orca_params().max_neighbors, int)
    assert nav.params("orca3d")["N_obstacles_aware"] == 2


def test_orca_parameters_are_the_solver_names_plus_the_obstacle_count():
    assert set(PARAMETERS["orca3d"]) == set(ALGORITHM_CONTROL_NAMES) | {"N_obstacles_aware"}


def test_set_selects_configure_only_tunes_and_names_are_aliased():
    nav = nai()
    assert nav.algorithm == "simple"
    assert nav.control("orca3d", "configure", ["timeHorizon"], [3.0]) == "orca3d parameters timeHorizon=3.0"
    assert nav.algorithm == "simple" and nav.params("orca3")["timeHorizon"] == 3.0
    assert nav.control("orca3", "set") == "orca3d selected"
    assert nav.algorithm == "orca3d" and nav.params()["timeHorizon"] == 3.0  # kept: set only applies what it gives
    nav.control("simple", "set", ["brakingDistance"], [4.0])
    assert nav.algorithm == "simple" and nav.params() == {"brakingDistance": 4.0}
    assert canonical_name("orca3") == canonical_name("orca3d") == "orca3d"
    assert nai().params("simple") == {"brakingDistance": 2.0}  # max_speed * 1 s


@pytest.mark.parametrize("call,message", [
    (("rvo2", "set"), "algorithm_control name 'rvo2' is unknown: give one of simple, orca3d (or orca3), "
                      "neural_network"),
    (("orca3", "select"), "algorithm_control action 'select' is unknown: give 'set' (select and configure) or "
                          "'configure' (only change parameters)"),
    (("orca3", "set", ["timeHorizon", "timeStep"], [1.0]), "params has 2 names but values has 1"),
    (("orca3", "set", ["horizon"], [1.0]), "algorithm_control parameter 'horizon' is not a parameter of orca3d; known: "
                                           "N_neighbors_aware, N_obstacles_aware, timeStep, neighborDist, "
                                           "timeHorizon, agent_radius, maxSpeed"),
    (("simple", "set", ["timeHorizon"], [1.0]), "'timeHorizon' is not a parameter of simple; known: brakingDistance"),
    (("orca3", "set", ["timeHorizon"], [-1.0]), "orca3d parameter timeHorizon is -1.0: give a positive number of "
                                                "seconds"),
    (("orca3", "set", ["N_neighbors_aware"], [1.5]), "N_neighbors_aware is 1.5: give a whole number >= 0"),
    (("orca3", "set", ["neighborDist"], [float("nan")]), "neighborDist is nan"),
    (("orca3", "set", ["maxSpeed"], ["fast"]), "maxSpeed is 'fast': give a finite speed >= 0 in m/s"),
    (("orca3", "set", ["maxSpeed"], [True]), "maxSpeed is True"),
    (("orca3", "set", ["timeStep", "timeStep"], [0.1, 0.2]), "'timeStep' is given twice"),
    (("orca3", "set", [], [], "model.pt"), "text_value 'model.pt' means nothing to orca3d"),
    (("neural_network", "set", ["model"], [3.0]), "neural_network parameter model is 3.0: give the path"),
])
def test_bad_requests_are_refused_naming_what_and_change_nothing(call, message):
    nav = nai()
    nav.control("orca3", "configure", ["timeHorizon"], [4.0])
    before = {name: nav.params(name) for name in PARAMETERS}
    with pytest.raises(ValueError) as err:
        nav.control(*call)
    assert message in str(err.value)
    assert nav.algorithm == "simple"
    assert {name: nav.params(name) for name in PARAMETERS} == before


def test_a_request_is_applied_whole_or_not_at_all():
    nav = nai()
    with pytest.raises(ValueError, match="timeStep is 0"):
        nav.control("orca3", "set", ["timeHorizon", "timeStep"], [9.0, 0.0])
    assert nav.params("orca3d")["timeHorizon"] == 5.0 and nav.algorithm == "simple"


@pytest.mark.parametrize("parameters,message", [
    ({"action": "set"}, "parameters.name is missing"),
    ({"name": "orca3", "action": "set", "params": "timeStep", "values": [1]}, "parameters.params is 'timeStep': "
                                                                               "give a list"),
    ({"name": "orca3", "action": "set", "value": [1]}, "parameters.value is unknown"),
    (["orca3"], "give an object with name, action, params, values"),
    ({"name": 3, "action": "set"}, "parameters.name is 3: give one of simple"),
    ({"name": "orca3", "action": 1}, "parameters.action is 1: give 'set' or 'configure'"),
    ({"name": "orca3", "action": "set", "params": (3,), "values": (1,)}, "parameters.params is (3,): give a list of "
                                                                         "parameter names"),
])
def test_malformed_state_parameters_are_refused(parameters, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        nai().control_from_state(parameters)


def test_constructor_checks_the_airframe_values():
    with pytest.raises(ValueError, match="NavigationInterface max_speed is 0"):
        NavigationInterface(0, 0.3)
    with pytest.raises(ValueError, match="NavigationInterface safety_radius is -1"):
        NavigationInterface(1.0, -1)
    with pytest.raises(ValueError, match="heading is 'spin'"):
        NavigationInterface(1.0, 0.3, heading="spin")


def one_uav(yaw=0.0):
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 5], orientation=[0, 0, np.sin(yaw / 2), np.cos(yaw / 2)]))
    return view


def test_simple_commands_are_saturated_and_carry_the_heading():
    nav = nai(heading="travel", max_yaw_rate=0.5)
    command = nav.velocity(one_uav(), Goal([0, 10, 5]))
    assert command.algorithm == "simple" and command.feasible and command.neighbors == () and not command.error
    np.testing.assert_allclose(command.velocity, [0, 2, 0])
    assert command.yaw_rate == pytest.approx(0.5)
    command = nai().velocity(one_uav(), Goal([1, 0, 5], role="agent_ap", velocity=[3, 0, 0], offset=[0, 0, 0]))
    assert np.linalg.norm(command.velocity) == pytest.approx(2.0)


def test_no_own_pose_gives_a_hover_with_a_logged_error(caplog):
    with caplog.at_level(logging.ERROR, logger="magna_uav.nai"):
        command = nai().velocity(WorldView(4), Goal([1, 0, 5]))
    assert not command.velocity.any() and command.yaw_rate == 0.0 and not command.feasible
    assert "/uav_4/ual/pose" in command.error
    assert "UAV 4: navigation with simple failed, hovering" in caplog.text


def test_errors_are_logged_again_only_when_the_reason_changes(caplog):
    nav = nai()
    with caplog.at_level(logging.ERROR, logger="magna_uav.nai"):
        for _ in range(3):
            nav.velocity(WorldView(4), Goal([1, 0, 5]))
        nav.velocity(one_uav(), Goal([1, 0, 5]))  # recovers
        nav.velocity(WorldView(4), Goal([1, 0, 5]))
    assert len(caplog.records) == 2
