"""The voice assistant's figures: typed and spoken exact-match, wrong actions sent unasked, end-to-end latency.

Targets: spoken exact match on the held-out set >= 90 % clean and >= 80 % at 10 dB SNR; wrong actions sent
without a confirmation question <= 0.5 % of utterances; latency <= 1.5 s p50 from the end of an utterance to
the ground station receiving the command, on 2 cores.

- typed: every sentence of voice/testset/*.jsonl through the parser; exact match of the whole command.
- spoken: each sentence of the frozen held-out set said by espeak-ng in the TEST_VOICES (voices and speeds),
  clean and with white noise at 20 and 10 dB SNR, recognised offline; side by side, the recogniser's best
  hypothesis alone and the rescored n-best the assistant uses, how often it asks to confirm and how often a
  wrong action would be sent without asking. --calibrate first prints the threshold's table on the tuning sets.
- latency: a private ROS master with a stand-in /magna/gs/command that notes when a request arrives; each
  utterance is streamed in real time, 100 ms chunks, through the voice-activity detector, as from a
  microphone. Reported: from the end of speech (including the detector's silence wait) and from the end of
  the utterance as handed over (what a file or push-to-talk gives).

    python bench/voice_accuracy.py [--calibrate] [--latency-n 20] [--sets commands fresh]
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

from voice.assistant import ACTING_ACTIONS, CONFIRM_THRESHOLD  # noqa: E402
from voice.audio import SAMPLE_RATE, VoiceActivityDetector, add_noise  # noqa: E402
from voice.evaluation import HELD_OUT, TEST_UAV_IDS, TESTSETS, describe, load_cases, matches  # noqa: E402
from voice.interpret import Command, parse  # noqa: E402
from voice.rescoring import rescore  # noqa: E402
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
    print(f"{'set':<16} {'sentences':>9} {'exact':>7} {'rate':>7}")
    for name in sets:
        cases = load_cases(TESTSETS.get(name, HELD_OUT))
        good = sum(matches(parse(c.text, TEST_UAV_IDS)[1], c.expect) for c in cases)
        print(f"{name:<16} {len(cases):>9} {good:>7} {good / len(cases):>7.1%}")


CONDITIONS = (("clean", None), ("20 dB", 20.0), ("10 dB", 10.0))  # white noise at this SNR (voice.audio.add_noise)


def hear(recognizer, case, voice, speed, snr, seed):
    """(the Hearing of one spoken case, decode seconds)."""
    audio = synthesize(case.text, voice=voice, speed=speed)
    if snr is not None:
        audio = add_noise(audio, snr, seed=seed)
    transcript = recognizer.transcribe(audio)
    return rescore(transcript.alternatives or [transcript.text], transcript.scores, TEST_UAV_IDS), transcript.seconds


def spoken_trials(recognizer, cases, conditions, label):
    """One trial per case, voice and condition: (condition, voice, case, Hearing, exact, best-hypothesis exact)."""
    trials, decode = [], []
    for condition, snr in conditions:
        for voice, speed in TEST_VOICES:
            for n, case in enumerate(tqdm(cases, desc=f"{label} {condition} {voice}@{speed}", leave=False)):
                hearing, seconds = hear(recognizer, case, voice, speed, snr, seed=n)
                decode.append(seconds)
                best = hearing.hypotheses[0].result
                exact = matches(hearing.chosen.result, case.expect)
                trials.append((condition, f"{voice}@{speed}", case, hearing, exact, matches(best, case.expect)))
    return trials, decode


def sent_unasked(hearing, threshold) -> bool:
    """Would the assistant send this without a question? (queries always; acting commands above the threshold)"""
    result = hearing.chosen.result
    return isinstance(result, Command) and (result.action not in ACTING_ACTIONS or hearing.confidence >= threshold)


def wrong_unasked(trial, threshold) -> bool:
    """A command that moves aircraft or changes the mission, not the one said, sent without a question."""
    _, _, _, hearing, exact, _ = trial
    result = hearing.chosen.result
    return (not exact and isinstance(result, Command) and result.action in ACTING_ACTIONS
            and hearing.confidence >= threshold)


def spoken(recognizer, show_misses):
    cases = load_cases(HELD_OUT)
    print(f"\n== spoken held-out set ({len(cases)} sentences, frozen; never tuned on), espeak-ng, offline recogniser")
    print("   exact match of the whole command (target >= 90 % clean, >= 80 % at 10 dB SNR); wrong actions sent "
          f"without a question at the confirmation threshold {CONFIRM_THRESHOLD:g} (target <= 0.5 %)")
    trials, decode = spoken_trials(recognizer, cases, CONDITIONS, "held-out")
    print(f"{'condition':<10} {'voice@wpm':<14} {'n':>5} {'best hyp':>9} {'rescored':>9} {'asked':>7} "
          f"{'wrong sent':>11}")
    for condition, _ in CONDITIONS:
        for voice in [*(f"{v}@{s}" for v, s in TEST_VOICES), "all"]:
            rows = [t for t in trials if t[0] == condition and (voice == "all" or t[1] == voice)]
            n = len(rows)
            asked = sum(isinstance(t[3].chosen.result, Command) and not sent_unasked(t[3], CONFIRM_THRESHOLD)
                        for t in rows)
            print(f"{condition:<10} {voice:<14} {n:>5} {sum(t[5] for t in rows) / n:>9.1%} "
                  f"{sum(t[4] for t in rows) / n:>9.1%} {asked / n:>7.1%} "
                  f"{sum(wrong_unasked(t, CONFIRM_THRESHOLD) for t in rows) / n:>11.2%}")
    wrong = sum(wrong_unasked(t, CONFIRM_THRESHOLD) for t in trials)
    print(f"all conditions: wrong actions sent without a question {wrong} of {len(trials)} utterances "
          f"({wrong / len(trials):.2%})")
    print(f"decode time per utterance: p50 {statistics.median(decode):.3f} s, max {max(decode):.3f} s")
    misses = [t for t in trials if not t[4]]
    if show_misses and misses:
        print(f"misses ({len(misses)}), the first {min(show_misses, len(misses))}:")
        for condition, voice, case, hearing, _, _ in misses[:show_misses]:
            print(f"  {condition} {voice}: {case.text!r} heard {hearing.text!r} -> {describe(hearing.chosen.result)} "
                  f"(confidence {hearing.confidence:.2f})")


def calibrate(recognizer, sets, every):
    """The confirmation threshold from the tuning sets (never the held-out one): wrong actions sent unasked and
    questions asked, for each threshold, clean and at 10 dB."""
    cases = [c for name in sets for c in load_cases(TESTSETS[name])[::every]]
    print(f"\n== calibration of the confirmation threshold on {', '.join(sets)} ({len(cases)} sentences, "
          "clean and 10 dB)")
    trials, _ = spoken_trials(recognizer, cases, (CONDITIONS[0], CONDITIONS[2]), "calibration")
    acting = [t for t in trials
              if isinstance(t[3].chosen.result, Command) and t[3].chosen.result.action in ACTING_ACTIONS]
    print(f"{'threshold':>9} {'wrong sent':>11} {'asked':>7} {'right sent':>11}   (shares of {len(trials)} utterances)")
    chosen = None
    for threshold in (0.0, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.01):
        wrong = sum(wrong_unasked(t, threshold) for t in trials) / len(trials)
        asked = sum(t[3].confidence < threshold for t in acting) / len(trials)
        right = sum(t[4] and t[3].confidence >= threshold for t in acting) / len(trials)
        print(f"{threshold:>9.2f} {wrong:>11.2%} {asked:>7.1%} {right:>11.1%}")
        if chosen is None and wrong <= 0.005:
            chosen = threshold
    print(f"lowest threshold with wrong actions sent <= 0.5 %: {chosen} (voice.assistant.CONFIRM_THRESHOLD is "
          f"{CONFIRM_THRESHOLD:g})")


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
            chosen = rescore(transcript.alternatives or [transcript.text], transcript.scores, TEST_UAV_IDS).text
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
        # every command is sent (no confirmation question): this measures the pipeline's speed
        assistant = Assistant(client.send, TEST_UAV_IDS, recognizer=recognizer, confirm_threshold=0.0)
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
    parser.add_argument("--sets", nargs="+", default=sorted(TESTSETS), choices=sorted(TESTSETS),
                        help="typed sets, and the tuning sets of --calibrate")
    parser.add_argument("--calibrate", action="store_true",
                        help="also print the confirmation threshold's table on the tuning sets (--sets)")
    parser.add_argument("--every", type=int, default=2, help="--calibrate: every Nth sentence of each tuning set")
    parser.add_argument("--latency-n", type=int, default=20, help="utterances for the latency figure")
    parser.add_argument("--show-misses", type=int, default=40, help="spoken misses to list")
    parser.add_argument("--templates", type=int, default=0,
                        help="spoken: commands in the corpus's own phrasing, per voice (0: skip)")
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores; voices: {', '.join(f'{v}@{s}' for v, s in TEST_VOICES)}")
    typed([*args.sets, "spoken_held_out"])
    built = time.monotonic()
    recognizer = make_recognizer(uav_ids=TEST_UAV_IDS)
    print(f"\noffline recogniser ready in {time.monotonic() - built:.1f} s (speech model cached after the first run)")
    if args.calibrate:
        calibrate(recognizer, args.sets, args.every)
    spoken(recognizer, args.show_misses)
    if args.templates:
        spoken_known_phrasing(args.templates, recognizer)
    latency(args.latency_n, recognizer)
    return 0


if __name__ == "__main__":
    sys.exit(main())
