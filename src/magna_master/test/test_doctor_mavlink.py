"""`magna doctor --mavlink URL`, as a user runs it: every line ok against a vehicle (exit 0), a clear line
with the URL and the fix when no vehicle answers (exit 1), a refused URL (exit 2).

The vehicle is magna_mavlink's scripted test vehicle (a UDP socket in this process speaking MAVLink 2)."""
from __future__ import annotations

import subprocess
from pathlib import Path

from magna_common.ports import free_port
from tests.support import load_module

ROOT = Path(__file__).resolve().parents[3]
TIMEOUT = 120  # s for the whole command: a guard against hangs


def scripted_vehicle_module():
    """magna_mavlink's test of link_check, for its ScriptedVehicle (test folders are not packages)."""
    return load_module(ROOT / "src" / "magna_mavlink" / "test" / "test_link_check.py", "magna_mavlink_scripted_vehicle")


def doctor(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(ROOT / "magna"), "doctor", *args], capture_output=True, text=True, timeout=TIMEOUT)


def test_every_line_passes_against_a_vehicle():
    with scripted_vehicle_module().ScriptedVehicle(mode="OFFBOARD", armed=True) as vehicle:
        url = f"udpout:127.0.0.1:{vehicle.port}"
        out = doctor("--mavlink", url, "--timeout", "10")
    assert out.returncode == 0, out.stdout + out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith(f"MAVLink link {url} ")
    for name, detail in (("heartbeat", f"from {url} after"), ("autopilot", "PX4 (HEARTBEAT.autopilot 12)"),
                         ("system id", "1, component 1"), ("flight mode", "OFFBOARD (the UAL's set-point mode)"),
                         ("armed", "armed"), ("position valid", "LOCAL_POSITION_NED"),
                         ("home", "47.3977420, 8.5455940, 488.0 m")):
        assert any(line.startswith(f"[ok  ] {name:<18} {detail}") for line in lines), (name, out.stdout)
    assert lines[-1] == "7 of 7 checks passed"
    assert "fix:" not in out.stdout


def test_no_vehicle_at_the_url_is_one_failed_line_with_the_url_and_the_fix():
    url = f"udpout:127.0.0.1:{free_port(udp=True)}"
    out = doctor("--mavlink", url, "--timeout", "0.5")
    assert out.returncode == 1, out.stdout + out.stderr
    assert f"[FAIL] heartbeat          no HEARTBEAT from a vehicle at {url} within 0.5 s" in out.stdout
    assert "       fix: is a vehicle running and listening at 127.0.0.1:" in out.stdout
    assert out.stdout.splitlines()[-1] == "0 of 1 checks passed"


def test_a_failing_line_among_passing_ones_exits_1():
    with scripted_vehicle_module().ScriptedVehicle(home=False) as vehicle:
        out = doctor("--mavlink", f"udpout:127.0.0.1:{vehicle.port}", "--timeout", "2")
    assert out.returncode == 1, out.stdout + out.stderr
    assert "[ok  ] position valid" in out.stdout and "[FAIL] home               no HOME_POSITION within 2 s" \
        in out.stdout
    assert out.stdout.splitlines()[-1] == "6 of 7 checks passed"


def test_a_bad_url_or_timeout_is_a_usage_error():
    out = doctor("--mavlink", "udpin:14540")
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.startswith("magna doctor: --mavlink udpin:14540: expected SCHEME:HOST:PORT; accepted: ")
    out = doctor("--mavlink", "udpin:0.0.0.0:14540", "--timeout", "0")
    assert out.returncode == 2 and "--timeout 0: give a positive number of seconds" in out.stderr
    out = doctor("--timeout", "3")
    assert out.returncode == 2 and "--timeout goes with --mavlink URL" in out.stderr


def test_help_shows_the_mavlink_check():
    out = doctor("--help")
    assert out.returncode == 0
    assert "--mavlink URL" in out.stdout and "magna doctor --mavlink udpin:0.0.0.0:14540" in out.stdout


def test_every_line_passes_against_magna_sims_px4_like_vehicle(fresh_ros_master):
    """A live magna_sim UAV spawned with interface "mavlink" (the stand-in for a HIL autopilot), reached both
    ways a ground station reaches PX4 SITL: udpout to the port it binds, udpin on the port it sends to."""
    import rosgraph

    from magna_common.ports import free_udp_ports
    from tests.support import wait_until

    master = fresh_ros_master
    master.spawn(["rosparam", "set", "/use_sim_time", "true"]).wait(timeout=30)
    sim = master.spawn(["rosrun", "magna_sim", "sim", "_uavs:=0", "_real_time_factor:=1.0"],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ros = rosgraph.Master("/test_doctor_mavlink", master_uri=master.uri)
    wait_until(lambda: _serves(ros, "/magna/sim/spawn_model"), "magna_sim's spawn service", timeout=60)
    local, remote = free_udp_ports(2)
    request = (f"{{name: uav_1, kind: uav, uav_id: 1, interface: mavlink, mavlink_local_port: {local}, "
               f"mavlink_remote_port: {remote}, pose: {{position: {{z: 0.05}}, orientation: {{w: 1.0}}}}}}")
    spawned = subprocess.run(["rosservice", "call", "/magna/sim/spawn_model", request], capture_output=True,
                             text=True, timeout=60, env=master.env())
    assert spawned.returncode == 0 and "success: True" in spawned.stdout, spawned.stdout + spawned.stderr
    for url in (f"udpout:127.0.0.1:{local}", f"udpin:127.0.0.1:{remote}"):
        out = doctor("--mavlink", url, "--timeout", "30")
        assert out.returncode == 0, out.stdout + out.stderr
        assert "[ok  ] autopilot          PX4 (HEARTBEAT.autopilot 12), vehicle type QUADROTOR" in out.stdout
        assert "[ok  ] system id          1, component 1" in out.stdout
        assert "[ok  ] armed              disarmed" in out.stdout
        assert out.stdout.splitlines()[-1] == "7 of 7 checks passed"
    assert sim.poll() is None, "magna_sim died during the test"


def _serves(ros, service: str) -> bool:
    try:
        ros.lookupService(service)
    except Exception:
        return False
    return True
