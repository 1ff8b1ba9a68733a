"""The restricted speech model: pronunciations (cmudict, spelled acronyms, espeak-ng for new words) and the
language model and dictionary files built from command sentences, cached by content."""
import re

import pytest

from voice import speech_model
from voice.speech_model import CMUDICT, Pronunciations, build_speech_model, cached_speech_model, espeak_to_cmu


def _cmudict_entries(word):
    """The pronunciations of `word` as written in the model's cmudict file, in file order."""
    out = []
    with open(CMUDICT, encoding="utf-8") as f:
        for line in f:
            head, _, pron = line.strip().partition(" ")
            if re.sub(r"\(\d+\)$", "", head) == word:
                out.append(pron.split("#")[0].strip())
    return out


def _model_phones():
    phones = set()
    with open(CMUDICT, encoding="utf-8") as f:
        for line in f:
            phones.update(line.split("#")[0].split()[1:])
    return phones


@pytest.fixture(scope="module")
def prons():
    return Pronunciations()


@pytest.mark.parametrize("word", ["drone", "read", "battery", "twenty", "meters"])
def test_words_in_cmudict_get_all_their_cmudict_pronunciations(prons, word):
    expected = _cmudict_entries(word)
    assert expected, f"{word} should be in cmudict"
    assert prons.lookup(word) == expected
    assert prons.lookup(word.upper()) == expected  # case does not matter


def test_listed_acronyms_and_words_without_vowels_are_spelled_out(prons):
    assert not prons.known("uav")
    assert prons.lookup("uav")[0] == "Y UW EY V IY"
    assert prons.lookup("uav")[1:] in ([], ["Y UW AE V"])  # also as espeak-ng reads it, if installed
    assert prons.lookup("uavs") == ["Y UW EY V IY Z"]
    assert prons.lookup("xkcd") == ["EH K S K EY S IY D IY"]


@pytest.mark.espeak
@pytest.mark.parametrize("word, start, end",
                         [("zorblat", "Z", "T"), ("skyrelix", "S", "S"), ("quadrocopterix", "K", "S")])
def test_a_made_up_word_gets_a_pronunciation_from_espeak_in_the_models_phones(prons, word, start, end):
    assert not prons.known(word)
    [pron] = prons.lookup(word)
    phones = pron.split()
    assert set(phones) <= _model_phones()
    assert phones[0] == start and phones[-1] == end
    assert len(phones) >= len(word) // 2


@pytest.mark.espeak
def test_a_call_sign_with_digits_joins_the_pronunciations_of_its_parts(prons):
    assert prons.lookup("zephyr9") == [f"{_cmudict_entries('zephyr')[0]} N AY N"]
    assert prons.lookup("uav3") == ["Y UW EY V IY TH R IY"]


def test_espeak_phonemes_map_to_cmu_phones():
    assert espeak_to_cmu("z_'E_f_3 n_'aI_n") == ["Z", "EH", "F", "ER", "N", "AY", "N"]
    assert espeak_to_cmu("T_'3:_t#_i") == ["TH", "ER", "T", "IY"]
    assert espeak_to_cmu("m_,A@_g_3_r_'i:_t") == ["M", "AA", "R", "G", "ER", "IY", "T"]  # one R after ER
    with pytest.raises(ValueError, match="no CMU phone"):
        espeak_to_cmu("b_'Q~_t", "blort")


@pytest.mark.parametrize("word", ["", "???", "héllo wörld", "#"])
def test_a_word_nobody_can_pronounce_is_a_value_error_naming_it(prons, word):
    with pytest.raises(ValueError, match="pronounce") as info:
        prons.lookup(word)
    assert repr(word.strip().lower()) in str(info.value) or not word.strip()


def test_a_missing_espeak_is_a_clear_error(tmp_path):
    prons = Pronunciations(espeak=str(tmp_path / "no-espeak-here"))
    assert prons.lookup("drone") == _cmudict_entries("drone")  # cmudict words need no espeak
    with pytest.raises(ValueError, match="'zorblat'.*espeak"):
        prons.lookup("zorblat")


SENTENCES = ["drone one take off", "drone two go up five meters", "all drones land",
             "what is the battery level of drone three", "uav two turn left ninety degrees"]


def _dict_words(path):
    return {re.sub(r"\(\d+\)$", "", line.split()[0]) for line in path.read_text().splitlines() if line.strip()}


@pytest.mark.espeak
def test_build_speech_model_writes_an_arpa_lm_and_a_dictionary_of_every_word(tmp_path):
    sentences = [*SENTENCES, "Drone Two, LAND!", "drone_one  tâke off"]
    model = build_speech_model(sentences, tmp_path / "m", extra_words=["magna", "zephyr9"])
    assert model.lm_path == tmp_path / "m" / "commands.arpa" and model.dict_path == tmp_path / "m" / "commands.dict"
    arpa = model.lm_path.read_text()
    assert "\\data\\" in arpa and "\\end\\" in arpa and "ngram 3=" in arpa
    unigrams = {line.split()[1] for line in arpa.split("\\1-grams:")[1].split("\\2-grams:")[0].splitlines() if line}
    corpus_words = {w for s in SENTENCES for w in s.split()}
    assert {"<s>", "</s>", "magna", "zephyr9"} | corpus_words == unigrams  # punctuation and case normalised
    assert _dict_words(model.dict_path) == corpus_words | {"magna", "zephyr9"} == set(model.words)
    dict_text = model.dict_path.read_text()
    assert "\nuav Y UW EY V IY\n" in dict_text and "\nread" not in dict_text
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == ["commands.arpa", "commands.dict"]  # no temp files


def test_build_speech_model_refuses_an_empty_corpus_or_an_unpronounceable_word(tmp_path):
    with pytest.raises(ValueError, match="at least one sentence"):
        build_speech_model(["", "  ", "?!"], tmp_path)
    with pytest.raises(ValueError, match="'无人机'"):
        build_speech_model(["drone one land", "无人机 take off"], tmp_path / "x")
    assert not (tmp_path / "x" / "commands.arpa").exists()  # nothing half-written


def test_the_cache_reuses_the_model_of_the_same_corpus_and_separates_other_corpora(tmp_path):
    first = cached_speech_model(SENTENCES, cache_dir=tmp_path)
    stamp = first.lm_path.stat().st_mtime_ns, first.dict_path.stat().st_mtime_ns
    again = cached_speech_model(list(reversed(SENTENCES)), cache_dir=tmp_path)  # same sentences, other order
    assert again == first
    assert (again.lm_path.stat().st_mtime_ns, again.dict_path.stat().st_mtime_ns) == stamp  # not rebuilt
    other = cached_speech_model([*SENTENCES, "drone four land"], cache_dir=tmp_path)
    assert other.lm_path.parent != first.lm_path.parent and "four" in other.words
    extra = cached_speech_model(SENTENCES, extra_words=["magna"], cache_dir=tmp_path)
    assert extra.lm_path.parent not in (first.lm_path.parent, other.lm_path.parent)
    assert first.lm_path.parent.parent == tmp_path


def test_the_default_cache_is_under_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert speech_model.default_cache_dir() == tmp_path / "xdg" / "magna" / "voice"
    model = cached_speech_model(["drone one land"])
    assert model.lm_path.parent.parent == tmp_path / "xdg" / "magna" / "voice"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert speech_model.default_cache_dir() == tmp_path / "home" / ".cache" / "magna" / "voice"
