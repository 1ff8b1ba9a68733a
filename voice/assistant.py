"""The assistant's loop: a sentence (typed, or transcribed from audio) -> command -> ground station.

It keeps a little dialogue state: when it asked a question ("Which UAV should land?"), a reply
that is not a command on its own ("drone two") completes the sentence that raised it; when it asked
to confirm a command it was unsure of, "yes" sends that command and "no" drops it.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from voice.backend import BackendError, Reply
from voice.entities import Understanding, tokenize
from voice.interpret import Command, Parameter, Question, parameter_json, parse, wit_entities

YES = {"yes", "yeah", "yep", "correct", "confirm", "confirmed", "affirmative", "exactly"}
NO = {"no", "nope", "cancel", "negative", "wrong", "not"}


@dataclass
class Outcome:
    heard: str  # the sentence understood (after completing a question)
    understanding: Understanding
    result: Command | Question
    reply: Reply | None = None
    error: str = ""
    transcript_seconds: float = 0.0  # speech: decoding time

    def to_json(self) -> dict:
        out = {"text": self.heard, "entities": wit_entities(self.understanding, self.result),
               "command": self.result.to_json() if isinstance(self.result, Command) else None,
               "question": self.result.to_json() if isinstance(self.result, Question) else None}
        if self.reply is not None:
            out["reply"] = {"accepted": self.reply.accepted, "message": self.reply.message,
                            "values": [parameter_json(v) for v in self.reply.values]}
        if self.error:
            out["error"] = self.error
        return out


def choose_hypothesis(alternatives: Iterable[str], uav_ids: Iterable[int] = ()) -> str:
    """The recogniser's n-best, best first: the first that makes a whole command, else the best.

    A dropped or swapped short word ("drone two go five meters") often leaves the best hypothesis
    incomplete while the next one is right; a complete command is never replaced by a question."""
    alternatives = [a for a in alternatives if a.strip()]
    if not alternatives:
        return ""
    for text in alternatives:
        if isinstance(parse(text, uav_ids)[1], Command):
            return text
    return alternatives[0]


class Assistant:
    """Understands sentences and sends the commands; `send` is None for a dry run."""

    def __init__(self, send: Callable[[Command], Reply] | None, uav_ids: Iterable[int] = (),
                 say: Callable[[str], object] | None = None, recognizer=None):
        self.send, self.uav_ids, self.say, self.recognizer = send, list(uav_ids), say, recognizer
        self._pending: str | None = None  # the sentence that raised the last question
        self._to_confirm: Command | None = None  # the command the last question asked to confirm

    def handle_text(self, text: str) -> Outcome:
        heard = text
        understanding, result = parse(text, self.uav_ids)
        if self._to_confirm is not None and not understanding.of("action"):
            words = set(tokenize(text))
            if words & NO:
                self._to_confirm = None
                return Outcome(text, understanding, Question("Cancelled: nothing was sent.", "cancelled"))
            if words & YES:
                command, self._to_confirm = self._to_confirm, None
                return self._send(Outcome(text, understanding, command), command)
        if self._pending is not None and not understanding.of("action"):
            completed = f"{self._pending} {text}"
            understanding, result = parse(completed, self.uav_ids)
            heard = completed
        outcome = Outcome(heard, understanding, result)
        self._to_confirm = None
        if isinstance(result, Question):
            self._pending = heard if result.missing in ("identity", "number", "direction", "algorithm") else None
            if result.missing == "confirmation":
                self._to_confirm = _command_of(result.partial)
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
        text = choose_hypothesis([transcript.text, *transcript.alternatives], self.uav_ids)
        outcome = self.handle_text(text)
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
