"""Spoken numbers, both ways: "twenty five" -> 25, "two point five" -> 2.5, 120 -> "one hundred twenty".

`read_number` consumes the longest number it can at a position of a token list, so the parser can
tell where a number ends; `say_number` writes what the speech model must be able to hear.
"""
from __future__ import annotations

import re

UNITS = {"zero": 0, "oh": 0, "one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7,
         "eight": 8, "nine": 9, "ten": 10, "eleven": 11, "twelve": 12, "thirteen": 13, "fourteen": 14,
         "fifteen": 15, "sixteen": 16, "seventeen": 17, "eighteen": 18, "nineteen": 19}
TENS = {"twenty": 20, "thirty": 30, "forty": 40, "fifty": 50, "sixty": 60, "seventy": 70, "eighty": 80,
        "ninety": 90}
FRACTIONS = {"half": 0.5, "quarter": 0.25}
NUMBER_WORDS = frozenset(UNITS) | frozenset(TENS) | {"hundred", "thousand", "point", "and", "a", "half", "quarter"}
_DIGITS = re.compile(r"^\d+(\.\d+)?$")


def _below_hundred(tokens: list[str], i: int) -> tuple[int | None, int]:
    """A number under 100 at tokens[i] ("seven", "forty", "forty two", "42"): (value, next index)."""
    if i >= len(tokens):
        return None, i
    word = tokens[i]
    if word in UNITS and word != "oh":
        return UNITS[word], i + 1
    if word in TENS:
        if i + 1 < len(tokens) and tokens[i + 1] in UNITS and 0 < UNITS[tokens[i + 1]] < 10:
            return TENS[word] + UNITS[tokens[i + 1]], i + 2
        return TENS[word], i + 1
    return None, i


def _integer(tokens: list[str], i: int) -> tuple[int | None, int]:
    """An integer in words up to the thousands: "a hundred and twenty", "two thousand five hundred"."""
    total, j, seen = 0, i, False
    count: int | None
    for scale in ("thousand", "hundred"):
        k = j
        if k < len(tokens) and tokens[k] == "a" and k + 1 < len(tokens) and tokens[k + 1] == scale:
            count, k = 1, k + 1
        else:
            count, k = _below_hundred(tokens, k)
        if count is not None and k < len(tokens) and tokens[k] == scale:
            total += count * (1000 if scale == "thousand" else 100)
            j, seen = k + 1, True
            if j < len(tokens) and tokens[j] == "and" and _below_hundred(tokens, j + 1)[0] is not None:
                j += 1
    rest, k = _below_hundred(tokens, j)
    if rest is not None:
        return total + rest, k
    return (total, j) if seen else (None, i)


def read_number(tokens: list[str], i: int) -> tuple[float | None, int]:
    """The number starting at tokens[i] and the index after it, or (None, i).

    Reads digits ("2.5"), words ("twenty five", "a hundred and ten"), decimals ("two point five",
    "zero point seven five") and halves ("one and a half", "half a").
    """
    if i >= len(tokens):
        return None, i
    if _DIGITS.match(tokens[i]):
        return float(tokens[i]), i + 1
    if tokens[i] == "point":  # "point five"
        value, j = read_number(["zero", *tokens[i:]], 0)
        return (value, i + j - 1) if j > 2 else (None, i)
    if tokens[i] == "half":  # "half a meter"
        return 0.5, i + (2 if i + 1 < len(tokens) and tokens[i + 1] == "a" else 1)
    if tokens[i] == "a" and i + 1 < len(tokens) and tokens[i + 1] in ("half", "quarter"):
        return FRACTIONS[tokens[i + 1]], i + 2
    value, j = _integer(tokens, i)
    if value is None:
        return None, i
    if j + 1 < len(tokens) and tokens[j] == "point":
        decimals, k = "", j + 1
        while k < len(tokens) and tokens[k] in UNITS and UNITS[tokens[k]] < 10:
            decimals += str(UNITS[tokens[k]])
            k += 1
        if decimals:
            return float(f"{value}.{decimals}"), k
    if j + 2 < len(tokens) and tokens[j] == "and" and tokens[j + 1] == "a" and tokens[j + 2] in FRACTIONS:
        return value + FRACTIONS[tokens[j + 2]], j + 3
    return float(value), j


_UNIT_NAMES = {v: k for k, v in UNITS.items() if k != "oh"}
_TEN_NAMES = {v: k for k, v in TENS.items()}


def say_integer(value: int) -> str:
    """Words for 0 <= value < 10000, the way people say them to a drone ("one hundred twenty")."""
    if not 0 <= value < 10000:
        raise ValueError(f"{value} is outside the spoken range 0..9999")
    words = []
    if value >= 1000:
        words += [_UNIT_NAMES[value // 1000], "thousand"]
        value %= 1000
    if value >= 100:
        words += [_UNIT_NAMES[value // 100], "hundred"]
        value %= 100
    if value >= 20:
        words.append(_TEN_NAMES[value // 10 * 10])
        value %= 10
        if value:
            words.append(_UNIT_NAMES[value])
    elif value or not words:
        words.append(_UNIT_NAMES[value])
    return " ".join(words)


def say_number(value: float) -> str:
    """Words for a non-negative number with at most two decimals ("two point five")."""
    if value < 0:
        return "minus " + say_number(-value)
    whole = int(value)
    decimals = f"{value - whole:.2f}"[2:].rstrip("0")
    words = say_integer(whole)
    if decimals:
        words += " point " + " ".join(_UNIT_NAMES[int(d)] for d in decimals)
    return words
