"""`magna learn`'s options follow the one CLI vocabulary (-o/--output, --force, --search-path, --rtf);
the old spellings still work for a release and say what replaces them; `board` runs TensorBoard."""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from magna_common.cli_vocabulary import deprecation_line
from magna_common.ports import free_port
from mlr import cli

ROOT = Path(__file__).resolve().parents[2]
PROG = "magna learn"


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=PROG)
    cli.add_arguments(parser)
    return parser.parse_args(list(argv))


def deprecations(capsys) -> list[str]:
    return capsys.readouterr().err.splitlines()


def test_train_new_spellings(capsys):
    args = parse("train", "c.yaml", "-o", "runs", "--force")
    assert args.output == Path("runs") and args.force is True and deprecations(capsys) == []
    assert parse("train", "c.yaml", "--output", "runs").output == Path("runs")
    assert parse("train", "c.yaml").output is None and parse("train", "c.yaml").force is False


def test_train_old_spellings_still_work_with_one_line_each(capsys):
    args = parse("train", "c.yaml", "--out", "runs", "--overwrite")
    assert args.output == Path("runs") and args.force is True
    assert deprecations(capsys) == [deprecation_line(f"{PROG} train", "--out", "-o/--output"),
                                    deprecation_line(f"{PROG} train", "--overwrite", "--force")]


def test_pickle_new_and_old_spellings(capsys):
    args = parse("pickle", "c.yaml", "-o", "s.npz", "--force")
    assert args.output == Path("s.npz") and args.force is True and deprecations(capsys) == []
    args = parse("pickle", "c.yaml", "--output", "s.npz", "--overwrite")
    assert args.output == Path("s.npz") and args.force is True
    assert deprecations(capsys) == [deprecation_line(f"{PROG} pickle", "--overwrite", "--force")]


def test_export_new_and_old_spellings(capsys):
    args = parse("export", "runs/r00", "-o", "net.pt", "--force")
    assert args.output == "net.pt" and args.force is True and deprecations(capsys) == []
    args = parse("export", "runs/r00", "--output", "net.pt", "--overwrite")
    assert args.force is True
    assert deprecations(capsys) == [deprecation_line(f"{PROG} export", "--overwrite", "--force")]
    with pytest.raises(SystemExit):
        parse("export", "runs/r00")  # the output is required
    assert "-o/--output" in capsys.readouterr().err


FLY = ("fly", "--world", "Gym/Central_Obstacle_Torus", "--mission", "Gym/2UAVs_Crossing_ORCA", "--model", "n.pt")


def test_fly_new_spellings_and_its_dataset_policies_stay(capsys):
    args = parse(*FLY, "-o", "cmp", "--rtf", "5", "--search-path", "a", "--search-path", "b", "--overwrite")
    assert args.output == Path("cmp") and args.rtf == "5" and args.search_path == [Path("a"), Path("b")]
    assert args.policy == "overwrite" and deprecations(capsys) == []  # --overwrite: the dataset policy, kept
    assert parse(*FLY, "--append").policy == "append"
    assert parse(*FLY).rtf == "max"


def test_fly_old_output_spelling(capsys):
    assert parse(*FLY, "--out", "cmp").output == Path("cmp")
    assert deprecations(capsys) == [deprecation_line(f"{PROG} fly", "--out", "-o/--output")]


def test_thesis_new_and_old_spellings(capsys):
    args = parse("thesis", "-o", "t", "--force", "--rtf", "2", "--search-path", "../shared/ros_magna_corpus")
    assert args.output == Path("t") and args.force is True and args.rtf == "2"
    assert args.search_path == [Path("../shared/ros_magna_corpus")] and deprecations(capsys) == []
    args = parse("thesis", "--out", "t", "--overwrite")
    assert args.output == Path("t") and args.force is True
    assert deprecations(capsys) == [deprecation_line(f"{PROG} thesis", "--out", "-o/--output"),
                                    deprecation_line(f"{PROG} thesis", "--overwrite", "--force")]


def test_rtf_metavar_is_the_same_everywhere():
    parser = argparse.ArgumentParser(prog=PROG)
    cli.add_arguments(parser)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in ("fly", "thesis"):
        assert "--rtf max|FACTOR" in sub.choices[name].format_help()


def test_pickle_refuses_an_existing_output_before_any_work_and_force_lifts_it(tmp_path, capsys):
    config = tmp_path / "c.json"
    config.write_text(json.dumps({"world": "Gym", "subworld": "Nowhere", "mission": "Gym", "submission": "None",
                                  "data_root": str(tmp_path)}))
    out = tmp_path / "s.npz"
    out.write_text("kept")
    assert cli.main(["pickle", str(config), "-o", str(out)]) == 2
    assert capsys.readouterr().err.strip() == f"mlr: --output {out} already exists; pass --force to replace it"
    assert out.read_text() == "kept"
    assert cli.main(["pickle", str(config), "-o", str(out), "--force"]) == 2  # past the check: no such dataset
    assert "no such dataset; run it first (magna run" in capsys.readouterr().err
    assert out.read_text() == "kept"


def test_messages_name_commands_that_exist():
    """No message, help or docstring tells users to type `mlr COMMAND` (there is no such command)."""
    pattern = re.compile(r"(?<![\w./-])mlr (train|pickle|board|export|fly|thesis)\b")
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}" for folder in ("mlr", "voice")
             for path in sorted((ROOT / folder).glob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert found == []


# --- board --------------------------------------------------------------------------------------------------

def test_board_runs_the_workspaces_tensorboard_with_the_port():
    args = parse("board", "~/runs/x", "--port", "6010")
    assert cli.board_argv(args) == [sys.executable, "-m", "tensorboard.main", "--logdir",
                                    str(Path("~/runs/x").expanduser()), "--port", "6010"]
    assert cli.board_argv(parse("board", "r", "--bind-all"))[-1] == "--bind_all"


def test_board_refuses_a_folder_without_logs(tmp_path, capsys):
    assert cli.main(["board", str(tmp_path / "missing")]) == 2
    assert f"{tmp_path / 'missing'}: no such folder" in capsys.readouterr().err
    assert cli.main(["board", str(tmp_path)]) == 2
    assert f"{tmp_path}: no TensorBoard logs in it" in capsys.readouterr().err


def serves(port: int) -> bool:
    try:
        with urllib.request.urlopen(f"http://localhost:{port}/", timeout=2) as reply:
            return reply.status == 200
    except OSError:
        return False


def tensorboards_on(logdir: Path) -> list[int]:
    """Processes whose command line serves `logdir`."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            argv = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"tensorboard.main" in argv and str(logdir).encode() in argv:
            found.append(int(proc.name))
    return found


def wait_until(condition, limit: float = 120.0) -> bool:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return condition()


@pytest.mark.timeout(300)
def test_board_serves_the_runs_and_ctrl_c_stops_it_cleanly(tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    runs = tmp_path / "runs"
    with SummaryWriter(str(runs / "r00")) as writer:
        writer.add_scalar("loss/train", 1.0, 0)
    port = free_port()
    board = subprocess.Popen([sys.executable, "-m", "mlr", "board", str(runs), "--port", str(port)], cwd=ROOT,
                             stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        assert wait_until(lambda: serves(port) or board.poll() is not None), "TensorBoard never answered"
        assert board.poll() is None and serves(port), board.stderr.read() if board.poll() is not None else ""
        assert tensorboards_on(runs)
        os.kill(board.pid, signal.SIGINT)  # what Ctrl-C sends it
        _, err = board.communicate(timeout=60)
    finally:
        if board.poll() is None:
            os.killpg(board.pid, signal.SIGKILL)
            board.wait()
    assert board.returncode == 0, err
    assert f"TensorBoard on {runs}: http://localhost:{port}/" in err and "TensorBoard stopped" in err
    assert "Traceback" not in err
    assert wait_until(lambda: not tensorboards_on(runs), 30) and not serves(port)
