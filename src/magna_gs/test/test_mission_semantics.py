"""The expansion and outcome rules of plan/build, run on small missions with scripted states."""
import threading

import pytest

from magna_gs.mission.build import build_machine
from magna_gs.mission.loader import mission_from_data
from magna_gs.mission.model import MissionError
from magna_gs.mission.outcome_callbacks import all_at_one_collision, collision_if_any_collided
from magna_gs.mission.scripted import HOLD, ScriptedFactory
from tests.support import WAIT, wait_until

AGENTS = [{"ID": i, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 1]} for i in (1, 2, 3)]


def mission(*states, agents=AGENTS):
    return {"Agents_Config": agents, "State_Machine": list(states)}


def load(data):
    return mission_from_data(data, "test.json")


def run(data, script=None, hold_timeout=10.0):
    loaded = load(data)
    factory = ScriptedFactory(script, hold_timeout=hold_timeout)
    return build_machine(loaded.mission, factory).execute(), factory, loaded


def definition(n):
    return {"definition": ["Zone", "Box", "matrix", [n, 0, 0]]}


def fly(name="fly", **extra):
    return {"type": "SimpleActionState", "state_type": "follow_path", "name": name,
            "parameters": {"path": [definition(0), definition(1), definition(2)]}, **extra}


def test_ids_expand_to_one_action_state_per_uav_and_cb_states_keep_their_name():
    loaded = load(mission(
        {"type": "CBState", "state_type": "algorithm_control", "name": "tune", "ids": "all", "ids_var": "agent",
         "parameters": {"name": "orca3", "action": "set"}, "outcomes": {"completed": "1_group"}},
        {"type": "Concurrence", "name": "group", "ids": 1, "occurrencies": [
            {"type": "SimpleActionState", "state_type": "take_off", "name": "up", "ids": [1, 3], "ids_var": "agent",
             "parameters": {"height": 1.5}}],
         "occurrencies_outcome_map": {"completed": {"all": "succeeded"}}, "outcomes": {"completed": "completed"}}))
    tune, group = loaded.plan.root.children
    assert (tune.label, tune.kind, tune.ids) == ("tune", "CBState", (1, 2, 3))
    assert [(c.label, c.uav) for c in group.children] == [("1_up", 1), ("3_up", 3)]
    assert group.outcome_map == {"completed": {"1_up": "succeeded", "3_up": "succeeded"}}


def test_wp_in_a_sequence_makes_one_state_per_waypoint_chained_by_the_connector():
    data = mission({"type": "Sequence", "name": "route", "ids": 2, "ids_var": "agent", "connector_outcome": "succeeded",
                    "occurrencies": [fly(ids="all", ids_var="wp")],
                    "outcomes": {"succeeded": "completed", "collision": "failed"}})
    outcome, factory, loaded = run(data)
    route = loaded.plan.root.children[0]
    assert [(c.label, c.uav) for c in route.children] == [("1_fly", 2), ("2_fly", 2), ("3_fly", 2)]
    assert outcome == "completed"
    flown = [s.parameters.path for s in factory.ran]
    assert [[d.arg for d in path] for path in flown] == [[[0, 0, 0]], [[1, 0, 0]], [[2, 0, 0]]]
    assert {s.uav for s in factory.ran} == {2}
    # a collision on the second waypoint stops the sequence there
    outcome, factory, _ = run(data, {"State_Machine[0].occurrencies[0]": ["succeeded", "collision"]})
    assert outcome == "failed" and len(factory.ran) == 2


def test_wp_in_a_state_machine_is_chained_by_succeeded_and_keeps_the_written_transitions():
    data = mission({"type": "StateMachine", "name": "route", "ids": 1, "ids_var": "agent", "occurrencies": [
        fly(ids="all", ids_var="wp", outcomes={"succeeded": "done", "collision": "crashed"})],
        "outcomes": {"done": "completed", "crashed": "failed"}})
    loaded = load(data)
    copies = loaded.plan.root.children[0].children
    assert [c.transitions["succeeded"] for c in copies] == ["2_fly", "3_fly", "done"]
    assert all(c.transitions["collision"] == "crashed" for c in copies)
    assert run(data)[0] == "completed"
    outcome, factory, _ = run(data, {"State_Machine[0].occurrencies[0]": ["succeeded", "succeeded", "collision"]})
    assert outcome == "failed" and len(factory.ran) == 3


def test_wp_ids_pick_waypoints_by_number():
    loaded = load(mission({"type": "Sequence", "name": "route", "ids": 1, "ids_var": "agent",
                           "connector_outcome": "succeeded", "occurrencies": [fly(ids=[3, 1], ids_var="wp")],
                           "outcomes": {"succeeded": "completed"}}))
    copies = loaded.plan.root.children[0].children
    assert [(c.label, c.parameters.path[0].arg) for c in copies] == [("3_fly", [2, 0, 0]), ("1_fly", [0, 0, 0])]


def test_all_at_one_collision_preempts_the_others_and_collision_if_any_collided_decides():
    data = mission({"type": "Concurrence", "name": "together", "ids": 1, "outcome_cb": "collision_if_any_collided",
                    "child_termination_cb": "all_at_one_collision",
                    "occurrencies": [{"type": "SimpleActionState", "state_type": "follow_agent_ad", "name": "follow",
                                      "ids": [2, 3], "ids_var": "agent",
                                      "parameters": {"target_ID": 1, "distance": 2}},
                                     fly(ids=1, ids_var="agent")],
                    "occurrencies_outcome_map": {"completed": {"all": "succeeded"}},
                    "outcomes": {"completed": "completed", "collision": "failed"}})
    script = {("State_Machine[0].occurrencies[0]", 2): HOLD, ("State_Machine[0].occurrencies[0]", 3): HOLD,
              ("State_Machine[0].occurrencies[1]", 1): "collision"}
    outcome, factory, _ = run(data, script)
    assert outcome == "failed"  # the Concurrence's collision, mapped to failed
    # "preempted", not "aborted": the followers were stopped, they did not wait for their guard (hold_timeout)
    assert sorted((s.uav, s.outcome) for s in factory.ran) == [(1, "collision"), (2, "preempted"), (3, "preempted")]


def test_without_a_termination_callback_the_others_run_to_their_end():
    data = mission({"type": "Concurrence", "name": "together", "ids": 1, "outcome_cb": "collision_if_any_collided",
                    "occurrencies": [fly(ids=[1, 2], ids_var="agent")],
                    "occurrencies_outcome_map": {"completed": {"all": "succeeded"}},
                    "outcomes": {"completed": "completed", "collision": "failed"}})
    outcome, factory, _ = run(data, {("State_Machine[0].occurrencies[0]", 1): "collision",
                                     ("State_Machine[0].occurrencies[0]", 2): HOLD}, hold_timeout=0.3)
    assert outcome == "failed"
    assert sorted((s.uav, s.outcome) for s in factory.ran) == [(1, "collision"), (2, "aborted")]


def test_the_callbacks_themselves():
    assert collision_if_any_collided({"1_a": "succeeded", "2_a": "collision"}) == "collision"
    assert collision_if_any_collided({"1_a": "succeeded", "2_a": "low_battery"}) is None
    assert all_at_one_collision({"1_a": "collision"}) and not all_at_one_collision({"1_a": "preempted"})


def test_the_outcome_map_entry_with_most_conditions_wins_else_completed():
    data = mission({"type": "Concurrence", "name": "pair", "ids": 1, "occurrencies": [fly(ids=[1, 2], ids_var="agent")],
                    "occurrencies_outcome_map": {"partial": {"1_fly": "succeeded"},
                                                 "full": {"all": "succeeded"}},
                    "outcomes": {"partial": "failed", "full": "completed", "completed": "failed"}})
    assert run(data)[0] == "completed"  # both succeeded: "full" (2 conditions) beats "partial" (1)
    where = ("State_Machine[0].occurrencies[0]", 2)
    assert run(data, {where: "collision"})[0] == "failed"  # only "partial" holds
    loaded = load(data)
    assert loaded.plan.root.children[0].default_outcome == "completed"
    assert run(data, {("State_Machine[0].occurrencies[0]", 1): "collision"})[0] == "failed"  # none holds: default


def test_an_outcome_with_no_transition_ends_the_mission_with_its_name():
    data = mission({"type": "SimpleActionState", "state_type": "take_off", "name": "up", "ids": 1, "ids_var": "agent",
                    "parameters": {"height": 2}, "outcomes": {"succeeded": "completed"}})
    outcome, _, loaded = run(data, {"State_Machine[0]": "low_battery"})
    assert outcome == "low_battery"
    assert "low_battery" in loaded.plan.outcomes and loaded.plan.outcomes[-1] == "preempted"
    assert any("State_Machine: outcomes with no transition end the mission with the same name: collision "
               "(from 1_up)" in w for w in loaded.warnings)


def test_an_outcome_nothing_inside_produces_is_dropped_with_its_transition():
    data = mission({"type": "StateMachine", "name": "leg", "ids": 1, "occurrencies": [
        {"type": "SimpleActionState", "state_type": "land", "name": "down", "ids": 1, "ids_var": "agent",
         "outcomes": {"succeeded": "done", "low_battery": "done", "collision": "done", "GS_critical_event": "done",
                      "utm_new_flightplan": "done", "aborted": "done"}}],
        "outcomes": {"done": "completed", "low_battery": "failed"}})
    loaded = load(data)
    leg = loaded.plan.root.children[0]
    assert leg.outcomes == ("done", "preempted") and leg.transitions == {"done": "completed"}
    assert "test.json: State_Machine[0].outcomes.low_battery: never taken: '1_leg' cannot end with 'low_battery' " \
           "(no state inside leads to it)" in loaded.warnings
    assert run(data)[0] == "completed"


def test_preempting_the_mission_preempts_the_running_state():
    data = mission({"type": "CBState", "state_type": "wait", "name": "hold", "parameters": {"exit_type": "button"},
                    "outcomes": {"completed": "completed"}})
    loaded = load(data)
    factory = ScriptedFactory({"State_Machine[0]": HOLD})
    machine = build_machine(loaded.mission, factory)
    result = {}
    runner = threading.Thread(target=lambda: result.setdefault("outcome", machine.execute()))
    runner.start()
    wait_until(machine.get_active_states, "the mission to be running its state")
    machine.request_preempt()
    runner.join(WAIT)
    assert result == {"outcome": "preempted"}


@pytest.mark.parametrize("child,message", [
    (fly(ids="all", ids_var="wp"), "'wp' states take their UAV from an enclosing container with \"ids_var\": "
                                   "\"agent\"; there is none"),
    (fly(ids=5, ids_var="wp"), "waypoint(s) 5 out of range: parameters.path has 3 (numbered from 1)"),
])
def test_wp_needs_a_uav_and_existing_waypoints(child, message):
    outer = {"type": "StateMachine", "name": "route", "ids": 1, "occurrencies": [child],
             "outcomes": {"succeeded": "completed"}}
    if "5" in message:
        outer["ids_var"] = "agent"
    with pytest.raises(MissionError) as error:
        load(mission(outer))
    assert message in str(error.value)
    assert "test.json: State_Machine[0].occurrencies[0].ids" in str(error.value)


def test_wp_in_a_concurrence_is_refused():
    with pytest.raises(MissionError, match=r"test.json: State_Machine\[0\].occurrencies\[0\].ids_var: 'wp' in a "
                                           r"Concurrence would fly every waypoint at once"):
        load(mission({"type": "Concurrence", "name": "c", "ids": 1, "ids_var": "agent",
                      "occurrencies": [fly(ids="all", ids_var="wp")], "outcomes": {"completed": "completed"}}))


def test_a_sequence_child_that_cannot_end_with_the_connector_is_refused():
    with pytest.raises(MissionError, match=r"test.json: State_Machine\[0\].connector_outcome: 'wait' never ends "
                                           r"with 'succeeded', so the Sequence cannot go on to '1_up'"):
        load(mission({"type": "Sequence", "name": "s", "ids": 1, "connector_outcome": "succeeded", "occurrencies": [
            {"type": "CBState", "state_type": "wait", "name": "wait", "parameters": {"exit_type": "time"}},
            {"type": "SimpleActionState", "state_type": "take_off", "name": "up", "ids": 1,
             "parameters": {"height": 1}}], "outcomes": {"succeeded": "completed"}}))


def test_a_container_repeated_per_agent_gives_its_uav_to_the_actions_inside():
    each = {"type": "StateMachine", "name": "each", "ids": "all", "ids_var": "agent",
            "occurrencies": [{"type": "SimpleActionState", "state_type": "land", "name": "down",
                              "outcomes": {"succeeded": "landed"}}],
            "outcomes": {"landed": "landed"}}
    data = mission({"type": "Concurrence", "name": "all", "ids": 1, "occurrencies": [each],
                    "occurrencies_outcome_map": {"completed": {"all": "landed"}},
                    "outcomes": {"completed": "completed"}})
    outcome, factory, loaded = run(data)
    group = loaded.plan.root.children[0]
    assert [(c.label, [(g.label, g.uav) for g in c.children]) for c in group.children] == [
        ("1_each", [("1_down", 1)]), ("2_each", [("2_down", 2)]), ("3_each", [("3_down", 3)])]
    assert outcome == "completed" and sorted(s.uav for s in factory.ran) == [1, 2, 3]
    # side by side in a StateMachine, copies after the first would never run (as in the original): refused
    with pytest.raises(MissionError, match=r"test.json: State_Machine\[0\]: '2_each' is never reached from "
                                           r"'1_each' \(the first state of MISSION\)"):
        load(mission(dict(each, outcomes={"landed": "completed"})))


def test_a_model_path_among_the_values_travels_as_text_value():
    # the AlgorithmControl service carries numbers in values, so the NAI's "model" parameter moves to text_value
    state = {"type": "CBState", "state_type": "algorithm_control", "name": "nn", "ids": "all", "ids_var": "agent",
             "parameters": {"name": "neural_network", "action": "set", "params": ["model", "neighborDist"],
                            "values": ["/nets/best.pt", 6.0]}, "outcomes": {"completed": "completed"}}
    (node,) = load(mission(state)).mission.root
    assert (node.parameters.params, node.parameters.values, node.parameters.text_value) == \
        (("neighborDist",), (6.0,), "/nets/best.pt")
    state["parameters"] |= {"values": [3, 6.0]}
    with pytest.raises(MissionError, match=r"values\[0\] \(model\) is 3: give the model's path once, as a string"):
        load(mission(state))
    state["parameters"] |= {"values": ["/a.pt", 6.0], "text_value": "/b.pt"}
    with pytest.raises(MissionError, match="give the model's path once"):
        load(mission(state))
