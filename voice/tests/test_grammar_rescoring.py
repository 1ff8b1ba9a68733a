"""The command grammar (generated from the vocabulary and the mission's UAV ids) and the n-best rescoring: only
hypotheses that make a command compete, grammatical ones first, and each has a confidence."""
import pytest

from voice import grammar
from voice.interpret import Command, Question, parse
from voice.rescoring import UNGRAMMATICAL_SHARE, rescore
from voice.speech import language_model_sentences
from voice.speech_model import ACOUSTIC_MODEL, cached_speech_model

IDS = (1, 2)


def test_the_grammar_says_the_commands_and_only_the_missions_uavs():
    g = grammar.grammar_for(IDS)
    for sentence in ("drone two go up five meters", "all drones land", "what is the battery level of drone one",
                     "drone one take off to three meters", "five meters up drone two", "please uav one land now",
                     "drone two follow drone one at three meters", "yes", "no"):
        assert g.accepts(sentence), sentence
    for sentence in ("drone three land", "drone two go on five meters", "go up five meters drone two drone one land",
                     "land drone two land"):
        assert not g.accepts(sentence), sentence


def test_sampled_grammar_sentences_are_understood():
    """Whatever the grammar says (and so the language model learns) the parser reads: a command, a question or an
    answer; never a crash, and most samples of the command rule make a whole command."""
    g = grammar.grammar_for(IDS)
    commands = g.sample(300, seed=3, rule="command")
    results = [parse(s, IDS)[1] for s in commands]
    assert all(isinstance(r, (Command, Question)) for r in results)
    assert sum(isinstance(r, Command) for r in results) >= 0.6 * len(results)
    assert all(g.accepts(s) for s in commands)


def test_the_grammar_is_valid_jsgf_for_pocketsphinx(tmp_path):
    from pocketsphinx import Decoder

    text = grammar.jsgf(IDS)
    model = cached_speech_model(language_model_sentences(IDS), cache_dir=tmp_path)
    assert set(grammar.words(text)) <= set(model.words)  # every word of the grammar can be heard
    decoder = Decoder(hmm=str(ACOUSTIC_MODEL), lm=str(model.lm_path), dict=str(model.dict_path), logfn="/dev/null")
    decoder.add_jsgf_string("commands", text)  # raises on a syntax error or a word missing from the dictionary


def test_only_commands_compete_and_a_grammatical_one_wins():
    hearing = rescore(["drone two go on up five meters", "drone two go up five meters"], [-0.1, -0.2], IDS)
    assert hearing.text == "drone two go up five meters" and hearing.chosen.grammatical
    assert rescore(["drone two uh", "drone two land"], None, IDS).text == "drone two land"
    nothing = rescore(["uh"], [-0.1], IDS)
    assert isinstance(nothing.chosen.result, Question) and nothing.confidence == 0.0


def test_the_confidence_is_the_share_of_the_n_best_meaning_the_same_command():
    same = rescore(["drone two go up five meters", "drone two go up five metres"], [-0.5, -0.5], IDS)
    assert same.confidence == pytest.approx(1.0)
    split = rescore(["drone two go up five meters", "drone two go down five meters"], [-0.5, -0.5], IDS)
    assert split.confidence == pytest.approx(0.5)
    # a far worse rival barely counts
    far = rescore(["drone two go up five meters", "drone two go down five meters"], [-0.5, -1.5], IDS)
    assert far.confidence > 0.99
    # the parser reads "drone two up five meters please then" but the grammar cannot say it
    odd = rescore(["then drone two up five meters please then"], [-0.5], IDS)
    assert not odd.chosen.grammatical and odd.confidence == pytest.approx(UNGRAMMATICAL_SHARE)
