"""The README's spoken examples: each sentence, said by espeak-ng in each voice the README names, is heard as
the command the README gives for it (offline recogniser, rescored n-best, the mission's UAVs 1 and 2)."""
import re

import pytest

from tests.support import ROOT
from voice.interpret import Command
from voice.rescoring import rescore
from voice.speech import make_recognizer
from voice.synth import synthesize

README = ROOT / "voice" / "README.md"
IDS = (1, 2)


def documented():
    """(sentence, command as Command.describe() says it) rows and the (voice, speed) pairs of "Spoken examples"."""
    text = README.read_text()
    section = text[text.index("## Spoken examples"):]
    section = section[:section.index("\n## ", 1)]
    rows = re.findall(r'^\| "([^"]+)" \| ([^|]+?) \|$', section, flags=re.MULTILINE)
    voices = [(voice, int(speed)) for voice, speed in re.findall(r"`([a-z-]+(?:\+[a-z0-9]+)?)@(\d+)`", section)]
    return rows, voices


ROWS, VOICES = documented()


def test_the_readme_documents_examples_and_voices():
    assert len(ROWS) >= 8 and len(VOICES) >= 3, (ROWS, VOICES)


@pytest.fixture(scope="module")
def recognizer(tmp_path_factory):
    return make_recognizer(uav_ids=IDS, cache_dir=tmp_path_factory.mktemp("speech_model"))


@pytest.mark.espeak
@pytest.mark.parametrize("voice,speed", VOICES)
def test_each_example_is_heard_as_its_command_in_each_voice(recognizer, voice, speed):
    wrong = {}
    for sentence, command in ROWS:
        transcript = recognizer.transcribe(synthesize(sentence, voice=voice, speed=speed))
        hearing = rescore(transcript.alternatives, transcript.scores, IDS)
        result = hearing.chosen.result
        understood = result.describe() if isinstance(result, Command) else f"a question ({result.text})"
        if understood != command:
            wrong[sentence] = (hearing.text, understood)
    assert not wrong, f"{voice}@{speed} heard: {wrong}"
