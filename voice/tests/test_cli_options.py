"""`magna voice`'s options follow the one CLI vocabulary (-o/--output for the folder it writes), the old
spelling still works for a release, and the assistant waits for a mission that is still starting."""
import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

from magna_common.cli_vocabulary import deprecation_line
from tests.support import ROOT
from voice import cli

PROG = "magna voice"


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=PROG)
    cli.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_the_utterances_folder_is_the_output(capsys):
    assert parse("--mic").output == Path("voice_utterances")
    assert parse("--mic", "-o", "said").output == Path("said")
    assert parse("--mic", "--output", "said").output == Path("said")
    assert capsys.readouterr().err == ""


def test_the_old_spelling_still_works_with_one_line(capsys):
    assert parse("--mic", "--utterances", "said").output == Path("said")
    assert capsys.readouterr().err.splitlines() == [deprecation_line(PROG, "--utterances", "-o/--output")]


@pytest.mark.parametrize("option,value,fix", [("--confirm-below", "2", "from 0 (never ask) to 1.01"),
                                               ("--confirm-seconds", "0", "a positive number of seconds")])
def test_a_bad_confirmation_setting_is_refused_with_its_fix(capsys, option, value, fix):
    assert cli.run(parse("--dry-run", option, value)) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"magna voice: {option} {value}: ") and fix in err


def test_the_confirmation_settings_reach_the_assistant():
    from voice.assistant import CONFIRM_SECONDS, CONFIRM_THRESHOLD

    default = cli._assistant(parse("--dry-run"), [1])
    assert (default.confirm_threshold, default.confirm_seconds) == (CONFIRM_THRESHOLD, CONFIRM_SECONDS)
    chosen = cli._assistant(parse("--dry-run", "--confirm-below", "1.01", "--confirm-seconds", "4"), [1])
    assert (chosen.confirm_threshold, chosen.confirm_seconds) == (1.01, 4.0)


def test_the_recogniser_is_made_for_the_uavs_the_assistant_commands(monkeypatch, tmp_path):
    """Its grammar and language model name those UAVs (the mission's, from the ground station, without --uavs)."""
    import voice.speech

    made_for = []

    class Deaf:
        def transcribe(self, samples):
            from voice.stt import Transcript

            return Transcript("", [], 0.0)

    monkeypatch.setattr(voice.speech, "make_recognizer",
                        lambda online=False, uav_ids=(), cache_dir=None: made_for.append(list(uav_ids)) or Deaf())
    wav = tmp_path / "quiet.wav"
    import numpy as np

    from voice.audio import write_wav

    write_wav(wav, np.zeros(1600, dtype=np.int16))
    assert cli.run(parse("--dry-run", "--uavs", "1,2", "--audio", str(wav))) == 0
    assert made_for == [[1, 2]]


def test_every_help_has_examples_that_name_commands_that_exist():
    parser = argparse.ArgumentParser(prog=PROG)
    cli.add_arguments(parser)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for help_text in (parser.format_help(), sub.choices["parse"].format_help(),
                      sub.choices["transcribe"].format_help()):
        examples = help_text.split("\nexamples:\n", 1)[1].splitlines()
        starts = [line.split()[0] for line in examples if line.strip() and not line.startswith("      ")]
        assert starts and set(starts) <= {"magna", "roslaunch"}, examples


STAND_IN_GS = """
import rospy
from magna_common import ros_names
from magna_msgs.srv import GroundStationCommand, GroundStationCommandResponse

rospy.init_node("stand_in_ground_station")
rospy.Service(ros_names.GS_COMMAND, GroundStationCommand,
              lambda req: GroundStationCommandResponse(True, f"{req.action} for UAV {req.agent}", []))
rospy.spin()
"""


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_the_assistant_waits_for_a_mission_that_is_still_starting(tmp_path):
    from magna_common.ports import free_port
    from magna_common.ros_master import RosMaster

    # the fixtures' RosMaster, started by hand: the master must come up after the assistant, on a port known before
    port = free_port()
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{port}", "ROS_IP": "127.0.0.1"}
    voice = subprocess.Popen([sys.executable, "-m", "voice", "--wait", "120", "--uavs", "1"], cwd=ROOT, env=env,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    master = RosMaster(port=port, log_dir=tmp_path / "ros")
    try:
        # the assistant is up and waiting before any master exists, as when started beside roslaunch
        assert voice.stderr.readline().startswith("waiting for the ground station (/magna/gs/command)")
        with master:
            master.spawn([sys.executable, "-c", STAND_IN_GS])
            out, err = voice.communicate("drone one land\n", timeout=180)
    finally:
        if voice.poll() is None:
            voice.kill()
            voice.wait()
    assert voice.returncode == 0, err
    assert "land for UAV 1" in out and "refused" not in out


SPAWNING_GS = """
import json, sys
import rospy
from magna_common import ros_names
from magna_msgs.srv import GroundStationCommand, GroundStationCommandResponse

log, asked = open(sys.argv[1], "a"), []

def answer(req):
    names = [p.name for p in req.parameters]
    asked.append(req.action)
    if req.action == "get" and names == ["position"] and asked.count("get") <= 2:
        ok, message = False, "UAV 1 has not reported a pose yet"  # a mission still spawning its UAVs
    else:
        ok, message = True, f"{req.action} for UAV {req.agent}"
    log.write(json.dumps([req.action, req.agent, names, ok]) + "\\n")
    log.flush()
    return GroundStationCommandResponse(ok, message, [])

rospy.init_node("spawning_ground_station")
rospy.set_param(ros_names.UAL_IDS, [1, 2])
rospy.Service(ros_names.GS_COMMAND, GroundStationCommand, answer)
rospy.spin()
"""


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_without_uav_ids_the_assistant_waits_until_the_ground_station_knows_where_they_are(fresh_ros_master,
                                                                                             tmp_path):
    import json

    log = tmp_path / "requests.jsonl"
    fresh_ros_master.spawn([sys.executable, "-c", SPAWNING_GS, str(log)])
    done = subprocess.run([sys.executable, "-m", "voice", "--wait", "120"], input="drone one land\n", cwd=ROOT,
                          env=fresh_ros_master.env(), capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert "land for UAV 1" in done.stdout and "refused" not in done.stdout
    requests = [json.loads(line) for line in log.read_text().splitlines()]
    where = ["get", "all", ["position"]]
    assert requests == [[*where, False], [*where, False], [*where, True], ["land", "1", [], True]]
