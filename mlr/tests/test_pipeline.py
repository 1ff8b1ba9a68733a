"""The pipeline on a real recorded simulation: the pickler's order and labels against the
recorder CSV's own columns, then `magna learn train` with its cache, reuse and refusals."""
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from magna_uav.nai.inputs import input_names
from magna_uav.recorder import read_csv
from mlr.config import load_sweep
from mlr.manager import run_sweep
from mlr.pickler import Teacher, find_simulations, pickle_simulations
from tests.support import ROOT

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.*` is deprecated:DeprecationWarning")


def col(teacher, name):
    return input_names(teacher.role, teacher.n_neighbors, teacher.n_obstacles).index(name)


def xyz(row, prefix):
    return np.array([row[f"{prefix}.{a}"] for a in "xyz"], dtype=float)


@pytest.mark.parametrize("fvi", [0, 3])
def test_samples_hold_the_csv_values_in_the_nai_order_and_labels_fvi_steps_ahead(recorded_run, fvi):
    teacher = Teacher(role="path", algorithm="orca3d", n_neighbors=1, n_obstacles=2, neighbor_dist=6.0, fvi=fvi)
    sims, skipped = find_simulations(recorded_run.selection())
    assert [s.directory for s in sims] == [recorded_run.sim_dir] and skipped == []
    samples = pickle_simulations(sims, teacher)
    assert samples.sources == [str(recorded_run.sim_dir / f"uav_{i}.csv") for i in recorded_run.uav_ids]
    checked = 0
    for origin, uav in enumerate(recorded_run.uav_ids):
        _, rows = read_csv(recorded_run.sim_dir / f"uav_{uav}.csv")
        other = 2 if uav == 1 else 1
        mine = np.flatnonzero(samples.origin == origin)
        teacher_rows = [i for i, r in enumerate(rows) if r["role"] == "path" and r["algorithm"] == "orca3d"]
        assert len(teacher_rows) > 50, "the crossing is flown with ORCA-3D"
        assert set(samples.step[mine]) <= set(teacher_rows)
        if fvi == 0:
            assert len(mine) == len(teacher_rows)  # every ORCA-3D path step is a sample
        for k in mine:
            i = samples.step[k]
            row, x = rows[i], samples.x[k]
            pos = xyz(row, "pos")
            np.testing.assert_allclose(x[[col(teacher, f"own_vel.{a}") for a in "xyz"]], xyz(row, "vel"))
            np.testing.assert_allclose(x[[col(teacher, f"goal_pose_rel.{a}") for a in "xyz"]],
                                       xyz(row, "goal") - pos)
            neighbour = x[[col(teacher, f"others_pos_rel[0].{a}") for a in "xyz"]]
            if row[f"uav{other}.gap"] < 6.0:
                np.testing.assert_allclose(neighbour, xyz(row, f"uav{other}.pos") - pos)
                np.testing.assert_allclose(x[[col(teacher, f"others_vel[0].{a}") for a in "xyz"]],
                                           xyz(row, f"uav{other}.vel"))
            else:
                np.testing.assert_allclose(neighbour, [12.0, 0, 0])
            if row["obs0.name"] and row["obs0.gap"] < 6.0:
                np.testing.assert_allclose(x[[col(teacher, f"obstacles_pos_rel[0].{a}") for a in "xyz"]],
                                           xyz(row, "obs0.pos") - pos)
            # the label: the teacher's choice fvi steps later, in the same run of the role
            np.testing.assert_allclose(samples.y[k], xyz(rows[i + fvi], "sel_vel"))
            assert all(rows[j]["role"] == "path" and rows[j]["algorithm"] == "orca3d" for j in range(i, i + fvi + 1))
            assert not any(rows[j]["outcome"] for j in range(i, i + fvi))
            checked += 1
    assert checked > 100
    assert np.all(samples.max_speed == 2.0)  # iris


def config(path, recorded_run, **changes):
    values = {"world": recorded_run.world, "subworld": recorded_run.subworld, "mission": recorded_run.mission,
              "submission": recorded_run.submission, "name": recorded_run.name, "data_root": str(path),
              "n_neighbors": 1, "n_obstacles": 2, "steps": 200, "eval_every": 100, "batch_size": 64,
              "hidden_layers": [[8], [16, 16]]} | changes
    target = path / "sweep.json"
    target.write_text(json.dumps(values))
    return target


@pytest.fixture
def own_copy(recorded_run, tmp_path):
    """The recorded dataset copied, so that touching its files does not disturb other tests."""
    source = recorded_run.data_root / "Simulations"
    shutil.copytree(source, tmp_path / "Simulations")
    sim_dir = tmp_path / recorded_run.sim_dir.relative_to(recorded_run.data_root)
    return tmp_path, sim_dir


def test_train_pickles_once_reuses_finished_runs_and_repickles_when_a_file_changes(recorded_run, own_copy):
    root, sim_dir = own_copy
    messages = []
    sweep = load_sweep(config(root, recorded_run))
    first = run_sweep(sweep, progress=False, log=messages.append)
    assert [r.name for r in first.results] == ["r00_hidden_layers=8", "r01_hidden_layers=16-16"]
    assert first.exported == root / "mlr" / "runs" / "sweep" / "sweep.pt" and first.exported.is_file()
    assert (first.out / "results.md").read_text().count("| r0") == 2
    assert any("pickled" in m for m in messages)
    messages.clear()
    second = run_sweep(sweep, progress=False, log=messages.append, export_best=False)
    assert any("(cached;" in m for m in messages)
    assert any(m.startswith("split:") and m.endswith("(cached)") for m in messages)
    assert sum("reused" in m for m in messages) == 2
    assert [r.test_accuracy for r in second.results] == [r.test_accuracy for r in first.results]
    # nothing changed: the export of the best run is current and kept (a rerun goes on, e.g. mlr thesis)
    exported = first.exported.read_bytes()
    messages.clear()
    third = run_sweep(sweep, progress=False, log=messages.append)
    assert third.exported == first.exported and third.exported.read_bytes() == exported
    assert any("exported before" in m for m in messages)
    # a changed input file is pickled again
    csv_file = sim_dir / "uav_1.csv"
    os.utime(csv_file, ns=(csv_file.stat().st_atime_ns, csv_file.stat().st_mtime_ns + 10**9))
    messages.clear()
    run_sweep(sweep, progress=False, log=messages.append, export_best=False)
    assert any("(pickled;" in m for m in messages)


def test_train_never_overwrites_another_configs_run_or_an_export(recorded_run, own_copy):
    root, _ = own_copy
    first = run_sweep(load_sweep(config(root, recorded_run)), progress=False, log=lambda m: None)
    exported = first.exported.read_bytes()
    changed = load_sweep(config(root, recorded_run, learning_rate=0.01))
    with pytest.raises(FileExistsError, match="a finished run with another config is there; pass --force"):
        run_sweep(changed, progress=False, log=lambda m: None)
    assert first.exported.read_bytes() == exported
    again = run_sweep(changed, progress=False, log=lambda m: None, overwrite=True)
    assert json.loads((again.out / "best.json").read_text())["config"]["learning_rate"] == 0.01


def test_the_command_line_trains_and_refuses_bad_configs_with_status_2(recorded_run, own_copy):
    root, _ = own_copy
    path = config(root, recorded_run, hidden_layers=[8])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-m", "mlr", "train", str(path), "--quiet", "-o", str(root / "out")],
                          capture_output=True, text=True, cwd=root, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "| r00 |" in done.stdout and (root / "out" / "sweep.pt").is_file()
    # what it suggests next are commands that exist, with this sweep's world and mission filled in
    assert f"TensorBoard: magna learn board {root / 'out'}" in done.stdout
    selection = recorded_run.selection()
    assert (f"fly it: magna learn fly --world {selection.world}/{selection.subworld} --mission "
            f"{selection.mission}/{selection.submission} --model {root / 'out' / 'sweep.pt'}") in done.stdout
    bad = root / "bad.yaml"
    bad.write_text("world: Gym\nsubworld: X\nmission: Gym\nsubmission: Y\nbatch_size: -4\n")
    done = subprocess.run([sys.executable, "-m", "mlr", "train", str(bad)], capture_output=True, text=True,
                          cwd=root, env=env, timeout=120)
    assert done.returncode == 2 and f"mlr: {bad}: batch_size is -4: give a whole number >= 1" in done.stderr
    missing = config(root, recorded_run, datasets=[7])
    done = subprocess.run([sys.executable, "-m", "mlr", "pickle", str(missing)], capture_output=True, text=True,
                          cwd=root, env=env, timeout=120)
    assert done.returncode == 2 and "dataset_7: no such dataset; run it first (magna run" in done.stderr
