"""Why the thesis's small networks fall short of its accuracies on our data: measurements on one scenario
(`magna learn thesis --stages analysis`, mlr/README.md "Why the thesis's networks fall short").

On the scenario's dataset, split as training splits it:
1. Label noise. ORCA-3D is solved again (numpy reference) from each test sample's input vector alone:
   the own UAV at the origin with its velocity, the goal, the neighbours and obstacles the vector holds
   (padding: absent), the mission's ORCA-3D parameters and the obstacles' radius. The share of samples
   whose label it reproduces within accuracy's tolerance is the best accuracy any function of these inputs
   can reach: 100 % means the labels are a function of the inputs, with no noise.
2. The class of the problem. A sample is an avoidance when the label differs from the preferred velocity
   (where simple guidance would fly) by more than the tolerance: ORCA-3D acted. Their share, and the
   20-30-20's accuracy on avoidances and on free flight apart. Predicting the preferred velocity scores
   exactly the free share.
3. Input scaling: the 20-30-20 with standard-deviation scaling of the inputs against max-abs (ours and
   the thesis's).
4. The amount of data: the 20-30-20 on 25 %, 50 % and 100 % of the training part.
5. The only accuracy the original's repository ever computed (gauss/scripts/rebeca/red_1_1.py, 2018):
   whether the largest component of the prediction is the largest of the label (argmax agreement).

The 20-30-20 is the thesis's best small architecture; every run trains it as the scenario's config does.
Writes OUT/analysis.json and OUT/analysis.md.
"""
from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from magna_common.files import write_text_atomically
from mlr.config import RunConfig
from mlr.metrics import TOLERANCE, within_tolerance
from mlr.relabel import orca_from_inputs, teacher_nai, teacher_setup

SHARES = (0.25, 0.5, 1.0)
BASELINE_LAYERS = (20, 30, 20)


def argmax_agreement(predicted: np.ndarray, labels: np.ndarray) -> float:
    """The original's accuracy: the largest component of the prediction is the label's largest (signed, as
    numpy.argmax over axis 1 compares them)."""
    return float(np.mean(np.argmax(predicted, axis=1) == np.argmax(labels, axis=1))) if len(labels) else math.nan


def analyse(run: RunConfig, out: Path, progress: bool = True, log: Callable[[str], None] = print) -> dict:
    """The measurements of the module docstring on `run`'s dataset; also written to out/analysis.json and .md."""
    from mlr import cache
    from mlr.pickler import find_simulations
    from mlr.preprocess import Part, split_indices
    from mlr.train import evaluate, load_trained, train_run

    run = dataclasses.replace(run, hidden_layers=BASELINE_LAYERS, augment="none", model="mlp")
    sims, _ = find_simulations(run.selection)
    samples, key, _ = cache.cached_samples(run.selection, run.teacher, run.source, sims)
    prepared, _ = cache.cached_prepared(samples, key, run.selection.data_root, run.split, run.seed)
    test = split_indices(len(samples), run.split, run.seed)[2]
    x_test, y_test, speed = samples.x[test], samples.y[test], samples.max_speed[test]

    setup = teacher_setup(sims[0], run)
    nav = teacher_nai(setup)
    solved = [orca_from_inputs(x, run, setup, nav) for x in x_test]
    recomputed = np.array([s[0] for s in solved]).reshape(-1, 3)
    preferred = np.array([s[1] for s in solved]).reshape(-1, 3)
    reproduced = within_tolerance(recomputed, y_test, speed)
    free = within_tolerance(preferred, y_test, speed)
    log(f"{run.subworld}: ORCA-3D from the inputs alone reproduces {reproduced.mean() * 100:.1f}% of the labels; "
        f"{(~free).mean() * 100:.1f}% of the samples are avoidances")

    out.mkdir(parents=True, exist_ok=True)
    trainings = {}
    variants = [("max-abs, 100%", run, 1.0),
                ("standard, 100%", dataclasses.replace(run, normalization="standard"), 1.0)]
    variants += [(f"max-abs, {int(share * 100)}%", run, share) for share in SHARES if share < 1.0]
    for label, variant, share in variants:
        folder = out / label.replace(", ", "_").replace("%", "").replace("-", "")
        data = prepared if variant.normalization == run.normalization else \
            cache.cached_prepared(samples, key, run.selection.data_root, run.split, run.seed,
                                  normalization=variant.normalization)[0]
        if share < 1.0:
            keep = int(round(len(data.train) * share))
            part = data.train
            data = dataclasses.replace(data, train=Part(part.x[:keep], part.y[:keep], part.y_raw[:keep],
                                                         part.max_speed[:keep]))
        result_file = folder / "result.json"
        if not result_file.is_file():
            train_run(variant, data, folder, f"20-30-20 {label}", progress=progress)
        result = json.loads(result_file.read_text())["result"]
        net, _ = load_trained(folder, data.train.x.shape[1])
        _, _, predicted = evaluate(net, data.test, data)
        right = within_tolerance(predicted, data.test.y_raw, data.test.max_speed)
        trainings[label] = {"train_samples": len(data.train), "test_accuracy": result["test_accuracy"],
                            "on_avoidances": float(right[~free].mean()) if (~free).any() else None,
                            "on_free_flight": float(right[free].mean()) if free.any() else None,
                            "argmax_agreement": argmax_agreement(predicted, data.test.y_raw)}
        log(f"{run.subworld}: 20-30-20 {label}: test accuracy {result['test_accuracy'] * 100:.1f}%")
    findings = {"scenario": f"{run.world}/{run.subworld}", "test_samples": int(len(test)),
                "tolerance_m_s": float(TOLERANCE * speed[0]) if len(speed) else None,
                "obstacle_radius": setup.obstacle_radius, "orca_params": list(setup.orca_params),
                "labels_reproduced_from_inputs": float(reproduced.mean()),
                "median_error_of_recomputation_m_s": float(np.median(np.linalg.norm(recomputed - y_test, axis=1))),
                "avoidance_share": float((~free).mean()), "preferred_velocity_accuracy": float(free.mean()),
                "trainings": trainings}
    write_text_atomically(out / "analysis.json", json.dumps(findings, indent=2) + "\n", overwrite=True)
    write_text_atomically(out / "analysis.md", markdown([findings]), overwrite=True)
    return findings


def _pct(value) -> str:
    return "-" if value is None else f"{value * 100:.1f}%"


def markdown(all_findings: list[dict]) -> str:
    lines = ["| measure | " + " | ".join(f["scenario"] for f in all_findings) + " |",
             "|---|" + "---|" * len(all_findings)]

    def row(title: str, values) -> None:
        lines.append(f"| {title} | " + " | ".join(values) + " |")

    row("test samples", [str(f["test_samples"]) for f in all_findings])
    row("labels ORCA-3D reproduces from the input vector alone (the ceiling)",
        [_pct(f["labels_reproduced_from_inputs"]) for f in all_findings])
    row("avoidances: label off the preferred velocity by more than the tolerance",
        [_pct(f["avoidance_share"]) for f in all_findings])
    row("accuracy of flying the preferred velocity (no network)",
        [_pct(f["preferred_velocity_accuracy"]) for f in all_findings])
    labels = list(all_findings[0]["trainings"])
    for label in labels:
        row(f"20-30-20, {label} of the training part: test accuracy",
            [_pct(f["trainings"][label]["test_accuracy"]) for f in all_findings])
    base = labels[0]
    row(f"20-30-20 ({base}): accuracy on avoidances", [_pct(f["trainings"][base]["on_avoidances"])
                                                       for f in all_findings])
    row(f"20-30-20 ({base}): accuracy on free flight", [_pct(f["trainings"][base]["on_free_flight"])
                                                        for f in all_findings])
    row(f"20-30-20 ({base}): argmax agreement (the original's 2018 measure)",
        [_pct(f["trainings"][base]["argmax_agreement"]) for f in all_findings])
    return "\n".join(lines) + "\n"
