"""Sentences the recogniser should expect, generated from the vocabulary tables and the UAV ids.

The offline speech model is a trigram language model trained on these sentences
(voice.speech_model), so the recogniser only hears commands. Every phrase of every table appears,
in the word orders people use ("drone two go up five meters", "five meters up, drone two", "go up
five meters drone two"), with fillers, so a new synonym or a new UAV id needs no hand-written
grammar. The sample is seeded: the same vocabulary gives the same corpus, hence the same cached model.
"""
from __future__ import annotations

import random
from collections.abc import Iterable

from voice import vocabulary as vocab
from voice.numbers import say_integer, say_number

DEFAULT_UAV_IDS = tuple(range(1, 10))
SENTENCES_PER_TEMPLATE = 60
LENGTHS = [*range(1, 31), 35, 40, 45, 50, 60, 70, 75, 80, 90, 100, 120, 150, 200, 0.5, 1.5, 2.5, 3.5, 0.25, 0.75]
ANGLES = [5, 10, 15, 20, 25, 30, 40, 45, 60, 75, 90, 100, 120, 135, 150, 180, 200, 270, 360]
FILLER_RATE = 0.3
FILLER_WORDS = sorted(w for w in vocab.FILLERS if w.isalpha() and len(w) > 1 and w not in vocab.YES_NO_OPENERS)
PREFIXES = ["", "", "", "please", "okay", "now", "uh", "um", "could you", "can you", "hey", "i want"]
SUFFIXES = ["", "", "", "please", "now", "right now", "thanks", "okay"]


def phrases_of(table: dict[str, str], *values: str) -> list[str]:
    """The phrases of a vocabulary table that mean one of `values` (every phrase without values)."""
    return [phrase for phrase, value in table.items() if not values or value in values]


def _uav_names(uav_ids: Iterable[int]) -> list[str]:
    nouns = ["drone", "uav", "quad", "number", "vehicle", "robot", "drone number", "uav number"]
    return [f"{noun} {say_integer(i)}" for i in uav_ids for noun in nouns]


def _templates() -> dict[str, list[str]]:
    """{who}, {who2}: UAVs; {len}/{ang}: a spoken length/angle; the rest: phrase slots."""
    return {
        "take_off": ["{who} {takeoff}", "{takeoff} {who}", "{who} {takeoff} to {len} {lunit}",
                     "{who} {takeoff} and climb to {len} {lunit}", "{takeoff} to {len} {lunit} {who}",
                     "{who} {takeoff} to a height of {len} {lunit}"],
        "land": ["{who} {land}", "{land} {who}", "{who} {land} now", "{who} please {land}",
                 "tell {who} to {land}"],
        "move": ["{who} {move} {dir} {len} {lunit}", "{who} {dir} {len} {lunit}", "{who} {move} {len} {lunit} {dir}",
                 "{move} {dir} {len} {lunit} {who}", "{len} {lunit} {dir} {who}", "{who} {len} {lunit} {dir}",
                 "{who} {climb} {len} {lunit}", "{who} {climb} by {len} {lunit}",
                 "{who} {move} {len} {lunit} along the {axis} axis", "{who} {move} along the {axis} axis {len} {lunit}",
                 "{who} {move} minus {len} {lunit} along {axis}", "{who} {move} {dir} by {len} {lunit}"],
        "turn": ["{who} {turn} {side} {ang} degrees", "{who} {turn} {ang} degrees {side}", "{who} {turn} {ang} degrees",
                 "{turn} {side} {ang} degrees {who}", "{who} {turn} to the {side} by {ang} degrees",
                 "{who} {turn} {side} {ang} {aunit}"],
        "follow": ["{who} {follow} {who2}", "{who} {follow} {who2} at {len} {lunit}", "{follow} {who2} {who}",
                   "{who} stay {len} {lunit} behind {who2}", "{who} {follow} {who2} keeping {len} {lunit}",
                   "{who} {follow} {who2} at a distance of {len} {lunit}"],
        "get": ["what is the {param} of {who}", "what is the {param} level of {who}", "{who} report your {param}",
                "{who} what is your {param}", "where is {who}", "how is {who} doing", "check the {param} of {who}",
                "tell me the {param} of {who}", "give me the {param} of {who}", "show the {param} of {who}",
                "how much battery does {who} have", "what is {who} doing", "what state is {who} in"],
        "set": ["{who} {set} {alg}", "{set} {alg} for {who}", "{set} {who} to {alg}", "{who} {set} to {alg}",
                "{who} fly with {alg}", "{who} navigate with {alg}", "{set} the algorithm of {who} to {alg}"],
        "mission": ["{standby} the {mission}", "{resume} the {mission}", "{standby}", "{resume}",
                    "everyone {standby}", "all drones {standby}", "{resume} with the {mission}"],
    }


def spoken(phrases: Iterable[str]) -> list[str]:
    """The phrases a person can say: words only ("orca3d" is typed, "orca three d" is said)."""
    return [p for p in phrases if all(w.isalpha() and (len(w) > 2 or w in vocab.AXES or w in ("on", "by", "me"))
                                      for w in p.split())]


def _slot_values(uav_ids: list[int]) -> dict[str, list[str]]:
    uavs = _uav_names(uav_ids)
    every = list(vocab.ALL_PHRASES)
    move_verbs = [p for p in phrases_of(vocab.ACTIONS, "move") if p not in vocab.ACTION_DIRECTIONS]
    return {
        "who": uavs + every, "who2": uavs,
        "takeoff": phrases_of(vocab.ACTIONS, "take_off"), "land": phrases_of(vocab.ACTIONS, "land"), "move": move_verbs,
        "climb": list(vocab.ACTION_DIRECTIONS), "turn": phrases_of(vocab.ACTIONS, "turn"),
        "follow": [p for p in phrases_of(vocab.ACTIONS, "follow") if not p.startswith(("stay", "keep", "behind"))],
        "set": phrases_of(vocab.ACTIONS, "set"), "standby": phrases_of(vocab.ACTIONS, "standby"),
        "resume": phrases_of(vocab.ACTIONS, "resume"),
        "dir": [p for p in vocab.DIRECTIONS if vocab.DIRECTIONS[p] not in vocab.AXES],
        "axis": ["x", "y", "z"], "side": list(vocab.TURN_SIDES),
        "param": [p for p in vocab.PARAMETERS if p not in ("where", "doing")],
        "alg": spoken(vocab.ALGORITHMS) + ["the neural network"],
        "mission": list(vocab.MISSION_COMPONENTS),
        "len": [say_number(v) for v in LENGTHS] + [f"{say_integer(v)} and a half" for v in (1, 2, 3, 4)] + ["half a"],
        "ang": [say_integer(v) for v in ANGLES],
        "lunit": [u for u, (_, unit, _) in vocab.UNITS.items() if unit == "m" and len(u) > 2],
        "aunit": [u for u, (_, unit, _) in vocab.UNITS.items() if unit == "deg" and len(u) > 3],
    }


def generate(uav_ids: Iterable[int] = DEFAULT_UAV_IDS, per_template: int = SENTENCES_PER_TEMPLATE,
             seed: int = 0) -> list[str]:
    """The speech model's corpus: whole commands, and every vocabulary phrase at least once."""
    ids = sorted(set(uav_ids)) or list(DEFAULT_UAV_IDS)
    sentences = command_sentences(ids, per_template, seed) + _every_phrase(_slot_values(ids))
    return sorted({" ".join(s.split()) for s in sentences})


def command_sentences(uav_ids: Iterable[int] = DEFAULT_UAV_IDS, per_template: int = SENTENCES_PER_TEMPLATE,
                      seed: int = 0) -> list[str]:
    """Whole commands from the templates, lower case, words only."""
    return sorted({s for s, _ in labelled_sentences(uav_ids, per_template, seed)})


def labelled_sentences(uav_ids: Iterable[int] = DEFAULT_UAV_IDS, per_template: int = SENTENCES_PER_TEMPLATE,
                       seed: int = 0) -> list[tuple[str, str]]:
    """(sentence, the action its template means: take_off, ..., "mission" for standby or resume)."""
    ids = sorted(set(uav_ids)) or list(DEFAULT_UAV_IDS)
    rng = random.Random(seed)
    slots = _slot_values(ids)
    sentences: list[tuple[str, str]] = []
    for action, templates in _templates().items():
        for template in templates:
            # each slot walks its values from a random start, so every value turns up across the templates
            starts = {name: rng.randrange(len(values)) for name, values in slots.items()}
            for n in range(per_template):
                filled = template
                if rng.random() < FILLER_RATE:  # people drop fillers after a name too: give the model those words
                    filler = rng.choice(FILLER_WORDS)
                    where = "{who}" if "{who}" in filled else ""
                    filled = filled.replace(where, f"{where} {filler}", 1) if where else f"{filler} {filled}"
                for name, values in slots.items():
                    filled = filled.replace("{" + name + "}", values[(starts[name] + n) % len(values)], 1)
                    if "{" + name + "}" in filled:
                        filled = filled.replace("{" + name + "}", rng.choice(values))
                sentences.append((" ".join(f"{rng.choice(PREFIXES)} {filled} {rng.choice(SUFFIXES)}".split()), action))
    return sentences


def _every_phrase(slots: dict[str, list[str]]) -> list[str]:
    """Each phrase of each table, alone and after a UAV name, so none is missing from the model."""
    out = []
    for table in vocab.phrase_tables():
        for phrase in spoken(table):
            out += [phrase, f"{slots['who'][0]} {phrase}"]
    return out


def words(sentences: Iterable[str]) -> list[str]:
    return sorted({w for s in sentences for w in s.split()})
