"""launch_watch finds roslaunch's report of a required node's death in a growing launch log."""
from magna_master.launch_watch import RequiredDeathWatch

# What roslaunch (pmon.py) prints when a required node dies, as it lands in the supervisor's launch log.
REPORT = ("================================================================================REQUIRED process "
          "[magna_sim-2] has died!\nprocess has died [pid 4242, exit code -9, cmd /work/devel/lib/magna_sim/sim "
          "__name:=magna_sim __log:=/tmp/x.log].\nlog file: /tmp/x*.log\nInitiating shutdown!\n"
          "================================================================================\n")


def test_nothing_is_reported_until_roslaunch_says_so(tmp_path):
    log = tmp_path / "launch.log"
    watch = RequiredDeathWatch(log)
    assert watch.poll() is None  # no log yet
    log.write_text("started roslaunch server\n[ground_station-5] process has finished cleanly\n")
    assert watch.poll() is None
    with log.open("a") as out:
        out.write(REPORT)
    death = watch.poll()
    assert (death.node, death.exit_code) == ("magna_sim", -9)
    assert death.component == "the simulator (magna_sim)"
    assert death.describe().startswith("the simulator (magna_sim) died (process has died [pid 4242, exit code -9")
    assert watch.poll() is death  # the first death stays the answer


def test_a_report_split_across_two_polls_is_found(tmp_path):
    log = tmp_path / "launch.log"
    text = REPORT.replace("magna_sim-2", "ground_station-7").replace("-9", "-11")
    cut = text.index("has died!") + 3
    log.write_text("x" * 5000 + text[:cut])
    watch = RequiredDeathWatch(log)
    assert watch.poll() is None
    with log.open("a") as out:
        out.write(text[cut:])
    death = watch.poll()
    assert (death.node, death.component, death.exit_code) == ("ground_station", "the ground station", -11)


def test_an_unknown_required_node_is_named_as_it_is(tmp_path):
    log = tmp_path / "launch.log"
    log.write_text("REQUIRED process [my_node-1] has died!\nprocess has died without exit code [pid 1, cmd x].\n")
    death = RequiredDeathWatch(log).poll()
    assert death.component == "the required node my_node" and death.exit_code is None
