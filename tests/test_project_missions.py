"""The project's own missions (missions/<mission>/<submission>.json) against the worlds they are written for.

missions/README.md pairs each mission with a world in its table; these tests read that
table, so a mission added without a line there, or a line naming a file that is gone,
fails here. Every mission must load (migration, parsing, validation: no problem and no
warning), build into a state machine, and resolve every place it names (spawn poses,
path waypoints) in its world, as `magna mission check MISSION --world WORLD` does.
tests/test_missions_fly.py flies every one of them to its end (or names the test that does).
"""
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = ROOT / "missions"
WORLDS = ROOT / "worlds"
README = MISSIONS / "README.md"
SEEDS = (0, 1, 2)  # the world's random pose sets and obstacles change with the seed

# A table row: | `Mission/Submission` | `World/Subworld` | ...
ROW = re.compile(r"^\|\s*`(?P<mission>[^`]+)`\s*\|\s*`(?P<world>[^`]+)`\s*\|")


def readme_pairs() -> dict[str, str]:
    pairs: dict[str, str] = {}
    for line in README.read_text().splitlines():
        match = ROW.match(line)
        if match:
            assert match["mission"] not in pairs, f"missions/README.md lists {match['mission']} twice"
            pairs[match["mission"]] = match["world"]
    return pairs


def mission_files() -> list[str]:
    return sorted(str(p.relative_to(MISSIONS).with_suffix("")) for p in MISSIONS.glob("*/*.json"))


PAIRS = readme_pairs()


def test_the_readme_table_lists_every_mission_file_and_nothing_else():
    assert mission_files(), "no mission files in missions/"
    assert sorted(PAIRS) == mission_files()


@pytest.mark.parametrize("world", sorted(set(PAIRS.values())))
def test_every_world_of_the_table_exists(world):
    assert (WORLDS / f"{world}.json").is_file(), f"missions/README.md names world {world}: no worlds/{world}.json"


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_mission_loads_builds_and_resolves_in_its_world(name):
    from magna_gs.mission.build import InertFactory, build_machine
    from magna_gs.mission.loader import load_mission
    from magna_gs.mission.world_check import check_against_world, pose_definitions
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world

    loaded = load_mission(MISSIONS / f"{name}.json")  # MissionError lists every problem
    assert loaded.changes == [], "written in the current schema: nothing to migrate"
    assert loaded.warnings == []
    assert "completed" in loaded.plan.outcomes
    build_machine(loaded.mission, InertFactory(), loaded.plan)
    assert pose_definitions(loaded.mission), "a mission of the project flies somewhere in its world"

    world = load_world(WORLDS / f"{PAIRS[name]}.json")
    for seed in SEEDS:
        assert check_against_world(loaded.mission, resolve_world(world, seed), seed) == [], f"seed {seed}"


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_mission_ends_completed_normally_and_fails_through_the_safety_branch(name):
    """The top-level machine reaches `completed` on the nominal path and `failed` through the safety landing."""
    from magna_gs.mission.loader import load_mission

    plan = load_mission(MISSIONS / f"{name}.json").plan
    states = {state.label: state for state in plan.root.children}
    for label in ("1_safety_hover", "safety_wait", "safety_save_csv", "1_safety_land"):
        assert label in states, f"no {label} in the safety branch"
    assert set(states["1_safety_land"].transitions.values()) == {"failed"}
    assert "completed" in states["delete_world"].transitions.values()
    flies = ("follow_path", "follow_agent_ad", "follow_agent_ap", "take_off")
    flying = [s for s in plan.root.walk()
              if s.kind == "Concurrence" and any(leaf.state_type in flies for leaf in s.leaves())]
    waits_for_operator = any(s.state_type == "wait" and s.node.parameters.exit_type == "button"
                             for s in plan.root.walk())
    assert flying or waits_for_operator, "nothing flies, and no operator is waited for to fly it"
    for state in flying:
        assert state.node.outcome_cb == "collision_if_any_collided", state.label
        assert state.node.child_termination_cb == "all_at_one_collision", state.label
        assert state.transitions.get("collision") == "1_safety_hover", state.label


def test_the_default_mission_uses_orca_for_two_uavs():
    from magna_gs.mission.loader import load_mission
    from magna_gs.mission.model import AlgorithmControlParams

    mission = load_mission(MISSIONS / "Gym" / "2UAVs_Crossing_ORCA.json").mission
    assert mission.agent_ids == [1, 2]
    controls = [n for n in mission.nodes() if isinstance(n.parameters, AlgorithmControlParams)]
    assert len(controls) == 1 and controls[0].ids == "all"
    params = dict(zip(controls[0].parameters.params, controls[0].parameters.values, strict=True))
    assert controls[0].parameters.name in ("orca3", "orca3d")
    assert params["agent_radius"] == 0.5
    assert 3.0 <= params["timeHorizon"] <= 5.0
    assert 2 <= params["N_neighbors_aware"] <= 4


def test_magna_mission_check_accepts_the_default_mission_in_its_world():
    out = subprocess.run(["./magna", "mission", "check", "missions/Gym/2UAVs_Crossing_ORCA.json", "--world",
                          PAIRS["Gym/2UAVs_Crossing_ORCA"]], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "pose definition(s) resolve" in out.stdout
    assert "warning" not in out.stderr
