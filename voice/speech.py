"""Which recogniser to use: offline pocketsphinx restricted to the command vocabulary (default), or
Google's online one when asked. The offline language model is made from the command vocabulary and the
mission's UAV ids."""
from __future__ import annotations

from collections.abc import Iterable

from voice import corpus
from voice.grammar import grammar_for

# Sentences sampled from the grammar for the language model: enough that every word order and number form is
# seen many times next to the corpus's ~4,000 (the model builds in about a second, then is cached).
GRAMMAR_SENTENCES = 20000


def make_recognizer(online: bool = False, uav_ids: Iterable[int] = (), cache_dir=None):
    """A recogniser with `transcribe(samples) -> Transcript`; the offline one's model is built from
    the vocabulary and the UAV ids once, then cached."""
    from voice import stt

    if online:
        return stt.OnlineRecognizer()
    from voice.speech_model import cached_speech_model

    return stt.OfflineRecognizer(cached_speech_model(language_model_sentences(uav_ids), cache_dir=cache_dir))


def language_model_sentences(uav_ids: Iterable[int] = ()) -> list[str]:
    """What the offline language model is trained on: the corpus of command templates (every vocabulary phrase)
    and a seeded sample of the command grammar (every word order it allows), for these UAV ids."""
    ids = tuple(sorted(set(uav_ids))) or corpus.DEFAULT_UAV_IDS
    return corpus.generate(ids) + grammar_for(ids).language_model_corpus(GRAMMAR_SENTENCES)
