"""Spoken numbers are read back to the value a person means, and written the way they are said."""
import pytest

from voice.numbers import read_number, say_integer, say_number


@pytest.mark.parametrize("words, value, used", [
    ("five meters", 5, 1), ("twenty five", 25, 2), ("ninety", 90, 1), ("one hundred", 100, 2),
    ("a hundred and twenty degrees", 120, 4), ("two thousand five hundred", 2500, 4),
    ("two point five", 2.5, 3), ("zero point seven five", 0.75, 4), ("one and a half", 1.5, 4),
    ("half a meter", 0.5, 2), ("3.5 m", 3.5, 1), ("forty two", 42, 2),
])
def test_reads_the_whole_number_and_says_where_it_ends(words, value, used):
    tokens = words.split()
    assert read_number(tokens, 0) == (pytest.approx(value), used)


def test_a_word_that_is_no_number_reads_nothing():
    assert read_number(["drone", "two"], 0) == (None, 0)
    assert read_number(["a", "drone"], 0) == (None, 0)


def test_two_number_words_in_a_row_are_two_numbers():
    # "drone two five meters": the id and the distance, not 25
    assert read_number(["two", "five"], 0) == (2, 1)


@pytest.mark.parametrize("value", [0, 7, 13, 20, 45, 99, 100, 101, 120, 999, 1000, 2025, 9999])
def test_said_integers_read_back(value):
    words = say_integer(value).split()
    assert read_number(words, 0) == (value, len(words))


def test_said_decimals_read_back():
    for value in (0.5, 2.5, 12.25, 3.05):
        words = say_number(value).split()
        assert read_number(words, 0)[0] == pytest.approx(value), words
    assert say_number(-2) == "minus two"
    with pytest.raises(ValueError, match="outside the spoken range"):
        say_integer(10000)
