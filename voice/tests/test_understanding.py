"""Sentences become the ground station's commands, whatever the word order, numbers in words or
digits, fillers and units; what is missing or unsure becomes a question, not a guess."""
import pytest

from voice.interpret import Command, Question, parse, wit_entities


def command(sentence, ids=(1, 2, 3)):
    result = parse(sentence, ids)[1]
    assert isinstance(result, Command), f"{sentence!r}: {result}"
    return result.intent, result.action, result.agent, {p.name: p.text or p.number for p in result.parameters}


def question(sentence, ids=(1, 2, 3)):
    result = parse(sentence, ids)[1]
    assert isinstance(result, Question), f"{sentence!r} gave a command: {result}"
    return result


@pytest.mark.parametrize("sentence", [
    "drone two, go up five meters", "five meters up, drone two", "go up five meters drone two",
    "uh, drone two, could you please move up 5 m", "UAV 2 climb five metres", "drone two up five meters",
    "drone 2 rise by 500 centimeters", "quad number two, upwards five meters now",
])
def test_word_order_numbers_units_and_fillers_do_not_change_the_command(sentence):
    assert command(sentence) == ("basic_action", "move", "2", {"direction": "up", "distance": 5.0})


@pytest.mark.parametrize("sentence, expected", [
    ("all drones land", ("basic_action", "land", "all", {})),
    ("everyone, touch down", ("basic_action", "land", "all", {})),
    ("tell drone one to land", ("basic_action", "land", "1", {})),
    ("drone one take off to three meters", ("basic_action", "take_off", "1", {"height": 3.0})),
    ("drone three, take off", ("basic_action", "take_off", "3", {})),
    ("drone two turn right ninety degrees", ("basic_action", "turn", "2", {"angle": 90.0, "direction": "right"})),
    ("rotate drone one forty five degrees", ("basic_action", "turn", "1", {"angle": 45.0})),
    ("drone one turn left half a radian", ("basic_action", "turn", "1", {"angle": pytest.approx(28.6479, abs=1e-3),
                                                                           "direction": "left"})),
    ("drone two follow drone one at three meters", ("basic_action", "follow", "2", {"target": 1.0, "distance": 3.0})),
    ("follow drone three, drone one", ("basic_action", "follow", "1", {"target": 3.0})),
    ("drone two stay four meters behind drone one", ("basic_action", "follow", "2", {"target": 1.0, "distance": 4.0})),
    ("drone two, follow one at 2 m", ("basic_action", "follow", "2", {"target": 1.0, "distance": 2.0})),
    ("U A V 3 move minus two meters along the y axis", ("basic_action", "move", "3", {"direction": "y",
                                                                                     "distance": -2.0})),
    ("drone one go back twenty five centimetres", ("basic_action", "move", "1", {"direction": "backward",
                                                                                "distance": 0.25})),
    ("what is the battery level of drone one", ("parameters", "get", "1", {"battery": 0.0})),
    ("how are all the drones doing", ("parameters", "get", "all", {"state": 0.0})),
    ("where's drone three", ("parameters", "get", "3", {"position": 0.0})),
    ("switch all drones to the neural network", ("algorithms", "set", "all", {"algorithm": "neural_network"})),
    ("drone one, use orca", ("algorithms", "set", "1", {"algorithm": "orca3d"})),
    ("set simple guidance for drone two", ("algorithms", "set", "2", {"algorithm": "simple"})),
    ("pause the mission", ("mission", "standby", "all", {})),
    ("okay, carry on", ("mission", "resume", "all", {})),
])
def test_every_kind_of_command(sentence, expected):
    assert command(sentence) == expected


@pytest.mark.parametrize("sentence, expected", [
    ("drone two, come down and land", ("basic_action", "land", "2", {})),
    ("drone three, go back to the simple algorithm", ("algorithms", "set", "3", {"algorithm": "simple"})),
    ("drone one, go follow drone two", ("basic_action", "follow", "1", {"target": 2.0})),
])
def test_of_several_verbs_the_one_that_makes_a_whole_command_wins(sentence, expected):
    assert command(sentence) == expected


@pytest.mark.parametrize("sentence, missing", [
    ("go up five meters", "identity"), ("land now", "identity"), ("what is the battery level", "identity"),
    ("drone one go up", "number"), ("drone two turn right", "number"), ("drone one, move five meters", "direction"),
    ("drone two use", "algorithm"), ("drone two make me a sandwich", "action"),
    ("what's the weather like", "parameter"), ("drone two take off to ninety degrees", "number"),
])
def test_what_is_missing_is_asked_for(sentence, missing):
    assert question(sentence).missing == missing


def test_the_question_offers_the_uavs_of_the_mission():
    assert "drone 1, drone 2 or all drones" in question("land", ids=(1, 2)).text


def test_a_typo_is_read_with_a_lower_confidence_and_too_low_a_confidence_asks_to_confirm():
    understanding, result = parse("drone one, lannd", (1,))
    action = understanding.first("action")
    assert action.value == "land" and 0.85 <= action.confidence < 1.0
    assert isinstance(result, Command) and result.confidence == action.confidence
    shaky = question("drone one, go up three metrz")  # 0.8 like "meter": worth asking, not worth doing
    assert shaky.missing == "confirmation" and "UAV 1: move (direction up, distance 3 m)?" in shaky.text
    assert question("drone one lnad").missing == "action"  # 0.75 like "land": not understood
    assert question("drone one xyzzy").missing == "action"  # nothing like any command word


def test_entities_come_out_wit_style_with_intent_and_confidences():
    understanding, result = parse("drone two follow drone one at three meters")
    entities = wit_entities(understanding, result)
    assert entities["intent"][0]["value"] == "basic_action"
    assert [(e["value"], e["role"]) for e in entities["identity"]] == [("uav_2", "agent"), ("uav_1", "target")]
    assert entities["number"] == [{"value": 3.0, "confidence": 1.0, "body": "three"}]
    assert entities["unit"][0]["value"] == "meters"
