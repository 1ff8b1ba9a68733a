"""Neural-network navigation: TorchScript models with their JSON spec, loaded, checked and flown."""
import json
import logging

import numpy as np
import pytest
import torch  # pinned in requirements.txt: a missing torch fails these tests, it does not skip them

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import input_names, input_size, output_names
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.neural import NeuralModelError, load_model, prepare_depth, spec_path
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, Obstacle, WorldView

# torch 2.13 marks TorchScript deprecated; it is still the format the NAI flies
pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")


class TowardsGoal(torch.nn.Module):
    """sel_vel = gain * goal_pose_rel (inputs 3..5 of every role)."""

    def __init__(self, size: int, gain: float = 0.5):
        super().__init__()
        self.fc = torch.nn.Linear(size, 3, bias=False)
        with torch.no_grad():
            self.fc.weight.zero_()
            for axis in range(3):
                self.fc.weight[axis, 3 + axis] = gain

    def forward(self, x):
        return self.fc(x)


class DepthStats(torch.nn.Module):
    """Image model: (mean depth, image height, first input) - shows what it was given."""

    def forward(self, image, x):
        return torch.stack([image.mean(), torch.tensor(float(image.shape[2])), x[0, 0]]).reshape(1, 3)


class FourOutputs(torch.nn.Module):
    def forward(self, x):
        return torch.zeros(1, 4)


def save(directory, module, role="path", n=2, m=1, image=None, name="net", **spec_changes):
    path = directory / f"{name}.pt"
    torch.jit.script(module).save(str(path))
    spec = {"role": role, "n_neighbors": n, "n_obstacles": m,
            "inputs": input_names(role if role != "basic_move" else "path", n, m),
            "outputs": output_names(), "image": image}
    spec.update(spec_changes)
    spec_path(path).write_text(json.dumps(spec))
    return path


def world(depth=None):
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 5], velocity=[0.3, 0, 0], safety_radius=0.3, depth=depth))
    view.update_agent(AgentState(2, [2, 0, 5], velocity=[-1, 0, 0], safety_radius=0.3))
    view.set_obstacles([Obstacle("post", np.array([0, 3.0, 5]), 0.5)])
    return view


def test_a_scripted_model_is_loaded_and_flies_one_step(tmp_path):
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)))
    model = load_model(path)
    assert model.role == "path" and model.spec.n_neighbors == 2 and model.spec.image is None
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    message = nav.control("neural_network", "set", text_value=str(path))
    assert nav.algorithm == "neural_network" and str(path) in message and "'path'" in message
    command = nav.velocity(world(), Goal([2, 1, 6]))
    assert command.algorithm == "neural_network" and not command.error
    np.testing.assert_allclose(command.velocity, [1.0, 0.5, 0.5], rtol=1e-6)  # float32 inside
    assert command.neighbors == (2,) and command.obstacles == ("post",)
    # far goal: the answer is saturated to the UAV's max speed
    command = nav.velocity(world(), Goal([100, 0, 5]))
    assert np.linalg.norm(command.velocity) == pytest.approx(2.0)


def test_the_model_sees_the_inputs_of_magna_uav_nai_inputs(tmp_path):
    recorded = []

    class Echo(torch.nn.Module):
        def forward(self, x):
            return x[:, :3] * 0.0

    path = save(tmp_path, Echo(), role="agent_ad", n=1, m=1)
    model = load_model(path)
    original = model.module
    model.module = lambda x: (recorded.append(x.clone()), original(x))[1]
    goal = Goal([1, 0, 5], role="agent_ad", velocity=[0, 1, 0], distance=1.5)
    velocity, neighbors = model.velocity(world(), goal)
    assert recorded[0].dtype == torch.float32 and tuple(recorded[0].shape) == (1, input_size("agent_ad", 1, 1))
    np.testing.assert_allclose(recorded[0][0].numpy(), [0.3, 0, 0, 1, 0, 0, 0, 1, 0, 1.5, 2, 0, 0, -1, 0, 0,
                                                         0, 3, 0])
    np.testing.assert_array_equal(velocity, np.zeros(3))


def test_an_image_model_gets_the_depth_image_resized_to_its_spec(tmp_path):
    path = save(tmp_path, DepthStats(), image={"height": 4, "width": 6})
    model = load_model(path)
    depth = np.full((48, 64), 3.0)
    depth[:24] = np.inf  # nothing seen in the upper half: reads as 20 m
    out = model.predict(np.r_[0.7, np.zeros(input_size("path", 2, 1) - 1)], depth)
    np.testing.assert_allclose(out, [11.5, 4.0, 0.7], rtol=1e-6)
    nav = NavigationInterface(20.0, 0.3)
    nav.control("neural_network", "set", ["model"], [str(path)])
    command = nav.velocity(world(depth), Goal([0, 0, 5]))
    np.testing.assert_allclose(command.velocity, [11.5, 4.0, 0.3], rtol=1e-6)
    command = nav.velocity(world(None), Goal([0, 0, 5]))
    assert "needs a depth image" in command.error and not command.velocity.any()


def test_prepare_depth_matches_torch_nearest_interpolation():
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.1, 30.0, (37, 53))
    depth[5, 7], depth[9, 9] = np.nan, -np.inf
    for height, width in [(4, 6), (37, 53), (64, 80), (1, 1)]:
        mine = prepare_depth(depth, height, width)
        clean = np.clip(np.nan_to_num(depth, nan=20.0, posinf=20.0, neginf=0.0), 0, 20.0)
        expected = torch.nn.functional.interpolate(torch.from_numpy(clean).float()[None, None], size=(height, width),
                                                   mode="nearest")[0, 0].numpy()
        assert mine.dtype == np.float32 and mine.shape == (height, width)
        np.testing.assert_array_equal(mine, expected)


def test_a_spec_that_differs_from_the_input_definition_is_refused_naming_the_file_and_input(tmp_path):
    names = input_names("path", 2, 1)
    names[3], names[4] = names[4], names[3]
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)), inputs=names)
    with pytest.raises(NeuralModelError) as err:
        load_model(path)
    assert str(err.value).startswith(f"{spec_path(path)}: inputs[3] is 'goal_pose_rel.y' but role 'path' with 2 "
                                     "neighbours and 1 obstacles expects 'goal_pose_rel.x'")
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)), inputs=input_names("path", 2, 0), name="short")
    with pytest.raises(NeuralModelError, match=r"short.json: inputs ends after 18 names .* first missing is "
                                               r"'obstacles_pos_rel\[0\].x'"):
        load_model(path)
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)), role="agent_ap", name="wrong_role",
                inputs=input_names("path", 2, 1))
    with pytest.raises(NeuralModelError, match="wrong_role.json: inputs.6. is 'others_pos_rel.0..x' but role "
                                               "'agent_ap' .* expects 'goal_vel.x'"):
        load_model(path)


def test_the_neighbour_distance_of_the_spec_wins_over_the_parameter(tmp_path):
    # UAV 2 and the post are 1.4 and 2.2 m apart (gaps): with the trained 1.0 m neither counts,
    # so both slots hold the padding at 2 x 1.0 m, whatever neighborDist the mission gives.
    recorded = []

    class Echo(torch.nn.Module):
        def forward(self, x):
            return x[:, :3] * 0.0

    model = load_model(save(tmp_path, Echo(), n=1, m=1, neighbor_dist=1.0, about={"trained_on": "test"}))
    assert model.spec.neighbor_dist == 1.0
    original = model.module
    model.module = lambda x: (recorded.append(x.clone()), original(x))[1]
    _, neighbors = model.velocity(world(), Goal([1, 0, 5]), neighbor_dist=6.0)
    assert neighbors.ids == () and neighbors.obstacle_names == ()
    np.testing.assert_allclose(recorded[0][0, 6:].numpy(), [2, 0, 0, 0, 0, 0, 2, 0, 0])
    without = load_model(save(tmp_path, Echo(), n=1, m=1, name="plain"))
    assert without.spec.neighbor_dist is None
    assert without.velocity(world(), Goal([1, 0, 5]), neighbor_dist=6.0)[1].ids == (2,)


@pytest.mark.parametrize("change,message", [
    ({"role": "basic_move"}, "role is 'basic_move': give one of path, agent_ad, agent_ap"),
    ({"outputs": ["vel.x", "vel.y", "vel.z"]}, "outputs is"),
    ({"image": {"height": 0, "width": 3}}, "image.height is 0"),
    ({"n_neighbors": -1}, "n_neighbors is -1"),
    ({"extra": 1}, "unknown key 'extra'"),
    ({"neighbor_dist": 0}, "neighbor_dist is 0: give the positive distance"),
    ({"neighbor_dist": "6"}, "neighbor_dist is '6'"),
])
def test_bad_specs_are_refused(tmp_path, change, message):
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)), **change)
    with pytest.raises(NeuralModelError, match=message):
        load_model(path)


def test_missing_and_broken_files_are_refused_naming_the_path(tmp_path):
    missing = tmp_path / "nowhere" / "net.pt"
    with pytest.raises(NeuralModelError, match=f"{missing}: no such TorchScript model file"):
        load_model(missing)
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)))
    spec_path(path).unlink()
    with pytest.raises(NeuralModelError, match=f"{spec_path(path)}: no such input spec"):
        load_model(path)
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a model")
    spec_path(junk).write_text(json.dumps({"role": "path", "n_neighbors": 0, "n_obstacles": 0,
                                           "inputs": input_names("path", 0, 0), "outputs": output_names(),
                                           "image": None}))
    with pytest.raises(NeuralModelError, match=f"{junk}: not a TorchScript model"):
        load_model(junk)
    spec_path(junk).write_text("{")
    with pytest.raises(NeuralModelError, match="junk.json: not a readable JSON file"):
        load_model(junk)


def test_models_that_fail_or_answer_the_wrong_size_are_refused_at_load(tmp_path):
    path = save(tmp_path, FourOutputs(), name="four")
    with pytest.raises(NeuralModelError, match=r"four.pt: the model answered \(1, 4\): it must give 3 values"):
        load_model(path)
    path = save(tmp_path, torch.nn.Linear(5, 3), name="narrow")  # a layer for 5 inputs, the spec says 21
    with pytest.raises(NeuralModelError) as err:
        load_model(path)
    assert str(err.value).startswith(f"{path}: the model fails on a zero vector [1, 21] as its spec narrow.json "
                                     "describes: RuntimeError: mat1 and mat2 shapes cannot be multiplied")
    assert "\n" not in str(err.value), "one line, not TorchScript's traceback"


def test_the_nai_keeps_one_model_per_role_and_hovers_for_a_role_without_one(tmp_path, caplog):
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver(), model_dir=tmp_path)
    with pytest.raises(ValueError, match="neural_network needs a model: give its path in text_value"):
        nav.control("neural_network", "set")
    assert nav.algorithm == "simple"
    save(tmp_path, TowardsGoal(input_size("path", 2, 1)), name="path_net")
    nav.control("neural_network", "set", text_value="path_net.pt")  # relative to model_dir
    assert set(nav.models) == {"path"}
    with caplog.at_level(logging.ERROR, logger="magna_uav.nai"):
        command = nav.velocity(world(), Goal([3, 0, 5], role="agent_ap", offset=[1, 0, 0]))
    assert "no model for role 'agent_ap' (loaded: path)" in command.error and not command.velocity.any()
    assert len(caplog.records) == 1
    save(tmp_path, TowardsGoal(input_size("agent_ap", 1, 0)), role="agent_ap", n=1, m=0, name="ap_net")
    nav.control("neural_network", "configure", ["model"], ["ap_net.pt"])
    assert set(nav.models) == {"path", "agent_ap"}
    command = nav.velocity(world(), Goal([1, 0, 5], role="agent_ap", offset=[1, 0, 0]))
    assert command.algorithm == "neural_network" and command.neighbors == (2,) and command.obstacles == ()
    np.testing.assert_allclose(command.velocity, [0.5, 0, 0], rtol=1e-6)
    # basic moves have no network: ORCA-3D flies them and the command says so
    command = nav.velocity(world(), Goal([0, 0, 7], role="basic_move"))
    assert command.algorithm == "orca3d" and not command.error
    # a failed load changes nothing
    with pytest.raises(NeuralModelError, match="missing.pt: no such TorchScript model file"):
        nav.control("neural_network", "configure", ["model"], ["missing.pt"])
    assert set(nav.models) == {"path", "agent_ap"} and nav.params()["model"] == str(tmp_path / "ap_net.pt")
    with pytest.raises(ValueError, match="give the model path once"):
        nav.control("neural_network", "set", ["model"], ["a.pt"], text_value="b.pt")


# --- the teacher (DAgger) and the safety fallback -----------------------------------------------------------------

def crossing_world():
    """UAV 2 comes head on 3 m ahead; a post stands 2 m to the left: ORCA-3D must turn away."""
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 5], velocity=[1.0, 0, 0], safety_radius=0.3))
    view.update_agent(AgentState(2, [3, 0.1, 5], velocity=[-1.0, 0, 0], safety_radius=0.3))
    view.set_obstacles([Obstacle("post", np.array([1.0, 2.0, 5]), 0.5)])
    return view


def test_while_a_network_flies_the_command_carries_orca3ds_answer_from_the_same_inputs(tmp_path):
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1)))
    teacher_params = (["N_neighbors_aware", "timeHorizon", "agent_radius"], [1, 4.0, 0.4])
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    nav.control("orca3d", "configure", *teacher_params)  # what the variant's ORCA configure state does
    nav.control("neural_network", "set", text_value=str(path))
    orca = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    orca.control("orca3d", "set", *teacher_params)
    for goal in (Goal([10, 0, 5]), Goal([2, 1, 6]), Goal([0, 0, 9])):
        flown, taught = nav.velocity(crossing_world(), goal), orca.velocity(crossing_world(), goal)
        assert flown.algorithm == "neural_network" and not flown.fallback
        np.testing.assert_array_equal(flown.teacher_velocity, taught.velocity)  # the same solve, bit for bit
    # head on, the network flies straight at UAV 2 while the teacher turns right, away from it and the post
    head_on = nav.velocity(crossing_world(), Goal([10, 0, 5]))
    assert head_on.velocity[1] == 0.0 and head_on.teacher_velocity[1] < -0.3
    # ORCA-3D flying, or a basic move under the network: nothing to relabel
    assert orca.velocity(crossing_world(), Goal([10, 0, 5])).teacher_velocity is None
    assert nav.velocity(crossing_world(), Goal([0, 0, 9], role="basic_move")).teacher_velocity is None
    # with other ORCA-3D parameters the teacher answers otherwise: it follows them
    nav.control("orca3d", "configure", ["timeHorizon"], [0.5])
    assert not np.allclose(nav.velocity(crossing_world(), Goal([10, 0, 5])).teacher_velocity,
                           orca.velocity(crossing_world(), Goal([10, 0, 5])).velocity)


def test_the_fallback_sends_the_teachers_answer_only_when_the_networks_would_collide(tmp_path):
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1), gain=1.0))
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    nav.control("neural_network", "set", ["fallback"], [1], text_value=str(path))
    assert nav.params("neural_network")["fallback"] == 1
    # straight at UAV 2: the network's command collides, the teacher's is sent
    into = nav.velocity(crossing_world(), Goal([10, 0, 5]))
    assert into.fallback and np.array_equal(into.velocity, into.teacher_velocity)
    # away from everything: the network's own command goes
    away = nav.velocity(crossing_world(), Goal([-10, -1, 5]))
    assert not away.fallback and not np.allclose(away.velocity, away.teacher_velocity)
    np.testing.assert_allclose(away.velocity, 2.0 * np.array([-10, -1, 0]) / np.hypot(10, 1), rtol=1e-6)
    # off by default: the plain network flies into it
    nav.control("neural_network", "configure", ["fallback"], [0])
    plain = nav.velocity(crossing_world(), Goal([10, 0, 5]))
    assert not plain.fallback and plain.velocity[0] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="fallback is 2: give 0 .* or 1"):
        nav.control("neural_network", "configure", ["fallback"], [2])


def test_teacher_0_skips_the_teachers_solve_unless_the_fallback_needs_it(tmp_path):
    path = save(tmp_path, TowardsGoal(input_size("path", 2, 1), gain=1.0))
    solves = []

    class CountingSolver(ReferenceSolver):
        def new_velocity(self, *args, **kwargs):
            solves.append(1)
            return super().new_velocity(*args, **kwargs)

    nav = NavigationInterface(2.0, 0.3, solver=CountingSolver())
    nav.control("neural_network", "set", ["teacher"], [0], text_value=str(path))
    alone = nav.velocity(crossing_world(), Goal([10, 0, 5]))
    assert alone.teacher_velocity is None and not alone.fallback and not solves
    assert alone.velocity[0] == pytest.approx(2.0)  # the network's own command, straight ahead
    # the fallback needs the teacher's answer: it is solved, and sent, all the same
    nav.control("neural_network", "configure", ["fallback"], [1])
    saved = nav.velocity(crossing_world(), Goal([10, 0, 5]))
    assert solves and saved.fallback and np.array_equal(saved.velocity, saved.teacher_velocity)
    with pytest.raises(ValueError, match="teacher is 0.5"):
        nav.control("neural_network", "configure", ["teacher"], [0.5])


@pytest.mark.parametrize("velocity,others,expected", [
    ([1, 0, 0], [AgentState(2, [3, 0, 5], velocity=[-1, 0, 0])], True),  # head on: closes 2 m/s, 2 m to go
    ([-1, 0, 0], [AgentState(2, [3, 0, 5], velocity=[-1, 0, 0])], False),  # same velocity: the gap stays
    ([0, 0.2, 0], [AgentState(2, [3, 0, 5], velocity=[-1, 0, 0])], True),  # too little aside: it runs into us
    ([0, 1, 0], [AgentState(2, [3, 0, 5], velocity=[-1, 0, 0])], False),  # enough aside: it passes 2.1 m off
    ([1, 0, 0], [AgentState(2, [9, 0, 5])], False),  # 8 m to the 1 m reach at 1 m/s: 8 s, beyond the 5 s horizon
    ([2, 0, 0], [AgentState(2, [9, 0, 5])], True),  # at 2 m/s: 4 s
    ([0, 0, 1], [AgentState(2, [0.5, 0, 5])], False),  # overlapping already, moving sideways: no closer
    ([-1, 0, 0], [AgentState(2, [0.5, 0, 5])], False),  # overlapping, moving away
    ([1, 0, 0], [AgentState(2, [0.5, 0, 5])], True),  # overlapping, moving closer
])
def test_would_collide_is_the_velocity_obstacle_within_the_horizon(velocity, others, expected):
    from magna_uav.nai.inputs import select_neighbors
    from magna_uav.nai.orca import would_collide

    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 5], safety_radius=0.3))
    for other in others:
        view.update_agent(other)
    neighbors = select_neighbors(view, 1, 0, 20.0)
    assert would_collide(view, np.array(velocity, float), neighbors, 0.3, 0.5, 5.0) is expected
