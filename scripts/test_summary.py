"""Sum up the JUnit XML files of pytest, gtest and rostest into one table and one closing line.

A skipped test is counted apart, never as a pass, and each one is listed with its reason. With
--fail-on-skip (CI: scripts/test.sh passes it when CI is set) any skip fails the run, as a failure
does: in CI a test either runs or is not there.

A skip is seen as pytest and gtest write it: a <skipped> element (pytest's xfail too), or gtest's
result="skipped" / status="notrun" (DISABLED_ tests). rosunit, which writes the results of
Python rostests, writes a skipped test as a pass: tests/test_skips.py keeps skips out of rostests.
"""
import argparse
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Counts:
    passed: int = 0
    failed: int = 0
    skipped: list[str] = field(default_factory=list)  # "name: reason" of each skipped test


def _skip_reason(case: ET.Element) -> str | None:
    """Why `case` was skipped, or None if it ran."""
    element = case.find("skipped")
    if element is not None:
        return element.get("message") or (element.text or "").strip() or "no reason given"
    if case.get("result") == "skipped":
        return "skipped (gtest)"
    if case.get("status") == "notrun":
        return "not run (a disabled gtest)"
    return None


def count_cases(xml_path: Path) -> Counts:
    """Passed, failed (errors included) and skipped test cases in one JUnit file."""
    counts = Counts()
    for case in ET.parse(xml_path).getroot().iter("testcase"):
        if any(child.tag in ("failure", "error") for child in case):
            counts.failed += 1
            continue
        reason = _skip_reason(case)
        if reason is None:
            counts.passed += 1
        else:
            name = "::".join(part for part in (case.get("classname"), case.get("name")) if part)
            counts.skipped.append(f"{name}: {reason}")
    return counts


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directories", nargs="*", help="folders searched for *.xml result files")
    parser.add_argument("--fail-on-skip", action="store_true", help="a skipped test fails the run (CI)")
    args = parser.parse_args(argv)
    rows: list[tuple[Path, Counts]] = []
    for directory in map(Path, args.directories):
        for xml_path in sorted(directory.rglob("*.xml")) if directory.is_dir() else []:
            try:
                rows.append((xml_path, count_cases(xml_path)))
            except ET.ParseError as error:
                rows.append((xml_path, Counts(failed=1)))
                print(f"unreadable test result {xml_path}: {error}", file=sys.stderr)
    print("\n== summary")
    for path, counts in rows:
        flag = "FAIL" if counts.failed else "SKIP" if counts.skipped else "ok  "
        print(f"[{flag}] {counts.passed:4d} passed {counts.failed:3d} failed {len(counts.skipped):3d} skipped  {path}")
    skipped = [name for _, counts in rows for name in counts.skipped]
    if skipped:
        print("\nskipped (counted apart, not as passes):")
        for name in skipped:
            print(f"  {name}")
    total_passed = sum(counts.passed for _, counts in rows)
    total_failed = sum(counts.failed for _, counts in rows)
    print(f"{total_passed} passed, {total_failed} failed, {len(skipped)} skipped")
    if total_passed + total_failed == 0:
        print("no test ran", file=sys.stderr)
        return 1
    if skipped and args.fail_on_skip:
        print(f"{len(skipped)} test(s) skipped: in CI every test must run (--fail-on-skip)", file=sys.stderr)
        return 1
    return 1 if total_failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
