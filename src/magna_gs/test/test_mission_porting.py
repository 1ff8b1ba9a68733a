"""Constructs of the original ROS-MAGNA's missions, one small mission each (written here, in the file's shape):
what the original tolerated loads with one warning (file, JSON path, what MAGNA does) and strict mode refuses it;
what crashed the original is refused with file, JSON path and the fix; older schemas migrate, saying so."""
import pytest

from magna_gs.mission.build import AbsentUavState, build_machine
from magna_gs.mission.loader import STRICT_NOTE, load_mission
from magna_gs.mission.model import FollowPathParams, MissionError
from magna_gs.mission.scripted import ScriptedFactory


def agent(n, **extra):
    return {"ID": n, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5], **extra}


def spawn(n_agents, then):
    return {"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
            "parameters": {"initial_poses": [["Ground_Station", "Agents_take_off", "matrix", [i, 0, 0]]
                                             for i in range(n_agents)]},
            "outcomes": {"completed": then}}


def action(state_type, name, uav, **parameters):
    return {"type": "SimpleActionState", "state_type": state_type, "name": name, "ids": uav, "ids_var": "agent",
            "parameters": parameters}


def hover(uav):
    return action("basic_move", "hover", uav, move_type="translation", dynamic="position", direction="left", value=0.0)


def path(*definitions):
    return [{"definition": d} for d in definitions]


def only_warning(loaded, where):
    found = [w for w in loaded.warnings if w.startswith(where)]
    assert len(found) == 1, loaded.warnings
    return found[0]


def refused_in_strict_mode(path_, where):
    with pytest.raises(MissionError) as error:
        load_mission(path_, strict=True)
    assert any(p.startswith(where) and p.endswith(STRICT_NOTE) for p in error.value.problems), error.value.problems


# --- a safety branch written for more UAVs than the mission configures (GAUSSUseCase1 one-UAV missions) -----------

ONE_UAV_SAFETY_BRANCH = {
    "Agents_Config": [agent(1)],
    "State_Machine": [
        spawn(1, "1_inspection"),
        {"type": "Concurrence", "name": "inspection", "ids": 1,
         "occurrencies": [action("follow_path", "survey", 1,
                                 path=path(["Zone", "Box", "matrix", [0, 0, 0]]))],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "collision": {"all": "collision"}},
         "outcomes": {"completed": "completed", "collision": "1_hovering"}},
        {"type": "Concurrence", "name": "hovering", "ids": 1,
         "occurrencies": [hover(1), hover(2), hover(3)],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}, "collision": {"all": "collision"}},
         "outcomes": {"completed": "failed", "collision": "failed"}},
    ],
}


def test_a_safety_branch_naming_unconfigured_uavs_loads_with_one_warning_each(write_mission):
    path_ = write_mission(ONE_UAV_SAFETY_BRANCH)
    loaded = load_mission(path_)
    warning = only_warning(loaded, f"{path_}: State_Machine[2].occurrencies[1].ids: UAV 2 not in Agents_Config "
                                   "(IDs 1)")
    assert "'2_hover'" in warning and "ends 'aborted' at once" in warning
    only_warning(loaded, f"{path_}: State_Machine[2].occurrencies[2].ids: UAV 3 not in Agents_Config")
    hovering = loaded.plan.root.children[2]
    assert [(c.label, c.absent) for c in hovering.children] == [("1_hover", False), ("2_hover", True),
                                                                ("3_hover", True)]
    refused_in_strict_mode(path_, f"{path_}: State_Machine[2].occurrencies[1].ids: UAV 2 not in Agents_Config")


def test_the_built_machine_runs_through_that_branch_without_waiting_for_absent_uavs(write_mission):
    loaded = load_mission(write_mission(ONE_UAV_SAFETY_BRANCH))
    factory = ScriptedFactory({"State_Machine[1].occurrencies[0]": "collision"})  # the survey collides
    machine = build_machine(loaded.mission, factory)
    assert machine.execute() == "failed"  # the hovering Concurrence ended and its transition was taken
    # the factory (the ground station's, in a real run) never made a state for UAVs 2 and 3 ...
    assert {s.uav for s in factory.made if s.kind == "SimpleActionState"} == {1}
    assert [(s.state_type, s.uav, s.outcome) for s in factory.ran] == [
        ("spawn_agents", None, "completed"), ("follow_path", 1, "collision"), ("basic_move", 1, "succeeded")]
    # ... theirs ended 'aborted' at once, so no outcome-map entry held and the default outcome decided
    hovering = machine["1_hovering"]
    assert isinstance(hovering["2_hover"], AbsentUavState) and isinstance(hovering["3_hover"], AbsentUavState)


# --- an outcome-map entry waiting for an outcome a child never gives (safety/follow_paths_sbys) --------------------

def test_an_outcome_map_entry_no_child_can_satisfy_is_left_out_with_a_warning(write_mission):
    data = {"Agents_Config": [agent(1), agent(2)],
            "State_Machine": [
                spawn(2, "1_together"),
                {"type": "Concurrence", "name": "together", "ids": 1,
                 "occurrencies": [action("take_off", "up", "all", height=2)],
                 "occurrencies_outcome_map": {"completed": {"all": "completed"}, "failed": {"all": "aborted"}},
                 "outcomes": {"completed": "completed", "failed": "failed"}}]}
    data["State_Machine"][1]["occurrencies"][0]["ids"] = "all"
    path_ = write_mission(data)
    loaded = load_mission(path_)
    warning = only_warning(loaded, f"{path_}: State_Machine[1].occurrencies_outcome_map.completed: never satisfied: "
                                   "'1_up' never ends with 'completed'")
    assert "left out" in warning and "or 'completed')" in warning
    assert loaded.plan.root.children[1].outcome_map == {"failed": {"1_up": "aborted", "2_up": "aborted"}}
    assert build_machine(loaded.mission, ScriptedFactory()).execute() == "completed"  # the default outcome
    refused_in_strict_mode(path_, f"{path_}: State_Machine[1].occurrencies_outcome_map.completed")


# --- agents: an ID given twice (SolarPlant/3UAVs_inspection), DJI-only keys (safety, February 2019) ----------------

def test_an_id_given_twice_becomes_the_entrys_position_as_the_original_numbered_agents(write_mission):
    data = {"UAVs_Config": [agent(1), agent(2), agent(2)],
            "State_Machine": [spawn(3, "3_up"),
                              {**action("take_off", "up", 3, height=2), "outcomes": {"succeeded": "completed"}}]}
    path_ = write_mission(data)
    loaded = load_mission(path_)
    assert loaded.mission.agent_ids == [1, 2, 3]
    warning = only_warning(loaded, f"{path_}: UAVs_Config[2].ID: 2 is already the ID of UAVs_Config[1]")
    assert "numbered agents by position, so this one is agent 3" in warning
    refused_in_strict_mode(path_, f"{path_}: UAVs_Config[2].ID")


def test_an_id_given_twice_whose_position_is_taken_is_refused(write_mission):
    data = {"Agents_Config": [agent(2), agent(2)], "State_Machine": [spawn(2, "completed")]}
    path_ = write_mission(data)
    with pytest.raises(MissionError) as error:
        load_mission(path_)
    assert error.value.problems == [f"{path_}: Agents_Config[1].ID: 2 is already the ID of Agents_Config[0]; every "
                                    "agent needs its own ID"]


def test_dji_settings_in_an_agent_entry_are_ignored_with_a_warning(write_mission):
    data = {"UAVs_Config": [agent(1, laser_altimeter=False, self_arming=True)],
            "State_Machine": [spawn(1, "completed")]}
    path_ = write_mission(data)
    loaded = load_mission(path_)
    assert "MAGNA's UAVs have no such setting, ignored" in only_warning(loaded,
                                                                        f"{path_}: UAVs_Config[0].laser_altimeter")
    only_warning(loaded, f"{path_}: UAVs_Config[0].self_arming")
    refused_in_strict_mode(path_, f"{path_}: UAVs_Config[0].laser_altimeter")


# --- three-item pose definitions (SolarPlant, February-March 2019): a migration -------------------------------------

def test_three_item_path_and_random_definitions_migrate_to_four(write_mission):
    data = {"Agents_Config": [agent(1)],
            "State_Machine": [spawn(1, "1_inspect"),
                              {**action("follow_path", "inspect", 1,
                                        path=path(["Zone", "Box", "random"], ["Panels", "Inspection", "path"])),
                               "outcomes": {"succeeded": "completed"}}]}
    path_ = write_mission(data)
    loaded = load_mission(path_)
    assert not [w for w in loaded.warnings if "definition" in w]  # a migration is reported as a change
    params = loaded.mission.root[1].parameters
    assert isinstance(params, FollowPathParams)
    assert [d.as_list() for d in params.path] == [["Zone", "Box", "random", 1], ["Panels", "Inspection", "path", None]]
    assert loaded.changes == [
        "State_Machine[1].parameters.path[0].definition: [Zone, Box, random] -> fourth item 1 (one random pose, what "
        "a definition of three items meant)",
        "State_Machine[1].parameters.path[1].definition: [Panels, Inspection, path] -> fourth item null (the "
        "geometry's zigzag path, what a definition of three items meant)"]


# --- what crashed the original: refused before anything starts, with file, JSON path and fix ----------------------

def test_fewer_initial_poses_than_agents_is_refused(write_mission):
    # the original spawned every agent from initial_poses[i] and failed with an index error at the second agent
    data = {"Agents_Config": [agent(1), agent(2)], "State_Machine": [spawn(1, "completed")]}
    path_ = write_mission(data)
    with pytest.raises(MissionError) as error:
        load_mission(path_)
    assert error.value.problems == [f"{path_}: State_Machine[0].parameters.initial_poses: 1 pose(s) for 2 agents "
                                    "(1, 2); give one [volume, geometry, kind, arg] per agent, in Agents_Config order"]


def test_spawn_agents_without_initial_poses_is_refused(write_mission):
    # the original called its spawn callback without the initial_poses argument (a TypeError at run time)
    data = {"Agents_Config": [agent(1)],
            "State_Machine": [{"type": "CBState", "state_type": "spawn_agents", "name": "spawn",
                               "outcomes": {"completed": "completed"}}]}
    path_ = write_mission(data)
    with pytest.raises(MissionError) as error:
        load_mission(path_)
    assert any(p.startswith(f"{path_}: State_Machine[0].parameters.initial_poses: missing;") and "[volume, geometry"
               in p for p in error.value.problems), error.value.problems


# --- the January 2019 schema: the file is the state list, leaves named by their type -------------------------------

def test_a_state_list_gets_agents_and_leaves_named_by_type_get_their_state_type(write_mission):
    states = [
        {"type": "CBState", "name": "new_world", "outcomes": {"completed": "spawn_uavs"}},
        {"type": "CBState", "name": "spawn_uavs", "outcomes": {"completed": "1_take_off"}},
        {"type": "Concurrence", "name": "take_off", "ids": 1,
         "occurrencies": [{"type": "SimpleActionState", "name": "take_off", "ids": [1, 2], "ids_var": "uav",
                           "parameters": {"height": 2}}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}}, "outcomes": {"completed": "completed"}}]
    path_ = write_mission(states)
    loaded = load_mission(path_)
    assert loaded.mission.agent_ids == [1, 2] and {a.model for a in loaded.mission.agents} == {"iris"}
    assert loaded.changes[0].startswith("the file is the state list alone (January 2019")
    assert "[2].occurrencies[0].state_type: added 'take_off' (its name, which named the type then)" in loaded.changes
    assert [s.state_type for s in loaded.plan.root.leaves()] == ["world_config", "spawn_agents", "take_off",
                                                                 "take_off"]
    # findings name the file's own paths (no State_Machine key in it)
    states[2]["occurrencies"][0]["parameters"]["height"] = -1
    with pytest.raises(MissionError) as error:
        load_mission(write_mission(states))
    assert error.value.problems[0].startswith(f"{path_}: [2].occurrencies[0].parameters.height: expected a height")
