"""The ground station's answer is shown and spoken as it is: an accepted command says what will happen, a
refusal says why; nothing claims "done" for a command that was only sent."""
from voice.assistant import Assistant, render
from voice.backend import Reply
from voice.interpret import Parameter


def test_an_accepted_command_shows_and_says_the_ground_stations_message():
    reply = Reply(True, "UAV 2 climbing to 7 m")
    assert reply.describe() == "UAV 2 climbing to 7 m"
    assert reply.spoken() == "UAV 2 climbing to 7 m."


def test_a_refusal_shows_refused_and_says_why():
    reply = Reply(False, "UAV 1 is landing, so it cannot move")
    assert reply.describe() == "refused: UAV 1 is landing, so it cannot move"
    assert reply.spoken() == "UAV 1 is landing, so it cannot move."
    assert Reply(False, "parameter 'distance' is missing: give it in m.").spoken() == (
        "parameter 'distance' is missing: give it in m.")  # no second full stop


def test_answers_to_questions_keep_their_values():
    reply = Reply(True, "uav_1.battery 87.0%", [Parameter("uav_1.battery", 87.0, "", "%")])
    assert reply.describe() == "uav_1.battery 87.0%\n  uav_1.battery: 87.0 %"
    assert reply.spoken() == "drone 1 battery 87 percent"


def test_the_assistant_speaks_and_renders_the_truthful_answer():
    said = []
    assistant = Assistant(lambda command: Reply(False, "UAV 2 is on the ground, so it cannot move: take off first"),
                          [1, 2], say=said.append)
    outcome = assistant.handle_text("drone two, go up two meters")
    assert said == ["UAV 2 is on the ground, so it cannot move: take off first."]
    assert render(outcome).splitlines()[-1] == "refused: UAV 2 is on the ground, so it cannot move: take off first"
