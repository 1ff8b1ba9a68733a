"""The recognisers: the offline one, restricted to a corpus of commands, transcribes synthetic speech of them;
the online one fails with a clear message when Google cannot be reached."""
import time

import numpy as np
import pytest

from voice.speech_model import cached_speech_model
from voice.stt import (
    OFFLINE_ALTERNATIVES,
    OfflineRecognizer,
    OnlineRecognizer,
    RecognitionError,
    Transcript,
    as_int16,
    dither_level,
    prepare,
)

NUMBERS = ("one two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen "
           "seventeen eighteen nineteen twenty").split()


def command_corpus():
    """~1000 command sentences: UAV x movement x distance, take-offs, landings, turns, battery questions."""
    who = ["drone one", "drone two", "drone three", "all drones"]
    out = []
    for w in who:
        for verb in ("go", "move"):
            for direction in ("up", "down", "left", "right", "forward", "backward"):
                out += [f"{w} {verb} {direction} {n} {'meter' if n == 'one' else 'meters'}" for n in NUMBERS]
        out += [f"{w} take off", f"{w} land", f"{w} turn left ninety degrees", f"{w} turn right ninety degrees"]
    out += [f"what is the battery level of drone {n}" for n in ("one", "two", "three")]
    return out


SPOKEN = ["drone one take off", "drone two go up five meters", "all drones land",
          "drone three turn left ninety degrees", "what is the battery level of drone two",
          "drone one move forward twelve meters", "all drones go down three meters",
          "drone two turn right ninety degrees", "drone three move backward seven meters",
          "drone one go left one meter"]


def speak(text, voice="en-us", speed=150):
    from voice.synth import synthesize

    return synthesize(text, voice=voice, speed=speed)


@pytest.fixture(scope="module")
def recognizer(tmp_path_factory):
    corpus = command_corpus()
    assert 200 <= len(corpus) <= 1000 and set(SPOKEN) <= set(corpus)
    return OfflineRecognizer(cached_speech_model(corpus, cache_dir=tmp_path_factory.mktemp("voice-cache")))


@pytest.mark.espeak
def test_the_offline_recogniser_transcribes_synthetic_commands(recognizer):
    transcripts, took = [], []
    for sentence in SPOKEN:
        audio = speak(sentence)
        started = time.monotonic()
        transcripts.append(recognizer.transcribe(audio))
        took.append(time.monotonic() - started)
    right = [s for s, t in zip(SPOKEN, transcripts, strict=True) if t.text == s]
    assert len(right) >= 8, [(s, t.text) for s, t in zip(SPOKEN, transcripts, strict=True) if t.text != s]
    for t, seconds in zip(transcripts, took, strict=True):
        # the time it reports is the call's own (how long that is: bench/voice_accuracy.py, "decode")
        assert isinstance(t, Transcript) and 0 < t.seconds <= seconds
        assert t.alternatives[0] == t.text and len(set(t.alternatives)) == len(t.alternatives) <= OFFLINE_ALTERNATIVES
        # one log score per alternative, the best hypothesis's the highest
        assert t.scores is not None and len(t.scores) == len(t.alternatives) and max(t.scores) == t.scores[0] <= 0
        assert all(a == " ".join(a.split()) and set(a.split()) <= set(recognizer.speech_model.words)
                   for a in t.alternatives)


@pytest.mark.espeak
def test_the_offline_recogniser_is_deterministic_and_takes_float_audio(recognizer):
    samples = speak("drone two go up five meters")
    first = recognizer.transcribe(samples)
    assert recognizer.transcribe(samples).text == first.text == "drone two go up five meters"
    assert recognizer.transcribe(samples.astype(np.float32) / 32768).text == first.text


@pytest.mark.espeak
def test_a_new_call_sign_is_recognised_with_its_derived_pronunciation(tmp_path):
    corpus = [*command_corpus()[:300], "zorblat take off", "zorblat land", "zorblat go up five meters"]
    recognizer = OfflineRecognizer(cached_speech_model(corpus, cache_dir=tmp_path))
    assert recognizer.transcribe(speak("zorblat take off")).text == "zorblat take off"


def test_nothing_to_hear_gives_an_empty_transcript(recognizer):
    assert recognizer.transcribe(np.zeros(0, dtype=np.int16)) == Transcript("", [], 0.0)
    silence = recognizer.transcribe(np.zeros(16000, dtype=np.int16))
    assert silence.alternatives == ([silence.text] if silence.text else [])


@pytest.mark.espeak
def test_audio_is_padded_and_dithered_to_a_noise_floor_below_the_speech():
    speech = speak("drone one land")
    ready = prepare(speech)
    assert ready.dtype == np.int16 and ready.size == speech.size + 2 * int(0.3 * 16000)
    assert np.count_nonzero(ready[:4800] == 0) < 200  # no digital silence left
    assert 30 <= np.std(ready[:4800]) < 0.1 * np.abs(speech).max()
    assert np.array_equal(prepare(speech), ready)  # seeded
    noisy = speech + np.random.default_rng(1).normal(0, 2000, speech.size)
    assert dither_level(as_int16(noisy)) == 30.0  # a recording noisy enough gets only the dither


def test_as_int16_takes_float_and_stereo_audio():
    assert as_int16(np.array([0.5, -1.0, 2.0])).tolist() == [16384, -32767, 32767]
    assert as_int16(np.array([[100, 300], [-2, -4]], dtype=np.int16)).tolist() == [200, -3]
    with pytest.raises(ValueError, match="mono"):
        as_int16(np.zeros((2, 2, 2)))


@pytest.mark.espeak
def test_the_online_recogniser_says_clearly_when_google_is_unreachable():
    recognizer = OnlineRecognizer(endpoint="http://127.0.0.1:9/speech-api/v2/recognize", timeout=5)
    with pytest.raises(RecognitionError, match=r"^Google's online recogniser is unreachable \(.+\): "
                                               r"drop --online to use the offline recogniser$"):
        recognizer.transcribe(speak("drone one land"))


def test_a_missing_speech_model_is_a_recognition_error(tmp_path):
    from voice.speech_model import SpeechModel

    with pytest.raises(RecognitionError, match="cannot load the offline speech model .*nothing.arpa"):
        OfflineRecognizer(SpeechModel(tmp_path / "nothing.arpa", tmp_path / "nothing.dict", ()))
