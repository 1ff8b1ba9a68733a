"""The hyperparameter file: sweeps, defaults and errors that name the file, the key and the fix."""
import json

import pytest

from mlr.config import ConfigError, load_sweep

BASE = {"world": "Gym", "subworld": "Empty_4_Cylinders", "mission": "Gym", "submission": "2UAVs_2paths_4_Cylinders"}


def write(tmp_path, values, name="sweep.yaml"):
    path = tmp_path / name
    if name.endswith(".json"):
        path.write_text(json.dumps(values))
    else:
        import yaml

        path.write_text(yaml.safe_dump(values))
    return path


def test_lists_sweep_scalars_and_lists_of_lists_sweep_list_values(tmp_path):
    path = write(tmp_path, BASE | {"hidden_layers": [[10, 10], [20, 30, 20]], "learning_rate": [0.001, 0.01],
                                   "datasets": [1, 2], "algorithm": "orca3"})
    sweep = load_sweep(path)
    assert sweep.name == "sweep" and sweep.swept == ("hidden_layers", "learning_rate")
    assert [(r.hidden_layers, r.learning_rate) for r in sweep.runs] == [
        ((10, 10), 0.001), ((10, 10), 0.01), ((20, 30, 20), 0.001), ((20, 30, 20), 0.01)]
    assert all(r.datasets == (1, 2) and r.algorithm == "orca3d" for r in sweep.runs)  # a list of ints: one value
    assert sweep.run_name(3) == "r03_hidden_layers=20-30-20_learning_rate=0.01"


def test_json_works_too_and_defaults_fill_the_rest(tmp_path):
    sweep = load_sweep(write(tmp_path, BASE, "plain.json"))
    (run,) = sweep.runs
    assert (run.role, run.n_neighbors, run.fvi, run.batch_size, run.model, run.split) == \
        ("path", 1, 0, 500, "mlp", (0.7, 0.2, 0.1))
    assert run.teacher.image is None and run.selection.datasets == (1,)


def test_a_sweep_of_datasets_is_a_list_of_lists(tmp_path):
    sweep = load_sweep(write(tmp_path, BASE | {"datasets": [[1], [1, 2]]}))
    assert [r.datasets for r in sweep.runs] == [(1,), (1, 2)]


def test_command_line_overrides_win(tmp_path):
    sweep = load_sweep(write(tmp_path, BASE | {"steps": 100}), {"steps": 7, "data_root": str(tmp_path)})
    assert sweep.runs[0].steps == 7 and sweep.runs[0].selection.data_root == tmp_path


@pytest.mark.parametrize("change,message", [
    ({"hiden_layers": [10]}, r"unknown key 'hiden_layers': known keys are world, "),
    ({"batch_size": 0}, r"batch_size is 0: give a whole number >= 1"),
    ({"learning_rate": [0.1, -1]}, r"learning_rate is -1: give a positive number"),
    ({"role": "land"}, r"role is 'land': give one of path, agent_ad, agent_ap"),
    ({"model": "rnn"}, r"model is 'rnn': give one of mlp, cnn"),
    ({"source": "rosbag"}, r"source is 'rosbag': give one of csv, bag"),
    ({"algorithm": "orca"}, r"algorithm is 'orca': give one of orca3d, simple, neural_network"),
    ({"loss": "huber"}, r"loss is 'huber': give one of mse, l1, norm"),
    ({"subworld": "Empty/4"}, r"subworld is 'Empty/4': give a plain name without '/'"),
    ({"split": [0.5, 0.2, 0.1]}, r"split is .*: give \[train, validation, test\] shares that add up to 1"),
    ({"image_size": [8]}, r"image_size is \[8\]: give \[height, width\]"),
    ({"model": "cnn", "padding": "valid", "image_size": [8, 8], "conv_depth": 3, "patch_size": 5},
     r"image_size \[8, 8\] is too small for 3 valid convolutions"),
])
def test_bad_values_name_the_file_the_key_and_the_fix(tmp_path, change, message):
    path = write(tmp_path, BASE | change)
    with pytest.raises(ConfigError, match=f"{path}: {message}"):
        load_sweep(path)


def test_missing_selection_and_broken_files_are_refused(tmp_path):
    path = write(tmp_path, {"world": "Gym"})
    with pytest.raises(ConfigError, match=f"{path}: subworld is missing"):
        load_sweep(path)
    broken = tmp_path / "broken.yaml"
    broken.write_text("world: [Gym\n")
    with pytest.raises(ConfigError, match=f"{broken}: not valid YAML"):
        load_sweep(broken)
    with pytest.raises(ConfigError, match="cannot read the config"):
        load_sweep(tmp_path / "absent.yaml")


def test_the_shipped_thesis_configs_load():
    from pathlib import Path

    from mlr.dagger import load_config
    from mlr.gym import rl

    configs = sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.yaml"))
    assert len(configs) >= 3
    for path in configs:
        if path.name.startswith("dagger_"):
            assert load_config(path).run.hidden_layers == (128, 128, 128)  # the network imitation left colliding
            continue
        if path.name.startswith("rl_"):  # magna learn rl's configs
            assert rl.load_config(path).total_steps >= 1
            continue
        sweep = load_sweep(path)
        assert sweep.runs and all(run.world and run.submission for run in sweep.runs)
    thesis = load_sweep(Path(__file__).resolve().parents[1] / "configs" / "thesis_four_cylinders.yaml")
    architectures = [(10, 10), (30, 30), (10, 20, 10), (20, 30, 20), (128, 128, 128)]
    assert [r.hidden_layers for r in thesis.runs][::2] == architectures
    assert [r.augment for r in thesis.runs][:2] == ["none", "yaw"]


def test_the_roles_a_config_may_give_are_those_the_nai_has_inputs_for():
    from typing import get_args

    from magna_uav.nai.inputs import ROLE_BLOCKS
    from mlr.config import Role

    assert get_args(Role) == tuple(ROLE_BLOCKS)
