"""Speech to text: the offline recogniser (PocketSphinx with the command speech model) and Google's online one.

Both take 16 kHz mono int16 samples and return a Transcript: the best text, the n-best alternatives and
the time the decoding took. The offline recogniser only knows the words of its speech model
(voice.speech_model), which is what makes it accurate on commands.
"""
from __future__ import annotations

import itertools
import math
import threading
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from voice.audio import SAMPLE_RATE, estimated_snr_db, frame_rms, prepare_for_recognition, suppress_noise
from voice.speech_model import ACOUSTIC_MODEL, SpeechModel

MAX_ALTERNATIVES = 10  # what the online recogniser returns at most
# The offline n-best is rescored by the parser (voice.rescoring): the right command is often a few dozen
# hypotheses down, behind variants of the best one that differ in a filler or a plural.
OFFLINE_ALTERNATIVES = 60
PAD_SECONDS = 0.3
DITHER_LSB = 30.0
# Noise floor the recogniser wants, relative to the speech level (the 90th percentile of 30 ms frame RMS).
# Synthetic speech is too clean for the acoustic model, trained on real recordings: raising its noise floor
# to ~23 dB below the speech took exact sentences on espeak-ng speech (4 voices, speeds 140-175, 40 command
# sentences each, the 979-sentence test corpus) from 119/160 (dither of 30 LSB only) to 150/160; on the full
# voice.corpus model from 83/160 to 99/160. Ratios 0.03 / 0.05 / 0.1 / 0.2 / 0.3 gave 144 / 150 / 149 / 141 / 85
# of 160. Recordings whose own noise floor is already that high get only the 30 LSB dither.
NOISE_FLOOR_RATIO = 0.05
SUPPRESS_NOISE_BELOW_DB = 30.0  # estimated SNR under which the background is suppressed; clean speech is left alone

# Decoder settings, measured on espeak-ng speech of 40 sentences x 4 voices (en-us, +m3, +f2, +m7) at 140-175
# wpm, exact sentences of 160, decode time per utterance on 2 cores, with the voice.corpus model (4061 sentences):
#   defaults (topn 4)       114 / 119 / 124 (three samples)   ~240 ms
#   topn 8                  114 / 119 /  -                    ~280 ms
#   topn 12                 121 / 123 / 130                   ~335 ms  <- chosen
#   topn 16                 122 /  -  /  -                    ~400 ms
#   lw 4 / 9 / 12 (6.5)     107 / 111 / 112 of the first 114; wip 0.1 / 2.0 (0.65): 111 / 111; pip 0.5: 110;
#   bestpath off: 108; fwdflat off: 106 (faster); wider beams (1e-60): 115, slower.
# On the small test corpus (979 sentences, 45 words) topn made no difference (149-150 of 160).
DECODER_OPTIONS: dict[str, object] = {"topn": 12}


class RecognitionError(RuntimeError):
    """The recogniser cannot work at all (as opposed to hearing nothing)."""


@dataclass
class Transcript:
    """What a recogniser heard: text (lower case for the offline one; "" if nothing), n-best alternatives
    (best first, so alternatives[0] == text when text is not empty; deduplicated; at most MAX_ALTERNATIVES),
    seconds the recognition took, and each alternative's log score where the recogniser gives one."""

    text: str
    alternatives: list[str] = field(default_factory=list)
    seconds: float = 0.0
    scores: list[float] | None = None  # the recogniser's log score of each alternative (None: not known)


def as_int16(samples: np.ndarray) -> np.ndarray:
    """Mono int16 samples: float audio (in [-1, 1]) is scaled, stereo is averaged."""
    samples = np.asarray(samples)
    scale = 32767.0 if samples.dtype.kind == "f" else 1.0
    if samples.ndim == 2:
        samples = samples.mean(axis=1)
    if samples.ndim != 1:
        raise ValueError(f"expected mono audio samples, got an array of shape {samples.shape}")
    if samples.dtype == np.int16:
        return samples
    if scale != 1.0:
        samples = np.clip(samples, -1.0, 1.0) * scale
    return np.clip(np.round(samples), -32768, 32767).astype(np.int16)


def dither_level(samples: np.ndarray) -> float:
    """Standard deviation (LSB) of the noise to add so the noise floor is NOISE_FLOOR_RATIO of the speech level."""
    rms = frame_rms(as_int16(samples))
    if rms.size == 0:
        return DITHER_LSB
    target, floor = NOISE_FLOOR_RATIO * np.percentile(rms, 90), np.percentile(rms, 10)
    return float(max(DITHER_LSB, np.sqrt(max(0.0, target**2 - floor**2))))


def prepare(samples: np.ndarray) -> np.ndarray:
    """Samples as the offline recogniser wants them: 0.3 s of padding both ends and noise (see dither_level).

    PocketSphinx's feature extraction breaks on exact digital zeros (synthetic speech and digital
    silence): without dither, 3 of 16 espeak sentences came back right, with 30 LSB of it 12 of 16.
    Noisy audio (under SUPPRESS_NOISE_BELOW_DB) has its background turned down first (voice.audio.suppress_noise).
    """
    samples = as_int16(samples)
    if estimated_snr_db(samples) < SUPPRESS_NOISE_BELOW_DB:
        samples = suppress_noise(samples)
    return as_int16(prepare_for_recognition(samples, pad_seconds=PAD_SECONDS, dither=dither_level(samples)))


def _unique(texts, limit: int = MAX_ALTERNATIVES) -> list[str]:
    out: list[str] = []
    for text in texts:
        text = " ".join(text.split())
        if text and text not in out:
            out.append(text)
            if len(out) == limit:
                break
    return out


def _best_scores(scored: list[tuple[str, float]]) -> tuple[list[str], list[float]]:
    """Unique texts, best first, each with the log of its best score (pocketsphinx gives exp-scaled scores)."""
    best: dict[str, float] = {}
    for text, score in scored:
        text = " ".join(text.split())
        if text:
            log_score = math.log(score) if score > 0 else -math.inf
            best[text] = max(best.get(text, -math.inf), log_score)
    return list(best), list(best.values())


class OfflineRecognizer:
    """PocketSphinx with the speech model's language model and dictionary; one decoder, reused."""

    def __init__(self, speech_model: SpeechModel, **decoder_options):
        from pocketsphinx import Decoder

        self.speech_model = speech_model
        options = {**DECODER_OPTIONS, **decoder_options}
        try:
            self._decoder = Decoder(hmm=str(ACOUSTIC_MODEL), lm=str(speech_model.lm_path),
                                    dict=str(speech_model.dict_path), logfn="/dev/null", **options)
        except (RuntimeError, ValueError, OSError) as e:
            raise RecognitionError(f"cannot load the offline speech model {speech_model.lm_path}: {e}") from e
        self._lock = threading.Lock()

    def transcribe(self, samples: np.ndarray) -> Transcript:
        """Text of 16 kHz mono int16 speech (one utterance)."""
        start = time.perf_counter()
        samples = as_int16(samples)
        if samples.size == 0:
            return Transcript("", [], 0.0)
        audio = prepare(samples).tobytes()
        with self._lock:
            d = self._decoder
            d.start_utt()
            d.process_raw(audio, full_utt=True)
            d.end_utt()
            hyp = d.hyp()
            text = " ".join(hyp.hypstr.split()) if hyp is not None else ""
            nbest = [(h.hypstr, h.score) for h in itertools.islice(d.nbest(), OFFLINE_ALTERNATIVES)] if text else []
        alternatives, scores = _best_scores([(text, hyp.score if text else 0.0), *nbest])
        return Transcript(text, alternatives, time.perf_counter() - start, scores)


class OnlineRecognizer:
    """Google's Web Speech API (through SpeechRecognition): needs the internet; opt-in."""

    def __init__(self, language: str = "en-US", timeout: float = 8.0, endpoint: str | None = None):
        with warnings.catch_warnings():  # it imports aifc and audioop, deprecated since Python 3.11
            warnings.simplefilter("ignore", DeprecationWarning)
            import speech_recognition as sr

        self._sr = sr
        self.language = language
        self._options = {"endpoint": endpoint} if endpoint else {}
        self._recognizer = sr.Recognizer()
        self._recognizer.operation_timeout = timeout

    def transcribe(self, samples: np.ndarray) -> Transcript:
        """Text of 16 kHz mono int16 speech; RecognitionError if Google cannot be reached."""
        sr = self._sr
        start = time.perf_counter()
        samples = as_int16(samples)
        if samples.size == 0:
            return Transcript("", [], 0.0)
        audio = sr.AudioData(samples.tobytes(), SAMPLE_RATE, 2)
        try:
            result = self._recognizer.recognize_google(audio, language=self.language, show_all=True, **self._options)
        except sr.UnknownValueError:
            result = None
        except (sr.RequestError, OSError, TimeoutError) as e:
            raise RecognitionError(f"Google's online recogniser is unreachable ({e}): "
                                   "drop --online to use the offline recogniser") from e
        alternatives = result.get("alternative", []) if isinstance(result, dict) else []
        texts = _unique(a.get("transcript", "").lower() for a in alternatives)
        return Transcript(texts[0] if texts else "", texts, time.perf_counter() - start)
