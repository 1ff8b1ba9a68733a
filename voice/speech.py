"""Which recogniser to use: offline pocketsphinx restricted to the command vocabulary (default), or
Google's online one when asked."""
from __future__ import annotations

from collections.abc import Iterable

from voice import corpus


def make_recognizer(online: bool = False, uav_ids: Iterable[int] = (), cache_dir=None):
    """A recogniser with `transcribe(samples) -> Transcript`; the offline one's model is built from
    the vocabulary and the UAV ids once, then cached."""
    from voice import stt

    if online:
        return stt.OnlineRecognizer()
    from voice.speech_model import cached_speech_model

    sentences = corpus.generate(uav_ids or corpus.DEFAULT_UAV_IDS)
    return stt.OfflineRecognizer(cached_speech_model(sentences, cache_dir=cache_dir))
