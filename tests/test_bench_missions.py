"""bench/missions/make_crossing.py: the N-UAV crossings bench/mission_batch.py flies. The files it writes are the
ones in bench/missions/, they load and check in their worlds as `magna mission check` does, and nothing is
overwritten without --force or written when it does not fit its world. Not flown here: 50 UAVs take minutes."""
import subprocess
import sys

import pytest

from tests.support import ROOT, load_module

BENCH = ROOT / "bench"
SCRIPT = BENCH / "missions" / "make_crossing.py"


@pytest.fixture(scope="module")
def make_crossing():
    return load_module(SCRIPT, "bench_make_crossing")


def test_it_answers_help_from_a_bare_terminal(tmp_path):
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": str(tmp_path), "LANG": "C.UTF-8"}
    done = subprocess.run([sys.executable, str(SCRIPT), "--help"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage:") and "--force" in done.stdout


@pytest.mark.parametrize("uavs", [10, 50])
def test_the_bench_missions_are_what_it_writes(make_crossing, tmp_path, uavs):
    written = tmp_path / f"{uavs}.json"
    assert make_crossing.main(["--uavs", str(uavs), "-o", str(written)]) == 0
    assert written.read_text() == (BENCH / "missions" / "Gym" / f"{uavs}UAVs_Crossing_ORCA.json").read_text()


def test_fifty_uavs_cross_with_orca_and_check_in_the_big_world(make_crossing, tmp_path):
    from magna_common.search_path import find_world_file, world_folders
    from magna_gs.mission.build import InertFactory, build_machine
    from magna_gs.mission.loader import load_mission
    from magna_gs.mission.model import AlgorithmControlParams, FollowPathParams
    from magna_gs.mission.world_check import check_against_world
    from magna_worlds.generate import resolve_world
    from magna_worlds.loader import load_world

    written = tmp_path / "50UAVs_Crossing_ORCA.json"
    assert make_crossing.main(["--uavs", "50", "-o", str(written)]) == 0
    loaded = load_mission(written)
    assert loaded.changes == [] and loaded.warnings == []
    assert loaded.mission.agent_ids == list(range(1, 51))
    build_machine(loaded.mission, InertFactory(), loaded.plan)
    world_file = find_world_file("Gym", "Big_Crossing", world_folders([BENCH]))
    assert world_file == BENCH / "worlds" / "Gym" / "Big_Crossing.json"  # as `magna run --search-path bench` finds it
    world = load_world(world_file, strict=True)
    for seed in (0, 1, 2):
        assert check_against_world(loaded.mission, resolve_world(world, seed), seed) == [], f"seed {seed}"
    assert len(resolve_world(world, 0).obstacles()) == 1  # the central obstacle

    nodes = list(loaded.mission.nodes())
    orca = [n for n in nodes if isinstance(n.parameters, AlgorithmControlParams)]
    assert [(n.parameters.name, n.ids) for n in orca] == [("orca3d", "all")]
    crossing = [n.parameters for n in nodes if n.name == "cross"]
    assert len(crossing) == 50
    ring = [n.parameters for n in nodes if n.name == "ring"]
    for start, cross in zip(ring, crossing, strict=True):
        assert isinstance(cross, FollowPathParams)
        here, there = start.path[0].as_list()[3][0], cross.path[0].as_list()[3][0]
        assert here[2] == there[2] and here[2] in (8.0, 10.5, 13.0, 15.5)  # each crosses at its own altitude
        assert there[0] == pytest.approx(-here[0], abs=1e-3) and there[1] == pytest.approx(-here[1], abs=1e-3)
    assert {c.path[0].as_list()[3][0][2] for c in crossing} == {8.0, 10.5, 13.0, 15.5}
    layer = {k: crossing[k].path[0].as_list()[3][0][2] for k in range(50)}
    assert all(layer[k] != layer[(k + 25) % 50] for k in range(50))  # never head-on in one layer


def test_layers_that_would_meet_head_on_are_refused(make_crossing, tmp_path, capsys):
    target = tmp_path / "x.json"
    with pytest.raises(SystemExit):
        make_crossing.main(["--uavs", "50", "--altitudes", "8", "10", "12", "14", "16", "-o", str(target)])
    assert "5 layers put each of the 50 UAVs in the layer of the one crossing towards it" in capsys.readouterr().err
    assert not target.exists()


def test_an_existing_file_is_replaced_only_with_force(make_crossing, tmp_path, capsys):
    target = tmp_path / "m.json"
    target.write_text("an earlier mission")
    with pytest.raises(SystemExit) as stop:
        make_crossing.main(["--uavs", "10", "-o", str(target)])
    assert stop.value.code == 2
    assert f"{target} already exists; pass --force to replace it" in capsys.readouterr().err
    assert target.read_text() == "an earlier mission"
    assert make_crossing.main(["--uavs", "10", "-o", str(target), "--force"]) == 0
    assert target.read_text().startswith('{\n    "Agents_Config"')


def test_a_crossing_that_leaves_its_world_is_not_written(make_crossing, tmp_path, capsys):
    target = tmp_path / "m.json"
    assert make_crossing.main(["--uavs", "50", "--ring-radius", "70", "-o", str(target)]) == 1
    err = capsys.readouterr().err
    assert "not written" in err and "outside the world boundaries x -60..60" in err
    assert not target.exists() and list(tmp_path.iterdir()) == []
