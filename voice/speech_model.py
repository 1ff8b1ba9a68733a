"""The restricted speech model of the offline recogniser: a trigram language model and a small dictionary.

PocketSphinx's generic English language model turns synthetic or accented commands into nonsense
("drone two go up five meters" -> "oh to go on we are"). Trained only on the command sentences
(voice.corpus), with a dictionary holding only their words, it recognises them well.

Pronunciations come from the CMU dictionary shipped with pocketsphinx. A word it lacks (a new UAV
call-sign such as "zephyr9" or "skyrelix", an acronym such as "uav") gets one derived automatically: acronyms
(words without vowels, or listed in ACRONYMS) are spelled out letter by letter, other words go through
espeak-ng's phonemiser, mapped onto the phone set of the acoustic model. So new names need no
hand-written dictionary.

Built models are cached under a directory named by a hash of their content (cached_speech_model).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import re
import shutil
import subprocess
import tempfile
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pocketsphinx
from pocketsphinx.lm import ArpaBoLM

from magna_common.files import write_atomically

MODEL_DIR = Path(pocketsphinx.get_model_path()) / "en-us"
ACOUSTIC_MODEL = MODEL_DIR / "en-us"
CMUDICT = MODEL_DIR / "cmudict-en-us.dict"

# Part of the cache key, with this module's source: a change to either rebuilds the cached models.
FORMAT_VERSION = 1
_SOURCE_HASH = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
LM_FILE = "commands.arpa"
DICT_FILE = "commands.dict"

# Words said letter by letter although they have vowels (words without vowels always are).
ACRONYMS = frozenset({"uav", "ugv", "gps", "imu", "rtl", "ros", "mlr", "fcu"})

ESPEAK_VOICE = "en-us"

# espeak-ng's ASCII phoneme mnemonics (`espeak-ng -v en-us -q -x --sep=_`) -> CMU phones (ARPAbet, no stress).
# Collected by phonemising 8000 cmudict words and compared with their cmudict entries.
ESPEAK_TO_CMU: dict[str, tuple[str, ...]] = {
    # consonants
    "p": ("P",), "b": ("B",), "t": ("T",), "d": ("D",), "k": ("K",), "g": ("G",), "f": ("F",), "v": ("V",),
    "T": ("TH",), "D": ("DH",), "s": ("S",), "z": ("Z",), "S": ("SH",), "Z": ("ZH",), "h": ("HH",),
    "m": ("M",), "n": ("N",), "N": ("NG",), "l": ("L",), "r": ("R",), "w": ("W",), "j": ("Y",),
    "tS": ("CH",), "dZ": ("JH",), "x": ("K",), "C": ("HH",), "t#": ("T",), "t2": ("T",), "d#": ("D",),
    "?": ("T",), "r-": ("R",), "l/": ("L",), "n-": ("AH", "N"), "m-": ("AH", "M"), "l-": ("AH", "L"),
    "W": ("W",), "hw": ("W",), "ts": ("T", "S"), "dz": ("D", "Z"),
    # vowels
    "@": ("AH",), "@2": ("AH",), "@5": ("AH",), "@-": ("AH",), "a#": ("AH",), "V": ("AH",), "3": ("ER",),
    "3:": ("ER",), "@L": ("AH", "L"), "a": ("AE",), "aa": ("AE",), "a2": ("AE",), "A:": ("AA",), "A": ("AA",),
    "0": ("AA",), "A@": ("AA", "R"), "e": ("EH",), "E": ("EH",), "E2": ("EH",), "E3": ("EH",), "e@": ("EH", "R"),
    "eI": ("EY",), "i": ("IY",), "i:": ("IY",), "I": ("IH",), "I#": ("IH",), "I2": ("IH",), "I3": ("IH",),
    "i@": ("IY", "AH"), "i@3": ("IH", "R"), "O": ("AO",), "O:": ("AO",), "O2": ("AO",), "O@": ("AO", "R"),
    "o@": ("AO", "R"), "o": ("OW",), "oU": ("OW",), "oU#": ("OW",), "u": ("UW",), "u:": ("UW",), "U": ("UH",),
    "U@": ("UH", "R"), "aI": ("AY",), "aI@": ("AY", "ER"), "aI3": ("AY", "ER"), "aU": ("AW",),
    "aU@": ("AW", "ER"), "OI": ("OY",), "IR": ("IH", "R"), "VR": ("ER",), "3:r": ("ER",),
}
# Marks in espeak's output that are not phones: stress, syllable and pause marks.
_ESPEAK_MARKS = "',%=;!|_:"


@functools.lru_cache(maxsize=4)
def _read_cmudict(path: str) -> dict[str, tuple[str, ...]]:
    """word -> its pronunciations in file order; "word(2)" lines are alternates of "word"."""
    entries: dict[str, list[str]] = {}
    with open(path, encoding="utf-8") as f:
        for line in f:
            parts = line.split("#", 1)[0].split()
            if len(parts) < 2:
                continue
            word = re.sub(r"\(\d+\)$", "", parts[0]).lower()
            entries.setdefault(word, []).append(" ".join(parts[1:]))
    return {word: tuple(prons) for word, prons in entries.items()}


class Pronunciations:
    """Pronunciations (space-separated CMU phones) of any word: cmudict first, then derived."""

    def __init__(self, dictionary: Path | str = CMUDICT, acronyms: Iterable[str] = ACRONYMS,
                 espeak: str = "espeak-ng", voice: str = ESPEAK_VOICE):
        self.dictionary = Path(dictionary)
        self.cmudict = _read_cmudict(str(self.dictionary))
        self.acronyms = frozenset(a.lower() for a in acronyms)
        self.espeak = espeak
        self.voice = voice
        # the acoustic model's phones are the ones its dictionary uses
        self.phones = frozenset(p for prons in self.cmudict.values() for pron in prons for p in pron.split())
        self._derived: dict[str, list[str]] = {}

    def known(self, word: str) -> bool:
        """Whether cmudict has the word."""
        return word.lower() in self.cmudict

    def lookup(self, word: str) -> list[str]:
        """All pronunciations of the word, most common first; ValueError if it cannot be pronounced."""
        word = word.strip().lower()
        if not word:
            raise ValueError("cannot pronounce an empty word")
        if word not in self._derived:
            self._derived[word] = self._pronounce(word)
        return list(self._derived[word])

    def _pronounce(self, word: str) -> list[str]:
        prons = list(self.cmudict.get(word, ()))
        if self.is_acronym(word):
            prons.append(self.spell(word))
            if word in self.acronyms and not prons[:-1]:
                # also as read like a word ("uav" as "you-av"): espeak-ng says it so, and some people
                with contextlib.suppress(ValueError):
                    prons.append(self.phonemise(word))
            return list(dict.fromkeys(prons))
        if prons:
            return prons
        parts = re.findall(r"[a-z']+|[0-9]+", word)
        if not parts or "".join(parts) != word.replace("-", "").replace(".", ""):
            raise ValueError(f"cannot pronounce the word {word!r}: use letters, digits, apostrophes only")
        if len(parts) > 1:  # "zephyr9", "uav3": each part on its own, in order
            return [" ".join(self.lookup(part)[0] for part in parts)]
        return [self.phonemise(word)]

    def is_acronym(self, word: str) -> bool:
        """Said letter by letter: listed in acronyms (a plural "s" allowed), or letters without any vowel."""
        word = word.lower()
        if word in self.acronyms or (word.endswith("s") and word[:-1] in self.acronyms):
            return True
        return word.isascii() and word.isalpha() and len(word) > 1 and not re.search(r"[aeiouy]", word)

    def spell(self, word: str) -> str:
        """The word spelled out letter by letter ("uav" -> "Y UW EY V IY"); a plural "s" of an acronym is "Z"."""
        word = word.lower()
        plural = word.endswith("s") and word[:-1] in self.acronyms
        letters = word[:-1] if plural else word
        phones = []
        for letter in letters:
            names = self.cmudict.get(letter + ".") or self.cmudict.get(letter)
            if not letter.isalpha() or not names:
                raise ValueError(f"cannot spell the word {word!r}: no letter name for {letter!r}")
            phones.append(names[0])
        if plural:
            phones.append("Z")
        return " ".join(phones)

    def phonemise(self, word: str) -> str:
        """The word's pronunciation from espeak-ng's phonemiser, in the acoustic model's phones."""
        if shutil.which(self.espeak) is None:
            raise ValueError(f"cannot pronounce the word {word!r}: it is not in {self.dictionary.name} "
                             f"and {self.espeak} (apt install espeak-ng) is not installed")
        try:
            out = subprocess.run([self.espeak, "-v", self.voice, "-q", "-x", "--sep=_"], input=word,
                                 capture_output=True, text=True, timeout=20, check=True).stdout
        except (subprocess.SubprocessError, OSError) as e:
            raise ValueError(f"cannot pronounce the word {word!r}: {self.espeak} failed ({e})") from e
        phones = espeak_to_cmu(out, word)
        unknown = [p for p in phones if p not in self.phones]
        if not phones or unknown:
            raise ValueError(f"cannot pronounce the word {word!r}: {self.espeak} gave {out.strip()!r}")
        return " ".join(phones)


def espeak_to_cmu(phonemes: str, word: str = "") -> list[str]:
    """espeak-ng's `-x --sep=_` phoneme string -> CMU phones; ValueError on a phoneme without a mapping."""
    phones: list[str] = []
    phonemes = re.sub(r"\([a-z-]+\)", " ", phonemes)  # language switches such as "(fr)"
    for token in re.split(r"[_\s]+", phonemes.strip()):
        token = token.lstrip(_ESPEAK_MARKS)
        if not token or all(c in _ESPEAK_MARKS for c in token):
            continue
        mapped = ESPEAK_TO_CMU.get(token) or ESPEAK_TO_CMU.get(token.rstrip("#-;~:"))
        if mapped is None and len(token) > 1 and token[-1].isdigit():
            mapped = ESPEAK_TO_CMU.get(token[:-1])
        if mapped is None:
            raise ValueError(f"cannot pronounce the word {word!r}: no CMU phone for espeak's {token!r}")
        if mapped == ("R",) and phones and phones[-1] in ("R", "ER"):  # "3_r", "A@_r": cmudict has one R
            continue
        phones.extend(mapped)
    return phones


@dataclass(frozen=True)
class SpeechModel:
    """The files the offline recogniser loads, and the words they know."""

    lm_path: Path
    dict_path: Path
    words: tuple[str, ...]


def normalise(sentence: str) -> str:
    """Lower case, words only, accents dropped: the form the language model is trained on and the recogniser
    returns. Letters of other scripts stay (and are refused by the Pronunciations)."""
    text = "".join(c for c in unicodedata.normalize("NFKD", sentence.lower()) if not unicodedata.combining(c))
    return " ".join(re.sub(r"[^\w']+|_", " ", text).split())


def _corpus(sentences: Iterable[str], extra_words: Iterable[str]) -> tuple[list[str], list[str]]:
    lines = [s for s in (normalise(s) for s in sentences) if s]
    if not lines:
        raise ValueError("the speech model needs at least one sentence with words")
    extra = sorted({w for word in extra_words for w in normalise(word).split()})
    return lines, extra


def build_speech_model(sentences: Iterable[str], out_dir: Path | str, extra_words: Iterable[str] = (),
                       pronunciations: Pronunciations | None = None) -> SpeechModel:
    """Write out_dir/commands.arpa (trigram LM of the sentences) and out_dir/commands.dict (their words).

    extra_words join the dictionary and the language model (as unigrams), so they can be recognised
    even if no sentence has them. Each file is written to a temporary file and renamed into place.
    """
    lines, extra = _corpus(sentences, extra_words)
    pronunciations = pronunciations or default_pronunciations()
    words = sorted({w for line in lines for w in line.split()} | set(extra))
    dict_lines = []
    for word in words:  # before writing anything: an unpronounceable word is a ValueError
        for i, pron in enumerate(pronunciations.lookup(word)):
            dict_lines.append(f"{word}{'' if i == 0 else f'({i + 1})'} {pron}\n")

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lm = ArpaBoLM(text="\n".join(lines), case="lower", add_start=True)
    if extra:
        with tempfile.NamedTemporaryFile("w", dir=out_dir, prefix=".extra-words.", suffix=".tmp") as f:
            f.write("\n".join(extra) + "\n")
            f.flush()
            lm.read_word_file(f.name)  # unigrams with count 1 for words no sentence has
    lm.compute()
    lm.sent_count = len(lines)  # for the header comment; ArpaBoLM leaves it at 0
    write_atomically(out_dir / LM_FILE, lm.write, overwrite=True)
    write_atomically(out_dir / DICT_FILE, lambda f: f.writelines(dict_lines), overwrite=True)
    return SpeechModel(out_dir / LM_FILE, out_dir / DICT_FILE, tuple(words))


@functools.lru_cache(maxsize=1)
def default_pronunciations() -> Pronunciations:
    """One Pronunciations for the process (reading cmudict takes a fraction of a second)."""
    return Pronunciations()


def default_cache_dir() -> Path:
    """$XDG_CACHE_HOME/magna/voice, or ~/.cache/magna/voice."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "magna" / "voice"


def model_key(sentences: Iterable[str], extra_words: Iterable[str] = (),
              pronunciations: Pronunciations | None = None) -> str:
    """A hash of everything the model files depend on: the cache directory's name."""
    lines, extra = _corpus(sentences, extra_words)
    p = pronunciations  # None: the defaults, without reading cmudict for a cache hit
    content = {"format": FORMAT_VERSION, "code": _SOURCE_HASH, "sentences": sorted(lines), "extra_words": extra,
               "acronyms": sorted(p.acronyms if p else ACRONYMS), "dictionary": str(p.dictionary if p else CMUDICT),
               "voice": p.voice if p else ESPEAK_VOICE, "espeak": p.espeak if p else "espeak-ng"}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:20]


def cached_speech_model(sentences: Iterable[str], extra_words: Iterable[str] = (), cache_dir: Path | str | None = None,
                        pronunciations: Pronunciations | None = None) -> SpeechModel:
    """The speech model of these sentences, built once into cache_dir/<content hash>/ and reused after."""
    sentences = list(sentences)
    extra_words = list(extra_words)
    directory = Path(cache_dir or default_cache_dir()) / model_key(sentences, extra_words, pronunciations)
    if (directory / LM_FILE).is_file() and (directory / DICT_FILE).is_file():
        lines, extra = _corpus(sentences, extra_words)
        words = tuple(sorted({w for line in lines for w in line.split()} | set(extra)))
        return SpeechModel(directory / LM_FILE, directory / DICT_FILE, words)
    return build_speech_model(sentences, directory, extra_words, pronunciations)
