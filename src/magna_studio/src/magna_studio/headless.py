"""`magna studio` in a process of its own, and Debian's chromium headless: what the browser tests and the
bench drive, in one place.

Chromium renders WebGL (the 3-D views) in software here: there is no GPU, and SwiftShader is what
Debian's chromium has for it.
"""
from __future__ import annotations

import re
import subprocess
import threading
from pathlib import Path

from magna_common.processes import end_process_group
from magna_common.workspace import find_root

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]
START_GUARD = 60.0  # s: a guard against a studio that never serves, not a speed expectation
STOP_GRACE = 45.0  # s: the studio ends a run in order first


def launch_chromium(playwright):
    """Debian's chromium, headless, through Playwright (its own browser download is not used)."""
    if not CHROMIUM.is_file():
        raise RuntimeError(f"{CHROMIUM} is missing: make setup installs Debian's chromium")
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)


class RunningStudio:
    """`magna studio --port 0 ...` in its own process group; `url` once it serves, `stop()` ends it all."""

    def __init__(self, *options: str):
        argv = [str(find_root() / "magna"), "studio", "--port", "0", *options]
        self.process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                        stdin=subprocess.DEVNULL, start_new_session=True)
        self.output: list[str] = []
        self.url = ""
        serving = threading.Event()

        def read() -> None:
            assert self.process.stdout is not None
            for line in self.process.stdout:
                self.output.append(line.rstrip("\n"))
                found = re.match(r"studio: (http://\S+)", line)
                if found and not self.url:
                    self.url = found.group(1)
                    serving.set()
            serving.set()  # it ended without serving

        threading.Thread(target=read, daemon=True).start()
        if not serving.wait(START_GUARD) or not self.url:
            self.stop()
            raise RuntimeError("magna studio did not say where it serves:\n" + "\n".join(self.output))

    def stop(self) -> None:
        end_process_group(self.process, grace=STOP_GRACE)
