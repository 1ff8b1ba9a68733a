"""The audio frontend: WAV reading/writing, dither, voice-activity detection, microphone, listen()."""
import os
import wave

import numpy as np
import pytest

from voice.audio import (
    SAMPLE_RATE,
    AudioError,
    NoAudioDevice,
    VoiceActivityDetector,
    list_input_devices,
    listen,
    microphone_chunks,
    prepare_for_recognition,
    read_wav,
    split_utterances,
    write_wav,
)

SR = SAMPLE_RATE


def _write_raw(path, data: np.ndarray, rate: int, width: int):
    """A WAV written by the standard library, independent of write_wav."""
    with wave.open(str(path), "wb") as w:
        w.setnchannels(1 if data.ndim == 1 else data.shape[1])
        w.setsampwidth(width)
        w.setframerate(rate)
        w.writeframes(data.tobytes())


def _tone(seconds, rate, freq=440.0, amplitude=10000.0):
    t = np.arange(int(seconds * rate)) / rate
    return amplitude * np.sin(2 * np.pi * freq * t)


def _noise(rng, seconds, std):
    return rng.normal(0.0, std, int(round(seconds * SR)))


def _bursts(rng):
    """[silence 1.0, burst 0.8, silence 1.2, burst 0.6, silence 1.0] with a low noise floor; burst times in s."""
    parts, times, t = [], [], 0.0
    for kind, seconds in (("sil", 1.0), ("burst", 0.8), ("sil", 1.2), ("burst", 0.6), ("sil", 1.0)):
        x = _noise(rng, seconds, 20.0)
        if kind == "burst":  # a noise burst with a speech-like level, 440 Hz tone on top
            x += _noise(rng, seconds, 2000.0) + _tone(seconds, SR, amplitude=3000.0)
            times.append((t, t + seconds))
        parts.append(x)
        t += seconds
    return np.clip(np.concatenate(parts), -32768, 32767).astype(np.int16), times


def _feed_randomly(detector, samples, rng):
    out, i = [], 0
    while i < samples.size:
        n = int(rng.integers(1, 4000))
        out += detector.feed(samples[i:i + n])
        i += n
    return out + detector.flush()


# --------------------------------------------------------------------------------------------------------- files


def test_stereo_22050_reads_back_as_16k_mono_of_the_right_duration(tmp_path):
    left = _tone(1.5, 22050, 440.0, 8000.0)
    right = _tone(1.5, 22050, 440.0, 4000.0)
    path = tmp_path / "stereo.wav"
    _write_raw(path, np.stack([left, right], axis=1).astype("<i2"), 22050, 2)
    x = read_wav(path)
    assert x.dtype == np.int16 and x.ndim == 1
    assert x.size == pytest.approx(1.5 * SR, abs=2)
    # mixed to mono: the mean of the channels, amplitude 6000 (RMS 6000/sqrt 2), still a 440 Hz tone
    rms = np.sqrt(np.mean(x[1000:-1000].astype(float) ** 2))
    assert rms == pytest.approx(6000 / np.sqrt(2), rel=0.02)
    spectrum = np.abs(np.fft.rfft(x))
    assert np.argmax(spectrum) * SR / x.size == pytest.approx(440, abs=2)


@pytest.mark.parametrize("width,rate", [(1, 8000), (2, 16000), (4, 44100)])
def test_8_16_32_bit_pcm_scale_to_int16(tmp_path, width, rate):
    tone = _tone(0.5, rate, amplitude=0.5)  # half of full scale in every format
    full = {1: 127, 2: 32767, 4: 2**31 - 1}[width]
    data = (tone * full + (128 if width == 1 else 0)).astype({1: "u1", 2: "<i2", 4: "<i4"}[width])
    path = tmp_path / f"w{width}.wav"
    _write_raw(path, data, rate, width)
    x = read_wav(path)
    assert x.size == pytest.approx(0.5 * SR, abs=2)
    assert np.abs(x[200:-200]).max() == pytest.approx(16384, rel=0.03)


def test_write_then_read_is_lossless(tmp_path):
    samples = np.random.default_rng(0).integers(-20000, 20000, SR, dtype=np.int16)
    path = write_wav(tmp_path / "x.wav", samples)
    np.testing.assert_array_equal(read_wav(path), samples)
    with wave.open(str(path)) as w:
        assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (1, 2, SR)


def test_write_wav_is_atomic_and_leaves_no_temporary_on_failure(tmp_path, monkeypatch):
    path = tmp_path / "x.wav"
    write_wav(path, np.zeros(100, dtype=np.int16))
    before = path.read_bytes()
    real = wave.Wave_write.writeframesraw

    def disk_full(self, data):  # half the samples reach the disk, then the write fails
        real(self, data[: len(data) // 2])
        raise OSError("No space left on device")

    monkeypatch.setattr(wave.Wave_write, "writeframesraw", disk_full)
    with pytest.raises(OSError, match="No space"):
        write_wav(path, np.ones(SR, dtype=np.int16))
    assert path.read_bytes() == before  # the old file is intact
    assert os.listdir(tmp_path) == ["x.wav"]  # and no temporary is left behind


@pytest.mark.parametrize("content,problem", [
    (b"", "empty file"),
    (b"hello, I am text", "not a WAV file (RIFF header missing)"),
    (b"ID3\x03\x00\x00\x00\x00\x00\x00", "MP3"),
    (b"RIFF\x10\x00\x00\x00AVI LIST", "not WAVE"),
    (b"RIFF\x24\x00\x00\x00WAVEfmt ", "truncated"),
])
def test_bad_files_raise_audio_error_naming_the_file_and_the_fix(tmp_path, content, problem):
    path = tmp_path / "bad.wav"
    path.write_bytes(content)
    with pytest.raises(AudioError) as error:
        read_wav(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and problem in message
    assert isinstance(error.value, ValueError)


def test_float_wav_and_missing_file_are_explained(tmp_path):
    path = tmp_path / "float.wav"
    data = _tone(0.1, SR, amplitude=0.5).astype("<f4").tobytes()
    fmt = (3).to_bytes(2, "little") + (1).to_bytes(2, "little") + SR.to_bytes(4, "little") + \
        (4 * SR).to_bytes(4, "little") + (4).to_bytes(2, "little") + (32).to_bytes(2, "little")
    body = b"WAVE" + b"fmt " + len(fmt).to_bytes(4, "little") + fmt + b"data" + len(data).to_bytes(4, "little") + data
    path.write_bytes(b"RIFF" + len(body).to_bytes(4, "little") + body)
    with pytest.raises(AudioError, match=r"float\.wav: not integer PCM \(IEEE float\).*sox"):
        read_wav(path)
    with pytest.raises(AudioError, match="missing.wav: no such file"):
        read_wav(tmp_path / "missing.wav")


def test_prepare_for_recognition_pads_and_dithers_deterministically():
    x = np.zeros(SR, dtype=np.int16)
    a, b = prepare_for_recognition(x, seed=3), prepare_for_recognition(x, seed=3)
    np.testing.assert_array_equal(a, b)
    assert a.size == SR + 2 * int(0.3 * SR)
    assert np.count_nonzero(a == 0) < 0.02 * a.size  # no runs of digital zeros left
    assert 20 < a.astype(float).std() < 40
    assert not np.array_equal(a, prepare_for_recognition(x, seed=4))


# ----------------------------------------------------------------------------------------------------------- VAD


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vad_finds_two_bursts_with_right_times_in_random_chunks(seed):
    rng = np.random.default_rng(seed)
    samples, times = _bursts(rng)
    detector = VoiceActivityDetector()
    utterances = _feed_randomly(detector, samples, rng)
    assert len(utterances) == 2
    for (start, end), (true_start, true_end), utterance in zip(detector.segments, times, utterances, strict=True):
        assert start == pytest.approx(true_start, abs=0.15)
        assert end == pytest.approx(true_end, abs=0.15)
        # the returned audio: 0.3 s pre-roll + the burst + 0.2 s post-roll
        assert utterance.size / SR == pytest.approx(0.3 + (true_end - true_start) + 0.2, abs=0.15)
    # the first utterance is the audio of the stream, not a copy of something else
    first = int(round((detector.segments[0][0] - 0.3) * SR))
    np.testing.assert_array_equal(utterances[0], samples[first:first + utterances[0].size])


def test_vad_chunking_does_not_change_the_result():
    rng = np.random.default_rng(5)
    samples, _ = _bursts(rng)
    whole = split_utterances(samples)
    chunked = _feed_randomly(VoiceActivityDetector(), samples, np.random.default_rng(9))
    assert len(whole) == len(chunked) == 2
    for a, b in zip(whole, chunked, strict=True):
        np.testing.assert_array_equal(a, b)


def test_short_click_is_dropped_and_quiet_noise_is_not_speech():
    rng = np.random.default_rng(0)
    click = np.concatenate([_noise(rng, 1.0, 20), _noise(rng, 0.15, 5000), _noise(rng, 1.5, 20)])
    assert split_utterances(click.astype(np.int16)) == []
    assert split_utterances(_noise(rng, 3.0, 40).astype(np.int16)) == []
    # the same burst at 0.5 s is long enough
    longer = np.concatenate([_noise(rng, 1.0, 20), _noise(rng, 0.5, 5000), _noise(rng, 1.5, 20)])
    assert len(split_utterances(longer.astype(np.int16))) == 1


def test_vad_pause_shorter_than_silence_seconds_keeps_one_utterance():
    rng = np.random.default_rng(1)
    parts = [_noise(rng, 0.5, 20), _noise(rng, 0.5, 3000), _noise(rng, 0.5, 20), _noise(rng, 0.5, 3000),
             _noise(rng, 1.0, 20)]
    x = np.concatenate(parts).astype(np.int16)
    assert len(split_utterances(x, silence_seconds=0.8)) == 1
    assert len(split_utterances(x, silence_seconds=0.3)) == 2


def test_vad_cuts_long_utterances_and_adapts_to_a_steady_noise():
    rng = np.random.default_rng(2)
    # a fan starts after 1 s and runs 9 s: heard as sound at first, then absorbed into the noise floor
    x = np.concatenate([_noise(rng, 1.0, 20), _noise(rng, 9.0, 1000)]).astype(np.int16)
    detector = VoiceActivityDetector(max_seconds=15.0)
    utterances = detector.feed(x) + detector.flush()
    assert len(utterances) == 1 and utterances[0].size < 7 * SR
    # continuous loud sound with max_seconds=2: cut into pieces of at most 2 s
    loud = np.concatenate([_noise(rng, 0.5, 20), _noise(rng, 4.0, 3000)]).astype(np.int16)
    pieces = split_utterances(loud, max_seconds=2.0)
    assert len(pieces) >= 2 and all(p.size <= 2.0 * SR + 480 for p in pieces)


def test_vad_flush_closes_an_utterance_in_progress():
    rng = np.random.default_rng(3)
    x = np.concatenate([_noise(rng, 0.5, 20), _noise(rng, 0.7, 3000)]).astype(np.int16)
    detector = VoiceActivityDetector()
    assert detector.feed(x) == [] and detector.in_speech
    assert len(detector.flush()) == 1 and not detector.in_speech


# ------------------------------------------------------------------------------------------- microphone, listen


def test_microphone_without_input_device_raises_no_audio_device(monkeypatch):
    # PortAudio is made to see a loudspeaker and no microphone, whatever this machine has
    import sounddevice

    speaker = {"name": "speaker", "max_input_channels": 0, "max_output_channels": 2, "default_samplerate": 48000.0}
    monkeypatch.setattr(sounddevice, "query_devices", lambda *args, **kwargs: [speaker])
    assert list_input_devices() == []
    with pytest.raises(NoAudioDevice, match="microphone|input device|libportaudio2"):
        microphone_chunks()


def test_missing_portaudio_or_sounddevice_is_explained(monkeypatch):
    """What a machine without libportaudio2 (OSError at import) or without the package (ImportError) sees."""
    import builtins

    real_import = builtins.__import__
    for error, hint in ((OSError("PortAudio library not found"), "install libportaudio2"),
                        (ImportError("No module named 'sounddevice'"), "run `make setup`")):
        def fake_import(name, *args, _error=error, **kwargs):
            if name == "sounddevice":
                raise _error
            return real_import(name, *args, **kwargs)

        monkeypatch.setattr(builtins, "__import__", fake_import)
        with pytest.raises(NoAudioDevice, match=hint):
            microphone_chunks()
        assert list_input_devices() == []
        monkeypatch.setattr(builtins, "__import__", real_import)


def test_listen_writes_each_utterance_without_overwriting(tmp_path):
    rng = np.random.default_rng(4)
    samples, _ = _bursts(rng)
    (tmp_path / "utterance_0001.wav").write_bytes(b"keep me")
    (tmp_path / "utterance_7.wav").write_bytes(b"keep me too")
    chunks = (samples[i:i + 1600] for i in range(0, samples.size, 1600))  # 0.1 s, like the microphone
    starts = []
    heard = list(listen(chunks, VoiceActivityDetector(), tmp_path, on_start=lambda: starts.append(1)))
    assert [p.name for p, _ in heard] == ["utterance_0008.wav", "utterance_0009.wav"]
    assert len(starts) == 2
    for path, utterance in heard:
        np.testing.assert_array_equal(read_wav(path), utterance)
    assert (tmp_path / "utterance_0001.wav").read_bytes() == b"keep me"
    assert (tmp_path / "utterance_7.wav").read_bytes() == b"keep me too"
    # a second session continues the numbering
    again = list(listen(iter([samples]), VoiceActivityDetector(), tmp_path))
    assert [p.name for p, _ in again] == ["utterance_0010.wav", "utterance_0011.wav"]


def test_listen_flushes_at_the_end_and_creates_the_directory(tmp_path):
    rng = np.random.default_rng(6)
    x = np.concatenate([_noise(rng, 0.5, 20), _noise(rng, 0.7, 3000)]).astype(np.int16)  # no silence at the end
    out = tmp_path / "new" / "dir"
    heard = list(listen(iter([x]), VoiceActivityDetector(), out))
    assert len(heard) == 1 and heard[0][0].parent == out and heard[0][0].exists()


def _tone_bursts(seconds=2.0):
    """A stand-in for speech: 440 Hz bursts of 0.3 s every 0.5 s at a speech-like level."""
    t = np.arange(int(seconds * SAMPLE_RATE)) / SAMPLE_RATE
    return (8000 * np.sin(2 * np.pi * 440 * t) * ((t % 0.5) < 0.3)).astype(np.int16)


def test_added_noise_has_the_asked_snr_and_fills_the_padding():
    from voice.audio import add_noise

    speech = _tone_bursts()
    noisy = add_noise(speech, 10.0, seed=1, pad_seconds=0.3).astype(np.float64)
    pad = int(0.3 * SAMPLE_RATE)
    assert noisy.size == speech.size + 2 * pad
    noise_power = np.mean(noisy[:pad] ** 2)
    bursts = speech.astype(np.float64)[(np.arange(speech.size) / SAMPLE_RATE % 0.5) < 0.3]
    assert 10 * np.log10(np.mean(bursts**2) / noise_power) == pytest.approx(10.0, abs=0.3)
    assert np.array_equal(add_noise(speech, 10.0, seed=1), add_noise(speech, 10.0, seed=1))  # seeded


def test_noise_suppression_turns_the_background_down_and_keeps_the_speech():
    from voice.audio import add_noise, estimated_snr_db, suppress_noise

    speech = _tone_bursts()
    noisy = add_noise(speech, 10.0, seed=2)
    cleaned = suppress_noise(noisy)
    assert cleaned.size == noisy.size and cleaned.dtype == np.int16
    pad = int(0.3 * SAMPLE_RATE)
    assert np.std(cleaned[:pad].astype(float)) < 0.6 * np.std(noisy[:pad].astype(float))  # the quiet part
    loud = slice(pad + 800, pad + 4000)  # inside the first burst
    assert np.std(cleaned[loud].astype(float)) > 0.8 * np.std(noisy[loud].astype(float))
    assert estimated_snr_db(cleaned) > estimated_snr_db(noisy) + 3


def test_clean_speech_is_not_suppressed():
    from voice import stt
    from voice.audio import add_noise, estimated_snr_db, prepare_for_recognition

    speech = _tone_bursts()
    assert estimated_snr_db(speech) == float("inf") > stt.SUPPRESS_NOISE_BELOW_DB
    untouched = prepare_for_recognition(speech, pad_seconds=stt.PAD_SECONDS, dither=stt.dither_level(speech))
    assert np.array_equal(stt.prepare(speech), untouched)
    noisy = add_noise(speech, 10.0, seed=3)
    assert not np.array_equal(stt.prepare(noisy), prepare_for_recognition(
        noisy, pad_seconds=stt.PAD_SECONDS, dither=stt.dither_level(noisy)))
