"""mlr.gym.export: a PPO policy, with VecNormalize's statistics, exported for the NAI and flown by it."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecNormalize

from magna_uav.nai.goal import Goal
from magna_uav.nai.interface import NavigationInterface
from mlr.gym.export import export_policy
from mlr.gym.scenario import load_scenario
from mlr.gym.vector import SwarmVecEnv
from tests.support import CORPUS


@pytest.fixture(scope="module")
def trained():
    torch.set_num_threads(1)
    scenario = load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])
    venv = VecNormalize(SwarmVecEnv(scenario, copies=2, max_steps=40), norm_reward=False)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=128, n_epochs=2, seed=0, device="cpu")
    model.learn(512)  # enough to move VecNormalize's statistics away from 0 and 1
    yield model, venv
    venv.close()


def test_the_export_answers_as_the_policy_does_and_the_nai_flies_it(tmp_path, trained):
    model, venv = trained
    assert not np.allclose(venv.obs_rms.mean, 0.0)
    path = export_policy(model, tmp_path / "ppo.pt", 1, 2, 6.0, normalize=venv)
    observation = venv.get_original_obs()[0]
    expected, _ = model.predict(venv.normalize_obs(observation[None]), deterministic=True)
    nav = NavigationInterface(2.0, 0.3)
    nav.control("neural_network", "set", text_value=str(path))
    view = venv.venv.swarm.view(0, 0)  # the state that observation describes
    command = nav.velocity(view, Goal(venv.venv.swarm.goal(0, 0)))
    assert command.algorithm == "neural_network"
    limited = expected[0] * min(1.0, 2.0 / np.linalg.norm(expected[0]))  # the NAI saturates to max_speed
    np.testing.assert_allclose(command.velocity, limited, atol=1e-5)


def test_an_export_refuses_to_overwrite_and_a_wrong_layout(tmp_path, trained):
    model, venv = trained
    export_policy(model, tmp_path / "ppo.pt", 1, 2, 6.0, normalize=venv)
    with pytest.raises(FileExistsError, match="ppo.pt: already exists"):
        export_policy(model, tmp_path / "ppo.pt", 1, 2, 6.0, normalize=venv)
    with pytest.raises(ValueError, match=r"takes \(18,\) observations.*has 24 inputs"):
        export_policy(model, tmp_path / "other.pt", 2, 2, 6.0, normalize=venv)
    assert not (tmp_path / "other.pt").exists() and not (tmp_path / "other.json").exists()


def test_a_policy_on_geometric_features_exports_them_inside_the_module(tmp_path):
    from magna_uav.nai.neural import load_model
    from mlr.features import GeometricFeatures
    from mlr.gym.policy_features import GeometricExtractor

    torch.set_num_threads(1)
    scenario = load_scenario("Gym/1Obs_Central_Cylinder", "Gym/2UAVs_2paths_Central_Cylinder", [CORPUS])
    venv = VecNormalize(SwarmVecEnv(scenario, copies=1, max_steps=40), norm_obs=False)
    kwargs = {"n_neighbors": 1, "n_obstacles": 2, "neighbor_dist": 6.0, "max_speed": 2.0}
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu",
                policy_kwargs={"features_extractor_class": GeometricExtractor, "features_extractor_kwargs": kwargs})
    try:
        model.learn(128)
        extractor = model.policy.pi_features_extractor
        assert extractor.features_dim == 18 + GeometricFeatures("path", 1, 2, 6.0, 2.0).size
        path = export_policy(model, tmp_path / "geo.pt", 1, 2, 6.0, normalize=venv)  # checked against SB3 inside
        observations = venv.get_original_obs()
        expected, _ = model.predict(observations, deterministic=True)
        np.testing.assert_allclose(load_model(path).predict(observations[0], None), expected[0], atol=1e-5)
    finally:
        venv.close()
