"""The storage tree, conflict policies, atomic result and summary files (no ROS)."""
import csv
import dataclasses
import json
import os
import threading
from pathlib import Path

import pytest

from magna_common import storage_tree
from magna_common.records import SimulationResult
from magna_common.storage_tree import StorageError, StorageKey
from magna_master import storage
from magna_master.storage import (
    APPEND,
    OVERWRITE,
    SKIP_SAVE,
    DatasetLock,
    StorageConflict,
    plan_storage,
    prepare_simulation_dir,
)

KEY = StorageKey("Gym", "1Obs_Central_Cylinder", "Gym", "2UAVs_2paths_Central_Cylinder")


def result(m, success=True, **fields):
    return SimulationResult(**{"id": m, "success": success, "outcome": "succeeded" if success else "collision",
                               "message": "done", "sim_duration": 12.5 + m, "wall_time": 1.25,
                               "collisions": 0 if success else 2, **fields})


def summary_cells(dataset_dir: Path) -> list[dict[str, str]]:
    """summary.csv as text cells, as a spreadsheet reads it."""
    with open(dataset_dir / "summary.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def make_dataset(tmp_path, ids):
    """A dataset holding finished simulations `ids` (each with a file and its summary row)."""
    dataset = KEY.dataset_dir(tmp_path, 1)
    for m in ids:
        folder = storage_tree.simulation_dir(dataset, m)
        folder.mkdir(parents=True)
        (folder / "uav_1.csv").write_text(f"old data of {m}\n")
        storage.write_result(folder, result(m))
        storage.update_summary(dataset, result(m))
    return dataset


def snapshot(root: Path) -> dict:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None) for p in sorted(root.rglob("*"))}


# --- paths -----------------------------------------------------------------------------------------------------

def test_the_tree_follows_the_design(tmp_path):
    key = StorageKey("Gym", "Four_Cylinders", "Gym", "Two_Paths", "orca")
    dataset = key.dataset_dir(tmp_path, 3)
    assert dataset == tmp_path / "Simulations/Gym/Four_Cylinders/Gym/Two_Paths/orca/dataset_3"
    assert storage_tree.simulation_dir(dataset, 7) == dataset / "simulation_7"
    assert StorageKey("W", "S", "M", "N").name == "default"


def test_the_default_data_root_is_in_home(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    assert KEY.dataset_dir(storage_tree.DEFAULT_DATA_ROOT, 1).parts[:len(tmp_path.parts) + 1] == \
        (*tmp_path.parts, "magna_data")


@pytest.mark.parametrize("bad", ["", "..", ".", "a/b", " x"])
def test_names_that_are_not_one_folder_are_refused(bad):
    with pytest.raises(StorageError, match="cannot name a folder"):
        StorageKey("Gym", "W", "Gym", "M", bad)


def test_existing_simulations_counts_only_simulation_folders(tmp_path):
    dataset = tmp_path / "dataset_1"
    for name in ("simulation_2", "simulation_10", "simulation_x", "logs"):
        (dataset / name).mkdir(parents=True)
    (dataset / "simulation_5").write_text("a file, not a folder")
    assert storage_tree.existing_simulations(dataset) == [2, 10]
    assert storage_tree.existing_simulations(tmp_path / "missing") == []


# --- conflicts -------------------------------------------------------------------------------------------------

def test_a_new_dataset_runs_one_to_n_without_conflict(tmp_path):
    plan = plan_storage(KEY.dataset_dir(tmp_path, 1), 3)
    assert plan.ids == [1, 2, 3] and plan.save and plan.policy is None and plan.overwrite == []
    assert not (tmp_path / "Simulations").exists()  # planning touches nothing


def test_a_conflict_without_policy_aborts_listing_the_options(tmp_path):
    dataset = make_dataset(tmp_path, [1, 2])
    before = snapshot(tmp_path)
    with pytest.raises(StorageConflict) as raised:
        plan_storage(dataset, 3)
    message = str(raised.value)
    for option in ("--append", "--overwrite", "--skip-save", "simulation_1..2", str(dataset), "nothing was started"):
        assert option in message
    assert snapshot(tmp_path) == before


def test_append_numbers_after_the_last_existing_simulation(tmp_path):
    dataset = make_dataset(tmp_path, [1, 2, 5])
    plan = plan_storage(dataset, 3, APPEND)
    assert plan.ids == [6, 7, 8] and plan.policy == APPEND and plan.overwrite == []
    # Appending to an empty dataset starts at 1.
    assert plan_storage(KEY.dataset_dir(tmp_path, 2), 2, APPEND).ids == [1, 2]


def test_overwrite_deletes_only_the_folders_it_rewrites(tmp_path):
    dataset = make_dataset(tmp_path, [1, 2, 3, 7])
    plan = plan_storage(dataset, 2, OVERWRITE)
    assert plan.ids == [1, 2] and plan.overwrite == [1, 2]
    assert storage_tree.existing_simulations(dataset) == [1, 2, 3, 7]  # nothing deleted by planning
    folder = prepare_simulation_dir(plan, 1)
    assert folder.is_dir() and list(folder.iterdir()) == []  # the old simulation_1 is gone
    assert [r["id"] for r in summary_cells(dataset)] == ["2", "3", "7"]  # and its row
    # simulation_2 is deleted only when its own turn comes; 3 and 7 are never touched.
    assert (dataset / "simulation_2" / "uav_1.csv").read_text() == "old data of 2\n"
    prepare_simulation_dir(plan, 2)
    for m in (3, 7):
        assert (dataset / f"simulation_{m}" / "uav_1.csv").read_text() == f"old data of {m}\n"
    assert [r["id"] for r in summary_cells(dataset)] == ["3", "7"]


def test_overwrite_without_conflict_deletes_nothing(tmp_path):
    dataset = make_dataset(tmp_path, [5])
    plan = plan_storage(dataset, 2, OVERWRITE)
    assert plan.ids == [1, 2] and plan.overwrite == [] and plan.policy is None


def test_a_folder_that_appears_during_the_batch_is_not_deleted(tmp_path):
    dataset = make_dataset(tmp_path, [1])
    plan = plan_storage(dataset, 3, APPEND)  # 2, 3, 4
    (dataset / "simulation_3").mkdir()
    (dataset / "simulation_3" / "keep").write_text("someone else's")
    prepare_simulation_dir(plan, 2)
    with pytest.raises(StorageError, match="appeared while the batch ran"):
        prepare_simulation_dir(plan, 3)
    assert (dataset / "simulation_3" / "keep").read_text() == "someone else's"


def test_skip_save_plans_nothing_to_write(tmp_path):
    dataset = make_dataset(tmp_path, [1, 2])
    before = snapshot(tmp_path)
    plan = plan_storage(dataset, 2, SKIP_SAVE)
    assert not plan.save and plan.dataset_dir is None and plan.simulation_dir(1) is None
    assert "--skip-save" in plan.reason
    with pytest.raises(StorageError):
        prepare_simulation_dir(plan, 1)
    assert snapshot(tmp_path) == before


def test_skip_save_without_conflict_saves_as_usual(tmp_path):
    plan = plan_storage(KEY.dataset_dir(tmp_path, 1), 2, SKIP_SAVE)
    assert plan.save and plan.ids == [1, 2]


def test_no_data_plans_nothing_to_write(tmp_path):
    plan = plan_storage(KEY.dataset_dir(tmp_path, 1), 2, save=False)
    assert not plan.save and plan.ids == [1, 2] and "--skip-save" in plan.reason


@pytest.mark.parametrize(("answer", "ids", "save"), [("a", [3, 4], True), ("o", [1, 2], True), ("s", [1, 2], False)])
def test_the_question_on_a_terminal_decides(tmp_path, answer, ids, save):
    dataset = make_dataset(tmp_path, [1, 2])
    asked = []

    def ask(conflict):
        asked.append(conflict)
        return storage.ask_policy(conflict, input_fn=lambda prompt: answer)

    plan = plan_storage(dataset, 2, ask=ask)
    assert len(asked) == 1 and (plan.ids, plan.save) == (ids, save)


@pytest.mark.parametrize("answers", [["q"], [""], ["what", "no", "maybe"]])
def test_quitting_or_unclear_answers_abort(tmp_path, answers):
    dataset = make_dataset(tmp_path, [1])
    replies = iter(answers)
    with pytest.raises(StorageConflict):
        plan_storage(dataset, 1, ask=lambda c: storage.ask_policy(c, input_fn=lambda p: next(replies)))


def test_end_of_input_aborts(tmp_path):
    def eof(_prompt):
        raise EOFError

    dataset = make_dataset(tmp_path, [1])
    assert storage.ask_policy(StorageConflict(dataset, [1], [1]), input_fn=eof) == storage.ABORT


def test_bad_counts_and_policies_are_refused(tmp_path):
    with pytest.raises(StorageError, match=">= 1"):
        plan_storage(tmp_path, 0)
    with pytest.raises(StorageError, match="unknown conflict policy"):
        plan_storage(tmp_path, 1, "merge")


# --- atomic files --------------------------------------------------------------------------------------------

def test_result_json_is_written_atomically(tmp_path, monkeypatch):
    storage.write_result(tmp_path, result(1))
    assert json.loads((tmp_path / "result.json").read_text())["sim_duration"] == 13.5

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError):
        storage.write_result(tmp_path, result(1, success=False))
    # The old file is whole and no temporary file is left.
    assert json.loads((tmp_path / "result.json").read_text())["success"] is True
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]


def test_summary_has_one_row_per_simulation_with_the_design_columns(tmp_path):
    storage.update_summary(tmp_path, result(2, success=False, message="collision\nbetween 1 and 2"))
    storage.update_summary(tmp_path, result(1))
    storage.update_summary(tmp_path, result(10))
    storage.update_summary(tmp_path, dataclasses.replace(result(1), outcome="replaced"))
    with open(tmp_path / "summary.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["id", "success", "outcome", "message", "duration", "wall_time", "collisions"]
    assert [r["id"] for r in rows] == ["1", "2", "10"]
    assert rows[0]["outcome"] == "replaced"
    assert rows[1] == {"id": "2", "success": "False", "outcome": "collision", "message": "collision between 1 and 2",
                       "duration": "14.500", "wall_time": "1.250", "collisions": "2"}


def test_summary_rewrites_never_show_a_partial_file(tmp_path):
    """A reader polling summary.csv while rows are added sees only whole files."""
    stop = threading.Event()
    seen_bad = []

    def reader():
        while not stop.is_set():
            try:
                text = (tmp_path / "summary.csv").read_text()
            except FileNotFoundError:
                continue
            lines = text.splitlines()
            if not text.endswith("\n") or lines[0] != ",".join(storage_tree.SUMMARY_COLUMNS) \
                    or any(len(line.split(",")) != 7 for line in lines):
                seen_bad.append(text)

    thread = threading.Thread(target=reader)
    thread.start()
    try:
        for m in range(1, 200):
            storage.update_summary(tmp_path, result(m))
    finally:
        stop.set()
        thread.join()
    assert not seen_bad
    assert len(storage.read_summary(tmp_path)) == 199
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.csv"]  # no temporary files left


def test_summary_keeps_unknown_columns_of_older_files(tmp_path):
    (tmp_path / "summary.csv").write_text("id,success,outcome,message,duration,wall_time,collisions,note\n"
                                          "1,True,succeeded,ok,1.000,1.000,0,hand-written\n")
    storage.update_summary(tmp_path, result(2))
    rows = summary_cells(tmp_path)
    assert rows[0]["note"] == "hand-written" and rows[1]["id"] == "2"


def test_read_result_of_a_missing_or_broken_file_is_none(tmp_path):
    assert storage.read_result(tmp_path / "result.json") is None
    (tmp_path / "result.json").write_text("{not json")
    assert storage.read_result(tmp_path / "result.json") is None


# --- the dataset lock ------------------------------------------------------------------------------------------

def test_two_batches_cannot_write_the_same_dataset(tmp_path):
    dataset = KEY.dataset_dir(tmp_path, 1)
    with DatasetLock(dataset):
        assert dataset.is_dir()
        with pytest.raises(StorageError, match="another magna run is writing"):
            DatasetLock(dataset).acquire()
    with DatasetLock(dataset):  # free again
        pass


def test_a_lock_that_wrote_nothing_leaves_no_folders(tmp_path):
    (tmp_path / "data").mkdir()
    with DatasetLock(KEY.dataset_dir(tmp_path / "data", 1)):
        pass
    assert list((tmp_path / "data").iterdir()) == []
    dataset = KEY.dataset_dir(tmp_path / "data", 1)
    with DatasetLock(dataset):
        (dataset / "simulation_1").mkdir()
    assert (dataset / "simulation_1").is_dir()


# --- a dataset its last batch could not finish, and room to write -----------------------------------------------

def test_folders_without_a_summary_row_get_one_and_finished_ones_stay_as_they_are(tmp_path):
    dataset = make_dataset(tmp_path, [1])
    before = snapshot(storage_tree.simulation_dir(dataset, 1))
    # 2: its supervisor wrote a final result after the batch died; 3: nothing but partial data;
    # 4: the ground station had reported, the launch was not down yet
    for m in (2, 3, 4):
        storage_tree.simulation_dir(dataset, m).mkdir()
    storage.write_result(storage_tree.simulation_dir(dataset, 2), result(2, final=True))
    (storage_tree.simulation_dir(dataset, 3) / "uav_1.csv").write_text("partial\n")
    storage.write_result(storage_tree.simulation_dir(dataset, 4), result(4, success=False, reported=True, final=False))

    assert storage.repair_summary(dataset) == [2, 3, 4]
    rows = {int(r["id"]): r for r in summary_cells(dataset)}
    assert sorted(rows) == [1, 2, 3, 4]
    assert (rows[2]["success"], rows[2]["outcome"]) == ("True", "succeeded")
    assert (rows[3]["success"], rows[3]["outcome"]) == ("False", "interrupted")
    assert (rows[4]["success"], rows[4]["outcome"]) == ("False", "collision")  # the ground station's verdict
    third = SimulationResult.read(storage_tree.simulation_dir(dataset, 3) / "result.json")
    assert (third.id, third.final, third.termination) == (3, True, "interrupted")
    assert "its batch ended before this simulation finished" in third.message
    assert (storage_tree.simulation_dir(dataset, 3) / "uav_1.csv").read_text() == "partial\n"
    assert SimulationResult.read(storage_tree.simulation_dir(dataset, 4) / "result.json").final
    assert snapshot(storage_tree.simulation_dir(dataset, 1)) == before
    assert storage.repair_summary(dataset) == []  # nothing left to repair


def test_a_disk_below_the_floor_is_refused_naming_the_folder_and_the_fix(tmp_path):
    storage.check_writable(tmp_path, min_free_mb=0)
    assert not list(tmp_path.iterdir())  # the probe is gone
    with pytest.raises(StorageError, match=rf"MB free on the disk of {tmp_path}, less than the 1e\+12 MB a batch "
                                           r"keeps free \(--min-free-space\); free space there, or choose another "
                                           r"--data-root"):
        storage.check_writable(tmp_path, min_free_mb=1e12)


@pytest.mark.parametrize(("code", "words"), [("ENOSPC", "no space left on the disk of"),
                                             ("EROFS", "is not writable"), ("EACCES", "is not writable"),
                                             ("EIO", "cannot write in")])
def test_write_errors_are_told_with_their_fix(tmp_path, code, words):
    import errno

    number = getattr(errno, code)
    message = storage.describe_write_error(tmp_path, OSError(number, os.strerror(number)))
    assert words in message and str(tmp_path) in message and "--data-root" in message
