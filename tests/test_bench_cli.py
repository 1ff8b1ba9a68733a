"""The benchmarks' command lines: `python bench/X.py` runs from any Python, and their options follow the one
CLI vocabulary (-o/--output, --force, --rtf max|FACTOR) with the old spellings kept for a release."""
import subprocess
import sys
from pathlib import Path

import pytest

from magna_common.cli_vocabulary import deprecation_line
from tests.support import ROOT, load_module

BENCH = ROOT / "bench"
SCRIPTS = sorted(p.name for p in BENCH.glob("*.py"))


def load(name: str):
    """A bench script as a module (its `if __name__ == "__main__"` parts do not run)."""
    return load_module(BENCH / f"{name}.py", f"bench_{name}")


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_bench_script_answers_help_from_a_bare_terminal(script, tmp_path):
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": str(tmp_path), "LANG": "C.UTF-8"}
    done = subprocess.run([sys.executable, str(BENCH / script), "--help"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage:")


def test_command_latency_new_spellings(capsys, tmp_path):
    bench = load("command_latency")
    parser = bench.build_parser()
    args = parser.parse_args(["-o", str(tmp_path / "l.png"), "--force", "--rtf", "max"])
    bench.check_args(parser, args)
    assert args.output == tmp_path / "l.png" and args.force is True and args.rtf == "max"
    assert parser.parse_args([]).output == bench.PICTURE and parser.parse_args([]).rtf == "1.0"
    assert "--rtf max|FACTOR" in parser.format_help()
    assert parser.parse_args(["--worker", "2", "--worker-output", "r.json"]).worker_output == Path("r.json")
    assert capsys.readouterr().err == ""


def test_command_latency_old_spellings_still_work(capsys):
    parser = load("command_latency").build_parser()
    args = parser.parse_args(["--picture", "p.png", "--worker", "1", "--out", "r.json"])
    assert args.output == Path("p.png") and args.worker_output == Path("r.json")
    prog = "python bench/command_latency.py"
    assert capsys.readouterr().err.splitlines() == [deprecation_line(prog, "--picture", "-o/--output"),
                                                    deprecation_line(prog, "--out", "--worker-output")]


def test_command_latency_refuses_before_measuring(tmp_path, capsys):
    bench = load("command_latency")
    parser = bench.build_parser()
    picture = tmp_path / "l.png"
    picture.write_bytes(b"an older figure")
    with pytest.raises(SystemExit) as stop:
        bench.check_args(parser, parser.parse_args(["-o", str(picture)]))
    assert stop.value.code == 2
    assert f"the plot {picture} already exists; pass --force to replace it" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench.check_args(parser, parser.parse_args(["-o", str(tmp_path / "new.png"), "--rtf", "fast"]))
    assert "--rtf 'fast': give 'max'" in capsys.readouterr().err
    assert picture.read_bytes() == b"an older figure"


def test_uav_control_loop_worker_output(capsys):
    parser = load("uav_control_loop").build_parser()
    assert parser.parse_args(["--worker", "2", "--worker-output", "r.json"]).worker_output == Path("r.json")
    assert capsys.readouterr().err == ""
    assert parser.parse_args(["--worker", "2", "--out", "r.json"]).worker_output == Path("r.json")
    assert capsys.readouterr().err.splitlines() == [
        deprecation_line("python bench/uav_control_loop.py", "--out", "--worker-output")]


def test_mission_batch_output(capsys):
    parser = load("mission_batch").build_parser()
    assert parser.parse_args(["-o", "kept"]).output == Path("kept")
    assert parser.parse_args([]).output is None
    assert capsys.readouterr().err == ""
    assert parser.parse_args(["--keep-data", "kept"]).output == Path("kept")
    assert capsys.readouterr().err.splitlines() == [
        deprecation_line("python bench/mission_batch.py", "--keep-data", "-o/--output")]
