"""Sum up the JUnit XML files of pytest, gtest and rostest into one table and one closing line."""
import sys
import xml.etree.ElementTree as ET
from pathlib import Path


def count_cases(xml_path: Path) -> tuple[int, int, int]:
    """(passed, failed, skipped) test cases in one JUnit file."""
    passed = failed = skipped = 0
    for case in ET.parse(xml_path).getroot().iter("testcase"):
        outcome = {child.tag for child in case}
        if outcome & {"failure", "error"}:
            failed += 1
        elif "skipped" in outcome:
            skipped += 1
        else:
            passed += 1
    return passed, failed, skipped


def main(directories: list[str]) -> int:
    rows = []
    for directory in map(Path, directories):
        for xml_path in sorted(directory.rglob("*.xml")) if directory.is_dir() else []:
            try:
                rows.append((xml_path, *count_cases(xml_path)))
            except ET.ParseError as error:
                rows.append((xml_path, 0, 1, 0))
                print(f"unreadable test result {xml_path}: {error}", file=sys.stderr)
    print("\n== summary")
    for path, passed, failed, skipped in rows:
        flag = "FAIL" if failed else "ok  "
        print(f"[{flag}] {passed:4d} passed {failed:3d} failed {skipped:3d} skipped  {path}")
    total_passed = sum(r[1] for r in rows)
    total_failed = sum(r[2] for r in rows)
    total_skipped = sum(r[3] for r in rows)
    print(f"{total_passed} passed, {total_failed} failed, {total_skipped} skipped")
    if total_passed + total_failed == 0:
        print("no test ran", file=sys.stderr)
        return 1
    return 1 if total_failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
