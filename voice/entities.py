"""Sentence -> WIT-style entities, each with a confidence: the first half of understanding.

The sentence is normalised into tokens, then read left to right: UAV names ("drone two", "all
drones"), phrases of the vocabulary tables (longest first), numbers with their sign and unit.
Filler words are skipped; a word that is none of these is matched against the vocabulary for a
typo ("meterz"), with the similarity as its confidence, or kept as not understood. Word order does
not matter to what is found; `voice.interpret` decides what the entities mean together.
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field, replace

from voice import vocabulary as vocab
from voice.numbers import NUMBER_WORDS, read_number

TYPO_CUTOFF = 0.8  # below this similarity a word is "not understood" rather than a typo of a known word


@dataclass(frozen=True)
class Entity:
    kind: str  # identity, action, direction, number, unit, parameter, algorithm, mission_component
    value: str | float  # canonical value: "move", "up", 5.0, "uav_2", "all", ... (a float for numbers only)
    confidence: float
    start: int  # token span [start, end)
    end: int
    body: str  # the words it came from
    role: str = ""  # identity: "agent" or "target" (the UAV to follow)
    factor: float = 1.0  # unit: multiply the number by this ...
    unit: str = ""  # ... to get it in this unit ("m", "deg")

    @property
    def text_value(self) -> str:
        """The value of an entity of words: every kind but number."""
        assert isinstance(self.value, str), f"a {self.kind} entity has the value {self.value!r}, not a text"
        return self.value

    @property
    def number_value(self) -> float:
        """The value of a number entity."""
        assert isinstance(self.value, float), f"a {self.kind} entity has the value {self.value!r}, not a number"
        return self.value


@dataclass
class Understanding:
    text: str
    tokens: list[str]
    entities: list[Entity] = field(default_factory=list)
    not_understood: list[str] = field(default_factory=list)

    def of(self, kind: str) -> list[Entity]:
        return [e for e in self.entities if e.kind == kind]

    def first(self, kind: str) -> Entity | None:
        found = self.of(kind)
        return found[0] if found else None

    def to_json(self) -> dict:
        """The entities as WIT returned them: kind -> [{value, confidence, body, role?}]."""
        out: dict[str, list] = {}
        for e in self.entities:
            item = {"value": e.value, "confidence": round(e.confidence, 3), "body": e.body}
            if e.role:
                item["role"] = e.role
            out.setdefault(e.kind, []).append(item)
        return out


# --- normalisation ----------------------------------------------------------------------------
_CONTRACTIONS = [(r"\bwhat's\b", "what is"), (r"\bwhere's\b", "where is"), (r"\bhow's\b", "how is"),
                 (r"\bthat's\b", "that is"), (r"\bit's\b", "it is"), (r"\blet's\b", "let us"),
                 (r"\bwho's\b", "who is"), (r"'s\b", ""), (r"n't\b", " not"), (r"'(d|ll|re|ve|m)\b", "")]


def _single_words() -> set[str]:
    words = set()
    for table in vocab.phrase_tables():
        for phrase in table:
            words.update(phrase.split())
    for phrase in vocab.ALL_PHRASES:
        words.update(phrase.split())
    return words | set(vocab.UAV_NOUNS) | set(NUMBER_WORDS) | set(vocab.FILLERS) | set(vocab.NEGATIVE_WORDS)


KNOWN_WORDS = frozenset(_single_words())


def tokenize(text: str) -> list[str]:
    """Lower-case words and numbers: "Drone 2, go up 5m!" -> [drone, 2, go, up, 5, m]."""
    text = text.lower().replace("\u2019", "'").replace("\u00b0", " degrees ")
    for pattern, replacement in _CONTRACTIONS:
        text = re.sub(pattern, replacement, text)
    text = re.sub(r"(?<!\d)\.|\.(?!\d)", " ", text)  # keep decimal points only
    text = re.sub(r"[^a-z0-9. ]+", " ", text)
    tokens = []
    for raw in text.split():
        if raw in KNOWN_WORDS:
            tokens.append(raw)
            continue
        # glued words: "5m" -> 5 m, "uav2" -> uav 2, "drone1" -> drone 1
        tokens.extend(re.findall(r"\d+(?:\.\d+)?|[a-z]+", raw))
    return _join_spelled(tokens)


def _join_spelled(tokens: list[str]) -> list[str]:
    """"u a v" -> "uav": an acronym spelled out letter by letter."""
    out, i = [], 0
    while i < len(tokens):
        if tokens[i:i + 3] == ["u", "a", "v"]:
            out.append("uav")
            i += 3
        elif tokens[i:i + 2] == ["n", "n"]:
            out.append("nn")
            i += 2
        else:
            out.append(tokens[i])
            i += 1
    return out


# --- phrase index --------------------------------------------------------------------------------
def _phrase_index() -> dict[str, list[tuple[list[str], str, object]]]:
    """first word -> [(phrase words, kind, value)], longest phrase first."""
    index: dict[str, list] = {}
    for kind, table in vocab.all_phrases().items():
        for phrase, value in table.items():
            words = phrase.split()
            index.setdefault(words[0], []).append((words, kind, value))
    for phrase, unit in vocab.UNITS.items():
        index.setdefault(phrase, []).append(([phrase], "unit", unit))
    for phrase in vocab.ALL_PHRASES:
        words = phrase.split()
        index.setdefault(words[0], []).append((words, "identity", "all"))
    for entries in index.values():
        entries.sort(key=lambda entry: -len(entry[0]))
    return index


PHRASES = _phrase_index()


def _typo_fix(word: str) -> tuple[str, float] | None:
    if len(word) < 4 or word.isdigit():
        return None
    match = difflib.get_close_matches(word, KNOWN_WORDS, n=1, cutoff=TYPO_CUTOFF)
    if not match:
        return None
    return match[0], difflib.SequenceMatcher(None, word, match[0]).ratio()


# --- reading -----------------------------------------------------------------------------------
def understand(text: str) -> Understanding:
    """All the entities of one sentence."""
    tokens = tokenize(text)
    fixed = list(tokens)
    trust = [1.0] * len(tokens)
    for i, word in enumerate(tokens):
        if word not in KNOWN_WORDS and not re.match(r"^\d", word):
            fix = _typo_fix(word)
            if fix:
                fixed[i], trust[i] = fix
    result = Understanding(text, tokens)
    _Reader(fixed, tokens, trust, result).run()
    _assign_roles(result)
    return result


class _Reader:
    def __init__(self, words: list[str], original: list[str], trust: list[float], out: Understanding):
        self.words, self.original, self.trust, self.out = words, original, trust, out

    def body(self, start: int, end: int) -> str:
        return " ".join(self.original[start:end])

    def add(self, kind: str, value, start: int, end: int, **extra) -> None:
        confidence = min(self.trust[start:end] or [1.0])
        self.out.entities.append(Entity(kind, value, confidence, start, end, self.body(start, end), **extra))

    def run(self) -> None:
        i = 0
        while i < len(self.words):
            i = self.step(i)

    def step(self, i: int) -> int:
        words = self.words
        word = words[i]
        if word in vocab.UAV_NOUNS:
            j = i + 1
            if j < len(words) and words[j] in vocab.ID_LINKERS and word not in vocab.ID_LINKERS:
                j += 1
            value, k = read_number(words, j)
            if value is not None and value == int(value) and 0 < value < 100:
                self.add("identity", f"uav_{int(value)}", i, k)
                return k
            if word in vocab.ID_LINKERS:  # "number" alone means nothing
                return i + 1
        if word in ("all", "both"):  # "all three drones": the count belongs to the name
            count, k = read_number(words, i + 1)
            if count is not None and k < len(words) and words[k] in vocab.UAV_NOUNS:
                self.add("identity", "all", i, k + 1)
                return k + 1
        for phrase, kind, meaning in PHRASES.get(word, ()):
            if words[i:i + len(phrase)] == phrase:
                return self.phrase(i, i + len(phrase), kind, meaning)
        value, k = read_number(words, i)
        if value is not None:
            return self.number(i, k, value)
        if word in ("a", "an") and i + 1 < len(words) and words[i + 1] in vocab.UNITS:  # "a meter"
            return self.number(i, i + 1, 1.0)
        if word in vocab.FILLERS or word in vocab.NEGATIVE_WORDS or word in vocab.UAV_NOUNS:
            return i + 1
        self.out.not_understood.append(self.original[i])
        return i + 1

    def phrase(self, i: int, end: int, kind: str, value) -> int:
        if kind == "unit":
            name, unit, factor = value
            self.add("unit", name, i, end, unit=unit, factor=factor)
            if self.words[end:end + 3] == ["and", "a", "half"]:  # "a meter and a half"
                number = next((e for e in reversed(self.out.entities) if e.kind == "number" and e.end == i), None)
                if number is not None:
                    half_more = replace(number, value=number.number_value + 0.5)
                    self.out.entities[self.out.entities.index(number)] = half_more
                    return end + 3
        elif kind == "action" and self.out.first("action") and " ".join(self.words[i:end]) in vocab.DIRECTIONS:
            # a second verb that is also a direction ("fly lower") is the direction
            self.add("direction", vocab.DIRECTIONS[" ".join(self.words[i:end])], i, end)
        else:
            self.add(kind, value, i, end)
            if kind == "action" and " ".join(self.words[i:end]) in vocab.ACTION_DIRECTIONS:
                self.add("direction", vocab.ACTION_DIRECTIONS[" ".join(self.words[i:end])], i, end)
        return end

    def number(self, i: int, end: int, value: float) -> int:
        start = i
        if i > 0 and self.words[i - 1] in vocab.NEGATIVE_WORDS:
            value, start = -value, i - 1
        self.add("number", value, start, end)
        return end


def _assign_roles(result: Understanding) -> None:
    """An identity right after "follow"/"behind" (fillers between allowed) is the one to follow."""
    markers = [e for e in result.entities if e.kind == "action"
               and (e.body in vocab.FOLLOW_TARGET_MARKERS or e.body.split()[0] in vocab.FOLLOW_TARGET_MARKERS)]
    behind = [i for i, w in enumerate(result.tokens) if w in ("behind", "after")]
    ends = [m.end for m in markers] + [i + 1 for i in behind]
    for n, e in enumerate(result.entities):
        if e.kind != "identity":
            continue
        gap_is_filler = any(end <= e.start and all(w in vocab.FILLERS for w in result.tokens[end:e.start])
                            for end in ends)
        result.entities[n] = Entity(e.kind, e.value, e.confidence, e.start, e.end, e.body,
                                    "target" if gap_is_filler and e.value != "all" else "agent")
