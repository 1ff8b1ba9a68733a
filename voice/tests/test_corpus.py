"""The speech model's corpus comes from the vocabulary and the UAV ids: every phrase is in it, every
generated command means what its template says, and new UAV ids need nothing written by hand."""
from voice import corpus
from voice import vocabulary as vocab
from voice.interpret import Command, parse


def test_every_generated_command_parses_to_the_action_of_its_template():
    wrong = []
    for sentence, action in corpus.labelled_sentences((1, 2, 3), per_template=25):
        result = parse(sentence, (1, 2, 3))[1]
        got = (result.intent if action == "mission" else result.action) if isinstance(result, Command) else result
        if got != action:
            wrong.append((sentence, action, got))
    assert not wrong, wrong[:10]


def test_every_spoken_phrase_of_every_table_is_in_the_corpus():
    text = "\n".join(corpus.generate((1, 2)))
    for table in (*vocab.all_phrases().values(), vocab.UNITS):
        for phrase in corpus.spoken(table):
            assert phrase in text, phrase


def test_the_uav_ids_decide_the_names_in_the_corpus():
    words = set(corpus.words(corpus.generate((2, 14))))
    assert {"two", "fourteen"} <= words
    assert "drone fourteen" in " ".join(corpus.generate((14,)))
    assert "drone seven" not in " ".join(corpus.generate((2, 14)))


def test_the_corpus_is_the_same_for_the_same_vocabulary():
    assert corpus.generate((1, 2)) == corpus.generate((2, 1))
    assert corpus.generate((1, 2)) != corpus.generate((1, 2), seed=1)
