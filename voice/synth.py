"""Speech synthesis with espeak-ng: synthetic test speech for the recogniser, and spoken answers.

espeak-ng is a Debian package (`make setup` installs it); it is called as a subprocess, the text always on stdin
so that a sentence starting with "-" is never taken for an option.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from voice.audio import decode_wav, write_wav

ESPEAK = "espeak-ng"

# American-English voices and speeds (words per minute) for the synthetic speech test set: different variants
# (male, female, pitch, timbre) and rates, so a recogniser tuned on one voice is caught out by the others.
# Each was checked with `espeak-ng --voices=variant` and `espeak-ng -v en-us+f2 "test" -w /tmp/x.wav`.
TEST_VOICES: tuple[tuple[str, int], ...] = (
    ("en-us", 150),
    ("en-us+m3", 175),
    ("en-us+f2", 140),
    ("en-us+m7", 165),
)


class SynthError(RuntimeError):
    """espeak-ng is missing or refused the request; the message says what to do."""


def _espeak() -> str:
    path = shutil.which(ESPEAK)
    if path is None:
        raise SynthError("espeak-ng not found: install espeak-ng (make setup)")
    return path


def _options(voice: str, speed: int, pitch: int | None) -> list[str]:
    options = ["-v", voice, "-s", str(int(speed))]
    if pitch is not None:
        options += ["-p", str(int(pitch))]
    return options


def synthesize(text: str, voice: str = "en-us", speed: int = 160, pitch: int | None = None) -> np.ndarray:
    """`text` spoken by espeak-ng -> int16 mono at 16 kHz (espeak-ng itself emits 22050 Hz)."""
    if not text.strip():
        raise ValueError("synthesize: nothing to say (empty text)")
    command = [_espeak(), *_options(voice, speed, pitch), "--stdout"]
    try:
        done = subprocess.run(command, input=text.encode(), capture_output=True, timeout=60, check=False)
    except subprocess.TimeoutExpired:
        raise SynthError(f"espeak-ng took over 60 s to synthesize {text[:40]!r}") from None
    if done.returncode != 0 or not done.stdout:
        message = done.stderr.decode(errors="replace").strip() or f"exit status {done.returncode}"
        raise SynthError(f"espeak-ng -v {voice}: {message} (`espeak-ng --voices=variant` lists the variants)")
    return decode_wav(done.stdout, name=f"espeak-ng output for {text[:40]!r}")


def synthesize_to_file(text: str, path, **kw) -> Path:
    """synthesize() written as a 16 kHz mono 16-bit WAV (atomically)."""
    return write_wav(path, synthesize(text, **kw))


def _no_output_device() -> str | None:
    """Why nothing can be played, or None if an output device exists (or we cannot tell without PortAudio)."""
    try:
        import sounddevice
    except (ImportError, OSError):
        return None  # no PortAudio to ask: let espeak-ng try its own audio backend
    try:
        if any(d.get("max_output_channels", 0) > 0 for d in sounddevice.query_devices()):
            return None
    except Exception:
        pass
    return "no audio output device found"


def speak(text: str, voice: str = "en-us", speed: int = 160) -> bool:
    """Say `text` aloud; True if it was played.

    Never raises or hangs for want of a loudspeaker: the assistant's spoken answers are a convenience, the
    printed ones are the record. On failure it prints why on stderr and returns False.
    """
    if not text.strip():
        return False
    reason = _no_output_device()
    if reason is None:
        try:
            command = [_espeak(), *_options(voice, speed, None)]
            # A generous limit (about 3x speaking time): a blocked sound server must not freeze the assistant.
            done = subprocess.run(command, input=text.encode(), capture_output=True, check=False,
                                  timeout=10 + 0.2 * len(text))
            stderr = done.stderr.decode(errors="replace")
            # espeak-ng exits 0 even when ALSA has no card, so its stderr is the only sign of failure.
            if done.returncode == 0 and "error" not in stderr.lower():
                return True
            reason = stderr.strip().splitlines()[-1] if stderr.strip() else f"espeak-ng exit {done.returncode}"
        except SynthError as error:
            reason = str(error)
        except subprocess.TimeoutExpired:
            reason = "espeak-ng did not finish playing (sound server blocked?)"
    print(f"cannot speak {text[:40]!r}: {reason}", file=sys.stderr)
    return False
