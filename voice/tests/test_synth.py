"""espeak-ng synthesis: real speech audio for the recogniser tests, and spoken answers that never hang."""
import math
import subprocess
import sys

import numpy as np
import pytest

from voice import synth
from voice.audio import SAMPLE_RATE, VoiceActivityDetector, prepare_for_recognition, read_wav, split_utterances
from voice.synth import TEST_VOICES, SynthError, speak, synthesize, synthesize_to_file


def _rms(x):
    return float(np.sqrt(np.mean(x.astype(np.float64) ** 2)))


@pytest.mark.espeak
def test_synthesize_gives_16k_speech_that_the_vad_finds_once():
    x = synthesize("drone one land")
    assert x.dtype == np.int16 and x.ndim == 1
    assert 0.5 < x.size / SAMPLE_RATE < 3.0
    assert _rms(x) > 500 and np.abs(x).max() > 5000  # speech, not silence
    # espeak-ng speaks at 22050 Hz: after resampling, voice energy must stay below 8 kHz (no aliasing garbage)
    spectrum = np.abs(np.fft.rfft(x.astype(np.float64))) ** 2
    freqs = np.fft.rfftfreq(x.size, 1 / SAMPLE_RATE)
    assert spectrum[freqs < 4000].sum() > 0.9 * spectrum.sum()
    padded = np.concatenate([np.zeros(SAMPLE_RATE, np.int16), x, np.zeros(SAMPLE_RATE, np.int16)])
    detector = VoiceActivityDetector()
    utterances = detector.feed(prepare_for_recognition(padded)) + detector.flush()
    assert len(utterances) == 1
    start, end = detector.segments[0]
    assert 1.0 + 0.3 - 0.15 < start and end < 1.0 + 0.3 + x.size / SAMPLE_RATE + 0.15


@pytest.mark.espeak
def test_speed_voice_and_pitch_change_the_audio():
    slow, fast = synthesize("drone two take off", speed=120), synthesize("drone two take off", speed=220)
    assert slow.size > 1.4 * fast.size
    low, high = synthesize("hello", pitch=10), synthesize("hello", pitch=90)
    assert not np.array_equal(low, high)
    assert not np.array_equal(synthesize("hello", voice="en-us+f2"), synthesize("hello", voice="en-us+m3"))


@pytest.mark.espeak
def test_every_test_voice_works():
    for voice, speed in TEST_VOICES:
        x = synthesize("go up five meters", voice=voice, speed=speed)
        assert 0.6 < x.size / SAMPLE_RATE < 3.5, voice
        assert len(split_utterances(prepare_for_recognition(x))) == 1, voice
    assert len({v for v, _ in TEST_VOICES}) == len(TEST_VOICES) >= 4


@pytest.mark.espeak
def test_text_starting_with_a_dash_is_spoken_not_parsed_as_an_option():
    assert synthesize("-s 400 minus five").size / SAMPLE_RATE > 1.0  # at 400 wpm it would be far shorter


@pytest.mark.espeak
def test_bad_voice_and_empty_text_are_clear_errors():
    with pytest.raises(SynthError, match="xx-nonexistent.*voice does not exist"):
        synthesize("hello", voice="xx-nonexistent")
    with pytest.raises(ValueError, match="nothing to say"):
        synthesize("   ")


def test_missing_espeak_says_how_to_install(monkeypatch):
    monkeypatch.setattr(synth, "ESPEAK", "espeak-ng-not-installed-here")
    with pytest.raises(SynthError, match=r"install espeak-ng \(make setup\)"):
        synthesize("hello")
    assert speak("hello") is False  # and speak() does not raise


@pytest.mark.espeak
def test_synthesize_to_file_round_trips(tmp_path):
    path = synthesize_to_file("hover", tmp_path / "hover.wav", voice="en-us+m7", speed=165)
    np.testing.assert_array_equal(read_wav(path), synthesize("hover", voice="en-us+m7", speed=165))


@pytest.mark.espeak
def test_speak_without_a_loudspeaker_returns_false_without_waiting_for_espeak(monkeypatch, capsys):
    started = []
    run = subprocess.run
    monkeypatch.setattr(synth.subprocess, "run", lambda command, **kw: started.append(command) or run(command, **kw))
    played = speak("drone one is landing")
    if synth._no_output_device() is not None:  # this machine: no sound card at all
        assert played is False
        assert "no audio output device" in capsys.readouterr().err
        assert started == []  # nothing was started that could keep the assistant waiting
    elif not played:
        assert "cannot speak" in capsys.readouterr().err


@pytest.mark.espeak
def test_speak_through_espeak_audio_backend_detects_its_failure(monkeypatch, capsys):
    """Even when PortAudio does not know better, espeak-ng's own failure (exit 0, ALSA error) is detected."""
    monkeypatch.setattr(synth, "_no_output_device", lambda: None)
    played = speak("hello")
    direct = subprocess.run(["espeak-ng", "hello"], capture_output=True, timeout=15)
    can_play = direct.returncode == 0 and b"error" not in direct.stderr.lower()  # here: no card, ALSA errors
    assert played is can_play
    if not played:
        assert "cannot speak 'hello'" in capsys.readouterr().err


def test_speak_does_not_hang_on_a_blocked_sound_server(monkeypatch, capsys):
    """espeak-ng stuck on a sound server that never answers: speak() gives up at its limit and says why."""
    monkeypatch.setattr(synth, "_no_output_device", lambda: None)
    monkeypatch.setattr(synth, "_espeak", lambda: "espeak-ng")
    limits = []
    run = subprocess.run
    blocked = [sys.executable, "-c", "import time; time.sleep(600)"]

    def stuck_espeak(command, timeout=None, **kw):
        limits.append(timeout)
        return run(blocked, timeout=0.2, **kw)  # speak()'s own limit, shortened for the test

    monkeypatch.setattr(synth.subprocess, "run", stuck_espeak)
    assert speak("drone one is landing") is False
    assert len(limits) == 1 and limits[0] is not None and 0 < limits[0] < math.inf
    assert "did not finish playing (sound server blocked?)" in capsys.readouterr().err
