"""The voice assistant's three figures: typed exact-match, spoken exact-match, end-to-end latency.

Targets: typed >= 98 %, spoken (synthetic speech, offline recogniser) >= 90 %, latency <= 1.5 s from the
end of an utterance to the ground station receiving the command, on 2 cores.

- typed: every sentence of voice/testset/*.jsonl through the parser; exact match of the whole command.
- spoken: each sentence said by espeak-ng in the TEST_VOICES (voices and speeds), recognised offline,
  then parsed; side by side, the recogniser's best hypothesis alone and the n-best choice the assistant uses.
  Then commands in the phrasing the speech model was generated from (its templates, another seed).
- latency: a private ROS master with a stand-in /magna/gs/command that notes when a request arrives; each
  utterance is streamed in real time, 100 ms chunks, through the voice-activity detector, as from a
  microphone. Reported: from the end of speech (including the detector's silence wait) and from the end of
  the utterance as handed over (what a file or push-to-talk gives).

    python bench/voice_accuracy.py [--limit N] [--latency-n 20] [--sets commands held_out]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # `python bench/voice_accuracy.py` from any Python runs in the workspace (bench/README.md)
    sys.path.append(str(Path(__file__).resolve().parents[1] / "src" / "magna_common" / "src"))
    from magna_common.workspace_bootstrap import run_script_in_workspace

    run_script_in_workspace(__file__, modules=("numpy", "pocketsphinx", "magna_master"))

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from voice.assistant import choose_hypothesis  # noqa: E402
from voice.audio import SAMPLE_RATE, VoiceActivityDetector  # noqa: E402
from voice.evaluation import TEST_UAV_IDS, TESTSETS, describe, load_cases, matches  # noqa: E402
from voice.interpret import parse  # noqa: E402
from voice.speech import make_recognizer  # noqa: E402
from voice.synth import TEST_VOICES, synthesize  # noqa: E402

SILENCE_SECONDS = 0.8  # magna voice --mic's default: this much silence ends an utterance

try:
    from tqdm import tqdm
except ImportError:  # the bench still runs, without a bar
    def tqdm(iterable, **_):
        return iterable


def typed(sets):
    print("\n== typed sentences: exact match of the whole command (target >= 98 %)")
    print(f"{'set':<10} {'sentences':>9} {'exact':>7} {'rate':>7}")
    for name in sets:
        cases = load_cases(TESTSETS[name])
        good = sum(matches(parse(c.text, TEST_UAV_IDS)[1], c.expect) for c in cases)
        print(f"{name:<10} {len(cases):>9} {good:>7} {good / len(cases):>7.1%}")


def spoken(sets, limit, recognizer, show_misses):
    print("\n== spoken sentences (espeak-ng), offline recogniser: exact match of the whole command (target >= 90 %)")
    rows, misses, decode = [], [], []
    for name in sets:
        cases = load_cases(TESTSETS[name])[:limit] if limit else load_cases(TESTSETS[name])
        for voice, speed in TEST_VOICES:
            best_ok = chosen_ok = 0
            for case in tqdm(cases, desc=f"{name} {voice}@{speed}", leave=False):
                transcript = recognizer.transcribe(synthesize(case.text, voice=voice, speed=speed))
                decode.append(transcript.seconds)
                best_ok += matches(parse(transcript.text, TEST_UAV_IDS)[1], case.expect)
                chosen = choose_hypothesis([transcript.text, *transcript.alternatives], TEST_UAV_IDS)
                result = parse(chosen, TEST_UAV_IDS)[1]
                if matches(result, case.expect):
                    chosen_ok += 1
                else:
                    misses.append(f"  {voice}@{speed}: {case.text!r} heard {chosen!r} -> {describe(result)}")
            rows.append((name, f"{voice}@{speed}", len(cases), best_ok, chosen_ok))
    print(f"{'set':<10} {'voice@wpm':<14} {'n':>5} {'best hyp':>9} {'n-best':>8}")
    for name, voice, n, best_ok, chosen_ok in rows:
        print(f"{name:<10} {voice:<14} {n:>5} {best_ok / n:>9.1%} {chosen_ok / n:>8.1%}")
    total = sum(r[2] for r in rows)
    best, chosen = sum(r[3] for r in rows), sum(r[4] for r in rows)
    print(f"{'all':<10} {'':<14} {total:>5} {best / total:>9.1%} {chosen / total:>8.1%}"
          f"   (n-best / best ratio {chosen / max(best, 1):.3f})")
    print(f"decode time per utterance: p50 {statistics.median(decode):.3f} s, max {max(decode):.3f} s")
    if show_misses and misses:
        print(f"misses ({len(misses)}):")
        print("\n".join(misses[:show_misses]))


def spoken_known_phrasing(n, recognizer):
    """Commands in the phrasing the speech model was built from (corpus templates, another seed): the
    spoken command must equal the typed one."""
    from voice.corpus import labelled_sentences

    print("\n== spoken commands in the corpus's own phrasing (templates, seed 7): spoken command = typed command")
    pairs = labelled_sentences(per_template=3, seed=7)[::3][:n]
    rows = []
    for voice, speed in TEST_VOICES:
        good = 0
        for sentence, _ in tqdm(pairs, desc=f"templates {voice}@{speed}", leave=False):
            transcript = recognizer.transcribe(synthesize(sentence, voice=voice, speed=speed))
            chosen = choose_hypothesis([transcript.text, *transcript.alternatives], TEST_UAV_IDS)
            typed_result, spoken_result = parse(sentence, TEST_UAV_IDS)[1], parse(chosen, TEST_UAV_IDS)[1]
            good += typed_result == spoken_result
        rows.append((f"{voice}@{speed}", len(pairs), good))
    for voice, total, good in rows:
        print(f"{'templates':<10} {voice:<14} {total:>5} {good / total:>8.1%}")
    total, good = sum(r[1] for r in rows), sum(r[2] for r in rows)
    print(f"{'all':<10} {'':<14} {total:>5} {good / total:>8.1%}")


def latency(n, recognizer):
    from magna_common.ros_master import RosMaster

    print(f"\n== latency, end of utterance -> the ground station receives the command ({n} utterances, "
          "streamed in real time; target <= 1.5 s)")
    sentences = [c.text for c in load_cases(TESTSETS["commands"]) if c.expect != "question"][:n]
    with tempfile.TemporaryDirectory() as tmp, RosMaster(log_dir=Path(tmp)) as master:
        os.environ.update(master.env())
        import rospy
        from magna_msgs.srv import GroundStationCommand, GroundStationCommandResponse

        from voice.assistant import Assistant
        from voice.backend import GroundStationClient

        arrivals = []

        def stand_in(req):
            arrivals.append(time.monotonic())
            return GroundStationCommandResponse(True, "noted", [])

        rospy.init_node("voice_latency_bench", disable_signals=True)
        service = rospy.Service("/magna/gs/command", GroundStationCommand, stand_in)
        client = GroundStationClient()
        client.wait(10.0)
        assistant = Assistant(client.send, TEST_UAV_IDS, recognizer=recognizer)
        detector_wait = SILENCE_SECONDS
        from_speech, from_handover, decode = [], [], []
        for sentence in tqdm(sentences, desc="latency", leave=False):
            speech = synthesize(sentence)
            stream = np.concatenate([np.zeros(SAMPLE_RATE // 2, np.int16), speech,
                                     np.zeros(int(SAMPLE_RATE * (detector_wait + 1.0)), np.int16)])
            detector = VoiceActivityDetector(silence_seconds=SILENCE_SECONDS)
            chunk = SAMPLE_RATE // 10
            start = time.monotonic()
            speech_end = start + (SAMPLE_RATE // 2 + len(speech)) / SAMPLE_RATE
            before = len(arrivals)
            for offset in range(0, len(stream), chunk):
                due = start + (offset + chunk) / SAMPLE_RATE  # when a microphone would deliver this chunk
                time.sleep(max(0.0, due - time.monotonic()))
                utterances = detector.feed(stream[offset:offset + chunk])
                if utterances:
                    handed_over = time.monotonic()
                    outcome = assistant.handle_audio(utterances[0])
                    decode.append(outcome.transcript_seconds)
                    break
            if len(arrivals) > before:
                from_speech.append(arrivals[-1] - speech_end)
                from_handover.append(arrivals[-1] - handed_over)
        service.shutdown()
        rospy.signal_shutdown("bench done")
    sent = len(from_speech)
    print(f"commands that reached the stand-in: {sent} of {len(sentences)}")
    if sent:
        def row(name, xs):
            xs = sorted(xs)
            print(f"{name:<48} p50 {statistics.median(xs):.3f} s   p90 {xs[int(0.9 * (len(xs) - 1))]:.3f} s   "
                  f"max {xs[-1]:.3f} s")
        row(f"from the end of speech (silence wait {detector_wait:g} s incl.)", from_speech)
        row("from the utterance handed over (file, push-to-talk)", from_handover)
        row("of which offline decoding", decode)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sets", nargs="+", default=sorted(TESTSETS), choices=sorted(TESTSETS))
    parser.add_argument("--limit", type=int, default=0, help="spoken: the first N sentences of each set (0: all)")
    parser.add_argument("--latency-n", type=int, default=20, help="utterances for the latency figure")
    parser.add_argument("--show-misses", type=int, default=40, help="spoken misses to list")
    parser.add_argument("--templates", type=int, default=60,
                        help="spoken: commands in the corpus's own phrasing, per voice (0: skip)")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores; voices: {', '.join(f'{v}@{s}' for v, s in TEST_VOICES)}")
    typed(args.sets)
    built = time.monotonic()
    recognizer = make_recognizer(uav_ids=())
    print(f"\noffline recogniser ready in {time.monotonic() - built:.1f} s (speech model cached after the first run)")
    spoken(args.sets, args.limit, recognizer, args.show_misses)
    if args.templates:
        spoken_known_phrasing(args.templates, recognizer)
    latency(args.latency_n, recognizer)
    return 0


if __name__ == "__main__":
    sys.exit(main())
