"""migrate: legacy -> current in one step, saying what changed, never touching its input."""
import copy

from magna_gs.mission.migrate import migrate

LEGACY = {
    "UAVs_Config": [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [1, 2, 3, 1], "uav_manager_on_gs": True},
                    {"ID": 2, "model": "iris", "mode": "sitl", "marker_color": [1, 2, 3, 1]}],
    "State_Machine": [
        {"type": "CBState", "state_type": "new_world", "name": "new world", "outcomes": {"completed": "spawn"}},
        {"type": "CBState", "state_type": "spawn_uavs", "name": "spawn", "outcomes": {"completed": "pause"}},
        {"type": "CBState", "state_type": "wait", "name": "pause", "parameters": {"duration": 2},
         "outcomes": {"completed": "1_go"}},
        {"type": "Concurrence", "name": "go", "ids": 1, "occurrencies": [
            {"type": "SimpleActionState", "state_type": "follow_uav_ap", "name": "follow", "ids": 2, "ids_var": "uav",
             "parameters": {"target_ID": 1, "pos": [1, 0, 0], "time": 30}},
            {"type": "CBState", "state_type": "save_csv", "name": "save", "ids": "all", "ids_var": "agent"}],
         "occurrencies_outcome_map": {"completed": {"2_follow": "succeeded", "save": "succeeded"},
                                      "failed": {"all": "aborted"}},
         "outcomes": {"completed": "completed"}},
    ],
}


def test_the_legacy_schema_becomes_the_current_one_and_every_change_is_listed():
    before = copy.deepcopy(LEGACY)
    result = migrate(LEGACY)
    assert LEGACY == before  # the input is untouched
    data = result.data
    assert list(data) == ["Agents_Config", "State_Machine"]
    assert data["Agents_Config"][0] == {"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [1, 2, 3, 1],
                                        "agent_manager_on_gs": True}
    new_world, spawn, pause, go = data["State_Machine"]
    assert new_world["state_type"] == "world_config"
    assert new_world["parameters"] == {"action": "spawn", "id": 1, "world_part_def": "from_hyperparameters"}
    assert spawn["state_type"] == "spawn_agents"
    assert spawn["parameters"] == {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]],
                                                     ["Ground_Station", "Agents_take_off", "matrix", [1, 0, 0]]]}
    assert pause["parameters"] == {"duration": 2, "exit_type": "time"}
    follow, save = go["occurrencies"]
    assert (follow["state_type"], follow["ids_var"]) == ("follow_agent_ap", "agent")
    assert follow["parameters"] == {"target_ID": 1, "pos": [1, 0, 0], "duration": 30}
    # conditions on the CBState take its vocabulary; those on the action state keep theirs; "all" mixes both: kept
    assert go["occurrencies_outcome_map"] == {"completed": {"2_follow": "succeeded", "save": "completed"},
                                              "failed": {"all": "aborted"}}
    assert [c.split(":")[0].split(" ")[0] for c in result.changes] == [
        "UAVs_Config", "UAVs_Config[0].uav_manager_on_gs", "State_Machine[0].state_type",
        "State_Machine[1].state_type", "State_Machine[2].parameters.exit_type",
        "State_Machine[3].occurrencies[0].state_type", "State_Machine[3].occurrencies[0].ids_var",
        "State_Machine[3].occurrencies[0].parameters.time", "State_Machine[3].occurrencies_outcome_map.completed.save"]
    assert "State_Machine[3].occurrencies[0].state_type: follow_uav_ap -> follow_agent_ap" in result.changes
    assert "State_Machine[3].occurrencies[0].parameters.time -> duration" in result.changes


def test_paths_of_renamed_keys_map_back_to_the_file():
    result = migrate(LEGACY)
    assert result.original_path("Agents_Config[1].model") == "UAVs_Config[1].model"
    assert result.original_path("Agents_Config[0].agent_manager_on_gs") == "UAVs_Config[0].uav_manager_on_gs"
    assert result.original_path("State_Machine[3].occurrencies[0].parameters.duration") == \
        "State_Machine[3].occurrencies[0].parameters.time"
    assert result.original_path("State_Machine[3].occurrencies[0].parameters.pos") == \
        "State_Machine[3].occurrencies[0].parameters.pos"


def test_a_current_mission_and_garbage_pass_unchanged():
    current = {"Agents_Config": [], "State_Machine": [{"type": "CBState", "state_type": "wait", "name": "w",
                                                       "parameters": {"exit_type": "time", "duration": 1}}]}
    result = migrate(current)
    assert result.data == current and result.changes == [] and not result.changed
    for garbage in ([], "text", {"State_Machine": "x"}, {"State_Machine": [3, {"occurrencies": 4}]}):
        assert migrate(garbage).data == garbage
