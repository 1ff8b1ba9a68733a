"""Training reduces the loss; the export is the trained network (normalisation inside) and
the NAI loads and flies it."""
import dataclasses
import json

import numpy as np
import pytest
import torch

from magna_uav.nai.goal import Goal
from magna_uav.nai.inputs import build_inputs, input_names
from magna_uav.nai.interface import NavigationInterface
from magna_uav.nai.neural import load_model
from magna_uav.nai.orca import ReferenceSolver
from magna_uav.world_view import AgentState, WorldView
from mlr.config import RunConfig
from mlr.export import export, wrap
from mlr.models import CNNMLP, build_model
from mlr.pickler import Samples
from mlr.preprocess import prepare
from mlr.train import evaluate, load_trained, train_run

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")


def teacher_like(n=3000, seed=0, image=False):
    """A velocity towards the goal, saturated at 2 m/s, plus a push away from a near neighbour."""
    rng = np.random.default_rng(seed)
    x = np.zeros((n, 12))
    x[:, 0:3] = rng.uniform(-2, 2, (n, 3))  # own velocity
    x[:, 3:6] = rng.uniform(-8, 8, (n, 3))  # goal relative
    x[:, 6:9] = rng.uniform(-6, 6, (n, 3))  # neighbour relative
    goal = x[:, 3:6]
    y = goal / np.maximum(np.linalg.norm(goal, axis=1, keepdims=True) / 2.0, 1.0)
    near = np.linalg.norm(x[:, 6:9], axis=1) < 2.0
    y[near] -= 0.5 * x[near, 6:9]
    images = None
    if image:
        images = rng.uniform(0, 20, (n, 8, 8)).astype(np.float32)
        # z depends on the upper half of the image, as much as on the inputs: the image carries
        # information that no input has (about 1 m/s of z's spread)
        y[:, 2] += (images[:, :4, :].mean(axis=(1, 2)) - 10.0) * 1.5
    return Samples(x, y, np.full(n, 2.0), np.zeros(n, dtype=int), np.arange(n), ["synthetic"], images)


def images_shuffled(samples: Samples, seed: int = 1) -> Samples:
    """The same samples with the images dealt out to other samples: the images tell nothing of the labels."""
    assert samples.images is not None
    order = np.random.default_rng(seed).permutation(len(samples.images))
    return dataclasses.replace(samples, images=samples.images[order])


def config(**changes):
    values = {"steps": 1500, "batch_size": 128, "eval_every": 250} | changes
    return RunConfig("Gym", "w", "Gym", "m", **values)


def test_a_short_training_reduces_the_loss_and_logs_to_tensorboard(tmp_path):
    prepared = prepare(teacher_like())
    run = config()
    torch.manual_seed(run.seed)
    untrained_loss, untrained_acc, _ = evaluate(build_model(run, 12), prepared.test, prepared)
    result = train_run(run, prepared, tmp_path / "run", "r00", progress=False)
    assert result.test_loss < 0.3 * untrained_loss
    assert result.test_accuracy > untrained_acc + 0.2
    saved = json.loads((tmp_path / "run" / "result.json").read_text())
    assert saved["config"]["hidden_layers"] == [20, 30, 20] and saved["samples"] == {"train": 2100, "val": 600,
                                                                                     "test": 300}
    events = list((tmp_path / "run" / "tb").rglob("events.out.tfevents.*"))
    assert events, "TensorBoard events are written"
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    tags = set()
    for event_file in events:
        acc = EventAccumulator(str(event_file), size_guidance={"histograms": 0, "scalars": 0})
        acc.Reload()
        tags |= set(acc.Tags()["scalars"]) | set(acc.Tags()["histograms"])
    assert {"loss/train", "loss/val", "accuracy/val", "accuracy/test"} <= tags
    assert any(tag.endswith("weight") for tag in tags) and any(tag.endswith("bias") for tag in tags)


def test_sgd_trains_too_and_a_diverging_run_says_what_to_change(tmp_path):
    prepared = prepare(teacher_like(600))
    result = train_run(config(optimizer="sgd", learning_rate=0.05, steps=300), prepared, tmp_path / "sgd", "sgd",
                       progress=False)
    assert np.isfinite(result.test_loss)
    with pytest.raises(FloatingPointError, match="lower learning_rate"):
        train_run(config(optimizer="sgd", learning_rate=1e6, steps=300), prepared, tmp_path / "bad", "bad",
                  progress=False)


def test_the_export_gives_the_trained_outputs_and_the_nai_flies_it(tmp_path):
    data = teacher_like()
    prepared = prepare(data)
    run = config(steps=400)
    train_run(run, prepared, tmp_path / "run", "r00", progress=False)
    net, _ = load_trained(tmp_path / "run", 12)
    path = export(net, run, prepared, tmp_path / "net.pt", about={"note": "test"})
    spec = json.loads(path.with_suffix(".json").read_text())
    assert spec["inputs"] == input_names("path", 1, 0) and spec["neighbor_dist"] == 6.0 and spec["image"] is None
    # the exported file answers in m/s what the trained network answers through the normalisation
    raw = data.x[:50]
    with torch.no_grad():
        by_hand = prepared.y_norm.invert(net(torch.tensor(prepared.x_norm.apply(raw), dtype=torch.float32)).numpy())
    model = load_model(path)
    for k in range(50):
        np.testing.assert_allclose(model.predict(raw[k]), by_hand[k], atol=1e-4)
    # and the NAI flies it: the command is the network's answer to the vector of magna_uav.nai.inputs
    view = WorldView(1)
    view.update_agent(AgentState(1, [0, 0, 3], velocity=[0.5, 0, 0], safety_radius=0.3))
    view.update_agent(AgentState(2, [1.5, 0.5, 3], velocity=[-1, 0, 0], safety_radius=0.3))
    nav = NavigationInterface(2.0, 0.3, solver=ReferenceSolver())
    nav.control("neural_network", "set", text_value=str(path))
    goal = Goal([4, 1, 3])
    command = nav.velocity(view, goal)
    assert command.algorithm == "neural_network" and not command.error and command.neighbors == (2,)
    expected = model.predict(build_inputs(view, goal, "path", 1, 0, 6.0))
    np.testing.assert_allclose(command.velocity, expected * min(1.0, 2.0 / np.linalg.norm(expected)), atol=1e-9)


def test_an_export_is_never_written_over_without_overwrite(tmp_path):
    prepared = prepare(teacher_like(300))
    run = config(steps=10)
    net = build_model(run, 12)
    path = export(net, run, prepared, tmp_path / "net.pt")
    before = path.read_bytes()
    with pytest.raises(FileExistsError, match="net.pt: already exists; pass --force"):
        export(build_model(run, 12), run, prepared, path)
    assert path.read_bytes() == before
    export(build_model(run, 12), run, prepared, path, overwrite=True)
    with pytest.raises(ValueError, match="is a .pt file"):
        export(net, run, prepared, tmp_path / "net.onnx")


def test_a_cnn_learns_from_the_depth_image_and_exports_with_its_image_spec(tmp_path):
    data = teacher_like(1500, image=True)
    prepared = prepare(data)
    # average pooling: the label depends on a mean over part of the image
    run = config(model="cnn", image_size=(8, 8), conv_depth=2, conv_channels=4, patch_size=3, pooling="avg",
                 steps=600)
    net = build_model(run, 12)
    assert isinstance(net, CNNMLP)
    before, _, _ = evaluate(net, prepared.test, prepared)
    result = train_run(run, prepared, tmp_path / "cnn", "cnn", progress=False)
    assert result.test_loss < 0.5 * before
    # The control: the same training (same seeds, split and steps) with the images dealt out to other
    # samples. The inputs alone explain part of the labels; only a network that reads the image
    # explains the rest, so on the held-out part the real pairing must do clearly better.
    blind = train_run(run, prepare(images_shuffled(data)), tmp_path / "blind", "blind", progress=False)
    assert result.test_loss < 0.7 * blind.test_loss, (result.test_loss, blind.test_loss)
    trained, _ = load_trained(tmp_path / "cnn", 12)
    path = export(trained, run, prepared, tmp_path / "cnn.pt")
    assert json.loads(path.with_suffix(".json").read_text())["image"] == {"height": 8, "width": 8}
    model = load_model(path)
    with torch.no_grad():
        module = wrap(trained, prepared)
        x = torch.tensor(data.x[:3], dtype=torch.float32)
        want = module(torch.tensor(data.images[:3]).unsqueeze(1), x).numpy()
    for k in range(3):
        np.testing.assert_allclose(model.predict(data.x[k], data.images[k]), want[k], atol=1e-4)
