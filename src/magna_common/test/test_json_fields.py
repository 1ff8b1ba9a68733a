"""The JSON field reader: the value each getter returns, the message each failure gets, and the two modes."""
import pytest

from magna_common.errors import UserError
from magna_common.json_fields import MISSING, FieldError, JsonFields, ObjectFields, did_you_mean, join_path


class Bad(FieldError):
    pass


def first() -> JsonFields:
    return JsonFields.first_error("f.json", Bad)


def test_paths_join_keys_and_indices():
    assert join_path("", "scenario") == "scenario"
    assert join_path("scenario", "volumes") == "scenario.volumes"
    assert join_path("scenario.volumes", 2) == "scenario.volumes[2]"


@pytest.mark.parametrize("read, value", [
    (lambda f: f.object({"a": 1}, "p"), {"a": 1}),
    (lambda f: f.list([1], "p"), [1]),
    (lambda f: f.text("x", "p"), "x"),
    (lambda f: f.text("", "p", allow_empty=True), ""),
    (lambda f: f.number(2, "p"), 2.0),
    (lambda f: f.number(0, "p", minimum=0), 0.0),
    (lambda f: f.integer(-3, "p"), -3),
    (lambda f: f.numbers([1, 2.5], "p", 2, "[a, b]"), (1.0, 2.5)),
    (lambda f: f.choice("b", "p", ("a", "b")), "b"),
    (lambda f: f.flag(False, "p"), False),
    (lambda f: f.flag(1, "p", zero_one=True), True),
    (lambda f: f.key({"k": None}, "p", "k", "add it"), None),
])
def test_a_good_value_is_returned_typed(read, value):
    got = read(first())
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize("read, path, message", [
    (lambda f: f.key([], "p", "k", "add it"), "p", "expected an object, got a list"),
    (lambda f: f.key({}, "p", "k", "add it: a name"), "p.k", "missing; add it: a name"),
    (lambda f: f.object("x", "p"), "p", "expected an object {...}, got a string"),
    (lambda f: f.list({}, "p", "a list of states"), "p", "expected a list of states, got an object"),
    (lambda f: f.list([], "p", "a non-empty list", non_empty=True), "p", "expected a non-empty list, got a list"),
    (lambda f: f.text(3, "p"), "p", "expected a non-empty string, got 3"),
    (lambda f: f.text("", "p", "a name"), "p", "expected a name, got ''"),
    (lambda f: f.number(True, "p"), "p", "expected a finite number, got True"),
    (lambda f: f.number(float("nan"), "p"), "p", "expected a finite number, got nan"),
    (lambda f: f.number(0, "p", "a height, > 0", positive=True), "p", "expected a height, > 0, got 0"),
    (lambda f: f.number(-1, "p", "seconds, >= 0", minimum=0), "p", "expected seconds, >= 0, got -1"),
    (lambda f: f.integer(1.5, "p"), "p", "expected a whole number, got 1.5"),
    (lambda f: f.integer(0, "p", "a count >= 1", minimum=1), "p", "expected a count >= 1, got 0"),
    (lambda f: f.numbers([1], "p", 3, "[x, y, z] in m"), "p", "expected [x, y, z] in m, got 1 value(s)"),
    (lambda f: f.numbers([1, "a"], "p", 2, "[low, high]"), "p[1]", "expected a finite number, got 'a'"),
    (lambda f: f.choice("hil", "p", ("sitl", "real")), "p", "'hil' is not one of sitl, real"),
    (lambda f: f.choice("sitll", "p", ("sitl", "real")), "p", "'sitll' is not one of sitl, real (did you mean "
                                                              "'sitl'?)"),
    (lambda f: f.choice("cone", "p", ("cube", "prism"), noun="shape"), "p", "unknown shape 'cone'; use one of "
                                                                            "cube, prism"),
    (lambda f: f.flag(1, "p"), "p", "expected true or false, got 1"),
    (lambda f: f.flag(2, "p", zero_one=True), "p", "expected true or false, got 2"),
])
def test_a_first_error_reader_raises_its_error_naming_file_and_path(read, path, message):
    with pytest.raises(Bad) as error:
        read(first())
    assert (error.value.source, error.value.path, error.value.message) == ("f.json", path, message)
    assert str(error.value) == f"f.json: {path}: {message}"
    assert isinstance(error.value, UserError) and isinstance(error.value, ValueError)


def test_a_collecting_reader_reports_every_problem_and_returns_none():
    fields = JsonFields.collect_all("m.json")
    assert fields.text(3, "a") is None
    assert fields.numbers([1, "x", None], "b", 3, "[x, y, z]") is None
    assert fields.choice("c", "c", ("a", "b")) is None
    assert fields.text("fine", "d") == "fine"
    assert fields.problems == ["m.json: a: expected a non-empty string, got 3",
                               "m.json: b[1]: expected a finite number, got 'x'",
                               "m.json: b[2]: expected a finite number, got None",
                               "m.json: c: 'c' is not one of a, b"]


def test_paths_are_named_as_the_file_writes_them():
    renamed = {"Agents_Config": "UAVs_Config"}

    def original(path: str) -> str:
        head, dot, rest = path.partition(".")
        return renamed.get(head, head) + dot + rest

    fields = JsonFields.collect_all("m.json", original)
    fields.flag("yes", "Agents_Config.ual_use")
    fields.warn("Agents_Config.x", "ignored")
    assert fields.problems == ["m.json: UAVs_Config.ual_use: expected true or false, got 'yes'"]
    assert fields.warnings == ["m.json: UAVs_Config.x: ignored"]
    with pytest.raises(FieldError) as error:
        JsonFields.first_error("m.json", original_path=original).number("no", "Agents_Config.a")
    assert error.value.path == "UAVs_Config.a"


def test_the_whole_document_is_named_by_its_file_alone():
    with pytest.raises(FieldError, match=r"^f\.json: expected an object, got 3$"):
        JsonFields.first_error("f.json").key(3, "", "scenario", "add it")


def object_fields(raw: dict) -> tuple[JsonFields, ObjectFields]:
    fields = JsonFields.collect_all("m.json")
    return fields, ObjectFields(fields, raw, "State[0].parameters", lambda key, usage: f"land needs {key} ({usage})")


def test_object_fields_read_keys_with_defaults():
    fields, obj = object_fields({"height": 2, "dynamic": "position", "final": True, "extra": 1})
    assert obj.number("height", positive=True) == 2.0
    assert obj.number("duration", default=0.0) == 0.0
    assert obj.number("speed", default=None) is None
    assert obj.integer("mode", default=0) == 0
    assert obj.choice("dynamic", ("position", "velocity"), default="velocity") == "position"
    assert obj.flag("final", False) is True and obj.flag("other", True) is True
    assert obj.text("name", default="") == ""
    assert obj.get("pos", False, "[x, y, z]") is MISSING
    assert obj.ok and fields.problems == []
    assert obj.unused() == ["extra"]


def test_object_fields_report_missing_and_bad_keys():
    fields, obj = object_fields({"height": -1, "final": "yes"})
    assert obj.number("height", positive=True, usage="a height in m, > 0") is None
    assert obj.text("name", usage="a name") is None
    assert obj.flag("final", False) is False
    assert not obj.ok
    assert fields.problems == ["m.json: State[0].parameters.height: expected a height in m, > 0, got -1",
                               "m.json: State[0].parameters.name: missing; land needs name (a name)",
                               "m.json: State[0].parameters.final: expected true or false, got 'yes'"]


def test_a_near_miss_gets_a_guess():
    assert did_you_mean("occurrences", ("occurrencies", "outcomes")) == " (did you mean 'occurrencies'?)"
    assert did_you_mean("zzz", ("occurrencies",)) == ""
