"""`magna voice` and `python -m voice`: command a running mission by voice or keyboard.

The same program as `rosrun magna_master voice`; examples in voice/README.md.

    magna voice [--keyboard | --mic | --audio FILE...]   the assistant (keyboard by default)
    magna voice parse "SENTENCE" ...                     one JSON line per sentence: entities, command or question
    magna voice transcribe FILE.wav ...                  the transcript and the same JSON
"""
from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

from magna_common import ros_names
from magna_common.cli_vocabulary import add_output

HELP = "command a running mission by voice or keyboard, offline: assistant, parse, transcribe"
PROMPT = "magna voice> "
TRANSCRIBE_HYPOTHESES = 5  # of the n-best, the ones `transcribe` prints


class CliError(Exception):
    """Bad input: printed as `magna voice: <message>`, exit status 2."""


def _check_confirmation(args) -> None:
    if not 0.0 <= args.confirm_below <= 1.01:
        raise CliError(f"--confirm-below {args.confirm_below:g}: give a confidence from 0 (never ask) to 1.01 "
                       "(always ask)")
    if args.confirm_seconds <= 0:
        raise CliError(f"--confirm-seconds {args.confirm_seconds:g}: give a positive number of seconds")


def _uav_ids(text: str | None) -> list[int]:
    if not text:
        return []
    try:
        ids = [int(part) for part in text.replace(",", " ").split()]
    except ValueError:
        raise CliError(f"--uavs {text!r}: give UAV ids separated by commas, e.g. --uavs 1,2,3") from None
    if any(i <= 0 for i in ids):
        raise CliError(f"--uavs {text!r}: UAV ids are positive integers")
    return ids


def _recognizer(args, uav_ids):
    from voice.speech import make_recognizer

    return make_recognizer(online=args.online, uav_ids=uav_ids)


def _existing_files(paths: list[str]) -> list[Path]:
    files = [Path(p) for p in paths]
    missing = [str(p) for p in files if not p.is_file()]
    if missing:
        raise CliError(f"no such audio file: {', '.join(missing)}")
    return files


def cmd_parse(args) -> int:
    from voice.interpret import parse

    sentences = args.sentences
    if sentences == ["-"]:
        sentences = [line.strip() for line in sys.stdin if line.strip()]
    if not sentences:
        raise CliError("give at least one sentence, or - to read them from standard input")
    ids = _uav_ids(args.uavs)
    for sentence in sentences:
        understanding, result = parse(sentence, ids)
        print(json.dumps(_line(sentence, understanding, result)), flush=True)
    return 0


def _line(text, understanding, result) -> dict:
    from voice.interpret import Command, wit_entities

    is_command = isinstance(result, Command)
    return {"text": text, "entities": wit_entities(understanding, result),
            "command": result.to_json() if is_command else None,
            "question": None if is_command else result.to_json()}


def cmd_transcribe(args) -> int:
    from voice.audio import read_wav
    from voice.interpret import parse
    from voice.rescoring import rescore

    files = _existing_files(args.files)
    ids = _uav_ids(args.uavs)
    recognizer = _recognizer(args, ids)
    for path in files:
        transcript = recognizer.transcribe(read_wav(path))
        hearing = rescore(transcript.alternatives or [transcript.text], transcript.scores, ids)
        understanding, result = parse(hearing.text, ids)
        line = {"file": str(path), "transcript": transcript.text, **_line(hearing.text, understanding, result),
                "confidence": round(hearing.confidence, 3),
                "hypotheses": [{"text": h.text, "confidence": round(h.confidence, 3), "grammatical": h.grammatical}
                               for h in hearing.hypotheses[:TRANSCRIBE_HYPOTHESES]],
                "decode_seconds": round(transcript.seconds, 3)}
        print(json.dumps(line), flush=True)
    return 0


def _assistant(args, ids, recognizer=None):
    from voice.assistant import Assistant

    say = None
    if args.speak:
        from voice.synth import speak as say
    options = {"confirm_seconds": args.confirm_seconds, "confirm_threshold": args.confirm_below}
    if args.dry_run:
        return Assistant(None, ids, say, recognizer, **options)
    from voice.backend import GroundStationClient

    print(f"waiting for the ground station ({args.service}) ...", file=sys.stderr)
    client = GroundStationClient(args.service, master_wait=args.wait)  # the mission may still be starting
    client.wait(args.wait)
    if not ids:  # the UAVs the mission flies; it may still be spawning them
        print(f"waiting for the mission's UAVs ({ros_names.UAL_IDS}) ...", file=sys.stderr)
        ids = client.wait_for_uavs(args.wait)
        if not ids:
            print(f"no UAVs in {ros_names.UAL_IDS} after {args.wait:g} s: questions will not offer UAV ids "
                  "(--uavs gives them)", file=sys.stderr)
    return Assistant(client.send, ids, say, recognizer, **options)


def cmd_assistant(args) -> int:
    from voice.assistant import render
    from voice.backend import BackendError

    ids = _uav_ids(args.uavs)
    _check_confirmation(args)
    audio = args.mic or args.audio
    if args.mic:  # fail early and clearly when there is no microphone
        from voice.audio import NoAudioDevice, list_input_devices

        if not list_input_devices():
            raise CliError(str(NoAudioDevice("no audio input device found: plug in a microphone, or use --keyboard "
                                             "(type the sentences) or --audio FILE.wav")))
    try:
        assistant = _assistant(args, ids)
    except BackendError as error:
        raise CliError(str(error)) from None
    if audio:  # made for the UAVs the mission flies (learnt from the ground station without --uavs)
        assistant.recognizer = _recognizer(args, assistant.uav_ids)
    if args.audio:
        from voice.audio import read_wav

        for path in _existing_files(args.audio):
            print(render(assistant.handle_audio(read_wav(path))), flush=True)
        return 0
    _watch_confirmations(assistant)
    if args.mic:
        return _listen(args, assistant)
    return _keyboard(assistant)


def _watch_confirmations(assistant) -> None:
    """Say so when a "did you say ...?" goes unanswered for --confirm-seconds (the command is dropped)."""
    from voice.assistant import render

    def watch():
        while True:
            time.sleep(0.25)
            outcome = assistant.expire()
            if outcome is not None:
                print(render(outcome), flush=True)

    threading.Thread(target=watch, name="confirmation-timeout", daemon=True).start()


def _keyboard(assistant) -> int:
    from voice.assistant import render

    interactive = sys.stdin.isatty()
    if interactive:
        print("Type a command (e.g. 'drone one, take off to three meters'); 'quit' or Ctrl-D ends.")
    while True:
        try:
            line = input(PROMPT) if interactive else sys.stdin.readline()
        except EOFError:
            return 0
        if not interactive and not line:
            return 0
        line = line.strip()
        if line.lower() in ("quit", "exit"):
            return 0
        if line:
            print(render(assistant.handle_text(line)), flush=True)


def _listen(args, assistant) -> int:
    from voice.assistant import render
    from voice.audio import VoiceActivityDetector, listen, microphone_chunks

    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    detector = VoiceActivityDetector(silence_seconds=args.silence)
    print(f"listening (utterances saved in {out_dir}); Ctrl-C ends", file=sys.stderr)
    for path, samples in listen(microphone_chunks(device=args.device), detector, out_dir):
        print(f"[{path.name}]", flush=True)
        print(render(assistant.handle_audio(samples)), flush=True)
    return 0


MISSION_LAUNCH = ("roslaunch magna_gs simulation.launch mission_file:=$PWD/missions/Gym/Operator_Control.json \\\n"
                  "      world:=Gym subworld:=Central_Obstacle_Torus rtf:=1.0")

EXAMPLES = f"""\
examples:
  magna voice parse "drone two, go up five meters" "land"    # one JSON line per sentence; no ROS needed
  magna voice --dry-run --uavs 1,2    # type commands: understood and printed, nothing sent [background]
  {MISSION_LAUNCH}    # a mission waiting for the operator (with devel/setup.bash sourced) [background]
  magna voice    # type commands to it; 'quit' or Ctrl-D ends
  magna voice --mic --speak    # speak them; questions and answers are spoken back [microphone]
  magna voice transcribe FILE.wav    # e.g. a WAV made by espeak-ng -w FILE.wav "drone one land" [synopsis]
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EXAMPLES
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--keyboard", action="store_true", help="type sentences (the default)")
    source.add_argument("--mic", action="store_true", help="listen to the microphone (voice-activity detection)")
    source.add_argument("--audio", nargs="+", metavar="FILE.wav", help="take the utterances from WAV files")
    parser.add_argument("--online", action="store_true",
                        help="use Google's online recogniser instead of the offline one (needs internet)")
    parser.add_argument("--speak", action="store_true", help="speak questions and answers back with espeak-ng")
    parser.add_argument("--dry-run", action="store_true", help="understand and print, send nothing (no ROS needed)")
    parser.add_argument("--uavs", metavar="IDS", help=f"UAV ids, e.g. 1,2,3 (default: the ids in {ros_names.UAL_IDS})")
    parser.add_argument("--service", default=ros_names.GS_COMMAND, help="the ground station's command service")
    parser.add_argument("--wait", type=float, default=30.0, metavar="S",
                        help="seconds to wait for each of: the ROS master, the ground station's service and "
                             "(without --uavs) the mission's UAVs (default %(default)g)")
    from voice.assistant import CONFIRM_SECONDS, CONFIRM_THRESHOLD

    parser.add_argument("--confirm-below", type=float, default=CONFIRM_THRESHOLD, metavar="C",
                        help="spoken commands that move aircraft or change the mission are confirmed when the "
                             "recogniser's confidence is below C (0..1; 1.01 confirms every one; default %(default)g, "
                             "calibrated: voice/README.md)")

    parser.add_argument("--confirm-seconds", type=float, default=CONFIRM_SECONDS, metavar="S",
                        help="seconds to answer \"did you say ...?\" before the command is dropped "
                             "(default %(default)g)")
    parser.add_argument("--device", default=None, help="microphone: a sounddevice input device (index or name)")
    parser.add_argument("--silence", type=float, default=0.8, metavar="S",
                        help="microphone: seconds of silence that end an utterance")
    add_output(parser, metavar="DIR", default=Path("voice_utterances"), old=("--utterances",),
               help="microphone: the folder each utterance is saved to as a WAV, numbered after the files there "
                    "(default: voice_utterances)")
    parser.set_defaults(_voice=cmd_assistant)
    sub = parser.add_subparsers(dest="voice_command", metavar="{parse,transcribe}")
    parse_p = sub.add_parser("parse", help="print the entities and the command (or question) of each sentence",
                             description="One JSON line per sentence: entities with confidences, and the "
                                         "ground-station command it maps to or the question it would ask back.",
                             formatter_class=argparse.RawDescriptionHelpFormatter,
                             epilog="examples:\n"
                                    "  magna voice parse \"drone two, go up five meters\" \"land\"\n"
                                    "  magna voice parse \"land now\" --uavs 1,2    # a question: which UAV?\n")
    parse_p.add_argument("sentences", nargs="*", help="sentences; - reads one per line from standard input")
    parse_p.add_argument("--uavs", metavar="IDS", help="UAV ids the questions offer, e.g. 1,2,3")
    parse_p.set_defaults(_voice=cmd_parse)
    trans = sub.add_parser("transcribe", help="transcribe WAV files and print the transcript and the same JSON",
                           description="Speech to text (offline by default), then the same JSON as parse.",
                           formatter_class=argparse.RawDescriptionHelpFormatter,
                           epilog="examples:\n"
                                  "  magna voice transcribe FILE.wav    # voice/README.md makes one with espeak-ng "
                                  "[synopsis]\n")
    trans.add_argument("files", nargs="+", metavar="FILE.wav")
    trans.add_argument("--online", action="store_true", help="Google's online recogniser (needs internet)")
    trans.add_argument("--uavs", metavar="IDS", help="UAV ids the speech model expects (default 1..9)")
    trans.set_defaults(_voice=cmd_transcribe)


def run(args) -> int:
    try:
        return args._voice(args)
    except CliError as error:
        print(f"magna voice: {error}", file=sys.stderr)
        return 2
    except Exception as error:  # the frontend's and recogniser's errors carry their own clear message
        from voice.errors import USER_ERRORS

        if isinstance(error, USER_ERRORS):
            print(f"magna voice: {error}", file=sys.stderr)
            return 2
        raise


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m voice", description=HELP)  # `magna voice` is the same
    add_arguments(parser)
    return run(parser.parse_args(argv))
