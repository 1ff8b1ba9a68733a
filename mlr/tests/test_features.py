"""Geometric features (`features: geometric`): the right numbers from the raw vector, a residual that makes
free flight trivial, and an export that the NAI flies from the thesis's input vector unchanged."""
import dataclasses
import json

import numpy as np
import pytest
import torch

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_names
from magna_uav.nai.neural import load_model
from magna_uav.nai.simple import simple_velocity
from magna_uav.world_view import AgentState, Obstacle, WorldView
from mlr.config import ConfigError, load_sweep
from mlr.export import export
from mlr.features import GeometricFeatures, expand, transformed
from mlr.preprocess import prepare
from mlr.tests.test_train_export import config, teacher_like
from mlr.train import load_trained, train_run

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")


def scene():
    view = WorldView(1)
    view.update_agent(AgentState(1, [1, 1, 3], velocity=[1.0, 0, 0], safety_radius=0.3))
    view.update_agent(AgentState(2, [4, 1, 3], velocity=[-1.0, 0.5, 0], safety_radius=0.3))
    view.set_obstacles([Obstacle("ball", np.array([1, 3, 3.0]), 0.25)])
    return view


def test_the_features_are_the_scenes_distances_directions_closing_speeds_and_preferred_velocity():
    view, goal = scene(), Goal([1.5, 1, 4])  # the goal 1.1 m away: within the 2 m braking distance
    x = build_inputs(view, goal, "path", 1, 2, 6.0)  # the second obstacle slot is padding
    features = GeometricFeatures("path", 1, 2, 6.0, 2.0)
    extra, preferred = (t.numpy()[0] for t in features(torch.tensor(x).reshape(1, -1)))
    want_preferred, _ = simple_velocity(view.own, goal, 2.0)
    np.testing.assert_allclose(preferred, want_preferred, atol=1e-12)
    np.testing.assert_allclose(extra[4:7], want_preferred, atol=1e-12)
    np.testing.assert_allclose(extra[:4], [np.hypot(0.5, 1), 0.5 / np.hypot(0.5, 1), 0, 1 / np.hypot(0.5, 1)])
    # UAV 2, 3 m ahead, coming at us: closing at 2 m/s, drifting 0.5 m/s sideways (relative: -0.5)
    np.testing.assert_allclose(extra[7:16], [3, 1, 0, 0, 2.0, 0, -0.5, 0, 1])
    # the ball, 2 m to the left, which we pass at 1 m/s without closing in
    np.testing.assert_allclose(extra[16:25], [2, 0, 1, 0, 0.0, 1.0, 0, 0, 1])
    # the padded slot reads as absent
    assert extra[25 + 8] == 0 and extra[25] == 12.0


def test_a_residual_on_the_preferred_velocity_learns_what_raw_inputs_do_not_in_the_same_steps(tmp_path):
    data = teacher_like()  # the goal velocity of simple guidance, plus a push away from a near neighbour
    run = config(steps=800)
    plain = train_run(run, prepare(data), tmp_path / "plain", "plain", progress=False)
    geometric = dataclasses.replace(run, features="geometric")
    with_features = train_run(geometric, prepare(transformed(data, geometric)), tmp_path / "geo", "geo",
                              progress=False)
    # far from the neighbour the residual is 0: the features network gets those right at once
    assert with_features.test_accuracy > plain.test_accuracy + 0.1, (with_features.test_accuracy,
                                                                     plain.test_accuracy)
    x, y = expand(data.x[:5], data.y[:5], GeometricFeatures("path", 1, 0, 6.0, 2.0))
    assert x.shape == (5, 12 + 16) and np.array_equal(x[:, :12], data.x[:5])


def test_a_features_network_exports_for_the_thesis_input_vector_and_the_nai_flies_it(tmp_path):
    data = teacher_like()
    run = config(steps=300, features="geometric")
    prepared = prepare(transformed(data, run))
    train_run(run, prepared, tmp_path / "run", "r00", progress=False)
    net, _ = load_trained(tmp_path / "run", prepared.train.x.shape[1])
    path = export(net, run, prepared, tmp_path / "geo.pt")  # checked against the trained network on export
    assert json.loads(path.with_suffix(".json").read_text())["inputs"] == input_names("path", 1, 0)
    model = load_model(path)
    features = GeometricFeatures("path", 1, 0, 6.0, 2.0)
    for k in range(20):
        raw = data.x[k]
        extra, preferred = (t.numpy()[0] for t in features(torch.tensor(raw).reshape(1, -1)))
        z = prepared.x_norm.apply(np.concatenate([raw, extra])[None])
        with torch.no_grad():
            change = prepared.y_norm.invert(net(torch.tensor(z, dtype=torch.float32)).numpy())[0]
        np.testing.assert_allclose(model.predict(raw), preferred + change, atol=1e-4)


def test_features_are_refused_with_augmentation_or_a_cnn(tmp_path):
    path = tmp_path / "c.json"
    for changes in ({"augment": "yaw"}, {"model": "cnn"}):
        path.write_text(json.dumps({"world": "Gym", "subworld": "w", "mission": "Gym", "submission": "m",
                                    "features": "geometric"} | changes))
        with pytest.raises(ConfigError, match="features geometric is for an mlp without augmentation"):
            load_sweep(path)
