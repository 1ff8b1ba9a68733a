"""`magna world check|draw`: the counts of every real world, one clear line for every kind of bad file."""
import copy
import json
import math
import re
import subprocess

import pytest

from magna_master import cli
from magna_worlds.generate import resolve_world
from magna_worlds.loader import load_world
from tests.support import CORPUS, ROOT

# Every world of the original project; if the corpus is missing this fails (one case naming the folder).
CORPUS_WORLDS = sorted((CORPUS / "Worlds").glob("*/*.json")) or [CORPUS / "Worlds" / "(corpus missing)"]


def magna(capsys, *argv):
    """Run `magna ARGV...` in this process: (exit status, stdout, stderr)."""
    try:
        status = cli.main([str(a) for a in argv])
    except SystemExit as done:  # argparse: --help, usage errors
        status = done.code
    out = capsys.readouterr()
    return status, out.out, out.err


def small_world():
    """A valid world: one volume, one 4 x 4 x 2 m box with a 2 x 2 x 1 matrix of poses."""
    return {"scenario": {
        "world_boundaries": [[-10, 10], [-10, 10], [0, 10]],
        "volumes": [{
            "name": "Zone", "prefix": "Z", "origin": [[0, 0, 0], [0, 0, 0]], "permits": "geofence",
            "geometries": [{
                "name": "Box", "prefix": "B", "shape": "cube", "id": 0, "origin": [[0, 0, 2], [0, 0, 0]],
                "dimensions": [4, 4, 2], "color": [0, 128, 255], "alpha": 0.3,
                "poses_sets": [{"type": "matrix", "use": "poses", "matrix_type": "dimension",
                                "dimensions": [2, 2, 1]}],
            }],
        }],
    }}


def write_world(folder, data, world="Test", subworld="World"):
    """Write `data` as <folder>/<world>/<subworld>.json (the layout includes are looked up in)."""
    path = folder / world / f"{subworld}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


# --- expected counts, computed from the JSON alone -----------------------------------------------------------------

def expected_count(pose_set):
    """The number of poses or obstacles a set yields, or None when it is drawn at random (density < 1)."""
    kind = pose_set["type"]
    if kind == "matrix":
        assert pose_set.get("matrix_type", "dimension") == "dimension", "the corpus has only dimension matrices"
        if pose_set.get("density", 1) < 1:
            return None
        return math.prod(int(n) for n in pose_set["dimensions"])
    if kind == "random":
        return pose_set["quantity"]
    if kind == "coordinates":
        return len(pose_set["coordinates"])
    raise AssertionError(f"no independent count for a {kind} set")


def expected_sets(path):
    """frame -> (shape, [(use, type, count or None, cap), ...]) from the raw JSON, one entry per pose set."""
    data = json.loads(path.read_text())
    out = {}
    for volume in data["scenario"]["volumes"]:
        for geometry in volume["geometries"]:
            sets = [(s.get("use", "poses"), s["type"], expected_count(s),
                     math.prod(int(k) for k in s["dimensions"]) if s["type"] == "matrix" else None)
                    for s in geometry.get("poses_sets", [])]
            out[f"{volume['prefix']}_{geometry['name']}"] = (geometry["shape"], sets)
    return out


@pytest.mark.parametrize("path", CORPUS_WORLDS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_check_reports_the_counts_of_every_corpus_world(path, capsys):
    assert path.is_file(), f"the ROS-MAGNA corpus is missing: {path}"
    expected = expected_sets(path)
    status, out, err = magna(capsys, "world", "check", path, "--json")
    assert status == 0, err
    data = json.loads(out)
    got = {g["frame"]: g for v in data["volumes"] for g in v["geometries"]}
    assert set(got) == set(expected)
    resolved = resolve_world(load_world(path), 0)  # consulted only for sets drawn at random (density < 1)
    for frame, (shape, sets) in expected.items():
        placed = next(p for p in resolved.geometries if p.frame_name == frame)
        poses, by_type, obstacles = 0, {}, 0
        for index, (use, kind, n, cap) in enumerate(sets):
            if n is None:  # a random share of the matrix: within it, and what the generator drew
                n = len(placed.obstacles) if use == "obstacles" else len(placed.pose_sets[index])
                assert 0 <= n <= cap
            if use == "poses":
                poses += n
                by_type[kind] = by_type.get(kind, 0) + n
            else:
                obstacles += n
        g = got[frame]
        assert (g["shape"], g["poses"], g["poses_by_type"], g["obstacles"]) == (shape, poses, by_type, obstacles), \
            frame
    totals = data["totals"]
    assert totals["geometries"] == len(expected)
    assert totals["poses"] == sum(g["poses"] for g in got.values()) == resolved.pose_count()
    assert totals["obstacles"] == sum(g["obstacles"] for g in got.values()) == len(resolved.obstacles())
    assert data["file"] == str(path) and data["included"] == []
    assert data["world_boundaries"] == json.loads(path.read_text())["scenario"]["world_boundaries"]

    # The same numbers in the text summary, one line per geometry.
    status, text, err = magna(capsys, "world", "check", path)
    assert status == 0, err
    assert f"file        {path}" in text and "boundaries  x " in text and "origin_geo  (none)" in text
    assert re.search(r"generated in \d+\.\d ms", text)
    for frame, g in got.items():
        line = next(row for row in text.splitlines() if re.search(rf"frame {re.escape(frame)}\s", row))
        assert f" {g['shape']} " in line
        assert f"poses {g['poses']}" in line and f"obstacles {g['obstacles']}" in line, line
    assert f"{totals['poses']} pose(s)" in text and f"{totals['obstacles']} obstacle(s)" in text


def test_check_summarises_includes_origin_geo_and_warnings(tmp_path, capsys):
    inner = small_world()
    inner["scenario"]["volumes"][0]["geometries"][0]["poses_sets"].append(
        {"type": "random", "use": "poses", "quantity": 5})
    write_world(tmp_path, inner, "Parts", "Inner")
    outer = small_world()
    outer["scenario"]["origin_geo"] = [37.41, -6.0, 12.0]
    outer["scenario"]["volumes"][0]["name"] = "Zone2"
    outer["scenario"]["volumes"][0]["prefix"] = "Z2"
    outer["scenario"]["volumes"][0]["colour_typo"] = 1  # an unknown field: warned about, not fatal
    outer["scenario"]["volumes"].append({"name": "JSON", "world": "Parts", "subworld": "Inner"})
    path = write_world(tmp_path, outer, "Main", "World")

    status, out, err = magna(capsys, "world", "check", path)
    assert status == 0, err
    assert f"included    {tmp_path / 'Parts' / 'Inner.json'}" in out
    assert "origin_geo  lat 37.41, lon -6, alt 12 m" in out
    assert "boundaries  x -10..10  y -10..10  z 0..10 m" in out
    assert "poses 9 (matrix 4, random 5)" in out  # the included Box
    assert "totals      2 volume(s), 2 geometries, 13 pose(s) (matrix 8, random 5), 0 obstacle(s)" in out
    assert err.count("warning") == 1 and "scenario.volumes[0].colour_typo: unknown field" in err

    status, out, _ = magna(capsys, "world", "check", path, "--json", "--seed", "7")
    data = json.loads(out)
    assert status == 0 and data["seed"] == 7 and data["origin_geo"] == [37.41, -6.0, 12.0]
    assert data["included"] == [str(tmp_path / "Parts" / "Inner.json")]
    assert data["volumes"][1]["source"] == str(tmp_path / "Parts" / "Inner.json")
    assert data["totals"]["poses_by_type"] == {"matrix": 8, "random": 5}
    assert len(data["warnings"]) == 1 and data["generate_ms"] >= 0


# --- bad input: exit 2 and one line naming the file and the JSON path ------------------------------------------------

GEOMETRY = "scenario.volumes[0].geometries[0]"


def unknown_shape(w):
    w["scenario"]["volumes"][0]["geometries"][0]["shape"] = "cone"


def missing_dimensions(w):
    del w["scenario"]["volumes"][0]["geometries"][0]["dimensions"]


def prism_of_two_vertices(w):
    g = w["scenario"]["volumes"][0]["geometries"][0]
    g["shape"], g["dimensions"], g["poses_sets"] = "prism", [3.0, [[0, 0, 0], [1, 0, 0]]], []


def matrix_that_does_not_fit(w):  # 5 m cells in a 4 m box
    w["scenario"]["volumes"][0]["geometries"][0]["poses_sets"] = [
        {"type": "matrix", "use": "poses", "matrix_type": "distance", "dimensions": [5, 1, 1]}]


def missing_included_world(w):
    w["scenario"]["volumes"].append({"name": "JSON", "world": "NoSuchWorld", "subworld": "NoSuchSubworld"})


BAD = [
    (unknown_shape, f"{GEOMETRY}.shape", "unknown shape 'cone'"),
    (missing_dimensions, f"{GEOMETRY}.dimensions", "missing"),
    (prism_of_two_vertices, f"{GEOMETRY}.dimensions[1]", "3 or more base vertices"),
    (matrix_that_does_not_fit, f"{GEOMETRY}.poses_sets[0].dimensions[0]", "does not fit"),
    (missing_included_world, "scenario.volumes[1]", "NoSuchWorld/NoSuchSubworld not found"),
]


@pytest.mark.parametrize(("spoil", "json_path", "words"), BAD, ids=[b[0].__name__ for b in BAD])
def test_bad_world_is_one_line_naming_file_and_json_path(spoil, json_path, words, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MAGNA_WORLDS_PATH", str(tmp_path / "nowhere"))
    world = copy.deepcopy(small_world())
    spoil(world)
    path = write_world(tmp_path, world)
    for action in (["check"], ["draw", "-o", tmp_path / "out.png"]):
        status, out, err = magna(capsys, "world", *action, path)
        assert status == 2
        assert out == ""
        lines = err.splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith(f"magna world: {path}: {json_path}: "), lines[0]
        assert words in lines[0]
    assert not (tmp_path / "out.png").exists()


def test_invalid_json_names_the_file_and_the_place(tmp_path, capsys):
    path = write_world(tmp_path, '{"scenario": {"world_boundaries": [[-1, 1], [-1, 1], [0, 1]],\n "volumes": [}}')
    status, out, err = magna(capsys, "world", "check", path)
    assert status == 2 and out == ""
    assert err.splitlines() == [f"magna world: {path}: not valid JSON: Expecting value at line 2 column 14"]


def test_missing_file_is_a_usage_error(tmp_path, capsys):
    status, _, err = magna(capsys, "world", "check", tmp_path / "absent.json")
    assert status == 2
    assert err.splitlines() == [f"magna world: {tmp_path / 'absent.json'}: no such file; check the path, or give a "
                                "world name WORLD/SUBWORLD (e.g. Gym/Four_Cylinders)"]


# --- worlds by name, as `magna run` takes them ----------------------------------------------------------------------

def test_check_takes_a_project_world_by_name(capsys):
    status, out, err = magna(capsys, "world", "check", "Gym/Four_Cylinders")
    assert status == 0, err
    assert out.splitlines()[0] == f"file        {ROOT / 'worlds' / 'Gym' / 'Four_Cylinders.json'}"
    # a trailing .json names the same world
    assert magna(capsys, "world", "check", "Gym/Four_Cylinders.json")[1].splitlines()[0] == out.splitlines()[0]


def test_check_and_draw_take_a_corpus_world_by_name_with_search_path(tmp_path, capsys):
    status, out, err = magna(capsys, "world", "check", "Gym/1Obs_Central_Cylinder", "--search-path", CORPUS, "--json")
    assert status == 0, err
    assert json.loads(out)["file"] == str(CORPUS / "Worlds" / "Gym" / "1Obs_Central_Cylinder.json")
    picture = tmp_path / "gym.png"
    status, out, err = magna(capsys, "world", "draw", "Gym/1Obs_Central_Cylinder", "--search-path", CORPUS,
                             "-o", picture)
    assert status == 0, err
    assert out.strip() == str(picture) and picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_search_path_comes_before_the_project_worlds(tmp_path, capsys):
    mine = write_world(tmp_path / "worlds", small_world(), "Gym", "Four_Cylinders")  # DIR/worlds/WORLD/SUBWORLD.json
    status, out, err = magna(capsys, "world", "check", "Gym/Four_Cylinders", "--search-path", tmp_path)
    assert status == 0, err
    assert out.splitlines()[0] == f"file        {mine}"


def test_includes_are_looked_up_in_the_search_path_too(tmp_path, capsys):
    parts = tmp_path / "parts"
    write_world(parts, small_world(), "Parts", "Inner")
    outer = small_world()
    outer["scenario"]["volumes"][0].update(name="Outer", prefix="O")
    outer["scenario"]["volumes"].append({"name": "JSON", "world": "Parts", "subworld": "Inner"})
    path = write_world(tmp_path / "elsewhere", outer, "Main", "World")  # its own root has no Parts/
    status, out, err = magna(capsys, "world", "check", path, "--search-path", parts)
    assert status == 0, err
    assert f"included    {parts / 'Parts' / 'Inner.json'}" in out


@pytest.mark.parametrize("action", [["check"], ["draw", "-o", "unused.png"]])
def test_a_name_found_nowhere_lists_every_place_looked_at(action, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = magna(capsys, "world", *action, "Gym/Four_Cylinder", "--search-path", CORPUS)
    assert status == 2 and out == ""
    lines = err.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("magna world: Gym/Four_Cylinder: no such file, nor a world WORLD/SUBWORLD of that "
                               "name; looked at ")
    for place in (CORPUS / "Worlds", CORPUS, ROOT / "worlds"):
        assert str(place / "Gym" / "Four_Cylinder.json") in lines[0]
    assert lines[0].endswith("add the folder holding it with --search-path DIR")
    assert list(tmp_path.iterdir()) == []


def test_a_missing_search_path_folder_is_a_usage_error(tmp_path, capsys):
    status, _, err = magna(capsys, "world", "check", "Gym/Four_Cylinders", "--search-path", tmp_path / "nope")
    assert status == 2
    assert err.startswith(f"magna world: --search-path {tmp_path / 'nope'}: no such folder")


def test_the_issue_command_works_from_the_repository_root():
    """`./magna world check Gym/Four_Cylinders` said "no such file" (issue 23)."""
    done = subprocess.run([str(ROOT / "magna"), "world", "check", "Gym/Four_Cylinders"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "worlds/Gym/Four_Cylinders.json" in done.stdout.splitlines()[0]


def test_through_the_magna_wrapper(tmp_path):
    """The real entry point: registered subcommand, exit statuses and stderr as a user sees them."""
    good = write_world(tmp_path, small_world(), "Good", "World")
    bad_world = small_world()
    unknown_shape(bad_world)
    bad = write_world(tmp_path, bad_world, "Bad", "World")
    ok = subprocess.run([str(ROOT / "magna"), "world", "check", str(good)], capture_output=True, text=True,
                        timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "poses 4 (matrix 4)" in ok.stdout
    failed = subprocess.run([str(ROOT / "magna"), "world", "check", str(bad)], capture_output=True, text=True,
                            timeout=120)
    assert failed.returncode == 2 and failed.stdout == ""
    assert failed.stderr.splitlines() == [f"magna world: {bad}: {GEOMETRY}.shape: unknown shape 'cone'; use one of "
                                          "cube, sphere, cylinder, torus, prism"]


def test_help_everywhere_with_examples(capsys):
    for argv in (["world", "--help"], ["world", "check", "--help"], ["world", "draw", "--help"]):
        status, out, _ = magna(capsys, *argv)
        assert status == 0
        assert f"usage: magna {' '.join(argv[:-1])}" in out
        examples = out.split("examples:")[1]
        assert "./magna world " in examples
        for line in examples.splitlines():  # every example names a file or world that exists
            for word in line.split("#")[0].split():
                if word.startswith(("worlds/", "../shared/")):
                    assert (ROOT / word).exists(), line
    status, _, err = magna(capsys, "world")
    assert status == 2 and "ACTION" in err
    assert ("world", "magna_worlds.cli") in cli.COMMANDS
