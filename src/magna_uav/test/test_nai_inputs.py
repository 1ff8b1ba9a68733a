"""The neural networks' input vector: names, sizes, values, neighbour order and padding per role."""
import numpy as np
import pytest

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import (
    OUTPUT,
    assemble_inputs,
    build_inputs,
    input_names,
    input_size,
    output_names,
    pad_position,
    select_neighbors,
)
from magna_uav.world_view import AgentState, Obstacle, WorldView

XYZ = ["x", "y", "z"]


def block(name, count=None):
    if count is None:
        return [f"{name}.{a}" for a in XYZ]
    return [f"{name}[{i}].{a}" for i in range(count) for a in XYZ]


def test_names_follow_the_documented_order_per_role():
    assert input_names("path", 2, 1) == (block("own_vel") + block("goal_pose_rel") + block("others_pos_rel", 2)
                                         + block("others_vel", 2) + block("obstacles_pos_rel", 1))
    assert input_names("agent_ad", 1, 2) == (block("own_vel") + block("goal_pose_rel") + block("goal_vel")
                                             + ["distance"] + block("others_pos_rel", 1) + block("others_vel", 1)
                                             + block("obstacles_pos_rel", 2))
    assert input_names("agent_ap", 0, 0) == block("own_vel") + block("goal_pose_rel") + block("goal_vel")
    assert input_names("path", 2, 1)[6:9] == ["others_pos_rel[0].x", "others_pos_rel[0].y", "others_pos_rel[0].z"]
    assert OUTPUT == "sel_vel" and output_names() == ["sel_vel.x", "sel_vel.y", "sel_vel.z"]


@pytest.mark.parametrize("role", ["path", "agent_ad", "agent_ap"])
@pytest.mark.parametrize("n,m", [(0, 0), (1, 0), (3, 2), (10, 10)])
def test_size_matches_the_names(role, n, m):
    assert input_size(role, n, m) == len(input_names(role, n, m)) == len(set(input_names(role, n, m)))


def test_unknown_role_and_bad_counts_are_refused():
    with pytest.raises(ValueError, match="role 'basic_move' has no neural network inputs: give one of path, "
                                         "agent_ad, agent_ap"):
        input_names("basic_move", 1, 1)
    with pytest.raises(ValueError, match="n_neighbors is -1: give a whole number >= 0"):
        input_size("path", -1, 0)
    with pytest.raises(ValueError, match="n_obstacles is 1.5"):
        input_names("path", 0, 1.5)


def view():
    v = WorldView(1)
    v.update_agent(AgentState(1, [1, 1, 5], velocity=[0.5, 0, 0], safety_radius=0.5))
    v.update_agent(AgentState(7, [4, 1, 5], velocity=[0, -1, 0], safety_radius=0.5))  # gap 2
    v.update_agent(AgentState(3, [1, 2, 5], velocity=[0, 0, 0.2], safety_radius=0.25))  # gap 0.25
    v.update_agent(AgentState(9, [1, 30, 5], velocity=[1, 1, 1], safety_radius=0.5))  # gap 28: beyond 6 m
    v.set_obstacles([Obstacle("tree", np.array([1.0, -2.0, 5.0]), 1.0),  # gap 1.5
                     Obstacle("tower", np.array([50.0, 1.0, 5.0]), 2.0)])  # beyond
    return v


def named(vector, role, n, m):
    return dict(zip(input_names(role, n, m), vector, strict=True))


def test_path_inputs_hold_own_velocity_goal_and_nearest_neighbours_first_then_padding():
    vector = build_inputs(view(), Goal([11, 1, 6]), "path", n_neighbors=3, n_obstacles=2, neighbor_dist=6.0)
    assert vector.shape == (input_size("path", 3, 2),)
    np.testing.assert_allclose(vector[:6], [0.5, 0, 0, 10, 0, 1])
    np.testing.assert_allclose(vector[6:15], [0, 1, 0, 3, 0, 0, 12, 0, 0])  # UAV 3, UAV 7, padding
    np.testing.assert_allclose(vector[15:24], [0, 0, 0.2, 0, -1, 0, 0, 0, 0])
    np.testing.assert_allclose(vector[24:], [0, -3, 0, 12, 0, 0])  # tree, padding
    values = named(vector, "path", 3, 2)
    assert values["others_pos_rel[1].x"] == 3.0 and values["others_vel[1].y"] == -1.0
    assert values["obstacles_pos_rel[1].x"] == 12.0


def test_following_roles_add_the_target_velocity_and_the_distance():
    goal = Goal([3, 3, 5], role="agent_ad", velocity=[0.1, 0.2, 0.3], distance=2.5)
    values = named(build_inputs(view(), goal, "agent_ad", 1, 1), "agent_ad", 1, 1)
    assert [values[f"goal_pose_rel.{a}"] for a in XYZ] == [2, 2, 0]
    assert [values[f"goal_vel.{a}"] for a in XYZ] == [0.1, 0.2, 0.3]
    assert values["distance"] == 2.5
    assert [values[f"others_pos_rel[0].{a}"] for a in XYZ] == [0, 1, 0]
    still = Goal([3, 3, 5], role="agent_ap", offset=[0, 1, 0])
    values = named(build_inputs(view(), still, "agent_ap", 0, 0), "agent_ap", 0, 0)
    assert [values[f"goal_vel.{a}"] for a in XYZ] == [0, 0, 0]
    with pytest.raises(ValueError, match="distance is missing"):
        build_inputs(view(), Goal([0, 0, 0]), "agent_ad", 0, 0)


def test_padding_is_twice_the_neighbor_distance_along_x():
    np.testing.assert_allclose(pad_position(6.0), [12, 0, 0])
    vector = build_inputs(view(), Goal([1, 1, 5]), "path", 2, 1, neighbor_dist=0.1)  # nothing within 0.1 m
    np.testing.assert_allclose(vector[6:], [0.2, 0, 0, 0.2, 0, 0, 0, 0, 0, 0, 0, 0, 0.2, 0, 0])
    with pytest.raises(ValueError, match="neighbor_dist is inf: give a finite positive distance"):
        pad_position(float("inf"))


def test_selection_is_shared_and_can_be_passed_in():
    chosen = select_neighbors(view(), 1, 1, 6.0)
    assert chosen.ids == (3,) and chosen.obstacle_names == ("tree",)
    assert select_neighbors(view(), 5, 5, 6.0).ids == (3, 7)
    np.testing.assert_array_equal(build_inputs(view(), Goal([0, 0, 0]), "path", 1, 1, 6.0, chosen),
                                  build_inputs(view(), Goal([0, 0, 0]), "path", 1, 1, 6.0))


def test_assemble_inputs_without_a_world_view():
    vector = assemble_inputs("agent_ap", [1, 2, 3], [4, 5, 6], [[1, 0, 0]], [[0, 1, 0]], [], 2, 1, 5.0,
                             goal_vel=[7, 8, 9])
    np.testing.assert_allclose(vector, [1, 2, 3, 4, 5, 6, 7, 8, 9, 1, 0, 0, 10, 0, 0, 0, 1, 0, 0, 0, 0, 10, 0, 0])
    with pytest.raises(ValueError, match="others_pos_rel has 3 entries: the vector holds 2"):
        assemble_inputs("path", np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3)), [], 2, 0)
    with pytest.raises(ValueError, match="others_pos_rel has 1 rows but others_vel 0"):
        assemble_inputs("path", np.zeros(3), np.zeros(3), np.zeros((1, 3)), [], [], 2, 0)
