"""A real `magna studio` in a process of its own, and a real headless browser (Debian's chromium,
driven by Playwright) on its page.

Screenshots go to build/magna_studio_screenshots/; with MAGNA_UPDATE_SCREENSHOTS=1 they also replace
the README's pictures in src/magna_studio/doc/.
"""
import os
import shutil
from pathlib import Path

import pytest

from magna_studio.headless import RunningStudio, launch_chromium
from tests.support import CORPUS

ROOT = Path(__file__).resolve().parents[3]
SCREENSHOTS = ROOT / "build" / "magna_studio_screenshots"
README_PICTURES = ROOT / "src" / "magna_studio" / "doc"


@pytest.fixture
def studio(tmp_path):
    """`magna studio` with the original's files on its search path, data into a temporary root."""
    running = RunningStudio("--data-root", str(tmp_path / "data"), "--search-path", str(CORPUS))
    yield running
    running.stop()
    assert running.process.returncode is not None


@pytest.fixture(scope="session")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = launch_chromium(playwright)
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
