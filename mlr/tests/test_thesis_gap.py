"""The thesis comparison's measurements (mlr.thesis_gap): the original's accuracy measure, and the analysis on
a recorded run (ORCA-3D solved again from the input vectors: tests/test_relabel.py)."""
import dataclasses
import json

import numpy as np
import pytest

from mlr import thesis_gap
from mlr.config import RunConfig

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")


def test_argmax_agreement_is_the_originals_measure():
    labels = np.array([[1.0, 0.5, 0.0], [0.0, -1.0, 0.2], [0.1, 0.2, 0.3]])
    assert thesis_gap.argmax_agreement(np.array([[2.0, 0.0, 0.0], [0.0, -2.0, 0.1], [0.3, 0.2, 0.1]]), labels) \
        == pytest.approx(2 / 3)  # the second: -1 is not the largest; 0.2 is, and 0.1 is the prediction's largest


def test_the_analysis_on_a_recorded_run_measures_and_writes_its_table(tmp_path, recorded_run):
    run = RunConfig(recorded_run.world, recorded_run.subworld, recorded_run.mission, recorded_run.submission,
                    name=recorded_run.name, data_root=str(recorded_run.data_root), n_neighbors=1, n_obstacles=2,
                    steps=150, eval_every=50, batch_size=64)
    findings = thesis_gap.analyse(dataclasses.replace(run), tmp_path / "analysis", progress=False,
                                  log=lambda message: None)
    assert findings["avoidance_share"] + findings["preferred_velocity_accuracy"] == pytest.approx(1.0)
    assert 0.0 <= findings["labels_reproduced_from_inputs"] <= 1.0
    assert list(findings["trainings"]) == ["max-abs, 100%", "standard, 100%", "max-abs, 25%", "max-abs, 50%"]
    sizes = [t["train_samples"] for t in findings["trainings"].values()]
    assert sizes[0] == sizes[1] and sizes[2] < sizes[3] < sizes[0]
    assert json.loads((tmp_path / "analysis" / "analysis.json").read_text()) == findings
    table = (tmp_path / "analysis" / "analysis.md").read_text()
    assert "reproduces from the input vector alone" in table and "argmax agreement" in table
