"""Fixtures of the magna_gs tests: a small valid mission to break, and a way to write missions to files."""
import copy
import json

import pytest

# A valid mission: spawn both agents, take off together, UAV 1 flies a path while UAV 2 follows it, both land.
BASE_MISSION = {
    "Agents_Config": [
        {"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]},
        {"ID": 2, "model": "iris", "mode": "sitl", "marker_color": [0, 255, 0, 0.5]},
    ],
    "State_Machine": [
        {"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
         "parameters": {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]],
                                          ["Ground_Station", "Agents_take_off", "matrix", [1, 0, 0]]]},
         "outcomes": {"completed": "1_take_off", "failed": "failed"}},
        {"type": "Concurrence", "name": "take_off", "ids": 1,
         "occurrencies": [{"type": "SimpleActionState", "state_type": "take_off", "name": "take_off", "ids": "all",
                           "ids_var": "agent", "parameters": {"height": 2}}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}},
         "outcomes": {"completed": "1_flight"}},
        {"type": "Concurrence", "name": "flight", "ids": 1, "outcome_cb": "collision_if_any_collided",
         "child_termination_cb": "all_at_one_collision",
         "occurrencies": [
             {"type": "SimpleActionState", "state_type": "follow_path", "name": "path", "ids": 1, "ids_var": "agent",
              "parameters": {"path": [{"definition": ["CentralZone", "Accessible", "random", 2]}]}},
             {"type": "SimpleActionState", "state_type": "follow_agent_ad", "name": "follow", "ids": 2,
              "ids_var": "agent", "parameters": {"target_ID": 1, "distance": 2.0}}],
         "occurrencies_outcome_map": {"completed": {"1_path": "succeeded"}},
         "outcomes": {"completed": "1_land", "collision": "1_land"}},
        {"type": "Concurrence", "name": "land", "ids": 1,
         "occurrencies": [{"type": "SimpleActionState", "state_type": "land", "name": "land", "ids": "all",
                           "ids_var": "agent"}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}},
         "outcomes": {"completed": "completed"}},
    ],
}


@pytest.fixture
def base_mission():
    """A fresh deep copy of BASE_MISSION to change."""
    return copy.deepcopy(BASE_MISSION)


@pytest.fixture
def write_mission(tmp_path):
    """write_mission(data, name="Test/Mission") -> the path of <tmp>/missions/<name>.json holding `data`."""
    def write(data, name="Test/Mission"):
        path = tmp_path / "missions" / f"{name}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(data if isinstance(data, str) else json.dumps(data, indent=1))
        return path
    return write
