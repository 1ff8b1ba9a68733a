"""A skip never passes for a pass: scripts/test_summary.py counts skips apart and, in CI, fails on
them; rostests, whose skips rosunit would write as passes, do not skip."""
import re
import subprocess
import sys

from tests.support import ROOT

SUMMARY = ROOT / "scripts" / "test_summary.py"

# What pytest (<skipped>, xfail included) and gtest (result="skipped", status="notrun") write.
RESULTS = """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="mixed">
  <testcase classname="t" name="runs"/>
  <testcase classname="t" name="also_runs"><system-out>hello</system-out></testcase>
  <testcase classname="t" name="breaks"><failure message="no"/></testcase>
  <testcase classname="t" name="errs"><error message="boom"/></testcase>
  <testcase classname="t" name="pytest_skip"><skipped type="pytest.skip" message="needs espeak-ng"/></testcase>
  <testcase classname="t" name="pytest_xfail"><skipped type="pytest.xfail" message="known bug"/></testcase>
  <testcase classname="G" name="gtest_skip" status="run" result="skipped"/>
  <testcase classname="G" name="DISABLED_gtest" status="notrun" result="suppressed"/>
</testsuite></testsuites>
"""

PASSING_AND_SKIPPED = """<?xml version="1.0" encoding="utf-8"?>
<testsuite name="quiet"><testcase classname="t" name="runs"/>
  <testcase classname="t" name="skips"><skipped message="no corpus"/></testcase></testsuite>
"""


def summary(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SUMMARY), *map(str, args)], capture_output=True, text=True,
                          timeout=60)


def test_skips_are_counted_apart_and_named_with_their_reason(tmp_path):
    (tmp_path / "mixed.xml").write_text(RESULTS)
    done = summary(tmp_path)
    assert done.returncode == 1  # the failure and the error
    assert done.stdout.splitlines()[-1] == "2 passed, 2 failed, 4 skipped"
    for line in ("t::pytest_skip: needs espeak-ng", "t::pytest_xfail: known bug", "G::gtest_skip: skipped (gtest)",
                 "G::DISABLED_gtest: not run (a disabled gtest)"):
        assert f"  {line}" in done.stdout.splitlines()


def test_a_skip_fails_the_run_only_with_fail_on_skip(tmp_path):
    (tmp_path / "quiet.xml").write_text(PASSING_AND_SKIPPED)
    done = summary(tmp_path)
    assert done.returncode == 0 and "[SKIP]    1 passed   0 failed   1 skipped" in done.stdout
    assert done.stdout.splitlines()[-1] == "1 passed, 0 failed, 1 skipped"
    failing = summary("--fail-on-skip", tmp_path)
    assert failing.returncode == 1
    assert "1 test(s) skipped: in CI every test must run" in failing.stderr


def test_only_skipped_tests_mean_that_no_test_ran(tmp_path):
    (tmp_path / "all_skipped.xml").write_text('<testsuite><testcase name="a"><skipped/></testcase></testsuite>')
    done = summary(tmp_path)
    assert done.returncode == 1 and "no test ran" in done.stderr


def test_ci_passes_fail_on_skip_to_the_summary():
    script = (ROOT / "scripts" / "test.sh").read_text()
    assert re.search(r'summary_options\+=\(--fail-on-skip\)', script)
    assert 'python scripts/test_summary.py "${summary_options[@]}"' in script
    assert 'export CI="${CI:-true}"' in (ROOT / ".ci" / "run").read_text()


def test_no_rostest_skips():
    """rosunit writes a skipped unittest as a pass (its XML has no <skipped>), so a skip in a rostest
    would be counted as a pass: the test either runs or fails."""
    skipping = re.compile(r"skipTest|unittest\.skip|SkipTest|pytest\.skip|importorskip")
    tests = sorted(ROOT.glob("src/*/test/*.test"))
    assert tests, "no rostest launch files found"
    scripts = set()
    for launch in tests:
        for package, script in re.findall(r'<test [^>]*pkg="([^"]+)"[^>]*type="([^"]+\.py)"', launch.read_text()):
            path = ROOT / "src" / package / "test" / script
            assert path.is_file(), f"{launch.relative_to(ROOT)} runs {script}: no such file at {path}"
            scripts.add(path)
    assert scripts
    found = [f"{path.relative_to(ROOT)}:{n}" for path in sorted(scripts)
             for n, line in enumerate(path.read_text().splitlines(), 1) if skipping.search(line)]
    assert found == [], f"a rostest skips (rosunit would count it as a pass): {found}"
