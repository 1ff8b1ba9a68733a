"""`magna learn rl`: the config's checks, a short PPO run that improves its return, and the resumption."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from mlr.gym.ppo_training import latest_checkpoint, train
from mlr.gym.rl import prepare_output
from mlr.gym.rl_config import RlConfig, RlError, load_config
from tests.support import CORPUS

SHIPPED = Path(__file__).resolve().parents[1] / "configs" / "rl_four_cylinders.yaml"


def config_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "rl.yaml"
    path.write_text(text)
    return path


def quick(**change) -> RlConfig:
    import dataclasses

    return dataclasses.replace(load_config(SHIPPED), **change)


def test_the_shipped_config_loads():
    config = load_config(SHIPPED)
    assert config.world == "Gym/Empty_4_Cylinders" and config.n_obstacles == 0 and config.copies == 8


@pytest.mark.parametrize("text,message", [
    ("world: Gym/Empty_4_Cylinders\nmission: Gym/2UAVs_2paths_4_Cylinders\ncopies: 0\n", "copies is 0: give copies"),
    ("world: Gym\nmission: Gym/2UAVs_2paths_4_Cylinders\n", "world is 'Gym': give the world"),
    ("world: Gym/A\nmission: Gym/B\nsteps: 3\n", "unknown key 'steps'"),
    ("world: Gym/A\nmission: Gym/B\nreward: {crash: 1}\n", "reward.crash is not a reward weight"),
    ("world: Gym/A\nmission: Gym/B\nneighbor_dist: -1\n", "neighbor_dist is -1"),
    ("world: Gym/A\nmission: Gym/B\nencounters: 2\n", "encounters is 2: give share of episodes"),
    ("world: Gym/A\nmission: Gym/B\nfeatures: polar\n", "features is 'polar': give none .* or geometric"),
])
def test_config_errors_name_the_file_and_the_key(tmp_path, text, message):
    path = config_file(tmp_path, text)
    with pytest.raises(RlError, match=message) as err:
        load_config(path)
    assert str(path) in str(err.value)


def test_a_short_run_improves_its_return_and_exports_a_policy_the_nai_loads(tmp_path):
    from magna_uav.nai.neural import load_model

    config = quick(total_steps=40_000, checkpoint_every=100_000, eval_flights=8)
    numbers = train(config, tmp_path / "run", [CORPUS], progress=False)
    assert numbers["episodes"] > 50
    assert numbers["last_mean_return"] > numbers["first_mean_return"] + 10.0  # about -22 -> +1 on this seed
    policy = load_model(tmp_path / "run" / "policy.pt")
    assert policy.spec.role == "path" and policy.spec.n_obstacles == 0
    written = json.loads((tmp_path / "run" / "rl.json").read_text())
    assert written["steps"] == numbers["steps"]
    final = written["evaluation"]  # whole missions flown in the gym by the final policy
    assert final["steps"] == numbers["steps"] and final["flights"] == config.eval_flights
    assert final["succeeded"] + final["collided"] + final["timed_out"] == final["flights"]
    assert written["success_rate"] == final["succeeded"] / final["flights"] and written["history"] == [final]
    assert any((tmp_path / "run" / "tensorboard").rglob("events.out.tfevents.*"))


def test_a_run_goes_on_from_its_latest_checkpoint_and_refuses_another_configs_folder(tmp_path):
    out = tmp_path / "run"
    first = quick(total_steps=8192, checkpoint_every=4096, copies=2, eval_flights=2)
    prepare_output(first, out, force=False)
    train(first, out, [CORPUS], progress=False)
    assert latest_checkpoint(out / "checkpoints")[0] == 8192
    longer = quick(total_steps=12288, checkpoint_every=4096, copies=2, eval_flights=2)
    prepare_output(longer, out, force=False)  # only total_steps differs: the same run, going on
    numbers = train(longer, out, [CORPUS], progress=False)
    assert numbers["resumed_from"] == 8192 and numbers["steps"] == 12288
    # the success rate at each checkpoint, with the training time it took, across the interruption
    history = numbers["history"]
    assert [entry["steps"] for entry in history] == [4096, 8192, 12288]
    assert history[0]["wall_seconds"] < history[1]["wall_seconds"] < history[2]["wall_seconds"]
    assert json.loads((out / "history.json").read_text()) == history
    assert (out / "success.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    other = quick(total_steps=8192, checkpoint_every=4096, copies=3, eval_flights=2)
    with pytest.raises(RlError, match="differs in copies.*--force"):
        prepare_output(other, out, force=False)
    prepare_output(other, out, force=True)
    assert latest_checkpoint(out / "checkpoints") is None
