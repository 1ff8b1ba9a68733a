"""Unsure means ask: a spoken command that moves aircraft or changes the mission is sent without a question
only when the recogniser is confident of it; below the threshold the assistant asks "did you say ...?", and
"no" or no answer in time cancels while "yes" sends it. Questions to the ground station are never confirmed.

The recogniser here is a stand-in returning a fixed n-best list with scores, so the confidence is known."""
import numpy as np
import pytest

from voice.assistant import CONFIRM_SECONDS, CONFIRM_THRESHOLD, Assistant
from voice.backend import Reply
from voice.rescoring import rescore
from voice.stt import Transcript

IDS = (1, 2)
CLIMB = "drone two go up five meters"
# "go on" is the resume verb: a hypothesis as close as this makes the climb doubtful
DOUBTFUL = Transcript(CLIMB, [CLIMB, "drone two go on five meters", "drone two go up nine meters"], 0.2,
                      [-0.50, -0.51, -0.52])
SURE = Transcript(CLIMB, [CLIMB, "drone two go up five metres"], 0.2, [-0.50, -0.60])
BATTERY = "what is the battery level of drone one"
DOUBTFUL_QUERY = Transcript(BATTERY, [BATTERY, "what is the state of drone one"], 0.2, [-0.50, -0.50])


class ScriptedRecognizer:
    """Hands out the transcripts given, one per utterance."""

    def __init__(self, *transcripts):
        self.transcripts = list(transcripts)

    def transcribe(self, samples):
        return self.transcripts.pop(0)


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class GroundStation:
    def __init__(self):
        self.sent = []

    def __call__(self, command):
        self.sent.append(command)
        return Reply(True, f"UAV {command.agent} {command.action}")


def assistant_hearing(*transcripts):
    gs, clock, said = GroundStation(), Clock(), []
    assistant = Assistant(gs, IDS, say=said.append, recognizer=ScriptedRecognizer(*transcripts), clock=clock)
    return assistant, gs, clock, said


AUDIO = np.zeros(1600, dtype=np.int16)  # the stand-in recogniser ignores it


def test_the_stand_in_transcripts_have_the_confidences_the_tests_need():
    assert rescore(DOUBTFUL.alternatives, DOUBTFUL.scores, IDS).confidence < CONFIRM_THRESHOLD
    assert rescore(SURE.alternatives, SURE.scores, IDS).confidence >= CONFIRM_THRESHOLD
    assert rescore(DOUBTFUL_QUERY.alternatives, DOUBTFUL_QUERY.scores, IDS).confidence < CONFIRM_THRESHOLD


def test_a_low_confidence_asks_and_sends_nothing():
    assistant, gs, _, said = assistant_hearing(DOUBTFUL)
    outcome = assistant.handle_audio(AUDIO)
    assert outcome.result.missing == "confirmation" and gs.sent == []
    assert said == [outcome.result.text] and outcome.result.text.startswith(f'Did you say "{CLIMB}"')
    assert "UAV 2: move" in outcome.result.text and outcome.confidence < CONFIRM_THRESHOLD


def test_yes_sends_the_command_asked_about():
    assistant, gs, clock, _ = assistant_hearing(DOUBTFUL, Transcript("yes", ["yes"], 0.1, [-0.1]))
    assistant.handle_audio(AUDIO)
    clock.now += CONFIRM_SECONDS / 2
    outcome = assistant.handle_audio(AUDIO)
    assert [(c.action, c.agent, c.parameters[1].number) for c in gs.sent] == [("move", "2", 5.0)]
    assert outcome.reply.message == "UAV 2 move"


def test_no_cancels():
    assistant, gs, _, said = assistant_hearing(DOUBTFUL, Transcript("no", ["no"], 0.1, [-0.1]))
    assistant.handle_audio(AUDIO)
    outcome = assistant.handle_audio(AUDIO)
    assert gs.sent == [] and outcome.result.missing == "cancelled" and "nothing was sent" in said[-1]
    assert assistant.handle_text("yes").result.missing != "cancelled" and gs.sent == []  # nothing left to confirm


def test_silence_cancels_and_a_late_yes_sends_nothing():
    assistant, gs, clock, said = assistant_hearing(DOUBTFUL)
    assistant.handle_audio(AUDIO)
    assert assistant.expire() is None  # not yet
    clock.now += CONFIRM_SECONDS + 0.1
    expired = assistant.expire()
    assert expired is not None and expired.result.missing == "cancelled" and "nothing was sent" in said[-1]
    assert assistant.handle_text("yes").result.missing != "confirmation" and gs.sent == []


def test_a_yes_after_the_time_out_is_too_late_even_without_the_timer():
    assistant, gs, clock, _ = assistant_hearing(DOUBTFUL)
    assistant.handle_audio(AUDIO)
    clock.now += CONFIRM_SECONDS + 0.1
    outcome = assistant.handle_text("yes")
    assert outcome.result.missing == "cancelled" and "Too late" in outcome.result.text and gs.sent == []


def test_a_new_command_instead_of_an_answer_is_handled_on_its_own():
    assistant, gs, _, _ = assistant_hearing(DOUBTFUL)
    assistant.handle_audio(AUDIO)
    assistant.handle_text("drone one land")  # typed: confidence 1
    assert [(c.action, c.agent) for c in gs.sent] == [("land", "1")]
    assert assistant.handle_text("yes").result.missing != "confirmation" and len(gs.sent) == 1


def test_a_confident_command_is_sent_without_a_question():
    assistant, gs, _, _ = assistant_hearing(SURE)
    outcome = assistant.handle_audio(AUDIO)
    assert [(c.action, c.agent) for c in gs.sent] == [("move", "2")] and outcome.confidence >= CONFIRM_THRESHOLD


def test_a_question_to_the_ground_station_is_never_confirmed():
    assistant, gs, _, _ = assistant_hearing(DOUBTFUL_QUERY)
    outcome = assistant.handle_audio(AUDIO)
    assert [(c.action, c.agent) for c in gs.sent] == [("get", "1")] and outcome.confidence < CONFIRM_THRESHOLD


@pytest.mark.parametrize("threshold", [0.0, 1.01])
def test_the_threshold_decides(threshold):
    gs = GroundStation()
    assistant = Assistant(gs, IDS, recognizer=ScriptedRecognizer(SURE), confirm_threshold=threshold)
    assistant.handle_audio(AUDIO)
    assert len(gs.sent) == (1 if threshold == 0.0 else 0)
