#!/usr/bin/env python3
"""A running mission driven by the voice assistant, typed and spoken (voice_commands.test).

Gym/Operator_Control waits for the operator with both UAVs on their pads. Typed: "drone one,
please take off to two meters" must lift UAV 1 to about 2 m. Spoken: the test makes a WAV of
"drone one, climb two meters" with espeak-ng and runs the assistant node on it as an operator
would (rosrun magna_master voice --audio FILE YES), followed by a spoken "yes" for when the assistant
is unsure and asks "did you say ...?" (a blind yes: were the climb misheard, the wrong command would
fly and the test fail); UAV 1 must climb 2 m more. A sentence without a
UAV gets a question and sends nothing; the battery is answered; "resume" lets the mission land:
UAV 1 comes down and the mission ends completed through its nominal landing.

The answers tell the truth: an accepted command says what will happen ("UAV 1 taking off to 2 m",
"UAV 1 climbing to 4 m", from where the ground station sees the UAV), and a command the UAV cannot
do in its UAL state is refused saying why: UAV 2, on its pad all along, cannot move (typed to the
assistant node, rosrun magna_master voice, whose printed answer is checked); UAV 1 cannot move
before its take-off, cannot take off again once flying, and cannot move while it lands.
"""
import os
import re
import subprocess
import sys
import tempfile
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped
from magna_msgs.msg import SMStatus
from uav_abstraction_layer.msg import State as UalState

from magna_common.workspace import find_root

sys.path.append(str(find_root()))  # voice/ sits at the repository root

from voice.assistant import Assistant  # noqa: E402
from voice.backend import GroundStationClient  # noqa: E402
from voice.interpret import Question  # noqa: E402
from voice.synth import synthesize_to_file  # noqa: E402


def wall_wait(predicate, what, seconds):
    deadline = time.monotonic() + seconds
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {seconds:g} s waiting for {what}")
        time.sleep(0.05)


def said_height(pattern, text):
    """The number `pattern` captures in `text` (a height in metres); fails naming the text when it is not there."""
    found = re.search(pattern, text)
    if found is None:
        raise AssertionError(f"{pattern!r} not in {text!r}")
    return float(found.group(1))


def voice_node(*args, typed=None):
    """The assistant node as an operator runs it; its printed answers (stdout) and its exit status."""
    return subprocess.run(["rosrun", "magna_master", "voice", "--wait", "10", *args], input=typed,
                          capture_output=True, text=True, timeout=120)


class VoiceCommands(unittest.TestCase):
    def test_typed_and_spoken_commands_fly_the_mission(self):
        seen = {"states": set(), "z": None, "end": "", "ual": None, "landing_from": None}

        def on_status(msg):
            if msg.path == "/MISSION":
                seen["states"].update(msg.active_states)
                if msg.info.startswith("finished:"):
                    seen["end"] = msg.info

        rospy.Subscriber("/magna/sm/mission/status", SMStatus, on_status)
        rospy.Subscriber("/uav_1/ual/pose", PoseStamped, lambda msg: seen.update(z=msg.pose.position.z))

        def on_ual_state(msg):
            if msg.state == UalState.LANDING and seen["landing_from"] is None:
                seen["landing_from"] = seen["z"]
            seen["ual"] = msg.state

        rospy.Subscriber("/uav_1/ual/state", UalState, on_ual_state)
        wall_wait(lambda: "operator_control" in seen["states"], "the mission to wait for the operator", 120)
        client = GroundStationClient()
        client.wait(10.0)
        sent = []

        def send(command):
            sent.append(command)
            return client.send(command)

        assistant = Assistant(send, client.uav_ids())
        self.assertEqual(client.uav_ids(), [1, 2])

        asked = assistant.handle_text("take off to two meters")
        self.assertIsInstance(asked.result, Question)
        self.assertEqual(sent, [], "a sentence without a UAV must not send anything")

        # on their pads: no move (UAV 2's through the assistant node, whose printed answer is what the operator reads)
        pad = voice_node(typed="drone two, go up two meters\n")
        self.assertEqual(pad.returncode, 0, pad.stdout + pad.stderr)
        self.assertIn("UAV 2: move (direction up, distance 2 m)", pad.stdout)
        self.assertIn("refused: UAV 2 is on the ground, so it cannot move: take off first", pad.stdout,
                      pad.stdout + pad.stderr)
        grounded = assistant.handle_text("drone one, go up two meters")
        self.assertEqual((grounded.reply.accepted, grounded.reply.message),
                         (False, "UAV 1 is on the ground, so it cannot move: take off first"), grounded.to_json())

        ground = seen["z"]
        typed = assistant.handle_text("drone one, please take off to two meters")
        self.assertTrue(typed.reply and typed.reply.accepted, typed.to_json())
        self.assertEqual((sent[-1].action, sent[-1].agent), ("take_off", "1"))
        self.assertAlmostEqual(said_height(r"^UAV 1 taking off to (\S+) m$", typed.reply.message), ground + 2.0,
                               delta=0.15)
        wall_wait(lambda: seen["z"] > ground + 1.7, "UAV 1 to take off to 2 m", 90)
        wall_wait(lambda: abs(seen["z"] - (ground + 2.0)) < 0.15 and seen["ual"] == UalState.FLYING_AUTO,
                  "UAV 1 to settle at 2 m, flying", 60)
        again = assistant.handle_text("drone one, take off")
        self.assertEqual((again.reply.accepted, again.reply.message),
                         (False, "UAV 1 is already flying, so it cannot take off"), again.to_json())

        before = seen["z"]
        with tempfile.TemporaryDirectory() as tmp:
            wav, yes = os.path.join(tmp, "go_up.wav"), os.path.join(tmp, "yes.wav")
            synthesize_to_file("drone one, climb two meters", wav)
            synthesize_to_file("yes", yes)  # the answer if the assistant asks "did you say ...?"
            spoken = voice_node("--audio", wav, yes)
        self.assertEqual(spoken.returncode, 0, spoken.stdout + spoken.stderr)
        self.assertIn("UAV 1: move (direction up, distance 2 m)", spoken.stdout)
        self.assertNotIn("refused", spoken.stdout, spoken.stdout + spoken.stderr)
        self.assertAlmostEqual(said_height(r"(?m)^UAV 1 climbing to (\S+) m$", spoken.stdout), before + 2.0,
                               delta=0.15)
        wall_wait(lambda: seen["z"] > before + 1.7, "UAV 1 to climb 2 m more", 90)

        battery = assistant.handle_text("what is the battery level of drone one")
        self.assertTrue(battery.reply.accepted, battery.to_json())
        self.assertEqual([v.name for v in battery.reply.values], ["uav_1.battery"])
        self.assertTrue(0 < battery.reply.values[0].number <= 100)

        resumed = assistant.handle_text("okay, carry on with the mission")
        self.assertEqual((resumed.reply.accepted, resumed.reply.message), (True, "mission resumed"),
                         resumed.to_json())
        # resumed, the mission takes its nominal end: every UAV lands (UAV 1 comes down from 4 m; UAV 2
        # never left its pad), the CSVs are saved, the world deleted, and the mission ends completed.
        # Once UAV 1 is well into its landing (0.3 m down: the ground station has heard LANDING too), a move is
        # refused, and the landing goes on.
        wall_wait(lambda: seen["landing_from"] is not None and seen["ual"] == UalState.LANDING
                  and seen["z"] < seen["landing_from"] - 0.3, "UAV 1 to be landing", 90)
        landing = assistant.handle_text("drone one, go up one meter")
        self.assertEqual((landing.reply.accepted, landing.reply.message),
                         (False, "UAV 1 is landing, so it cannot move"), landing.to_json())
        wall_wait(lambda: seen["z"] < ground + 0.1, "UAV 1 to land", 90)
        wall_wait(lambda: seen["end"], "the mission to end", 90)
        self.assertEqual(seen["end"], "finished:completed")
        self.assertTrue({"1_land", "save_csv", "delete_world"} <= seen["states"], seen["states"])
        self.assertNotIn("1_safety_hover", seen["states"])


if __name__ == "__main__":
    rospy.init_node("voice_commands_rostest", disable_signals=True)
    rostest.rosrun("magna_master", "voice_commands_rostest", VoiceCommands)
