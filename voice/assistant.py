"""The assistant's loop: a sentence (typed, or transcribed from audio) -> command -> ground station.

It keeps a little dialogue state: when it asked a question ("Which UAV should land?"), a reply
that is not a command on its own ("drone two") completes the sentence that raised it; when it asked
to confirm a command it was unsure of, "yes" sends that command, and "no" or no answer within
`confirm_seconds` drops it.

Spoken commands that move aircraft or change the mission (ACTING_ACTIONS) are sent without a question
only when the recogniser's confidence in them (voice.rescoring) is at least CONFIRM_THRESHOLD;
questions to the ground station ("what is the battery of drone one") are never confirmed.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from voice.backend import BackendError, Reply
from voice.entities import Understanding, tokenize
from voice.interpret import Command, Parameter, Question, parameter_json, parse, wit_entities
from voice.rescoring import rescore

YES = {"yes", "yeah", "yep", "correct", "confirm", "confirmed", "affirmative", "exactly"}
NO = {"no", "nope", "cancel", "negative", "wrong", "not"}
# Commands that move aircraft or change the mission: a spoken one the recogniser is unsure of is confirmed first.
ACTING_ACTIONS = frozenset({"take_off", "land", "move", "turn", "follow", "set", "standby", "resume"})
# Calibrated with `python bench/voice_accuracy.py --calibrate` on the tuning sets (never the held-out set): the
# lowest threshold at which no more than 0.5 % of utterances became a wrong action sent without a question.
# 2026-11-27, 1,552 utterances (194 sentences, 4 voices, clean and 10 dB): 0.5 -> 0.71 %, 0.6 -> 0.45 %,
# 0.7 -> 0.26 %, 0.8 -> 0.06 %; asked 60.5 / 66.1 / 69.5 / 72.7 % of utterances.
CONFIRM_THRESHOLD = 0.6
CONFIRM_SECONDS = 10.0  # an answer to "did you say ...?" later than this is too late: nothing is sent


@dataclass
class Outcome:
    heard: str  # the sentence understood (after completing a question)
    understanding: Understanding
    result: Command | Question
    reply: Reply | None = None
    error: str = ""
    transcript_seconds: float = 0.0  # speech: decoding time
    confidence: float = 1.0  # speech: the recogniser's confidence in the command heard (voice.rescoring)

    def to_json(self) -> dict:
        out: dict[str, object] = {"text": self.heard, "entities": wit_entities(self.understanding, self.result),
               "command": self.result.to_json() if isinstance(self.result, Command) else None,
               "question": self.result.to_json() if isinstance(self.result, Question) else None}
        if self.reply is not None:
            out["reply"] = {"accepted": self.reply.accepted, "message": self.reply.message,
                            "values": [parameter_json(v) for v in self.reply.values]}
        if self.error:
            out["error"] = self.error
        out["confidence"] = round(self.confidence, 3)
        return out


def choose_hypothesis(alternatives: Iterable[str], uav_ids: Iterable[int] = ()) -> str:
    """The text heard from the recogniser's n-best, best first (voice.rescoring.rescore, without scores)."""
    return rescore(list(alternatives), None, uav_ids).text


class Assistant:
    """Understands sentences and sends the commands; `send` is None for a dry run."""

    def __init__(self, send: Callable[[Command], Reply] | None, uav_ids: Iterable[int] = (),
                 say: Callable[[str], object] | None = None, recognizer=None,
                 confirm_threshold: float = CONFIRM_THRESHOLD, confirm_seconds: float = CONFIRM_SECONDS,
                 clock: Callable[[], float] = time.monotonic):
        self.send, self.uav_ids, self.say, self.recognizer = send, list(uav_ids), say, recognizer
        self.confirm_threshold, self.confirm_seconds, self.clock = confirm_threshold, confirm_seconds, clock
        self._pending: str | None = None  # the sentence that raised the last question
        self._to_confirm: Command | None = None  # the command the last question asked to confirm
        self._confirm_by = 0.0  # clock() after which the confirmation is too late
        self._lock = threading.Lock()  # expire() runs on a timer thread in `magna voice --mic`

    def expire(self) -> Outcome | None:
        """Drop a confirmation not answered within confirm_seconds; the outcome says so (None if none was due)."""
        with self._lock:
            if self._to_confirm is None or self.clock() < self._confirm_by:
                return None
            command, self._to_confirm = self._to_confirm, None
        text = f"No answer within {self.confirm_seconds:g} s: nothing was sent."
        self._speak(text)
        return Outcome("", parse("", self.uav_ids)[0], Question(text, "cancelled", command.to_json()))

    def handle_text(self, text: str, confidence: float = 1.0) -> Outcome:
        """A sentence typed or heard; `confidence`: the recogniser's in it (1 for typed text)."""
        with self._lock:
            return self._handle_text(text, confidence)

    def _handle_text(self, text: str, confidence: float) -> Outcome:
        heard = text
        understanding, result = parse(text, self.uav_ids)
        if self._to_confirm is not None and self.clock() >= self._confirm_by:
            self._to_confirm = None  # too late: a "yes" now confirms nothing
            if not understanding.of("action"):
                late = f"Too late to confirm (more than {self.confirm_seconds:g} s): nothing was sent. Say it again."
                self._speak(late)
                return Outcome(text, understanding, Question(late, "cancelled"), confidence=confidence)
        if self._to_confirm is not None and not understanding.of("action"):
            words = set(tokenize(text))
            if words & NO:
                self._to_confirm = None
                cancelled = Question("Cancelled: nothing was sent.", "cancelled")
                self._speak(cancelled.text)
                return Outcome(text, understanding, cancelled, confidence=confidence)
            if words & YES:
                command, self._to_confirm = self._to_confirm, None
                return self._send(Outcome(text, understanding, command), command)
        if self._pending is not None and not understanding.of("action"):
            completed = f"{self._pending} {text}"
            understanding, result = parse(completed, self.uav_ids)
            heard = completed
        if isinstance(result, Command) and result.action in ACTING_ACTIONS and confidence < self.confirm_threshold:
            result = Question(f'Did you say "{heard}", {result.describe()}? Say yes or no.', "confirmation",
                              result.to_json())
        outcome = Outcome(heard, understanding, result, confidence=confidence)
        self._to_confirm = None
        if isinstance(result, Question):
            self._pending = heard if result.missing in ("identity", "number", "direction", "algorithm") else None
            if result.missing == "confirmation":
                self._to_confirm = _command_of(result.partial)
                self._confirm_by = self.clock() + self.confirm_seconds
            self._speak(result.text)
            return outcome
        self._pending = None
        return self._send(outcome, result)

    def _send(self, outcome: Outcome, command: Command) -> Outcome:
        """Send `command` (the outcome's result) unless this is a dry run; the reply goes into the outcome."""
        if self.send is not None:
            try:
                outcome.reply = self.send(command)
            except BackendError as error:
                outcome.error = str(error)
            if outcome.reply is not None:
                self._speak(outcome.reply.spoken())
        return outcome

    def handle_audio(self, samples: np.ndarray) -> Outcome:
        if self.recognizer is None:
            raise RuntimeError("no recogniser: build the Assistant with one to handle audio")
        transcript = self.recognizer.transcribe(samples)
        hearing = rescore(transcript.alternatives or [transcript.text], transcript.scores, self.uav_ids)
        outcome = self.handle_text(hearing.text, hearing.confidence)
        outcome.transcript_seconds = transcript.seconds
        return outcome

    def _speak(self, text: str) -> None:
        if self.say is not None:
            self.say(text)


def _command_of(fields: dict) -> Command:
    return Command(fields["intent"], fields["action"], fields["agent"],
                   tuple(Parameter(**p) for p in fields["parameters"]))


def render(outcome: Outcome) -> str:
    """What the operator reads on the console."""
    lines = [f'heard: "{outcome.heard}"']
    if isinstance(outcome.result, Question):
        lines.append(f"? {outcome.result.text}")
    else:
        lines.append(f"> {outcome.result.describe()}")
        if outcome.error:
            lines.append(f"! {outcome.error}")
        elif outcome.reply is not None:
            lines.append(outcome.reply.describe())
    return "\n".join(lines)
