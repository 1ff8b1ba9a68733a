"""Parameters from missions, and bad input refused with the same sentence by C++ and Python."""
import json
import math

import numpy as np
import pytest

from magna_orca_cpp import native, reference
from magna_orca_cpp.model import Agent, Params, agent_rows
from magna_orca_cpp.validation import OrcaInputError
from tests.support import CORPUS


def _algorithm_control_states(node):
    if isinstance(node, dict):
        if node.get("state_type") == "algorithm_control" and node.get("parameters", {}).get("name") == "orca3":
            yield node["parameters"]
        for value in node.values():
            yield from _algorithm_control_states(value)
    elif isinstance(node, list):
        for value in node:
            yield from _algorithm_control_states(value)


def test_algorithm_control_of_the_original_missions_becomes_params():
    found = 0
    for path in sorted((CORPUS / "Missions").rglob("*.json")):
        for state in _algorithm_control_states(json.loads(path.read_text())):
            params = Params.from_algorithm_control(dict(zip(state["params"], state["values"], strict=True)))
            for name, value in zip(state["params"], state["values"], strict=True):
                field = {"N_neighbors_aware": "max_neighbors", "timeStep": "time_step", "neighborDist": "neighbor_dist",
                         "timeHorizon": "time_horizon", "agent_radius": "agent_radius", "maxSpeed": "max_speed"}[name]
                assert getattr(params, field) == value, f"{path.name}: {name}"
            assert isinstance(params.max_neighbors, int)
            found += 1
    assert found >= 3, "the corpus has orca3 algorithm_control states"


def test_unknown_algorithm_control_name_is_refused_with_the_known_ones():
    with pytest.raises(ValueError, match="'timehorizon' is not an ORCA-3D parameter; known: N_neighbors_aware"):
        Params.from_algorithm_control({"timehorizon": 3.0})


GOOD = Agent([0, 0, 0], [1, 0, 0], [1, 0, 0], 0.5, 2.0)
NEIGHBOR = Agent([3, 0, 0], [-1, 0, 0], [-1, 0, 0], 0.5, 2.0)


@pytest.mark.parametrize(("agent", "neighbors", "params", "expected"), [
    (Agent([math.nan, 0, 0]), [NEIGHBOR], Params(), "agent.position.x is nan"),
    (GOOD, [NEIGHBOR, Agent([0, 0, 0], [0, math.inf, 0])], Params(), "neighbors[1].velocity.y is inf"),
    (GOOD, [Agent([1, 1, 1], radius=-1.0)], Params(), "neighbors[0].radius is -1"),
    (GOOD, [NEIGHBOR], Params(time_horizon=0.0), "params.time_horizon (timeHorizon) is 0"),
    (GOOD, [NEIGHBOR], Params(time_step=-0.1), "params.time_step (timeStep) is -0.1"),
    (GOOD, [NEIGHBOR], Params(neighbor_dist=-1.0), "params.neighbor_dist (neighborDist) is -1: give a finite"),
    (GOOD, [NEIGHBOR], Params(max_speed=math.nan), "params.max_speed (maxSpeed) is nan"),
    (Agent([0, 0, 0]), [NEIGHBOR], Params(agent_radius=0.0), "agent.radius is 0 and params.agent_radius is 0"),
])
def test_bad_input_gets_the_same_named_error_from_both(agent, neighbors, params, expected):
    messages = []
    for solver in (native, reference):
        with pytest.raises(OrcaInputError) as caught:
            solver.new_velocity(agent, neighbors, params)
        messages.append(str(caught.value))
        assert expected in messages[-1]
    assert messages[0] == messages[1]


def test_good_input_after_bad_input_still_solves():
    with pytest.raises(OrcaInputError):
        native.new_velocity(GOOD, [NEIGHBOR], Params(time_horizon=math.nan))
    solved = native.new_velocity(GOOD, [NEIGHBOR], Params())
    assert np.all(np.isfinite(solved.velocity))


def test_agent_rows_are_each_agents_row():
    agents = [Agent([1, 2, 3], [4, 5, 6], [7, 8, 9], 0.5, 2.5), Agent([-1, 0, 1e-300], radius=0, cooperative=False)]
    np.testing.assert_array_equal(agent_rows(agents), np.stack([a.row() for a in agents]))
    assert agent_rows([]).shape == (0, 12)
