#!/usr/bin/env python3
"""A running mission driven by the voice assistant, typed and spoken (voice_commands.test).

Gym/Operator_Control waits for the operator with both UAVs on their pads. Typed: "drone one,
please take off to two meters" must lift UAV 1 to about 2 m. Spoken: the test makes a WAV of
"drone one, go up two meters" with espeak-ng and runs the assistant node on it as an operator
would (rosrun magna_master voice --audio FILE); UAV 1 must climb 2 m more. A sentence without a
UAV gets a question and sends nothing; the battery is answered; "resume" lets the mission land:
UAV 1 comes down and the mission ends completed through its nominal landing.
"""
import os
import subprocess
import sys
import tempfile
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseStamped
from magna_msgs.msg import SMStatus

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


class VoiceCommands(unittest.TestCase):
    def test_typed_and_spoken_commands_fly_the_mission(self):
        seen = {"states": set(), "z": None, "end": ""}

        def on_status(msg):
            if msg.path == "/MISSION":
                seen["states"].update(msg.active_states)
                if msg.info.startswith("finished:"):
                    seen["end"] = msg.info

        rospy.Subscriber("/magna/sm/mission/status", SMStatus, on_status)
        rospy.Subscriber("/uav_1/ual/pose", PoseStamped, lambda msg: seen.update(z=msg.pose.position.z))
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

        ground = seen["z"]
        typed = assistant.handle_text("drone one, please take off to two meters")
        self.assertTrue(typed.reply and typed.reply.accepted, typed.to_json())
        self.assertEqual((sent[-1].action, sent[-1].agent), ("take_off", "1"))
        wall_wait(lambda: seen["z"] > ground + 1.7, "UAV 1 to take off to 2 m", 90)
        wall_wait(lambda: abs(seen["z"] - (ground + 2.0)) < 0.15, "UAV 1 to settle at 2 m", 60)

        before = seen["z"]
        with tempfile.TemporaryDirectory() as tmp:
            wav = os.path.join(tmp, "go_up.wav")
            synthesize_to_file("drone one, go up two meters", wav)
            spoken = subprocess.run(["rosrun", "magna_master", "voice", "--audio", wav, "--wait", "10"],
                                    capture_output=True, text=True, timeout=120)
        self.assertEqual(spoken.returncode, 0, spoken.stdout + spoken.stderr)
        self.assertIn("done:", spoken.stdout, spoken.stdout + spoken.stderr)
        self.assertIn("UAV 1: move (direction up, distance 2 m)", spoken.stdout)
        wall_wait(lambda: seen["z"] > before + 1.7, "UAV 1 to climb 2 m more", 90)

        battery = assistant.handle_text("what is the battery level of drone one")
        self.assertTrue(battery.reply.accepted, battery.to_json())
        self.assertEqual([v.name for v in battery.reply.values], ["uav_1.battery"])
        self.assertTrue(0 < battery.reply.values[0].number <= 100)

        self.assertTrue(assistant.handle_text("okay, carry on with the mission").reply.accepted)
        # resumed, the mission takes its nominal end: every UAV lands (UAV 1 comes down from 4 m; UAV 2
        # never left its pad), the CSVs are saved, the world deleted, and the mission ends completed
        wall_wait(lambda: seen["z"] < ground + 0.1, "UAV 1 to land", 90)
        wall_wait(lambda: seen["end"], "the mission to end", 90)
        self.assertEqual(seen["end"], "finished:completed")
        self.assertTrue({"1_land", "save_csv", "delete_world"} <= seen["states"], seen["states"])
        self.assertNotIn("1_safety_hover", seen["states"])


if __name__ == "__main__":
    rospy.init_node("voice_commands_rostest", disable_signals=True)
    rostest.rosrun("magna_master", "voice_commands_rostest", VoiceCommands)
