"""`magna studio` as a program: its options, its refusals, and the guards of its HTTP API."""
import http.client
import json
import os
import signal
import socket
import subprocess
from pathlib import Path

import pytest

from magna_studio.headless import RunningStudio

ROOT = Path(__file__).resolve().parents[3]
GUARD = 60.0  # s: a guard against a hung command, not a speed expectation


def studio_command(*options: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(ROOT / "magna"), "studio", *options], capture_output=True, text=True, timeout=GUARD)


@pytest.fixture
def running(tmp_path):
    studio = RunningStudio("--data-root", str(tmp_path / "data"))
    yield studio
    studio.stop()


def request(studio, method: str, path: str, body=None, headers=None, host=None):
    """(status, decoded JSON or text) of one request; `host` replaces the Host header."""
    address = studio.url.split("//", 1)[1].rstrip("/")
    connection = http.client.HTTPConnection(address, timeout=GUARD)
    sent = {"Content-Type": "application/json", **(headers or {})}
    if host is not None:
        sent["Host"] = host
    connection.request(method, path, body=json.dumps(body) if body is not None else None, headers=sent)
    answer = connection.getresponse()
    text = answer.read().decode()
    connection.close()
    try:
        return answer.status, json.loads(text)
    except ValueError:
        return answer.status, text


OURS = {"X-Magna-Studio": "1"}


def test_a_port_out_of_range_is_refused():
    result = studio_command("--port", "70000")
    assert result.returncode == 2 and "--port 70000" in result.stderr


def test_a_busy_port_is_refused_naming_the_fix():
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        result = studio_command("--port", str(port))
    assert result.returncode == 2 and f"127.0.0.1:{port}" in result.stderr and "--port" in result.stderr


def test_a_missing_search_folder_is_refused(tmp_path):
    result = studio_command("--search-path", str(tmp_path / "nowhere"))
    assert result.returncode == 2 and "--search-path" in result.stderr


def test_ctrl_c_ends_the_studio_cleanly(running):
    running.process.send_signal(signal.SIGINT)
    assert running.process.wait(GUARD) == 0


def test_the_page_and_its_3d_library_are_served_from_the_package(running):
    status, page = request(running, "GET", "/")
    assert status == 200 and "/vendor/three/build/three.module.js" in page and "//cdn" not in page
    status, library = request(running, "GET", "/vendor/three/build/three.module.js")
    assert status == 200 and "REVISION" in library


def test_a_post_without_the_studio_header_is_refused(running, tmp_path):
    target = tmp_path / "World.json"
    status, answer = request(running, "POST", "/api/world/save", {"data": {"x": 1}, "path": str(target)})
    assert status == 403 and "X-Magna-Studio" in answer["error"]
    assert not target.exists()


def test_a_request_naming_another_host_is_refused(running):
    status, _ = request(running, "GET", "/api/files?kind=world", host="attacker.example:80")
    assert status == 403
    status, answer = request(running, "GET", "/api/files?kind=world")
    assert status == 200 and any(f["name"] == "Gym/Four_Cylinders" for f in answer["files"])


def test_save_asks_before_replacing_a_file_and_bad_requests_name_the_field(running, tmp_path):
    target = tmp_path / "World.json"
    target.write_text("{}\n")
    status, answer = request(running, "POST", "/api/world/save", {"data": {"x": 1}, "path": str(target)}, OURS)
    assert status == 409 and answer["exists"] is True
    assert target.read_text() == "{}\n"
    status, answer = request(running, "POST", "/api/world/save",
                             {"data": {"x": 1}, "path": str(target), "overwrite": True}, OURS)
    assert status == 200 and json.loads(target.read_text()) == {"x": 1}
    status, answer = request(running, "POST", "/api/world/check", {"data": [1, 2]}, OURS)
    assert status == 400 and answer["error"].startswith("data:")
    status, answer = request(running, "POST", "/api/run/start", {"world": None}, OURS)
    assert status == 400 and answer["error"].startswith("world:")
    status, answer = request(running, "GET", "/api/files?kind=robots")
    assert status == 400 and "kind" in answer["error"]


def test_reports_are_served_from_the_data_root_only(running, tmp_path):
    report = tmp_path / "data" / "Simulations" / "report.html"
    report.parent.mkdir(parents=True)
    report.write_text("<html>a report</html>")
    status, text = request(running, "GET", "/reports/Simulations/report.html")
    assert status == 200 and "a report" in text
    secret = tmp_path / "secret.txt"
    secret.write_text("not for the page")
    status, text = request(running, "GET", "/reports/../secret.txt")
    assert status in (403, 404) and "not for the page" not in str(text)
    assert os.path.exists(secret)
