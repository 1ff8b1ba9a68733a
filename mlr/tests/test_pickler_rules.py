"""The pickler's rules on hand-made steps: which steps become samples, the labels FVI steps
ahead, and the neighbours chosen and padded as the NAI does."""
from pathlib import Path

import numpy as np
import pytest

from magna_uav.nai.inputs import input_names
from mlr.pickler import PicklerError, Teacher, runs, samples
from mlr.steps import UavSteps


def steps(n=8, roles=None, algorithms=None, role_end=()):
    t = np.arange(n) * 0.1
    steps = UavSteps(
        source=Path("uav_1.csv"), uav_id=1, max_speed=2.0, time=t,
        role=np.array(roles or ["path"] * n, dtype=object),
        algorithm=np.array(algorithms or ["orca3d"] * n, dtype=object),
        position=np.column_stack([t, np.zeros(n), np.full(n, 3.0)]),
        velocity=np.tile([1.0, 0.0, 0.0], (n, 1)),
        goal=np.tile([10.0, 2.0, 3.0], (n, 1)),
        goal_vel=np.full((n, 3), np.nan), goal_dist=np.full(n, np.nan),
        sel_vel=np.column_stack([np.arange(n) * 1.0, np.zeros(n), np.zeros(n)]),
        role_end=np.isin(np.arange(n), list(role_end)),
    )
    # UAV 2 approaches (gap 8 m then 1 m), UAV 3 stays at gap 3 m
    gap2 = np.where(np.arange(n) < 4, 8.0, 1.0)
    steps.others = {
        2: (steps.position + [[2.0, 0, 0]], np.tile([-1.0, 0, 0], (n, 1)), gap2),
        3: (steps.position + [[0, 3.6, 0]], np.zeros((n, 3)), np.full(n, 3.0)),
    }
    steps.obstacle_pos = np.tile([[[5.0, 5.0, 3.0], [9.0, 9.0, 3.0]]], (n, 1, 1)) + 0.0
    steps.obstacle_gap = np.tile([[4.0, 7.0]], (n, 1))
    return steps


def column(name, teacher):
    return input_names(teacher.role, teacher.n_neighbors, teacher.n_obstacles).index(name)


def test_runs_end_at_role_ends_and_at_changes_of_role_or_algorithm():
    s = steps(10, roles=["take_off"] * 2 + ["path"] * 8, algorithms=["ual"] * 2 + ["orca3d"] * 5 + ["simple"] * 3,
              role_end=(4,))
    assert runs(s, "path", "orca3d") == [(2, 5), (5, 7)]
    assert runs(s, "path", "simple") == [(7, 10)]
    assert runs(s, "agent_ad", "orca3d") == []


@pytest.mark.parametrize("fvi", [0, 2])
def test_labels_are_the_teachers_choice_fvi_steps_ahead_within_one_run(fvi):
    s = steps(8, role_end=(4,))  # runs [0, 5) and [5, 8)
    teacher = Teacher(n_neighbors=1, fvi=fvi)
    out = samples(s, teacher)
    expected_steps = [i for i in range(0, 5 - fvi)] + [i for i in range(5, 8 - fvi)]
    assert out.step.tolist() == expected_steps
    np.testing.assert_array_equal(out.y[:, 0], np.array(expected_steps) + fvi)  # sel_vel.x == its step number
    assert out.x.shape == (len(expected_steps), 12) and out.max_speed.tolist() == [2.0] * len(expected_steps)


def test_inputs_follow_the_nai_order_with_neighbours_by_gap_and_padding():
    s = steps(8)
    teacher = Teacher(n_neighbors=2, n_obstacles=2, neighbor_dist=6.0)
    out = samples(s, teacher)
    x = out.x
    np.testing.assert_array_equal(x[:, column("own_vel.x", teacher)], 1.0)
    np.testing.assert_allclose(x[:, column("goal_pose_rel.x", teacher)], 10.0 - s.position[:, 0])
    np.testing.assert_array_equal(x[:, column("goal_pose_rel.y", teacher)], 2.0)
    # steps 0-3: UAV 2 is beyond 6 m, so UAV 3 comes first and the second slot is padding (12, 0, 0)
    first = [column(f"others_pos_rel[0].{a}", teacher) for a in "xyz"]
    second = [column(f"others_pos_rel[1].{a}", teacher) for a in "xyz"]
    np.testing.assert_allclose(x[0, first], [0, 3.6, 0])
    np.testing.assert_allclose(x[0, second], [12.0, 0, 0])
    np.testing.assert_allclose(x[0, [column(f"others_vel[1].{a}", teacher) for a in "xyz"]], 0.0)
    # steps 4-7: UAV 2 (gap 1 m) is nearest, then UAV 3
    np.testing.assert_allclose(x[5, first], [2.0, 0, 0])
    np.testing.assert_allclose(x[5, [column(f"others_vel[0].{a}", teacher) for a in "xyz"]], [-1, 0, 0])
    np.testing.assert_allclose(x[5, second], [0, 3.6, 0])
    # obstacles: the one 4 m away counts, the one 7 m away does not (padding)
    np.testing.assert_allclose(x[5, [column(f"obstacles_pos_rel[0].{a}", teacher) for a in "xyz"]],
                               [5.0 - s.position[5, 0], 5.0, 0.0])
    np.testing.assert_allclose(x[5, [column(f"obstacles_pos_rel[1].{a}", teacher) for a in "xyz"]], [12.0, 0, 0])


def test_a_smaller_neighbour_distance_moves_the_padding_and_drops_far_neighbours():
    teacher = Teacher(n_neighbors=1, neighbor_dist=2.0)
    x = samples(steps(8), teacher).x
    np.testing.assert_allclose(x[0, [column(f"others_pos_rel[0].{a}", teacher) for a in "xyz"]], [4.0, 0, 0])
    np.testing.assert_allclose(x[6, [column(f"others_pos_rel[0].{a}", teacher) for a in "xyz"]], [2.0, 0, 0])


def test_steps_without_a_known_state_or_label_are_skipped():
    s = steps(6)
    s.velocity[1] = np.nan
    s.sel_vel[3] = np.nan
    assert samples(s, Teacher()).step.tolist() == [0, 2, 4, 5]


def test_follower_roles_need_the_recorded_distance():
    s = steps(4, roles=["agent_ad"] * 4)
    with pytest.raises(PicklerError, match="uav_1.csv: step 0 of role agent_ad has no goal_dist"):
        samples(s, Teacher(role="agent_ad", n_neighbors=1))
    s.goal_dist[:] = 1.5
    s.goal_vel[:] = [0.0, 1.0, 0.0]
    teacher = Teacher(role="agent_ad", n_neighbors=1)
    x = samples(s, teacher).x
    assert x[0, column("distance", teacher)] == 1.5 and x[0, column("goal_vel.y", teacher)] == 1.0


def test_more_obstacles_than_recorded_is_refused():
    with pytest.raises(PicklerError, match="2 obstacles were recorded per step but n_obstacles is 3"):
        samples(steps(4), Teacher(n_obstacles=3))


def test_image_samples_take_the_newest_frame_and_skip_steps_before_the_first():
    s = steps(6)
    s.depth_frames = np.stack([np.full((4, 6), 1.0), np.full((4, 6), np.inf)]).astype(np.float32)
    s.depth_rows = np.array([2, 4])
    out = samples(s, Teacher(image=(2, 3)))
    assert out.step.tolist() == [2, 3, 4, 5]
    assert out.images.shape == (4, 2, 3)
    assert out.images[:, 0, 0].tolist() == [1.0, 1.0, 20.0, 20.0]  # +inf reads as the far plane, as in flight
