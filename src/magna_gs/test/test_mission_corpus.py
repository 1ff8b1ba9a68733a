"""The real ROS-MAGNA missions: every one loads (legacy ones migrated, saying how), passes its world
check, builds, and runs with scripted UAVs through the branches the mission writes."""
import json
import re

import pytest

from magna_gs.mission.build import InertFactory, build_machine
from magna_gs.mission.loader import load_mission
from magna_gs.mission.model import ACTION_TYPES, CALLBACK_TYPES, FollowAgentADParams, TakeOffParams
from magna_gs.mission.scripted import ScriptedFactory
from magna_gs.mission.world_check import check_against_world, pose_definitions
from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world
from tests.support import CORPUS

MISSIONS = sorted((CORPUS / "Missions").glob("*/*.json")) or [CORPUS / "Missions" / "(corpus missing)"]
LEGACY_STATE_TYPES = {"new_world", "spawn_uavs", "follow_uav_ad", "follow_uav_ap"}


def readme_pairs():
    """(mission, world) from the table of the corpus README; 'any world' is taken as Gym/Empty."""
    pairs = []
    for line in (CORPUS / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and re.fullmatch(r"\w+/\w+", cells[0]):
            pairs.append((cells[0], "Gym/Empty" if cells[1] == "any world" else cells[1]))
    return pairs or [("(corpus missing)", "(corpus missing)")]


# The one README pair that does not fit: the world has two take-off cells, the mission spawns three agents
# (the mission resolves in Gym/Empty_4_Cylinders, which has three).
MISFITS = {("Gym/3UAVs_3paths_4_Cylinders", "Gym/Empty_4_Cylinders_1Obs"):
           "State_Machine[2].parameters.initial_poses[2][3]: GS4_Agents_take_off has no cell [2, 0, 0]"}


def legacy_markers(raw) -> list[str]:
    """What in the raw file is of the legacy schema, found independently of the migration code."""
    found = ["UAVs_Config"] if "UAVs_Config" in raw else []

    def walk(node):
        if node.get("state_type") in LEGACY_STATE_TYPES:
            found.append(node["state_type"])
        if node.get("ids_var") == "uav":
            found.append("ids_var uav")
        if "time" in node.get("parameters", {}):
            found.append("parameters.time")
        for child in node.get("occurrencies", []):
            walk(child)

    for node in raw["State_Machine"]:
        walk(node)
    return found


def mission_path(name):
    return CORPUS / "Missions" / f"{name}.json"


def resolved(name, seed=0):
    return resolve_world(load_world(CORPUS / "Worlds" / f"{name}.json", search_path=[]), seed)


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_corpus_mission_loads_and_legacy_ones_say_what_changed(path):
    raw = json.loads(path.read_text())
    loaded = load_mission(path)
    markers = legacy_markers(raw)
    legacy_changes = [c for c in loaded.changes if "occurrencies_outcome_map" not in c]
    assert bool(legacy_changes) == bool(markers), (markers, loaded.changes)
    if "UAVs_Config" in raw:
        assert "UAVs_Config -> Agents_Config" in loaded.changes
        assert loaded.mission.agents_key == "UAVs_Config"
    for marker in set(markers) & LEGACY_STATE_TYPES:
        assert any(f"state_type: {marker} -> " in c for c in loaded.changes)
    if "parameters.time" in markers:
        assert any(c.endswith(".parameters.time -> duration") for c in loaded.changes)
    # after migration only current state types are left, and the agents are those of the file
    types = {n.state_type for n in loaded.mission.nodes() if n.state_type}
    assert types <= set(ACTION_TYPES) | set(CALLBACK_TYPES)
    assert not types & LEGACY_STATE_TYPES
    agents = raw.get("Agents_Config") or raw["UAVs_Config"]
    assert loaded.mission.agent_ids == [a["ID"] for a in agents]


def test_a_legacy_mission_in_detail():
    loaded = load_mission(mission_path("Delivery/2UAVs_follow_ad_safe"))
    assert loaded.changes[:3] == ["UAVs_Config -> Agents_Config", "UAVs_Config[0].uav_manager_on_gs -> "
                                  "agent_manager_on_gs", "UAVs_Config[1].uav_manager_on_gs -> agent_manager_on_gs"]
    assert "State_Machine[5].occurrencies[1].occurrencies[1].state_type: follow_uav_ad -> follow_agent_ad" in \
        loaded.changes
    assert "State_Machine[5].occurrencies[1].occurrencies[1].parameters.time -> duration" in loaded.changes
    root = loaded.plan.root
    assert [s.label for s in root.children] == ["new world", "world_created_wait", "spawn_UAVs", "initial_wait",
                                                "1_take_off", "1_filmed_delivery", "1_hovering", "safety_wait",
                                                "1_save_csv", "1_all_land"]
    take_off = root.children[4]
    assert [c.label for c in take_off.children] == ["1_take_off", "2_take_off"]
    assert take_off.outcome_map == {"completed": {"1_take_off": "succeeded", "2_take_off": "succeeded"},
                                    "failed": {"1_take_off": "aborted", "2_take_off": "aborted"}}
    # the legacy spawn had no parameters: the migration wrote where the original put each agent
    spawn = root.children[2]
    assert spawn.ids == (1, 2)
    assert [d.as_list() for d in spawn.parameters.initial_poses] == [
        ["Ground_Station", "Agents_take_off", "matrix", [0, 0, 0]],
        ["Ground_Station", "Agents_take_off", "matrix", [1, 0, 0]]]
    follow = next(s for s in root.walk() if s.label == "2_filming_ad")
    assert follow.uav == 2 and follow.parameters == FollowAgentADParams(target_ID=1, distance=2.2, duration=300.0)


@pytest.mark.parametrize("mission,world", readme_pairs())
def test_every_readme_pair_passes_the_world_check(mission, world):
    loaded = load_mission(mission_path(mission))
    problems = check_against_world(loaded.mission, resolved(world))
    if (mission, world) in MISFITS:
        assert len(problems) == 1 and MISFITS[mission, world] in problems[0]
        assert check_against_world(loaded.mission, resolved("Gym/Empty_4_Cylinders")) == []
    else:
        assert problems == []
    if mission != "Gym/only_world":
        assert pose_definitions(loaded.mission)


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_corpus_mission_builds_and_runs_to_completed_when_all_goes_well(path):
    loaded = load_mission(path)
    inert = build_machine(loaded.mission, InertFactory(), loaded.plan)
    assert inert.get_registered_outcomes()[-1] == "preempted"
    factory = ScriptedFactory()
    machine = build_machine(loaded.mission, factory, loaded.plan)
    assert machine.execute() == "completed"
    ran = factory.ran
    assert {s.outcome for s in ran} <= {"succeeded", "completed"}
    actions = {(s.state_type, s.uav) for s in ran if s.kind == "SimpleActionState"}
    agents = loaded.mission.agent_ids
    if any(s.kind == "SimpleActionState" for s in ran):
        assert {("take_off", a) for a in agents} <= actions
        assert {("land", a) for a in agents} <= actions
        assert not any(s.state_type == "basic_move" for s in ran)  # the hovering safety branch is not taken


def steps_of(factory, uav):
    return [(s.json_path, s.state_type, s.outcome) for s in factory.ran if s.uav == uav]


def test_a_collision_in_the_filmed_delivery_goes_through_the_hovering_safety_branch():
    loaded = load_mission(mission_path("Delivery/2UAVs_follow_ap_safe"))
    first_leg = "State_Machine[6].occurrencies[0].occurrencies[0]"  # UAV 1's to_delivery_height
    factory = ScriptedFactory({(first_leg, 1): "collision"})
    assert build_machine(loaded.mission, factory).execute() == "completed"
    order = [(s.json_path, s.state_type, s.uav, s.ids) for s in factory.ran]
    # UAV 1 collided on its first leg and never flew the delivery itself
    assert steps_of(factory, 1)[1] == (first_leg, "follow_path", "collision")
    assert not any(p == "State_Machine[6].occurrencies[0].occurrencies[1]" for p, *_ in order)
    # both hovered (the hovering Concurrence), then the safety wait of 10 s, then save_csv and land for both
    hover = [i for i, step in enumerate(order) if step[1] == "basic_move"]
    assert sorted(order[i][2] for i in hover) == [1, 2]
    safety = next(i for i, s in enumerate(factory.ran) if s.json_path == "State_Machine[8]")
    assert factory.ran[safety].parameters.duration == 10.0 and safety > max(hover)
    lands = [i for i, step in enumerate(order) if step[1] == "land"]
    assert sorted(order[i][2] for i in lands) == [1, 2] and min(lands) > safety


def test_low_battery_takes_the_recharge_path_and_comes_back():
    loaded = load_mission(mission_path("Delivery/2UAVs_follow_ad_safe"))
    to_height = "State_Machine[5].occurrencies[0].occurrencies[0]"
    factory = ScriptedFactory({(to_height, 1): ["low_battery", "succeeded"]})
    assert build_machine(loaded.mission, factory).execute() == "completed"
    recharge = "State_Machine[5].occurrencies[0].occurrencies[3]"
    assert steps_of(factory, 1)[1:10] == [
        (to_height, "follow_path", "low_battery"),
        (f"{recharge}.occurrencies[0]", "follow_path", "succeeded"),  # to_home
        (f"{recharge}.occurrencies[1]", "land", "succeeded"),
        (f"{recharge}.occurrencies[3]", "take_off", "succeeded"),  # after the recharge wait
        (to_height, "follow_path", "succeeded"),  # back where it left
        ("State_Machine[5].occurrencies[0].occurrencies[1]", "follow_path", "succeeded"),  # the delivery
        ("State_Machine[5].occurrencies[0].occurrencies[2]", "follow_path", "succeeded"),  # home
        ("State_Machine[8].occurrencies[0]", "save_csv", "succeeded"),  # an action state in this legacy mission
        ("State_Machine[9].occurrencies[0]", "land", "succeeded"),
    ]
    waits = [s for s in factory.ran if s.json_path == f"{recharge}.occurrencies[2]"]
    assert len(waits) == 1 and waits[0].parameters.exit_type == "button"


def test_the_factory_gets_typed_parameters_uav_and_json_path():
    loaded = load_mission(mission_path("Gym/2UAVs_2paths_Central_Cylinder"))
    factory = ScriptedFactory()
    build_machine(loaded.mission, factory)
    take_offs = [(s.uav, s.parameters, s.json_path) for s in factory.made if s.state_type == "take_off"]
    assert take_offs == [(1, TakeOffParams(3.0), "State_Machine[6].occurrencies[0]"),
                         (2, TakeOffParams(3.0), "State_Machine[6].occurrencies[0]")]
    control = next(s for s in factory.made if s.state_type == "algorithm_control")
    assert control.ids == (1, 2) and control.parameters.name == "orca3"
    assert control.parameters.params[:2] == ("N_neighbors_aware", "timeStep")
    worlds = [s.parameters for s in factory.made if s.state_type == "world_config"]
    assert [(w.action, w.id) for w in worlds] == [("spawn", "1"), ("add", None), ("delete", "1")]
    assert worlds[1].world_part_def.from_hyperparameters
    save = next(s for s in factory.made if s.state_type == "save_csv")
    assert save.kind == "CBState" and save.ids == (1, 2)  # one CBState for every agent, named save_csv
