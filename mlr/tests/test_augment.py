"""Yaw augmentation: a turned sample is a sample the teacher would have given (checked with
ORCA-3D itself), and padding and scalars stay as the NAI makes them."""
import numpy as np
import torch

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_names
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, Obstacle, WorldView
from mlr.augment import YawAugmenter


def scene(rng, far_obstacle=False):
    """A UAV, a neighbour close enough for ORCA-3D to act, one near obstacle and maybe a far one."""
    view = WorldView(1)
    own = np.array([0.0, 0.0, 3.0])
    view.update_agent(AgentState(1, own, velocity=rng.uniform(-1.5, 1.5, 3), safety_radius=0.3))
    view.update_agent(AgentState(2, own + rng.uniform(-2.5, 2.5, 3), velocity=rng.uniform(-1.5, 1.5, 3),
                                 safety_radius=0.3))
    obstacles = [Obstacle("near", own + rng.uniform(-3, 3, 3), 0.4)]
    if far_obstacle:
        obstacles.append(Obstacle("far", own + [30.0, 0, 0], 0.4))
    view.set_obstacles(obstacles)
    return view, Goal(own + rng.uniform(-8, 8, 3))


def orca():
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    nav.control("orca3d", "set", ["N_neighbors_aware", "N_obstacles_aware"], [1, 2])
    return nav


def turned_scene(view, goal, angle):
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    own = view.own.position
    out = WorldView(1)
    for agent in (view.own, view.agent(2)):
        out.update_agent(AgentState(agent.id, own + turn @ (agent.position - own), velocity=turn @ agent.velocity,
                                    safety_radius=agent.safety_radius))
    out.set_obstacles([Obstacle(o.name, own + turn @ (o.position - own), o.radius) for o in view.obstacles])
    return out, Goal(own + turn @ (goal.position - own)), turn


def test_a_turned_orca_sample_is_what_orca_answers_for_the_turned_scene():
    rng = np.random.default_rng(4)
    augmenter = YawAugmenter("path", 1, 2, 6.0)
    nav = orca()
    checked = 0
    for k in range(40):
        view, goal = scene(rng, far_obstacle=k % 2 == 0)
        x = torch.tensor(build_inputs(view, goal, "path", 1, 2, 6.0), dtype=torch.float64).reshape(1, -1)
        y = torch.tensor(nav.velocity(view, goal).velocity, dtype=torch.float64).reshape(1, 3)
        generator = torch.Generator().manual_seed(k)
        angle = float(torch.rand(1, generator=torch.Generator().manual_seed(k))[0] * 2 * np.pi)
        tx, ty = augmenter(x, y, generator)
        turned_view, turned_goal, _ = turned_scene(view, goal, angle)
        want_x = build_inputs(turned_view, turned_goal, "path", 1, 2, 6.0)
        np.testing.assert_allclose(tx[0].numpy(), want_x, atol=1e-6)  # padding included
        np.testing.assert_allclose(ty[0].numpy(), nav.velocity(turned_view, turned_goal).velocity, atol=1e-6)
        checked += 1
    assert checked == 40


def test_padding_and_scalars_stay_and_lengths_are_kept():
    names = input_names("agent_ad", 2, 1)
    augmenter = YawAugmenter("agent_ad", 2, 1, 6.0)
    x = torch.zeros(3, len(names))
    x[:, names.index("distance")] = 1.5
    x[:, names.index("own_vel.x")] = 1.0
    x[:, names.index("others_pos_rel[0].y")] = 2.0
    for block in ("others_pos_rel[1]", "obstacles_pos_rel[0]"):
        x[:, names.index(f"{block}.x")] = 12.0  # padding at 2 x 6 m
    y = torch.tensor([[1.0, 0.0, 0.5]] * 3)
    tx, ty = augmenter(x, y, torch.Generator().manual_seed(1))
    assert torch.all(tx[:, names.index("distance")] == 1.5)
    for block in ("others_pos_rel[1]", "obstacles_pos_rel[0]"):
        assert torch.all(tx[:, [names.index(f"{block}.{a}") for a in "xyz"]] == torch.tensor([12.0, 0, 0]))
    own = tx[:, [names.index(f"own_vel.{a}") for a in "xy"]]
    torch.testing.assert_close(own.norm(dim=1), torch.ones(3))
    assert not torch.allclose(own, torch.tensor([[1.0, 0.0]] * 3))  # turned
    torch.testing.assert_close(ty.norm(dim=1), y.norm(dim=1))
    torch.testing.assert_close(ty[:, 2], y[:, 2])
