"""A JSGF grammar of every command that can be said, generated from the vocabulary and the mission's UAVs.

The offline language model is trained on sentences sampled from it, and the recogniser's n-best is
rescored by it (voice.rescoring): a hypothesis it can say wins over one it cannot. (Pocketsphinx's own
grammar search was measured on it and is too slow: 2-28 s per utterance.) The grammar is made
of the same tables the parser reads (voice.vocabulary), in the word orders people use: the UAV
named before or after what it must do, fillers at the edges and after the name, units optional,
numbers as said ("two point five", "a hundred and twenty", "one and a half", "half a").
Answers to the assistant's own questions ("yes", "no", "drone two", "five meters") are in it too.
"""
from __future__ import annotations

import functools
import random
import re
from collections.abc import Iterable
from dataclasses import dataclass

from voice import corpus
from voice import vocabulary as vocab
from voice.corpus import phrases_of
from voice.numbers import TENS, UNITS, say_integer

GRAMMAR_NAME = "magna_commands"
# Fillers said before or after a command or after a UAV's name. A few, not every FILLERS word: each one
# allowed everywhere is one more word the search can mistake a short command word for.
EDGE_FILLERS = ("please", "okay", "now", "uh", "um", "hey", "then", "right now", "just", "could you",
                "can you", "would you", "i want", "i want you to", "thanks", "thank you", "alright", "go ahead and",
                "quickly", "slowly", "again", "so")
YES_WORDS = ("yes", "yeah", "yep", "correct", "confirm", "confirmed", "affirmative", "exactly", "yes please")
NO_WORDS = ("no", "nope", "cancel", "negative", "wrong", "no cancel")
OPTIONAL_RATE = 0.35
TYPED_ONLY = frozenset({"m", "cm", "mm", "ft", "deg", "rad", "nn", "ok", "ex", "orca3", "orca3d", "3d"})


def _alternatives(phrases: Iterable[str]) -> str:
    """`a | b c | d`, spoken phrases only, sorted and without repeats."""
    words = sorted({" ".join(p.split()) for p in phrases
                    if p.split() and all(w.isalpha() and w not in TYPED_ONLY for w in p.split())})
    if not words:
        raise ValueError("a grammar rule needs at least one spoken phrase")
    return " | ".join(words)


def _number_rules() -> list[str]:
    digits = [w for w, v in UNITS.items() if 1 <= v <= 9 and w != "oh"]
    teens = [w for w, v in UNITS.items() if v >= 10]
    return [
        f"<digit> = {' | '.join(digits)};",
        f"<below_hundred> = zero | {' | '.join(teens)} | <digit> | ({' | '.join(TENS)}) [<digit>];",
        "<integer> = <below_hundred> | (a | one | two) hundred [and <below_hundred>];",
        "<length> = <integer> [point (zero | <digit>) | and a half] | half a | a half | point <digit>;",
    ]


def jsgf(uav_ids: Iterable[int]) -> str:
    """The grammar (JSGF text) for a mission flying `uav_ids`.

    Every rule is referenced once where it can be (the UAV's name before or after one shared <body>):
    pocketsphinx expands each reference into its own copy of the rule, and its search time grows with them.
    """
    ids = sorted(set(uav_ids)) or list(corpus.DEFAULT_UAV_IDS)
    length_units = [u for u, (_, unit, _) in vocab.UNITS.items() if unit == "m" and len(u) > 2]
    angle_units = [u for u, (_, unit, _) in vocab.UNITS.items() if unit == "deg" and len(u) > 3]
    directions = [p for p, v in vocab.DIRECTIONS.items() if v not in vocab.AXES]
    move_verbs = [p for p in phrases_of(vocab.ACTIONS, "move") if p not in vocab.ACTION_DIRECTIONS]
    follow_verbs = [p for p in phrases_of(vocab.ACTIONS, "follow") if not p.startswith(("stay", "keep", "behind"))]
    parameters = [p for p in vocab.PARAMETERS if p not in ("where", "doing")]
    rules = [
        "#JSGF V1.0;",
        f"grammar {GRAMMAR_NAME};",
        "public <utterance> = [<filler>] (<command> | <query> | <mission> | <answer>) [<filler>];",
        "<command> = [<who> [<filler>]] <body> [<who>];",
        "<body> = <take_off> | <land> | <move> | <turn> | <follow> | <set>;",
        f"<filler> = {_alternatives(EDGE_FILLERS)};",
        f"<id> = {' | '.join(say_integer(i) for i in ids)};",
        f"<noun> = {_alternatives(vocab.UAV_NOUNS)};",
        "<uav> = [the] <noun> [number] <id> | number <id>;",
        f"<everyone> = {_alternatives(vocab.ALL_PHRASES)};",
        "<who> = <uav> | <everyone>;",
        f"<lunit> = {_alternatives(length_units)};",
        f"<aunit> = {_alternatives(angle_units)};",
        f"<dir> = {_alternatives(directions)};",
        f"<axis> = {_alternatives(vocab.AXES)};",
        f"<side> = {_alternatives(vocab.TURN_SIDES)};",
        *_number_rules(),
        f"<take_off> = ({_alternatives(phrases_of(vocab.ACTIONS, 'take_off'))})"
        " [[and climb] [up] to [a height of | an altitude of] <length> [<lunit>]];",
        f"<land> = {_alternatives(phrases_of(vocab.ACTIONS, 'land'))};",
        f"<move_verb> = {_alternatives(move_verbs)};",
        f"<climb_verb> = {_alternatives(vocab.ACTION_DIRECTIONS)};",
        "<move> = ([<move_verb>] (<dir> [by] | [minus | negative]) | <climb_verb> [by]) <length> [<lunit>]"
        " [[to the] <dir> | along [the] <axis> [axis]]"
        " | <move_verb> along [the] <axis> [axis] [by] [minus] <length> [<lunit>];",
        f"<turn> = ({_alternatives(phrases_of(vocab.ACTIONS, 'turn'))}) [to the] [<side>] [by] <integer> [<aunit>]"
        " [to the <side> | <side>];",
        f"<follow> = (({_alternatives(follow_verbs)}) | [stay | keep] <length> [<lunit>] behind | (stay | keep) behind)"
        " <uav> [at [a distance of] <length> [<lunit>] | keeping <length> [<lunit>]];",
        f"<algorithm> = [the] ({_alternatives(vocab.ALGORITHMS)}) [algorithm];",
        f"<set> = ({_alternatives(phrases_of(vocab.ACTIONS, 'set'))})"
        " [[the algorithm of] <who>] [to] <algorithm> [for <who>]"
        " | (fly | navigate) with <algorithm> | go back to <algorithm>;",
        f"<parameter> = {_alternatives(parameters)};",
        "<query> = what is the <parameter> [level] of <who> | what is <who> doing | what state is <who> in"
        " | where is <who> | how (is | are) <who> doing | how much battery does <who> have"
        " | <who> (report | what is) your <parameter> | (check | tell me | give me | show | report)"
        " the <parameter> of <who> | is <who> (airborne | flying | landed | in the air | on the ground);",
        f"<mission> = [<everyone>] ({_alternatives(phrases_of(vocab.ACTIONS, 'standby'))})"
        f" [the ({_alternatives(vocab.MISSION_COMPONENTS)})]"
        f" | ({_alternatives(phrases_of(vocab.ACTIONS, 'resume'))})"
        f" [[with] the ({_alternatives(vocab.MISSION_COMPONENTS)})];",
        f"<answer> = {_alternatives(YES_WORDS)} | {_alternatives(NO_WORDS)} | <who> | <length> [<lunit> | <aunit>]"
        " | <dir> | <algorithm>;",
    ]
    return "\n".join(rules) + "\n"


def words(grammar: str) -> list[str]:
    """Every word a grammar can produce (for the dictionary)."""
    bodies = " ".join(line.split("=", 1)[1] for line in grammar.splitlines()[2:] if "=" in line)
    return sorted(set(re.sub(r"<[^>]*>|[^a-z' ]", " ", bodies).split()))


# --- the grammar as a tree: sampled for the language model, matched to keep only sentences it can say ---------
@dataclass(frozen=True)
class Node:
    """kind: "word" (value: the word), "ref" (value: a rule name), "seq", "alt" or "opt" (children)."""

    kind: str
    value: str = ""
    children: tuple[Node, ...] = ()


_TOKEN = re.compile(r"<[^>]+>|[()\[\]|]|[a-z']+")


def _parse_expansion(tokens: list[str], i: int = 0, closing: str = "") -> tuple[Node, int]:
    """An expansion from tokens[i] to `closing` (or the end): alternatives of sequences."""
    alternatives: list[Node] = []
    sequence: list[Node] = []
    while i < len(tokens) and tokens[i] != closing:
        token = tokens[i]
        if token == "|":
            alternatives.append(Node("seq", children=tuple(sequence)))
            sequence, i = [], i + 1
        elif token in "([":
            inner, i = _parse_expansion(tokens, i + 1, ")" if token == "(" else "]")
            sequence.append(inner if token == "(" else Node("opt", children=(inner,)))
            i += 1  # the closing bracket
        elif token.startswith("<"):
            sequence.append(Node("ref", token[1:-1]))
            i += 1
        else:
            sequence.append(Node("word", token))
            i += 1
    alternatives.append(Node("seq", children=tuple(sequence)))
    return (alternatives[0] if len(alternatives) == 1 else Node("alt", children=tuple(alternatives))), i


class Grammar:
    """The rules of a jsgf() text: sample sentences from it, and tell whether it can say a sentence."""

    def __init__(self, text: str):
        self.text = text
        self.rules: dict[str, Node] = {}
        for line in text.splitlines()[2:]:
            if "=" not in line:
                continue
            head, body = line.split("=", 1)
            name = head.removeprefix("public").strip().strip("<>")
            self.rules[name], _ = _parse_expansion(_TOKEN.findall(body.rstrip().rstrip(";")))
        self.root = next(line.split("=")[0].removeprefix("public").strip().strip("<>")
                         for line in text.splitlines() if line.startswith("public"))
        self._pattern = re.compile(self._regex(Node("ref", self.root)))

    def accepts(self, sentence: str) -> bool:
        return self._pattern.fullmatch(" ".join(sentence.split()) + " ") is not None

    def sample(self, count: int, seed: int = 0, rule: str | None = None) -> list[str]:
        """`count` sentences of `rule` (default: the whole grammar) drawn at random, seeded; every alternative
        is equally likely at each choice, and an optional part is said one time in OPTIONAL_RATE."""
        rng = random.Random(seed)
        out = []
        for _ in range(count):
            words: list[str] = []
            self._expand(Node("ref", rule or self.root), rng, words)
            out.append(" ".join(words))
        return out

    def language_model_corpus(self, count: int, seed: int = 0) -> list[str]:
        """Sentences for the language model: whole utterances, with commands weighted as people say them
        (an answer to a question is short and rare next to commands); a fifth open or end with a filler."""
        shares = {"command": 0.6, "query": 0.15, "mission": 0.1, "answer": 0.15}
        rng = random.Random(seed)
        out: list[str] = []
        for rule, share in shares.items():
            for _ in range(int(count * share)):
                words: list[str] = []
                if rng.random() < 0.1:
                    self._expand(Node("ref", "filler"), rng, words)
                self._expand(Node("ref", rule), rng, words)
                if rng.random() < 0.1:
                    self._expand(Node("ref", "filler"), rng, words)
                out.append(" ".join(words))
        return out

    def _expand(self, node: Node, rng: random.Random, words: list[str]) -> None:
        if node.kind == "word":
            words.append(node.value)
        elif node.kind == "ref":
            self._expand(self.rules[node.value], rng, words)
        elif node.kind == "seq":
            for child in node.children:
                self._expand(child, rng, words)
        elif node.kind == "alt":
            self._expand(rng.choice(node.children), rng, words)
        elif rng.random() < OPTIONAL_RATE:  # opt
            self._expand(node.children[0], rng, words)

    def _regex(self, node: Node) -> str:
        if node.kind == "word":
            return re.escape(node.value) + " "
        if node.kind == "ref":
            return self._regex(self.rules[node.value])
        inner = [self._regex(child) for child in node.children]
        if node.kind == "seq":
            return "".join(inner)
        if node.kind == "alt":
            return "(?:" + "|".join(inner) + ")"
        return "(?:" + inner[0] + ")?"


@functools.lru_cache(maxsize=8)
def grammar_for(uav_ids: tuple[int, ...]) -> Grammar:
    """The Grammar of a mission's UAVs, made once per set of ids."""
    return Grammar(jsgf(uav_ids))
