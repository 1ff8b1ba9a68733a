"""Fuzzed worlds and missions: whatever a file holds, `magna world check`, `magna mission check` and the
mission loader end with exit 0, or exit 2 and one line per problem naming the file and the JSON path.
Never a traceback, never a hang.

The inputs are the real files (the ROS-MAGNA corpus, read in place, and the project's worlds/ and
missions/) mutated by hypothesis: keys deleted, retyped and renamed; NaN, inf and huge numbers; wrong
nesting; transitions to states that do not exist; empty containers; unicode. A few byte-level cases
(not UTF-8, truncated, nested 100 000 deep, a 5000-digit number, 10 MB files) are written out by hand.
Most cases run in-process through the same `magna` entry point the command runs (fast); a sample runs
the real `./magna` command as a subprocess. The profile is derandomized (the same cases on every run),
with no deadline: the work is bounded by the number of examples instead. Each test prints how many
cases it tried.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from magna_gs.mission.loader import load_mission
from magna_gs.mission.model import MissionError
from magna_master.cli import main as magna_main
from tests.support import CORPUS, ROOT

pytestmark = pytest.mark.timeout(600)  # a guard against a hang, far above what the cases take

PROFILE = dict(derandomize=True, deadline=None, database=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
IN_PROCESS_EXAMPLES = 250  # per kind (worlds, missions)
SUBPROCESS_EXAMPLES = 4  # per kind, on top of the hand-written byte-level cases
COMMAND_GUARD = 120.0  # s: a subprocess still running then is a hang

WORLDS = sorted([*CORPUS.glob("Worlds/**/*.json"), *(ROOT / "worlds").glob("**/*.json")])
MISSIONS = sorted([*CORPUS.glob("Missions/**/*.json"), *(ROOT / "missions").glob("**/*.json")])

# Values put where the format expects something else.
NUMBERS = [math.nan, math.inf, -math.inf, 1e308, -1e308, 10 ** 30, -(10 ** 400), 10 ** 400, 0, -1, 1e-320, 0.5]
OTHERS = [None, True, False, "", " ", "all", "from_hyperparameters", [], {}, [[]], [{}], {"": None}]
TEXTS = st.text(alphabet=st.characters(exclude_categories=["Cs"]), max_size=12)  # any unicode but lone surrogates

tried = {"world": 0, "mission": 0, "loader": 0, "subprocess": 0}
exits = {"world": {0: 0, 2: 0}, "mission": {0: 0, 2: 0}}  # in-process outcomes, to show the cases reach both


# --- mutations ------------------------------------------------------------------------------------------------

def _paths(node, at=()):
    """Every place in a JSON document, as a tuple of keys and indices (the document itself is ())."""
    yield at
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, (*at, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _paths(value, (*at, index))


def _at(node, at):
    for key in at:
        node = node[key]
    return node


def _replace(doc, at, value):
    if not at:
        return value
    _at(doc, at[:-1])[at[-1]] = value
    return doc


@st.composite
def mutated(draw, sources: list[Path]):
    """(source file, mutated document, what was done): one to four mutations of one real file."""
    source = draw(st.sampled_from(sources))
    doc = json.loads(source.read_text())
    done = []
    for _ in range(draw(st.integers(1, 4))):
        places = list(_paths(doc))
        at = draw(st.sampled_from(places))
        value = _at(doc, at)
        parent = _at(doc, at[:-1]) if at else None
        op = draw(st.sampled_from(["delete", "retype", "rename", "number", "nest", "unnest", "missing_state",
                                   "empty", "unicode", "duplicate"]))
        if op == "delete" and at:
            del parent[at[-1]]
        elif op == "retype":
            doc = _replace(doc, at, draw(st.sampled_from(OTHERS + NUMBERS[:3])))
        elif op == "rename" and isinstance(parent, dict):
            new = draw(st.one_of(TEXTS, st.just(str(at[-1]).upper()), st.just(str(at[-1])[:-1])))
            parent[new] = parent.pop(at[-1])
        elif op == "number":
            doc = _replace(doc, at, draw(st.sampled_from(NUMBERS)))
        elif op == "nest":
            doc = _replace(doc, at, draw(st.sampled_from([[value], {"value": value}, [[value]]])))
        elif op == "unnest" and isinstance(value, list | dict) and value:
            doc = _replace(doc, at, value[0] if isinstance(value, list) else next(iter(value.values())))
        elif op == "missing_state":
            outcomes = [p for p in places if p and p[-1] == "outcomes" and isinstance(_at(doc, p), dict)
                        and _at(doc, p)]
            if outcomes:
                table = _at(doc, draw(st.sampled_from(outcomes)))
                table[draw(st.sampled_from(sorted(table)))] = draw(st.sampled_from(["no_such_state", "ghost"]))
        elif op == "empty":
            doc = _replace(doc, at, draw(st.sampled_from([[], {}, ""])))
        elif op == "unicode":
            doc = _replace(doc, at, draw(TEXTS))
        elif op == "duplicate" and isinstance(value, list) and value:
            value.append(json.loads(json.dumps(value[-1])))
        else:
            continue
        done.append(f"{op} at {'/'.join(map(str, at)) or '(top)'}")
    return source, doc, done


def _write(directory: Path, name: str, doc) -> Path:
    path = directory / name
    path.write_text(json.dumps(doc, ensure_ascii=False), encoding="utf-8")  # NaN and Infinity as JSON5-ish tokens
    return path


# --- what every outcome must look like ----------------------------------------------------------------------------

WHOLE_FILE = ("no such file", "cannot read it", "not UTF-8 text", "not valid JSON", "not a JSON document",
              "nested too deeply", "the top level must be")
# Where a JSON path may start, besides the keys of the file's own top level.
FORMAT_KEYS = {"scenario", "Agents_Config", "UAVs_Config", "State_Machine", "UTM"}


def check_outcome(command: str, file: Path, status: int, stderr: str, what: str, doc=None) -> None:
    """Exit 0, or exit 2 with every problem one line `magna <command>: FILE: JSON.path: message` (FILE the file
    checked, or a real file it includes; the path starts at a top-level key of that file)."""
    assert "Traceback" not in stderr, f"{what}: a traceback\n{stderr[-3000:]}"
    assert status in (0, 2), f"{what}: exit {status}\n{stderr[-3000:]}"
    if status == 0:
        return
    problems = [line for line in stderr.splitlines() if not line.startswith(f"magna {command}: warning: ")]
    assert problems, f"{what}: exit 2 without a message"
    top_keys = FORMAT_KEYS | (set(map(str, doc)) if isinstance(doc, dict) else set())
    for line in problems:
        assert line.startswith(f"magna {command}: "), f"{what}: not a `magna {command}:` line: {line[:500]!r}"
        located = line.removeprefix(f"magna {command}: ")
        if located.startswith(f"{file}: "):
            rest = located.removeprefix(f"{file}: ")
        else:  # a file the checked one includes
            other, _, rest = located.partition(": ")
            assert Path(other).is_file(), f"{what}: the problem does not start with the file: {line[:500]!r}"
        if rest.startswith(WHOLE_FILE):
            continue
        path, _, message = rest.partition(": ")
        assert message, f"{what}: no JSON path and message after the file: {line[:500]!r}"
        first = re.split(r"[.\[]", path, maxsplit=1)[0]
        assert first in top_keys or path.startswith("["), f"{what}: {path!r} is not a JSON path: {line[:500]!r}"


def run_in_process(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        status = magna_main(argv)
    return status, err.getvalue()


def check_world(path: Path, what: str, doc=None) -> None:
    status, stderr = run_in_process(["world", "check", str(path), "--search-path", str(CORPUS)])
    check_outcome("world", path, status, stderr, what, doc)
    tried["world"] += 1
    exits["world"][status] += 1


def check_mission(path: Path, what: str, doc=None) -> None:
    status, stderr = run_in_process(["mission", "check", str(path), "--search-path", str(CORPUS)])
    check_outcome("mission", path, status, stderr, what, doc)
    tried["mission"] += 1
    exits["mission"][status] += 1
    try:  # the loader the ground station and `magna run` use: a MissionError or a mission, nothing else
        load_mission(path)
    except MissionError as error:
        assert error.problems and all(p.startswith(str(path)) for p in error.problems), (what, error.problems)
    tried["loader"] += 1


def report(capsys, text: str) -> None:
    with capsys.disabled():
        print(f"\n[fuzz] {text}")


@pytest.fixture(scope="module")
def corpus():
    assert WORLDS and MISSIONS, f"no worlds or missions found; the ROS-MAGNA corpus belongs at {CORPUS}"
    assert any(CORPUS in p.parents for p in WORLDS), f"the ROS-MAGNA corpus is missing at {CORPUS} (MAGNA_CORPUS)"
    return CORPUS


# --- in-process: many cases -----------------------------------------------------------------------------------------

def test_mutated_worlds_end_in_exit_0_or_a_located_error(corpus, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("worlds")
    start = time.monotonic()

    @settings(max_examples=IN_PROCESS_EXAMPLES, **PROFILE)
    @given(mutated(WORLDS))
    def case(example):
        source, doc, done = example
        check_world(_write(folder, "wörld fuzzed.json", doc), f"{source.name}: {'; '.join(done)}", doc)

    before = tried["world"]
    case()
    report(capsys, f"worlds: {tried['world'] - before} mutated cases through `magna world check` in-process "
                   f"({time.monotonic() - start:.1f} s); exits so far {exits['world']}")
    assert tried["world"] - before >= IN_PROCESS_EXAMPLES // 2


def test_mutated_missions_end_in_exit_0_or_a_located_error(corpus, tmp_path_factory, capsys):
    folder = tmp_path_factory.mktemp("missions")
    start = time.monotonic()

    @settings(max_examples=IN_PROCESS_EXAMPLES, **PROFILE)
    @given(mutated(MISSIONS))
    def case(example):
        source, doc, done = example
        check_mission(_write(folder, "missión fuzzed.json", doc), f"{source.name}: {'; '.join(done)}", doc)

    before, loaded = tried["mission"], tried["loader"]
    case()
    report(capsys, f"missions: {tried['mission'] - before} mutated cases through `magna mission check` and "
                   f"{tried['loader'] - loaded} through magna_gs.mission.loader, in-process "
                   f"({time.monotonic() - start:.1f} s); exits so far {exits['mission']}")
    assert tried["mission"] - before >= IN_PROCESS_EXAMPLES // 2


# --- byte-level cases, written by hand --------------------------------------------------------------------------

TEN_MB = 10 * 1024 * 1024


def ten_mb_world() -> dict:
    """A valid world of 10 MB: a cube with one set of long-written coordinates (fewer than MAX_POSES_PER_SET)."""
    pose = [[0.12345678901234567, -0.2345678901234567, 0.3456789012345678],
            [0.0123456789012345, -0.0234567890123456, 1.2345678901234567]]
    count = TEN_MB // len(json.dumps(pose)) + 1
    geometry = {"name": "big", "prefix": "b", "shape": "cube", "origin": [[0, 0, 5], [0, 0, 0]],
                "dimensions": [4, 4, 4], "poses_sets": [{"type": "coordinates", "coordinates": [pose] * count}]}
    return {"scenario": {"world_boundaries": [[-10, 10], [-10, 10], [0, 20]],
                         "volumes": [{"name": "V", "prefix": "v", "origin": [[0, 0, 0], [0, 0, 0]],
                                      "geometries": [geometry]}]}}


def ten_mb_mission() -> dict:
    """A valid mission of 10 MB: one follow_path of long-written coordinate waypoints."""
    mission = json.loads((ROOT / "missions/Gym/Safe_Stop.json").read_text())
    waypoint = {"definition": ["Volume", "volume", "coordinates",
                               [[1.2345678901234567, 2.345678901234567, 3.456789012345678], [0, 0, 0]]]}
    count = TEN_MB // len(json.dumps(waypoint)) + 1
    states = mission["State_Machine"]
    # Flown by UAV 1 when the operator's wait ends, before the landing: reachable, so the mission is valid.
    wait = next(state for state in states if state["name"] == "operator_wait")
    after, wait["outcomes"]["completed"] = wait["outcomes"]["completed"], "1_long"
    states.insert(states.index(wait) + 1, {"type": "SimpleActionState", "state_type": "follow_path", "name": "long",
                                           "ids": 1, "parameters": {"path": [waypoint] * count},
                                           "outcomes": {"succeeded": after, "aborted": after}})
    return mission


def byte_cases(kind: str, folder: Path) -> list[tuple[str, Path]]:
    """(what, file) of the hand-written cases for worlds or missions."""
    real = (CORPUS / "Worlds/Gym/1Obs_Central_Cylinder.json" if kind == "world"
            else CORPUS / "Missions/Gym/2UAVs_2paths_Central_Cylinder.json")
    text = real.read_bytes()
    cases = {
        "empty file": b"",
        "truncated in the middle": text[: len(text) // 2],
        "not UTF-8 (Latin-1 bytes)": text.replace(b'"', b'"\xe9', 1),
        "a UTF-8 byte-order mark": b"\xef\xbb\xbf" + text,
        "nested 100 000 deep": b"[" * 100_000 + b"]" * 100_000,
        "a 5000-digit number": text.replace(b"[", b"[" + b"9" * 5000 + b", ", 1),
        "a bare NaN": b"NaN",
        "a list where the object goes": b"[" + text + b"]",
        "10 MB, valid": json.dumps(ten_mb_world() if kind == "world" else ten_mb_mission()).encode(),
        "10 MB of one string": json.dumps({"scenario" if kind == "world" else "State_Machine":
                                           "\u00e9" * (TEN_MB // 2)}).encode(),
    }
    out = []
    for index, (what, data) in enumerate(cases.items()):
        path = folder / f"{kind}_{index}.json"
        path.write_bytes(data)
        out.append((what, path))
    assert any(p.stat().st_size >= TEN_MB for _, p in out)
    return out


@pytest.mark.parametrize("kind", ["world", "mission"])
def test_hand_written_byte_cases_end_in_exit_0_or_a_located_error(corpus, kind, tmp_path, capsys):
    slowest = (0.0, "")
    cases = byte_cases(kind, tmp_path)
    for what, path in cases:
        start = time.monotonic()
        (check_world if kind == "world" else check_mission)(path, what)
        slowest = max(slowest, (time.monotonic() - start, what))
    report(capsys, f"{kind}s: {len(cases)} byte-level cases in-process; slowest {slowest[1]!r} "
                   f"({slowest[0]:.1f} s)")


# --- the real command, as a subprocess: a smaller sample -----------------------------------------------------------

def run_magna(argv: list[str]) -> tuple[int, str]:
    try:
        done = subprocess.run([str(ROOT / "magna"), *argv], capture_output=True, text=True, timeout=COMMAND_GUARD,
                              cwd=ROOT)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"magna {' '.join(argv)}: still running after {COMMAND_GUARD:g} s (a hang)") from None
    tried["subprocess"] += 1
    return done.returncode, done.stderr


@pytest.mark.parametrize("kind", ["world", "mission"])
def test_the_magna_command_ends_in_exit_0_or_a_located_error(corpus, kind, tmp_path, capsys):
    sources = WORLDS if kind == "world" else MISSIONS
    samples: list[tuple[str, Path, object]] = []

    @settings(max_examples=SUBPROCESS_EXAMPLES, **PROFILE)
    @given(mutated(sources))
    def collect(example):
        source, doc, done = example
        samples.append((f"{source.name}: {'; '.join(done)}", _write(tmp_path, f"sample_{len(samples)}.json", doc),
                        doc))

    collect()
    (tmp_path / "bytes").mkdir()
    chosen = [(what, path, None) for what, path in byte_cases(kind, tmp_path / "bytes")
              if what in ("not UTF-8 (Latin-1 bytes)", "nested 100 000 deep", "10 MB, valid")]
    before = tried["subprocess"]
    for what, path, doc in [*samples, *chosen]:
        status, stderr = run_magna([kind, "check", str(path), "--search-path", str(CORPUS)])
        check_outcome(kind, path, status, stderr, f"./magna {kind} check: {what}", doc)
    report(capsys, f"{kind}s: {tried['subprocess'] - before} cases through the ./magna command as a subprocess")
    assert tried["subprocess"] - before == len(samples) + len(chosen) >= SUBPROCESS_EXAMPLES


# --- what the fuzzing found, kept as plain cases: each refused with its file and JSON path --------------------------

def _four_cylinders(change) -> dict:
    world = json.loads((ROOT / "worlds/Gym/Four_Cylinders.json").read_text())
    change(world["scenario"]["volumes"][0]["geometries"][0])
    return world


def _set(key, value):
    return lambda geometry: geometry["poses_sets"][0].update({key: value})


SET = "scenario.volumes[0].geometries[0].poses_sets[0]"
FOUND_IN_WORLDS = [  # (what, change to the first geometry, JSON path named)
    ("an integer beyond any float", lambda g: g.update(alpha=10 ** 400), "scenario.volumes[0].geometries[0].alpha"),
    ("a dimension beyond any float", lambda g: g.update(dimensions=[8.0, 10 ** 400, 0.1]),
     "scenario.volumes[0].geometries[0].dimensions[1]"),
    ("a geometry name that is a list", lambda g: g.update(name=["Agents_take_off"]),
     "scenario.volumes[0].geometries[0].name"),
    ("a matrix of 10^12 cells", _set("dimensions", [1_000_000, 1_000_000, 1]), f"{SET}.dimensions"),
    ("a distance matrix of 1 um spacing", lambda g: g["poses_sets"][0].update(matrix_type="distance",
                                                                                dimensions=[1e-6, 1e-6, 1e-6]),
     f"{SET}.dimensions"),
    ("a billion random poses", lambda g: g["poses_sets"][0].update(type="random", quantity=10 ** 9),
     f"{SET}.quantity"),
]


@pytest.mark.parametrize("what, change, path", FOUND_IN_WORLDS, ids=[case[0] for case in FOUND_IN_WORLDS])
def test_what_fuzzing_found_in_worlds_is_refused_with_its_path(what, change, path, tmp_path):
    file = _write(tmp_path, "world.json", _four_cylinders(change))
    status, stderr = run_in_process(["world", "check", str(file)])
    assert status == 2 and stderr.startswith(f"magna world: {file}: {path}: "), stderr


def test_an_outcome_map_condition_of_the_wrong_type_is_refused_with_its_path(tmp_path):
    mission = json.loads((ROOT / "missions/Gym/Safe_Stop.json").read_text())
    take_off = next(state for state in mission["State_Machine"] if state["name"] == "take_off")
    take_off["occurrencies_outcome_map"]["completed"]["all"] = ["succeeded"]
    file = _write(tmp_path, "mission.json", mission)
    status, stderr = run_in_process(["mission", "check", str(file)])
    assert status == 2, stderr
    assert f"magna mission: {file}: State_Machine[5].occurrencies_outcome_map.completed.all: " in stderr, stderr


# --- ground-station commands, in-process: planned or refused with a reason, nothing else --------------------------

def test_fuzzed_operator_commands_are_planned_or_refused_with_a_reason(capsys):
    from magna_gs.commands import MISSION_ACTIONS, CommandRefused, Param, UavStatus, plan_command

    boundaries = np.array([[-10.0, 10.0], [-10.0, 10.0], [0.0, 8.0]])
    uavs = {1: UavStatus(1, np.array([0.0, 0.0, 3.0])), 2: UavStatus(2, np.array([2.0, 0.0, 3.0]), math.nan),
            3: UavStatus(3, None)}
    known = [("mission", a) for a in MISSION_ACTIONS] + [("parameters", "get"), ("algorithms", "set")] + \
        [("basic_action", a) for a in ("take_off", "land", "move", "turn", "follow")]
    # A known command with, now and then, its intent or action replaced by any text.
    commands = st.tuples(st.sampled_from(known), st.sampled_from(["", "intent", "action"]), TEXTS).map(
        lambda c: (c[2] if c[1] == "intent" else c[0][0], c[2] if c[1] == "action" else c[0][1]))
    agents = st.sampled_from(["1", "2", "3", "all", "7", "-1", "1e400", ""]) | TEXTS
    words = st.sampled_from(["up", "left", "x", "right", "2", "uav_1", "simple", "orca3d", ""]) | TEXTS
    numbers = st.sampled_from(NUMBERS[:6] + [2.0, -2.0, 1.5, 1e-9]) | st.floats(allow_nan=True, allow_infinity=True)
    params = st.lists(st.builds(Param, st.sampled_from(["height", "distance", "angle", "direction", "target",
                                                        "algorithm", "battery", "state", "position"]) | TEXTS,
                                numbers, words, st.sampled_from(["", "m", "deg", "cm"])), max_size=4)
    outcomes = {"planned": 0, "refused": 0}

    @settings(max_examples=400, **PROFILE)
    @given(commands, agents, params, st.sampled_from([(), (2,), (1, 2)]))
    def case(command, agent, given_params, locked):
        intent, action = command
        try:
            plan = plan_command(intent, action, agent, given_params, uavs, boundaries, locked=locked)
        except CommandRefused as refusal:
            assert str(refusal).strip(), "a refusal without a reason"
            outcomes["refused"] += 1
            return
        outcomes["planned"] += 1
        for order in plan.orders:  # what is sent is finite, inside the world and for a UAV the operator may command
            assert order.uav_id not in locked, (order, locked)
            assert all(math.isfinite(v) for v in order.fields.values() if isinstance(v, float)), order

    case()
    report(capsys, f"operator commands: {sum(outcomes.values())} cases through plan_command in-process ({outcomes})")
    assert outcomes["planned"] and outcomes["refused"]
