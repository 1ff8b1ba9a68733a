"""Small machines shaped like MAGNA missions, for drawing, demos, tests and benchmarks."""
from __future__ import annotations

from magna_sm.concurrence import Concurrence
from magna_sm.state import CBState
from magna_sm.state_machine import StateMachine


def pause(seconds: float, outcome: str = "completed") -> CBState:
    """A state that waits `seconds` (waking at once if preempted), like the mission's `wait`."""
    def wait(ud, state):
        if state.wait_for_preempt(seconds):
            state.service_preempt()
            return "preempted"
        return outcome
    return CBState(wait, [outcome, "preempted"], pass_state=True)


def filmed_delivery(step: float = 0.0) -> StateMachine:
    """Take off, then UAV 1 delivers while UAV 2 films it, then both land (each state waits `step` s)."""
    def uav_leg(*labels: str) -> StateMachine:
        leg = StateMachine(["succeeded", "collision"])
        with leg:
            for index, label in enumerate(labels):
                following = labels[index + 1] if index + 1 < len(labels) else "succeeded"
                StateMachine.add(label, pause(step, "succeeded"),
                                 {"succeeded": following, "preempted": "collision"})
        return leg

    delivery = Concurrence(["completed", "failed"], default_outcome="failed",
                           outcome_map={"completed": {"1_delivery": "succeeded", "2_filming": "succeeded"},
                                        "failed": {"1_delivery": "collision"}},
                           child_termination_cb=lambda outcomes: "collision" in outcomes.values())
    with delivery:
        Concurrence.add("1_delivery", uav_leg("to_delivery_height", "delivery", "back_home"))
        Concurrence.add("2_filming", uav_leg("follow_agent_ap"))

    mission = StateMachine(["mission_completed", "mission_failed"], name="MISSION")
    with mission:
        StateMachine.add("spawn_agents", pause(step), {"completed": "1_take_off", "preempted": "mission_failed"})
        StateMachine.add("1_take_off", pause(step), {"completed": "1_filmed_delivery",
                                                     "preempted": "mission_failed"})
        StateMachine.add("1_filmed_delivery", delivery, {"completed": "1_land", "failed": "1_safe_land"})
        StateMachine.add("1_land", pause(step), {"completed": "mission_completed", "preempted": "mission_failed"})
        StateMachine.add("1_safe_land", pause(step), {"completed": "mission_failed", "preempted": "mission_failed"})
    return mission


def chain(length: int) -> StateMachine:
    """`length` trivial states in a row: the engine's own overhead, for the benchmark."""
    machine = StateMachine(["done"], name="CHAIN")
    for index in range(length):
        following = f"S{index + 1}" if index + 1 < length else "done"
        machine.add_state(f"S{index}", CBState(lambda ud: "next", ["next"]), {"next": following})
    return machine


def wide_concurrence(children: int) -> Concurrence:
    """`children` trivial states at once: the cost of threads and the outcome map."""
    concurrence = Concurrence(["done", "failed"], default_outcome="failed",
                              outcome_map={"done": {f"C{i}": "ok" for i in range(children)}}, name="WIDE")
    for index in range(children):
        concurrence.add_state(f"C{index}", CBState(lambda ud: "ok", ["ok"]))
    return concurrence
