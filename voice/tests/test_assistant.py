"""The assistant's dialogue (no ROS): commands are sent once, questions send nothing, an answer to a
question completes the sentence that raised it, and an unsure command waits for a yes. Then its
command line, and what it says when there is no ROS master or no ground station."""
import json
import subprocess
import sys

import pytest

from tests.support import ROOT
from voice.assistant import Assistant, choose_hypothesis, render
from voice.backend import BackendError, Reply
from voice.interpret import Command, Parameter, Question


class FakeGroundStation:
    def __init__(self, fail=False):
        self.sent, self.fail = [], fail

    def __call__(self, command):
        if self.fail:
            raise BackendError("the ground station's /magna/gs/command is not up")
        self.sent.append(command)
        if command.action == "get":
            return Reply(True, "uav_1.battery 87.0%", [Parameter("uav_1.battery", 87.0, "", "%")])
        return Reply(True, f"{command.action} for UAV {command.agent}")


def test_a_command_is_sent_once_and_its_answer_shown():
    gs = FakeGroundStation()
    outcome = Assistant(gs, [1, 2]).handle_text("drone one, what is your battery level")
    assert [(c.action, c.agent) for c in gs.sent] == [("get", "1")]
    assert outcome.reply.values[0].number == 87.0
    shown = render(outcome)
    assert "UAV 1: get (battery)" in shown and "uav_1.battery: 87.0 %" in shown


def test_a_question_sends_nothing_and_the_answer_completes_the_sentence():
    gs, said = FakeGroundStation(), []
    assistant = Assistant(gs, [1, 2], say=said.append)
    asked = assistant.handle_text("take off to three meters")
    assert isinstance(asked.result, Question) and gs.sent == []
    assert said == ["Which UAV should take off: drone 1, drone 2 or all drones?"]
    done = assistant.handle_text("drone two")
    assert done.heard == "take off to three meters drone two"
    assert gs.sent == [Command("basic_action", "take_off", "2", (Parameter("height", 3.0, "", "m"),))]
    assistant.handle_text("drone one")  # no question pending any more: not a command
    assert len(gs.sent) == 1


def test_an_unsure_command_waits_for_yes_and_no_drops_it():
    gs = FakeGroundStation()
    assistant = Assistant(gs, [1])
    assert assistant.handle_text("drone one go up three metrz").result.missing == "confirmation"
    assert assistant.handle_text("no").result.missing == "cancelled" and gs.sent == []
    assistant.handle_text("drone one go up three metrz")
    confirmed = assistant.handle_text("yes")
    assert confirmed.reply.accepted
    assert gs.sent[0].parameters == (Parameter("direction", 0.0, "up"), Parameter("distance", 3.0, "", "m"))


def test_an_unreachable_ground_station_is_reported_not_raised():
    outcome = Assistant(FakeGroundStation(fail=True), [1]).handle_text("drone one land")
    assert "is not up" in outcome.error and "! the ground station" in render(outcome)


def test_of_the_recogniser_alternatives_the_first_whole_command_is_taken():
    assert choose_hypothesis(["drone two go meters", "drone two go up five meters"]) == "drone two go up five meters"
    assert choose_hypothesis(["drone one land", "drone one hand"]) == "drone one land"
    assert choose_hypothesis(["go up", "go up five"]) == "go up"  # no whole command: the best
    assert choose_hypothesis(["", " "]) == ""


def test_parse_prints_one_json_line_per_sentence_with_the_command_or_the_question():
    result = subprocess.run([sys.executable, "-m", "voice", "parse", "drone two, go up five meters", "land"],
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 0, result.stderr
    first, second = (json.loads(line) for line in result.stdout.splitlines())
    assert first["command"] == {"intent": "basic_action", "action": "move", "agent": "2", "parameters": [
        {"name": "direction", "number": 0.0, "text": "up", "unit": ""},
        {"name": "distance", "number": 5.0, "text": "", "unit": "m"}]}
    assert first["entities"]["intent"][0]["value"] == "basic_action" and first["question"] is None
    assert second["command"] is None and second["question"]["missing"] == "identity"


def test_the_keyboard_assistant_reads_typed_lines_in_a_dry_run():
    result = subprocess.run([sys.executable, "-m", "voice", "--dry-run", "--uavs", "1,2"], input="land\ndrone two\n",
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "? Which UAV should land: drone 1, drone 2 or all drones?" in result.stdout
    assert "> UAV 2: land" in result.stdout


def test_bad_input_is_named_with_its_fix():
    bad = subprocess.run([sys.executable, "-m", "voice", "--uavs", "one,two", "--dry-run"], capture_output=True,
                         text=True, cwd=ROOT, timeout=60, input="")
    assert bad.returncode == 2 and "--uavs 'one,two': give UAV ids separated by commas" in bad.stderr
    missing = subprocess.run([sys.executable, "-m", "voice", "transcribe", "/nonexistent/x.wav"],
                             capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert missing.returncode == 2 and "no such audio file: /nonexistent/x.wav" in missing.stderr


def _voice_env(uri):
    import os

    return {**os.environ, "ROS_MASTER_URI": uri}


def test_without_a_ros_master_the_assistant_says_what_to_start():
    from magna_common.ports import free_port

    result = subprocess.run([sys.executable, "-m", "voice", "--wait", "1"], input="drone one land\n",
                            env=_voice_env(f"http://127.0.0.1:{free_port()}"), capture_output=True, text=True,
                            cwd=ROOT, timeout=60)
    assert result.returncode == 2 and "no ROS master at http://127.0.0.1:" in result.stderr, result.stderr


@pytest.mark.ros
def test_without_a_ground_station_the_assistant_says_what_to_start(fresh_ros_master):
    result = subprocess.run([sys.executable, "-m", "voice", "--wait", "1"], input="drone one land\n",
                            env=_voice_env(fresh_ros_master.env()["ROS_MASTER_URI"]), capture_output=True,
                            text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 2, result.stderr
    assert "the ground station's /magna/gs/command is not up after 1 s" in result.stderr
