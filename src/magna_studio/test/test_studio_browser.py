"""The studio as a user drives it: a real `magna studio` and Debian's chromium (Playwright), headless.

Each test waits on what the page shows (Playwright's waits, with generous guards), never on a fixed
delay. The screenshots they take are the package README's pictures (conftest.screenshot).
"""
import json
import subprocess
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
GUARD_MS = 60_000  # a guard against a page that never shows what is awaited, not a speed expectation
RUN_GUARD_MS = 240_000  # a whole simulation, started from the page, on a loaded 2-core machine


def tid(name: str) -> str:
    return f"[data-testid={name}]"


def ready(page):
    page.wait_for_selector("body[data-ready=true]", timeout=GUARD_MS)


def open_world(page, spec: str):
    page.click(tid("tab-world"))
    page.fill(tid("world-spec"), spec)
    page.click(tid("world-open"))
    page.wait_for_function("name => document.querySelector('[data-testid=world-title]').textContent.includes(name)",
                           arg=spec.split("/")[-1], timeout=GUARD_MS)


def open_mission(page, spec: str):
    page.click(tid("tab-mission"))
    page.fill(tid("mission-spec"), spec)
    page.click(tid("mission-open"))
    page.wait_for_function("name => document.querySelector('[data-testid=mission-title]').textContent.includes(name)",
                           arg=spec.split("/")[-1], timeout=GUARD_MS)
    page.wait_for_selector(f"{tid('mission-graph')} svg", timeout=GUARD_MS)


def select_part(page, tree: str, path: str):
    page.click(f"{tid(tree)} [data-path='{path}'] >> .tree-row >> nth=0")


@pytest.mark.ros
def test_an_original_world_and_mission_load_with_the_migration_reported(page, shoot):
    ready(page)
    open_world(page, "Gym/1Obs_Central_Cylinder")  # the original's files, from the search path
    page.wait_for_selector(f"{tid('world-view')} canvas", timeout=GUARD_MS)
    assert page.locator(f"{tid('world-tree')} [data-testid=tree-item]").count() >= 3
    assert page.locator(f"{tid('world-diagnostics')} [data-severity=error]").count() == 0
    shoot(page, "world")

    open_mission(page, "Gym/2UAVs_2paths_Central_Cylinder")
    assert "legacy schema" in page.inner_text(tid("mission-schema")).lower()
    assert page.locator(f"{tid('mission-changes')} [data-testid=change]").count() >= 1
    assert page.locator(f"{tid('mission-tree')} [data-testid=tree-item]").count() >= 4
    assert page.locator(f"{tid('mission-graph')} svg [data-state]").count() >= 4
    assert page.locator(f"{tid('mission-diagnostics')} [data-severity=error]").count() == 0
    shoot(page, "mission")
    assert page.console_errors == []


def world_check_message(tmp_path, change) -> str:
    """What `magna world check` says of Gym/Four_Cylinders with `change` made to it: the text after the path."""
    data = json.loads((ROOT / "worlds" / "Gym" / "Four_Cylinders.json").read_text())
    change(data)
    edited = tmp_path / "Four_Cylinders.json"
    edited.write_text(json.dumps(data))
    check = subprocess.run([str(ROOT / "magna"), "world", "check", str(edited)], capture_output=True, text=True,
                           timeout=120)
    assert check.returncode == 2, check.stdout
    line = check.stderr.strip().splitlines()[-1]  # magna world: FILE: PATH: MESSAGE
    return line.split(": ", 3)[3]


@pytest.mark.ros
def test_a_bad_geometry_shows_the_check_message_on_its_field_until_it_is_fixed(page, shoot, tmp_path):
    def negative_diameter(data):
        data["scenario"]["volumes"][1]["geometries"][0]["dimensions"][0] = -3

    expected = world_check_message(tmp_path, negative_diameter)
    ready(page)
    open_world(page, "Gym/Four_Cylinders")
    geometry = "scenario.volumes[1].geometries[0]"
    select_part(page, "world-tree", geometry)
    dimension = f"{tid('world-form')} [data-path='{geometry}.dimensions[0]']"
    page.wait_for_selector(dimension, timeout=GUARD_MS)
    page.fill(dimension, "-3")
    error = page.wait_for_selector(tid("field-error"), timeout=GUARD_MS)
    assert error.get_attribute("data-diagnostic-path").startswith(f"{geometry}.dimensions")
    assert expected in error.inner_text()  # the same words as `magna world check` on that file
    assert expected in page.inner_text(tid("world-diagnostics"))
    shoot(page, "world_error")
    page.fill(dimension, "3")
    page.wait_for_selector(tid("field-error"), state="detached", timeout=GUARD_MS)
    assert page.locator(f"{tid('world-diagnostics')} [data-severity=error]").count() == 0
    assert page.console_errors == []


@pytest.mark.ros
def test_a_mission_built_from_nothing_is_saved_and_passes_magna_mission_check(page, tmp_path, shoot):
    ready(page)
    open_world(page, "Gym/Four_Cylinders")
    page.click(tid("tab-mission"))
    page.click(tid("mission-new"))
    first = "State_Machine[0]"
    page.wait_for_selector(f"{tid('mission-tree')} [data-path='{first}']", timeout=GUARD_MS)
    # a take-off and a landing after the spawn, connected in order
    select_part(page, "mission-tree", first)
    page.select_option(tid("mission-new-state-type"), "take_off")
    page.fill(tid("mission-new-state-name"), "take_off")
    page.click(tid("mission-add-state"))
    take_off = page.get_attribute(f"{tid('mission-tree')} [aria-selected=true]", "data-path")
    page.select_option(tid("mission-new-state-type"), "land")
    page.fill(tid("mission-new-state-name"), "land")
    page.click(tid("mission-add-state"))
    land = page.get_attribute(f"{tid('mission-tree')} [aria-selected=true]", "data-path")
    assert len({first, take_off, land}) == 3

    def connect(state: str, outcome: str, target: str):
        select_part(page, "mission-tree", state)
        target_select = f"select[data-path='{state}.outcomes.{outcome}']"
        page.wait_for_selector(target_select, timeout=GUARD_MS)
        page.select_option(target_select, label=target)

    # a UAV's state is labelled {id}_{name}, as the original labels them: UAV 1 is new_mission's one UAV
    connect(first, "completed", "1_take_off")
    connect(take_off, "succeeded", "1_land")
    connect(land, "succeeded", "ends the mission with completed")
    try:
        page.wait_for_function("() => document.querySelectorAll('[data-testid=mission-diagnostics] "
                               "[data-severity=error]').length === 0", timeout=GUARD_MS)
    except Exception:
        raise AssertionError(page.inner_text(tid("mission-diagnostics"))) from None
    page.wait_for_selector(f"{tid('mission-graph')} svg", timeout=GUARD_MS)
    shoot(page, "mission_new")

    saved = tmp_path / "Built_Here.json"
    page.fill(tid("mission-save-path"), str(saved))
    page.click(tid("mission-save"))
    page.wait_for_function("() => document.querySelector('[data-testid=mission-saved]').textContent.includes('saved')",
                           timeout=GUARD_MS)
    check = subprocess.run([str(ROOT / "magna"), "mission", "check", str(saved), "--world", "Gym/Four_Cylinders"],
                           capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stderr
    assert "pose definition(s) resolve" in check.stdout
    states = [s.get("name") or s.get("id") for s in json.loads(saved.read_text())["State_Machine"]]
    assert len(states) == 3
    assert page.console_errors == []


@pytest.mark.ros
def test_a_run_started_from_the_page_is_watched_and_commanded(page, studio, shoot):
    ready(page)
    open_world(page, "Gym/Central_Obstacle_Torus")
    open_mission(page, "Gym/2UAVs_Crossing_ORCA")
    page.click(tid("tab-run"))
    page.fill(tid("run-rtf"), "1")
    page.click(tid("run-start"))
    page.wait_for_function("() => document.querySelector('[data-testid=run-bridge]').textContent"
                           ".startsWith('connected')", timeout=RUN_GUARD_MS)

    # The UAVs move: UAV 1's shown position changes, and the machine goes from state to state.
    position = f"{tid('uav-row-1')} [data-cell=position]"
    page.wait_for_function(f"() => /\\d/.test(document.querySelector(\"{position}\").textContent)",
                           timeout=RUN_GUARD_MS)
    first = page.inner_text(position)
    page.wait_for_function(f"p => document.querySelector(\"{position}\").textContent !== p", arg=first,
                           timeout=RUN_GUARD_MS)
    page.wait_for_function("() => document.querySelector('[data-testid=run-active]').textContent.includes('take_off')",
                           timeout=RUN_GUARD_MS)
    page.wait_for_function("() => document.querySelector('[data-testid=run-active]').textContent.includes('crossing')",
                           timeout=RUN_GUARD_MS)
    assert page.locator(f"{tid('run-graph')} svg .active").count() >= 1
    role = f"{tid('uav-row-1')} [data-cell=role]"  # the role cell follows the manager's own steps
    page.wait_for_function(f"() => document.querySelector(\"{role}\").textContent === 'path'", timeout=GUARD_MS)

    # A question is accepted and answered; a command for a UAV the mission does not have is refused.
    page.select_option(tid("command-intent"), "parameters")
    page.fill(tid("command-agent"), "1")
    page.locator(f"{tid('command-param')} [data-field=name]").first.fill("battery")
    page.click(tid("command-send"))
    answer = tid("command-answer")
    page.wait_for_selector(f"{answer}[data-result=accepted]", timeout=GUARD_MS)
    assert "battery" in page.inner_text(answer)
    shoot(page, "run")
    page.locator(f"{tid('command-param')} [data-field=name]").first.fill("")
    page.select_option(tid("command-intent"), "basic_action")
    page.select_option(tid("command-action"), "land")
    page.fill(tid("command-agent"), "7")
    page.click(tid("command-send"))
    page.wait_for_selector(f"{answer}[data-result=refused]", timeout=GUARD_MS)
    assert "7" in page.inner_text(answer)

    # Pause and resume go through the same service.
    page.click(tid("run-pause"))
    page.wait_for_function("() => document.querySelector('[data-testid=command-answer]').textContent"
                           ".includes('mission paused')", timeout=GUARD_MS)
    page.click(tid("run-resume"))
    page.wait_for_function("() => document.querySelector('[data-testid=command-answer]').textContent"
                           ".includes('mission resumed')", timeout=GUARD_MS)

    # The operator's critical event: listed as it is raised, and as Resume clears it (the mission has taken
    # its safety branch meanwhile, and lands).
    page.select_option(tid("command-intent"), "mission")
    page.select_option(tid("command-action"), "critical")
    page.click(tid("command-send"))
    events = tid("run-events")
    page.wait_for_function(f"() => document.querySelector('{events}').textContent"
                           ".includes('critical event is raised')", timeout=GUARD_MS)
    page.click(tid("run-resume"))
    page.wait_for_function(f"() => document.querySelector('{events}').textContent"
                           ".includes('critical event is cleared')", timeout=GUARD_MS)

    # Afterwards: the dataset's reports, served by the studio.
    page.wait_for_selector(f"{tid('run-progress')}[data-state=finished]", timeout=RUN_GUARD_MS)
    report = page.wait_for_selector(f"{tid('run-reports')} a[href$='report.html']", timeout=GUARD_MS)
    href = report.get_attribute("href")
    with urllib.request.urlopen(studio.url.rstrip("/") + href, timeout=30) as answer_page:
        assert answer_page.status == 200 and b"<html" in answer_page.read(4096).lower()
    assert "exit status 0" in page.inner_text(tid("run-progress"))
    assert page.console_errors == []
