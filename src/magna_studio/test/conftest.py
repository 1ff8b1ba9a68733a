"""A real `magna studio` in a process of its own, and a real headless browser (Debian's chromium,
driven by Playwright) on its page.

Screenshots go to build/magna_studio_screenshots/; with MAGNA_UPDATE_SCREENSHOTS=1 they also replace
the README's pictures in src/magna_studio/doc/.
"""
import os
import re
import shutil
import subprocess
import threading
from pathlib import Path

import pytest

from magna_common.processes import end_process_group
from tests.support import CORPUS

ROOT = Path(__file__).resolve().parents[3]
CHROMIUM = Path("/usr/bin/chromium")
SCREENSHOTS = ROOT / "build" / "magna_studio_screenshots"
README_PICTURES = ROOT / "src" / "magna_studio" / "doc"
START_GUARD = 60.0  # s: a guard against a studio that never serves, not a speed expectation


class RunningStudio:
    def __init__(self, data_root: Path, *extra: str):
        self.data_root = data_root
        argv = [str(ROOT / "magna"), "studio", "--port", "0", "--data-root", str(data_root), *extra]
        self.process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                        stdin=subprocess.DEVNULL, start_new_session=True)
        self.output: list[str] = []
        found = threading.Event()
        self.url = ""

        def read():
            assert self.process.stdout is not None
            for line in self.process.stdout:
                self.output.append(line.rstrip("\n"))
                match = re.match(r"studio: (http://\S+)", line)
                if match and not self.url:
                    self.url = match.group(1)
                    found.set()
            found.set()

        threading.Thread(target=read, daemon=True).start()
        if not found.wait(START_GUARD) or not self.url:
            self.stop()
            raise AssertionError("magna studio did not say where it serves:\n" + "\n".join(self.output))

    def stop(self) -> None:
        end_process_group(self.process, grace=45.0)  # it stops a run in order first


@pytest.fixture
def studio(tmp_path):
    """`magna studio` with the original's files on its search path, data into a temporary root."""
    running = RunningStudio(tmp_path / "data", "--search-path", str(CORPUS))
    yield running
    running.stop()
    assert running.process.returncode is not None


@pytest.fixture(scope="session")
def browser():
    from playwright.sync_api import sync_playwright

    assert CHROMIUM.is_file(), f"{CHROMIUM} is missing: make setup installs Debian's chromium"
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader"])
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser, studio):
    context = browser.new_context(viewport={"width": 1500, "height": 950})
    page = context.new_page()
    errors: list[str] = []
    page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(studio.url)
    page.console_errors = errors
    yield page
    context.close()


def screenshot(page, name: str) -> Path:
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    path = SCREENSHOTS / f"{name}.png"
    page.screenshot(path=str(path))
    if os.environ.get("MAGNA_UPDATE_SCREENSHOTS") == "1":
        README_PICTURES.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, README_PICTURES / f"{name}.png")
    return path


@pytest.fixture
def shoot():
    return screenshot
