"""The recogniser's n-best list -> the command heard, and how sure of it we are.

Only hypotheses that make a whole command compete: each is parsed, and among those that parse the
first one the command grammar can say (voice.grammar) wins, else the first that parses, else the
best hypothesis (which then becomes a question). The confidence of a hypothesis is the share of the
n-best list, weighted by the recogniser's scores, that means the same command: when "go up five
meters" and "go on five meters" both come back close together the command is in doubt, even if
the first is right. A hypothesis the grammar cannot say (a paraphrase, or a mishearing the language
model let through) keeps UNGRAMMATICAL_SHARE of that confidence.
"""
from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from voice.grammar import grammar_for
from voice.interpret import Command, Question, parse

# Sharpness of the scores' softmax: the recogniser's path scores are relative log-likelihoods in units of
# ln(score); larger makes the best hypothesis more dominant. Fitted on the tuning sets (see bench/voice_accuracy.py
# --calibrate), never on the held-out set.
SCORE_SHARPNESS = 20.0
UNGRAMMATICAL_SHARE = 0.5


@dataclass(frozen=True)
class Hypothesis:
    text: str
    confidence: float  # the share of the n-best that means the same command, less when ungrammatical; 0 if no command
    grammatical: bool  # the command grammar can say it
    result: Command | Question


@dataclass(frozen=True)
class Hearing:
    """What was heard: the chosen hypothesis first, then the others in the recogniser's order."""

    chosen: Hypothesis
    hypotheses: tuple[Hypothesis, ...]

    @property
    def text(self) -> str:
        return self.chosen.text

    @property
    def confidence(self) -> float:
        return self.chosen.confidence


def _meaning(result: Command | Question) -> str | None:
    return json.dumps(result.to_json(), sort_keys=True) if isinstance(result, Command) else None


def weights(scores: Sequence[float]) -> list[float]:
    """Softmax of the scores (ln of the recogniser's), sharpened by SCORE_SHARPNESS; equal weights without scores."""
    if not scores:
        return []
    top = max(scores)
    raw = [math.exp(SCORE_SHARPNESS * (s - top)) for s in scores]
    total = sum(raw)
    return [r / total for r in raw]


def rescore(alternatives: Sequence[str], scores: Sequence[float] | None = None,
            uav_ids: Iterable[int] = ()) -> Hearing:
    """The hypotheses (best first, `scores` their log scores, or None: all alike) as a Hearing."""
    ids = tuple(sorted(set(uav_ids)))
    texts: list[str] = []
    text_scores: list[float] = []
    for n, text in enumerate(alternatives):
        text = " ".join(text.split())
        if text and text not in texts:
            texts.append(text)
            text_scores.append(scores[n] if scores is not None else 0.0)
    if not texts:
        empty = Hypothesis("", 0.0, False, parse("", ids)[1])
        return Hearing(empty, (empty,))
    grammar = grammar_for(ids)
    results = [parse(text, ids)[1] for text in texts]
    shares: dict[str | None, float] = {}
    for result, weight in zip(results, weights(text_scores), strict=True):
        meaning = _meaning(result)
        shares[meaning] = shares.get(meaning, 0.0) + weight
    hypotheses = []
    for text, result in zip(texts, results, strict=True):
        meaning, grammatical = _meaning(result), grammar.accepts(text)
        confidence = shares[meaning] * (1.0 if grammatical else UNGRAMMATICAL_SHARE) if meaning else 0.0
        hypotheses.append(Hypothesis(text, confidence, grammatical, result))
    commands = [h for h in hypotheses if isinstance(h.result, Command)]
    chosen = next((h for h in commands if h.grammatical), commands[0] if commands else hypotheses[0])
    return Hearing(chosen, tuple(hypotheses))
