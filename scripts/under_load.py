#!/usr/bin/env python3
"""Run tests again and again while busy loops hold every core: proof that they wait on conditions.

    bash scripts/with_env.sh python3 scripts/under_load.py [--runs 10] [--hogs N] [-- TESTS...]

A test that waits on wall-clock luck passes on an idle machine and fails when the CPU is taken; one that
waits on conditions and simulated time passes either way, only slower. This runs pytest --runs times in a
row (by default over the fault suite and the tests that were once timing-sensitive, see DEFAULT_TESTS;
TESTS are pytest arguments, and a `.test` file of a package is run with rostest as well)
with --hogs busy processes (default: one per core) competing at the same priority, and prints one line
per run and a total. Exit status 1 when any run had a failure (or a skip: in this proof a skip hides
what it claims to show), 2 on bad arguments.

The hogs are this script's own children, ended by their ids when it finishes, also on Ctrl-C.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_TESTS = (
    "tests/faults",
    "src/magna_uav/test/uav_manager.test",  # the UAV managers' rostest
    "mlr/tests/test_recording.py",  # the bag against the CSVs
    "src/magna_viz/test/test_recording.py",
    "src/magna_gs/test/test_bag_recorder.py",
)
HOG = "while True: pass"


@dataclass
class RunResult:
    index: int
    passed: int
    failed: int
    skipped: int
    wall: float

    @property
    def clean(self) -> bool:
        return self.failed == 0 and self.skipped == 0 and self.passed > 0


def parse_args(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    parser = argparse.ArgumentParser(prog="scripts/under_load.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=10, help="how many times pytest runs (default 10)")
    parser.add_argument("--hogs", type=int, default=os.cpu_count() or 1,
                        help="busy processes held during the runs (default: one per core, %(default)s here)")
    if "--" in argv:
        cut = argv.index("--")
        args, tests = parser.parse_args(argv[:cut]), argv[cut + 1:]
    else:
        args, tests = parser.parse_args(argv), []
    if args.runs < 1 or args.hogs < 0:
        parser.error("--runs must be at least 1 and --hogs at least 0")
    return args, tests or [str(ROOT / test) for test in DEFAULT_TESTS]


def start_hogs(count: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", HOG], start_new_session=True) for _ in range(count)]


def end_hogs(hogs: list[subprocess.Popen]) -> None:
    for hog in hogs:
        if hog.poll() is None:
            os.kill(hog.pid, signal.SIGKILL)
        hog.wait()


def counts(report: Path) -> tuple[int, int, int]:
    """passed, failed (errors included), skipped, from pytest's JUnit XML report."""
    root = ElementTree.parse(report).getroot()
    suites = [root] if root.tag == "testsuite" else list(root)
    tests = sum(int(s.get("tests", 0)) for s in suites)
    failed = sum(int(s.get("failures", 0)) + int(s.get("errors", 0)) for s in suites)
    skipped = sum(int(s.get("skipped", 0)) for s in suites)
    return tests - failed - skipped, failed, skipped


def rostest_command(launch: Path) -> list[str]:
    """rostest PACKAGE FILE for src/PACKAGE/test/FILE.test."""
    package = launch.resolve().relative_to(ROOT / "src").parts[0]
    return ["rostest", package, launch.name]


def run_once(index: int, tests: list[str], folder: Path) -> RunResult:
    """One pytest run of the pytest arguments, then one rostest run per .test file; counts added up."""
    commands, reports = [], []
    pytest_args = [test for test in tests if not test.endswith(".test")]
    if pytest_args:
        reports.append(folder / f"run{index}.xml")
        commands.append(([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          f"--junitxml={reports[-1]}", *pytest_args], {}))
    for launch in (Path(test) for test in tests if test.endswith(".test")):
        results_dir = folder / f"run{index}-{launch.stem}"
        reports.append(results_dir)
        commands.append((rostest_command(launch), {"ROS_TEST_RESULTS_DIR": str(results_dir)}))
    start = time.monotonic()
    output = ""
    for command, env in commands:
        output += subprocess.run(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 env={**os.environ, **env}).stdout
    wall = time.monotonic() - start
    passed = failed = skipped = 0
    for report in reports:
        # rostest writes a rosunit-*.xml per test node (the rostest-*.xml beside it only says it ran)
        files = sorted(report.rglob("rosunit-*.xml")) if report.is_dir() else [report]
        if not files or not all(f.exists() for f in files):  # stopped before any test ran: show why
            print(output[-3000:], file=sys.stderr)
            failed += 1
            continue
        for file in files:
            p, f, s = counts(file)
            passed, failed, skipped = passed + p, failed + f, skipped + s
    result = RunResult(index, passed, failed, skipped, wall)
    if not result.clean:
        failures = [line for line in output.splitlines() if re.match(r"(FAILED|ERROR|SKIPPED|\[FAIL)", line)]
        print("\n".join(failures[-20:]), file=sys.stderr)
    return result


def main(argv: list[str] | None = None) -> int:
    args, tests = parse_args(sys.argv[1:] if argv is None else argv)
    print(f"{args.runs} runs of {' '.join(tests)}\nwith {args.hogs} busy processes on "
          f"{os.cpu_count()} cores", flush=True)
    hogs = start_hogs(args.hogs)
    print(f"busy processes: {' '.join(str(hog.pid) for hog in hogs) or 'none'}", flush=True)
    results = []
    try:
        with tempfile.TemporaryDirectory(prefix="magna-under-load-") as folder:
            for index in range(1, args.runs + 1):
                result = run_once(index, tests, Path(folder))
                results.append(result)
                print(f"run {index:2d}/{args.runs}: {result.passed} passed, {result.failed} failed, "
                      f"{result.skipped} skipped in {result.wall:.0f} s", flush=True)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        end_hogs(hogs)
    clean = sum(result.clean for result in results)
    print(f"{clean} of {len(results)} runs clean (every test passed, none skipped) under {args.hogs} busy "
          f"processes")
    return 0 if clean == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
