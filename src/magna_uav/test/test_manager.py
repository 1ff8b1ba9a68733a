"""The UAV manager's loop with every real part (roles, NAI, evaluator, recorder) against a
kinematic stand-in for the simulator: roles end with the right outcomes, the evaluator
stops a role on collision, preemption hovers, one recorded row per control step."""
import math

import numpy as np
import pytest

from magna_uav.config import configs_from_mission
from magna_uav.evaluator import Evaluator
from magna_uav.manager import Clock, UavManager
from magna_uav.nai.interface import NavigationInterface
from magna_uav.recorder import Recorder, read_csv
from magna_uav.roles import (
    FLYING_AUTO,
    FLYING_MANUAL,
    LANDED_ARMED,
    BasicMoveRole,
    FollowAgentAtDistanceRole,
    FollowAgentAtPositionRole,
    FollowPathRole,
    LandRole,
    OnBoardMissionRole,
    TakeOffRole,
)
from magna_uav.world_view import WorldView

from .kinematic import KinematicUav, KinematicWorld

AGENTS = [{"ID": 1, "model": "iris", "mode": "sitl", "marker_color": [255, 0, 0, 0.5]},
          {"ID": 2, "model": "iris", "mode": "sitl", "marker_color": [0, 0, 255, 0.5]}]


def setup(positions, algorithm="simple", others_step=None):
    configs = configs_from_mission(AGENTS[:len(positions)], "test")
    view = WorldView(1, boundaries=[[-50, 50], [-50, 50], [0, 30]])
    uavs = [KinematicUav(c.id, p, c.safety_radius, c.max_speed) for c, p in zip(configs, positions, strict=True)]
    world = KinematicWorld(view, uavs, others_step=others_step)
    nai = NavigationInterface(configs[0].max_speed, configs[0].safety_radius)
    if algorithm != "simple":
        nai.control(algorithm, "set", ["N_neighbors_aware", "timeHorizon"], [3, 4.0])
    recorder = Recorder(1, [c.id for c in configs[1:]])
    manager = UavManager(view, uavs[0], nai, Evaluator(configs[0]), recorder, Clock(world.now, world.sleep))
    return manager, world, uavs, recorder, configs[0]


def fly(manager, role, **kwargs):
    return manager.run_role(role, **kwargs)


def with_uav_2_hovering_at(position, algorithm="simple"):
    """UAV 1 flown by the manager, up at 3 m; UAV 2 already hovering at `position`."""
    manager, world, uavs, recorder, config = setup([[0, 0, 0], position], algorithm)
    uavs[1].state = FLYING_AUTO
    uavs[1].hold_pose(uavs[1].position, 0.0)
    take_off(manager, uavs)
    return manager, world, uavs, recorder, config


def take_off(manager, uavs, height=3.0):
    result = fly(manager, TakeOffRole(height))
    assert result.outcome == "succeeded", result.message
    assert uavs[0].state == FLYING_AUTO


@pytest.mark.parametrize("algorithm", ["simple", "orca3"])
def test_path_reaches_every_waypoint_within_the_accepted_radius(algorithm):
    manager, world, uavs, recorder, config = setup([[0, 0, 0]], algorithm)
    take_off(manager, uavs)
    waypoints = [[4, 0, 3], [4, 4, 4], [0, 4, 3]]
    closest = [math.inf] * 3

    def watch(step):
        for k, w in enumerate(waypoints):
            closest[k] = min(closest[k], float(np.linalg.norm(uavs[0].position - w)))

    result = fly(manager, FollowPathRole(waypoints, config.accepted_target_radius), feedback=watch)
    assert result.outcome == "succeeded", result.message
    assert all(c <= config.accepted_target_radius for c in closest), closest
    assert "set_velocity" in uavs[0].calls


def test_smoothed_path_and_position_dynamic_also_reach_every_waypoint():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    waypoints = [[3, 0, 3], [3, 3, 3], [0, 3, 4]]
    for role in (FollowPathRole(waypoints, config.accepted_target_radius, smooth_path_mode=3),
                 FollowPathRole(waypoints[::-1], config.accepted_target_radius, dynamic="position")):
        result = fly(manager, role)
        assert result.outcome == "succeeded", result.message
    assert "go_to_waypoint" in uavs[0].calls


def test_take_off_and_land_follow_the_ual_states():
    manager, world, uavs, recorder, config = setup([[1, 1, 0]])
    take_off(manager, uavs, 2.5)
    assert uavs[0].position[2] == pytest.approx(2.5, abs=0.3)
    result = fly(manager, LandRole())
    assert result.outcome == "succeeded"
    assert uavs[0].state == LANDED_ARMED


@pytest.mark.parametrize("make_role", [lambda: TakeOffRole(2.0), lambda: OnBoardMissionRole([TakeOffRole(2.0)])],
                         ids=["take_off", "set_mission"])
def test_a_take_off_answered_late_is_given_its_time_from_the_answer(make_role):
    # The UAL's service answers 6 simulated s after the request (a busy ROS master while simulated
    # time runs on), and the UAV's state shows the take-off only a control step after the answer, as
    # the UAL's state topic does. Counted from the request, the 5 s the UAL has to show TAKING_OFF
    # would be over at the first look after the answer.
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    answer_after = 6.0
    take_off_now, sleep_now = uavs[0].take_off, world.sleep
    pending = {"height": 0.0, "sleeps": 0}  # the take-off starts after this many more sleeps

    def slow_take_off(height):
        for _ in range(int(answer_after / world.dt)):
            world.t += world.dt  # simulated time passes while the call waits; the UAV stays landed
        world.publish()
        pending.update(height=height, sleeps=2)

    def sleep():
        if pending["sleeps"]:
            pending["sleeps"] -= 1
            if not pending["sleeps"]:
                take_off_now(pending["height"])
        sleep_now()

    uavs[0].take_off, world.sleep = slow_take_off, sleep
    manager.clock = Clock(world.now, sleep)
    result = fly(manager, make_role())
    assert result.outcome == "succeeded", result.message
    assert uavs[0].state == FLYING_AUTO
    assert world.t > answer_after


def test_a_take_off_the_ual_never_shows_still_fails_after_its_time():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    uavs[0].take_off = lambda height: uavs[0].calls.append("take_off")  # accepted, and nothing happens
    result = fly(manager, TakeOffRole(2.0))
    assert result.outcome == "aborted"
    assert "still reports LANDED_ARMED 5.0 s after it accepted the take-off" in result.message


def test_evaluator_stops_the_role_on_collision_and_the_uav_hovers():
    # UAV 2 hovers on the path; simple guidance flies straight through it.
    manager, world, uavs, recorder, config = with_uav_2_hovering_at([5.0, 0.0, 3.0])
    result = fly(manager, FollowPathRole([[10, 0, 3]], config.accepted_target_radius))
    assert result.outcome == "collision"
    assert "uav_2" in result.message
    assert uavs[0].calls[-1] == "hold_pose"


def test_orca_flies_around_the_hovering_uav_without_collision():
    manager, world, uavs, recorder, config = with_uav_2_hovering_at([5.0, 0.2, 3.0], "orca3")
    result = fly(manager, FollowPathRole([[10, 0, 3]], config.accepted_target_radius))
    assert result.outcome == "succeeded", result.message
    assert manager.evaluator.collision_count == 0


def test_preemption_stops_the_role_and_hovers_where_the_uav_is():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    result = fly(manager, FollowPathRole([[20, 0, 3]], config.accepted_target_radius),
                 preempt_requested=lambda: world.t > 4.0)
    assert result.outcome == "preempted"
    where = uavs[0].position.copy()
    for _ in range(20):
        world.sleep()
    assert np.linalg.norm(uavs[0].position - where) < 0.2, "a preempted UAV holds its pose"


def moving_target(speed):
    def step(world):
        target = world.uavs[2]
        target.state = FLYING_AUTO
        target.set_velocity([speed, 0, 0])
    return step


def test_follow_at_distance_holds_the_distance():
    manager, world, uavs, recorder, config = setup([[0, 0, 0], [3, 0, 3]], others_step=moving_target(0.5))
    take_off(manager, uavs)
    errors = []

    def watch(step):
        if world.t > 10.0:
            errors.append(abs(np.linalg.norm(uavs[0].position - uavs[1].position) - 2.0))

    result = fly(manager, FollowAgentAtDistanceRole(2, 2.0, duration=20.0), feedback=watch)
    assert result.outcome == "succeeded"
    assert max(errors) < 0.05, max(errors)  # exact kinematics: only the loop's own lag remains


def test_follow_at_position_holds_the_offset():
    manager, world, uavs, recorder, config = setup([[0, 0, 0], [3, 0, 3]], others_step=moving_target(0.5))
    take_off(manager, uavs)
    offset = np.array([-1.5, 1.5, 0.5])
    errors = []

    def watch(step):
        if world.t > 10.0:
            errors.append(float(np.linalg.norm(uavs[0].position - (uavs[1].position + offset))))

    result = fly(manager, FollowAgentAtPositionRole(2, offset, duration=20.0), feedback=watch)
    assert result.outcome == "succeeded"
    # The naive prediction aims where the target will be 0.3 s ahead: with exact kinematics the
    # follower leads by 0.3 s x 0.5 m/s, and by no more.
    assert max(errors) < 0.3 * 0.5 + 0.05, max(errors)


@pytest.mark.parametrize(("move", "direction", "value", "check"), [
    ("translation", "up", 2.0, lambda p0, p, y: np.allclose(p - p0, [0, 0, 2], atol=0.3)),
    ("translation", "left", 3.0, lambda p0, p, y: np.allclose(p - p0, [0, 3, 0], atol=0.3)),
    ("translation", "backward", 1.5, lambda p0, p, y: np.allclose(p - p0, [-1.5, 0, 0], atol=0.3)),
    ("rotation", "left", 90.0, lambda p0, p, y: abs(y - math.pi / 2) < math.radians(6)),
    ("rotation", "right", 45.0, lambda p0, p, y: abs(y + math.pi / 4) < math.radians(6)),
])
@pytest.mark.parametrize("dynamic", ["position", "velocity"])
def test_basic_moves_in_every_direction_and_both_dynamics(move, direction, value, check, dynamic):
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    start = uavs[0].position.copy()
    result = fly(manager, BasicMoveRole(move, direction, value, dynamic, duration=30.0))
    assert result.outcome == "succeeded", result.message
    assert check(start, uavs[0].position, uavs[0].yaw)


def test_one_recorded_row_per_control_step_with_the_documented_columns(tmp_path):
    manager, world, uavs, recorder, config = setup([[0, 0, 0], [8, 8, 3]])
    take_off(manager, uavs)
    before = recorder.rows
    result = fly(manager, FollowPathRole([[3, 0, 3]], config.accepted_target_radius))
    assert recorder.rows - before == result.steps
    columns, rows = read_csv(recorder.save_csv(tmp_path / "uav_1.csv"))
    assert len(rows) == recorder.rows
    assert {"time", "sel_vel.x", "uav2.pos.x", "uav2.gap", "collision", "role", "algorithm"} <= set(columns)
    flown = [r for r in rows if r["role"] == "path"]
    assert len(flown) == result.steps
    assert flown[-1]["outcome"] == "succeeded"
    assert {r["algorithm"] for r in flown[:-1]} == {"simple"}
    assert flown[-1]["algorithm"] == "ual", "the last step hands the UAV to UAL to hover"


def test_a_role_started_in_contact_may_separate_the_uavs_but_a_new_contact_ends_it():
    manager, world, uavs, recorder, config = with_uav_2_hovering_at([5.0, 0.0, 3.0])
    assert fly(manager, FollowPathRole([[10, 0, 3]], config.accepted_target_radius)).outcome == "collision"
    # In contact now: climbing away is allowed, it is what the ground station asks for.
    assert fly(manager, BasicMoveRole("translation", "up", 2.0)).outcome == "succeeded"
    # Back down into UAV 2: a new contact ends the role.
    assert fly(manager, BasicMoveRole("translation", "down", 2.0)).outcome == "collision"


def test_low_battery_at_the_start_does_not_stop_a_landing_but_a_new_low_battery_ends_a_path():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    battery = {"level": 0.8}
    world_publish = world.publish

    def publish():
        world_publish()
        own = world.view.own
        own.battery = battery["level"]
    world.publish = publish
    result = fly(manager, FollowPathRole([[20, 0, 3]], config.accepted_target_radius),
                 feedback=lambda step: battery.update(level=0.1 if world.t > 3.0 else 0.8))
    assert result.outcome == "low_battery"
    assert fly(manager, LandRole()).outcome == "succeeded"


def test_set_mission_flies_take_off_path_and_landing_on_board():
    from magna_uav.goals import mission_role

    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    role = mission_role('{"path": [[2, 0, 3], [2, 2, 3]], "include_takeoff": true, "include_land": true, '
                        '"height": 3.0}', config)
    reached = []
    result = fly(manager, role, feedback=lambda step: reached.append(uavs[0].position.copy()))
    assert result.outcome == "succeeded", result.message
    assert uavs[0].state == LANDED_ARMED
    assert min(np.linalg.norm(p - [2, 2, 3]) for p in reached) <= config.accepted_target_radius


def test_set_mission_on_a_landed_uav_takes_off_first_as_px4_mission_mode_does():
    from magna_uav.goals import mission_role

    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    role = mission_role('{"path": [[2, 0, 3], [2, 2, 3]]}', config)  # no take-off asked, as the original's missions
    reached = []
    result = fly(manager, role, feedback=lambda step: reached.append(uavs[0].position.copy()))
    assert result.outcome == "succeeded", result.message
    assert min(np.linalg.norm(p - [2, 2, 3]) for p in reached) <= config.accepted_target_radius


def test_a_path_for_a_landed_uav_ends_aborted_with_the_reason_instead_of_waiting():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    result = fly(manager, FollowPathRole([[2, 0, 3]], config.accepted_target_radius))
    assert result.outcome == "aborted" and "landed" in result.message and "take off" in result.message


@pytest.mark.parametrize(("text", "reason"), [
    ("not json", "is not JSON"),
    ('{"path": [[1, 2]]}', "list of \\[x, y, z\\] points"),
    ('{"paths": []}', "mission_json.paths is unknown"),
    ("{}", "nothing to do"),
])
def test_set_mission_refuses_bad_missions_with_the_reason(text, reason):
    from magna_uav.goals import mission_role

    config = configs_from_mission(AGENTS[:1], "test")[0]
    with pytest.raises(ValueError, match=reason):
        mission_role(text, config)


def test_a_short_basic_move_from_the_ground_station_is_flown_all_the_way():
    from types import SimpleNamespace

    from magna_uav.goals import role_from_goal

    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    start = uavs[0].position.copy()
    goal = SimpleNamespace(move_type="translation", direction="up", value=1.0, dynamic="position", duration=0.0)
    assert fly(manager, role_from_goal("basic_move", goal, config)).outcome == "succeeded"
    assert uavs[0].position[2] - start[2] >= 0.8, "not stopped within the 0.9 m a path's waypoint allows"


def test_a_stale_hold_that_reaches_the_ual_after_the_waypoint_only_delays_it():
    # The idle manager streams its held pose on a topic, the waypoint goes through a service: under
    # load a hold published before the role began reached the UAL after the waypoint and replaced it.
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)
    uav = uavs[0]
    held = uav.position.copy()
    go_to_waypoint = uav.go_to_waypoint

    def waypoint_overtaken_by_a_stale_hold(position, yaw=0.0):
        go_to_waypoint(position, yaw)
        if uav.calls.count("go_to_waypoint") == 1:
            uav.hold_pose(held, 0.0)

    uav.go_to_waypoint = waypoint_overtaken_by_a_stale_hold
    started = world.t
    result = fly(manager, BasicMoveRole("translation", "up", 3.0, "position", duration=0.0),
                 preempt_requested=lambda: world.t - started > 60.0)
    assert result.outcome == "succeeded", result.message
    assert uav.calls.count("go_to_waypoint") >= 2, "the waypoint was sent again"
    assert uav.position[2] - held[2] == pytest.approx(3.0, abs=config.accepted_target_radius)


def test_a_path_that_comes_no_nearer_its_waypoint_ends_aborted_as_stuck_instead_of_flying_on():
    from magna_uav.roles import STALL_TIME
    from magna_uav.world_view import AgentState

    view = WorldView(1)
    view.update_agent(AgentState(1, position=[0, 0, 3], ual_state=FLYING_AUTO))
    role = FollowPathRole([[10, 0, 3]], 0.9)
    t, step = 0.0, role.step(view, 0.0)
    while step.outcome is None and t < 2 * STALL_TIME:  # the UAV never moves: held by something
        t += 0.5
        step = role.step(view, t)
    assert step.outcome == "aborted" and t == pytest.approx(STALL_TIME, abs=0.5)
    assert "stuck: waypoint 1 of 1 came no nearer than 10.00 m" in step.message


def test_the_smoothed_paths_last_stretch_aims_at_the_waypoint_itself():
    role = FollowPathRole([[0, 0, 3], [10, 0, 3], [10, 10, 3]], 0.9, smooth_path_mode=3)
    target = role.waypoints[1]
    assert np.array_equal(role._carrot(target + [-0.5, 1.5, 0], target), target)


def test_a_smoothed_path_that_turns_back_on_itself_is_flown_on_instead_of_going_down_again():
    """Down to a delivery point and up again (Delivery/2UAVs_follow_ad_safe): the spline's two legs lie
    millimetres apart, and once the delivery point was reached the UAV was sent back down after each climb
    until the path ended stuck over the recipient."""
    manager, world, uavs, recorder, config = setup([[0, 14, 0]])
    take_off(manager, uavs, 4.0)
    approach, delivery, next_approach = [0, 15, 4], [0, 15, 2], [15, 15, 4]
    role = FollowPathRole([approach, delivery, approach, next_approach], config.accepted_target_radius,
                          smooth_path_mode=2)
    heights_towards_next_approach = []

    def watch(step):
        if role.tracker.index == 3:
            heights_towards_next_approach.append(uavs[0].position[2])

    result = fly(manager, role, feedback=watch)
    assert result.outcome == "succeeded", result.message
    # the approach point is reached again (0.9 m below it at the least) and the UAV never goes back down
    assert min(heights_towards_next_approach) >= approach[2] - config.accepted_target_radius - 0.1


def test_a_pilot_take_over_ends_the_role_aborted_and_magna_stops_commanding():
    manager, world, uavs, recorder, config = setup([[0, 0, 0]])
    take_off(manager, uavs)

    def pilot_takes_over_after_2_s():
        if world.t > 2.0 and uavs[0].state == FLYING_AUTO:
            uavs[0].state = FLYING_MANUAL  # what the UAL shows once the autopilot leaves OFFBOARD
        return False

    result = fly(manager, FollowPathRole([[20, 0, 3]], config.accepted_target_radius),
                 preempt_requested=pilot_takes_over_after_2_s)
    assert result.outcome == "aborted" and result.events == ["pilot_takeover"]
    assert "UAV 1 is out of MAGNA's hands: its UAL is FLYING_MANUAL (a safety pilot" in result.message
    commands = len(uavs[0].calls)
    manager.hover()
    assert len(uavs[0].calls) == commands, "no command goes to a UAV the pilot flies"
    # A role begun while the pilot flies ends at once, the same way.
    result = fly(manager, LandRole())
    assert result.outcome == "aborted" and result.events == ["pilot_takeover"] and result.steps == 0
