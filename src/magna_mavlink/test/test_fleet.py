"""The fleet file: what it accepts, what it refuses (naming file, field and fix), and its fit to a mission."""
import pytest

from magna_mavlink.fleet import FleetError, check_against_mission, check_url, load_fleet, mavlink_uavs


def write(tmp_path, text, name="fleet.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_full_fleet_file_loads_with_its_defaults(tmp_path):
    fleet = load_fleet(write(tmp_path, """
origin_geo: [37.4107, -6.0028, 12.0]
uavs:
  3: {url: "udpin:0.0.0.0:14542", autopilot: px4, arming: auto, system_id: 7}
  4: {url: "/dev/ttyACM0,57600"}
  5: {stand_in: true, link_faults: {loss: 0.2, delay: 0.05, cut_at: 30, cut_for: 5, seed: 3}}
"""))
    assert fleet.origin_geo == (37.4107, -6.0028, 12.0)
    three, four, five = fleet.uavs[3], fleet.uavs[4], fleet.uavs[5]
    assert (three.url, three.autopilot, three.arming, three.system_id) == ("udpin:0.0.0.0:14542", "px4", "auto", 7)
    assert (four.autopilot, four.system_id, four.stand_in) == ("auto", 4, False)
    assert four.arming_for("real") == "pilot" and four.arming_for("hil") == "auto"
    assert three.arming_for("real") == "auto"  # said explicitly: kept
    assert five.stand_in and five.url == ""
    assert five.link_faults.proxy_arguments() == ["--loss", "0.2", "--delay", "0.05", "--seed", "3",
                                                  "--cut-at", "30", "--cut-for", "5"]
    assert three.link_faults is None


@pytest.mark.parametrize("url", ["udpin:0.0.0.0:14540", "udpout:192.168.1.10:14550", "tcp:127.0.0.1:5760",
                                 "udp:localhost:14540", "/dev/ttyUSB0", "/dev/ttyACM0,921600", "COM3,57600"])
def test_pymavlink_connection_strings_are_urls(url):
    assert check_url(url) is None


@pytest.mark.parametrize("url, why", [("udp://:14540", "not a MAVLink connection string"),
                                      ("udpin:0.0.0.0:70000", "port 70000"),
                                      ("localhost:14540", "not a MAVLink connection string")])
def test_other_text_is_no_url_and_the_fix_is_shown(url, why):
    text = check_url(url)
    assert why in text and ("udpin:0.0.0.0:14540" in text or "1..65535" in text)


@pytest.mark.parametrize("text, field, fix", [
    ("uavs: {3: {url: 'udp://:14540'}}", "uavs.3.url", "udpin:0.0.0.0:14540"),
    ("uavs: {3: {}}", "uavs.3.url", "stand_in: true"),
    ("uavs: {3: {stand_in: true, url: 'udpin:0.0.0.0:1'}}", "uavs.3.url", "remove the url"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1', autopilot: inav}}", "uavs.3.autopilot", "auto, px4, ardupilot"),
    ("uavs: {3: {stand_in: true, autopilot: ardupilot}}", "uavs.3.autopilot", "PX4-like"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1', arming: yes}}", "uavs.3.arming", "auto, pilot"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1', system_id: 300}}", "uavs.3.system_id", "1..255"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1', baud: 57600}}", "uavs.3.baud", "url, autopilot, arming"),
    ("uavs: {uav_3: {url: 'udpin:0.0.0.0:1'}}", "uavs.uav_3", "mission IDs"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1'}, 4: {url: 'udpin:0.0.0.0:1'}}", "uavs", "share the URL"),
    ("uavs: {}", "uavs", "one entry per hil or real UAV"),
    ("origin_geo: [37.4, -6.0]\nuavs: {3: {stand_in: true}}", "origin_geo", "[latitude, longitude, altitude]"),
    ("origin_geo: [97.4, -6.0, 0]\nuavs: {3: {stand_in: true}}", "origin_geo", "-90..90"),
    ("uav: {3: {stand_in: true}}", "uav", "origin_geo, uavs"),
    ("uavs: {3: {url: 'udpin:0.0.0.0:1', link_faults: {loss: 0.2}}}", "uavs.3.link_faults", "udp_proxy"),
    ("uavs: {3: {stand_in: true, link_faults: {loss: 1.5}}}", "uavs.3.link_faults.loss", "below 1"),
    ("uavs: {3: {stand_in: true, link_faults: {delay: -1}}}", "uavs.3.link_faults.delay", "0 or more"),
    ("uavs: {3: {stand_in: true, link_faults: {cut_at: 3}}}", "uavs.3.link_faults", "cut_at and cut_for"),
    ("uavs: {3: {stand_in: true, link_faults: {jitter: 3}}}", "uavs.3.link_faults.jitter", "loss, delay"),
    ("- 3", "the file must be a mapping", "uavs"),
    ("uavs: [3: {", "not valid YAML", ""),
])
def test_bad_files_are_refused_naming_file_field_and_fix(tmp_path, text, field, fix):
    path = write(tmp_path, text)
    with pytest.raises(FleetError) as error:
        load_fleet(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and field in message and fix in message


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FleetError, match="fleet.yaml: no such file"):
        load_fleet(tmp_path / "fleet.yaml")


def test_the_fleet_must_fit_the_mission(tmp_path):
    fleet = load_fleet(write(tmp_path, """
uavs:
  2: {url: "udpin:0.0.0.0:14541"}
  3: {stand_in: true}
  4: {stand_in: true}
  9: {url: "udpin:0.0.0.0:14549"}
"""))
    modes = {1: "sitl", 2: "sitl", 3: "real", 4: "hil", 5: "hil"}
    problems = check_against_mission(fleet, modes)
    assert any("UAV 5 is hil in the mission but has no entry" in p for p in problems)
    assert any("uavs.2: UAV 2 is sitl in the mission, so magna_sim flies it" in p for p in problems)
    assert any("uavs.3.stand_in: UAV 3 is real" in p for p in problems)
    assert any("uavs.9: the mission has no UAV 9" in p for p in problems)
    assert not any("uavs.4" in p for p in problems)  # a hil stand-in fits
    assert len(problems) == 4
    assert mavlink_uavs(modes) == [3, 4, 5]


def test_a_fitting_fleet_has_no_problems(tmp_path):
    fleet = load_fleet(write(tmp_path, "uavs: {3: {stand_in: true}}"))
    assert check_against_mission(fleet, {1: "sitl", 2: "sitl", 3: "hil"}) == []
