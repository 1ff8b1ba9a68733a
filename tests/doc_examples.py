"""Every shell example in the READMEs and the `--help` texts, found and run as a user would.

An example is one command line of a ```sh block of a README, or one line under `examples:` in a
`--help` text (continuation lines ending in `\\` join the next). A trailing comment may carry marks
in square brackets that say why an example is not run here, or how it runs:

    [display]     needs a screen           [microphone]  needs a microphone
    [hardware]    needs a real UAV or autopilot
    [long]        takes longer than this test's budget
    [cluster]     needs other machines or a Slurm cluster
    [fresh clone] needs a clone without catkin build's build/ and devel/ (e.g. catkin_make)
    [synopsis]    a form with placeholders, not an example
    [background]  runs until stopped: started, then the block's next lines run, then it is stopped

The examples of one README block run in one shell, in order, so `source devel/setup.bash` or `cd`
carries to the next line, as for a user typing them. READMEs run with nothing sourced, from the
repository root; `--help` examples run as their `magna ...` reads, with `magna` on PATH.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from tests.support import ros_nodes

ROOT = Path(__file__).resolve().parents[1]

NOT_RUN_MARKS = ("display", "microphone", "hardware", "long", "cluster", "fresh clone", "synopsis")
RUN_MARKS = ("background",)
MARKS = NOT_RUN_MARKS + RUN_MARKS
SHELL_LANGUAGES = {"sh", "bash", "shell", "console"}
EXAMPLE_STARTS = ("magna ", "./magna ", "rosrun ", "roslaunch ", "rosservice ", "rostopic ", "make ",
                  "python ", "python3 ")
# Commands that change the shell a user types in, so they run in it rather than in a child.
SHELL_STATE_COMMANDS = ("source ", ". ", "cd ", "export ")
COMMAND_TIMEOUT = 420.0  # s per example: the bounded time an example may take here
STOP_GRACE = 15.0  # s a background example gets to end after Ctrl-C
BLOCK_TOKEN = "MAGNA_DOCS_BLOCK"
DIED = "has died"  # roslaunch's words for a node that ended by itself


@dataclass
class Example:
    source: str  # "README.md:12" or "magna run --help"
    command: str  # the shell text, continuations joined
    marks: tuple[str, ...] = ()
    block: str = ""  # examples of one block share one shell

    @property
    def runs_here(self) -> bool:
        return not any(mark in NOT_RUN_MARKS for mark in self.marks)

    @property
    def background(self) -> bool:
        return "background" in self.marks


@dataclass
class Outcome:
    example: Example
    status: str  # "passed", "failed", or "not run: <mark>"
    returncode: int | None = None
    seconds: float = 0.0
    output: str = ""


@dataclass
class Block:
    name: str
    examples: list[Example] = field(default_factory=list)
    sourced: bool = False  # help-text examples: run with the workspace sourced (`magna` on PATH)


class ExampleError(ValueError):
    """A documented example that cannot be understood (an unknown mark)."""


def split_comment(line: str) -> tuple[str, str]:
    """The command and its trailing comment: `#` after whitespace, outside quotes."""
    quote = ""
    for index, char in enumerate(line):
        if quote:
            if char == quote:
                quote = ""
        elif char in "'\"":
            quote = char
        elif char == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index].rstrip(), line[index + 1:].strip()
    return line.rstrip(), ""


def marks_of(comment: str, where: str) -> tuple[str, ...]:
    found = tuple(mark.strip() for mark in re.findall(r"\[([a-z ]+)\]", comment))
    unknown = [mark for mark in found if mark not in MARKS]
    if unknown:
        raise ExampleError(f"{where}: unknown mark [{unknown[0]}]; use one of "
                           + ", ".join(f"[{m}]" for m in MARKS))
    return found


def _join_continuations(lines: list[tuple[int, str]]) -> list[tuple[int, str]]:
    joined, pending, start = [], "", 0
    for number, line in lines:
        stripped = line.strip()
        if not pending:
            start = number
        if stripped.endswith("\\"):
            pending += stripped[:-1].rstrip() + " "
            continue
        joined.append((start, pending + stripped))
        pending = ""
    if pending:
        joined.append((start, pending.rstrip()))
    return joined


def readme_blocks(path: Path, root: Path = ROOT) -> list[Block]:
    """The ```sh blocks of one Markdown file, each a list of examples."""
    rel = path.relative_to(root).as_posix()
    blocks, current, in_block, start = [], [], False, 0
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        fence = re.match(r"^\s*```(\S*)", line)
        if fence:
            if in_block:
                blocks.append(_block(rel, start, current))
                in_block, current = False, []
            elif fence.group(1).lower() in SHELL_LANGUAGES:
                in_block, start = True, number
            continue
        if in_block:
            current.append((number, line))
    return [block for block in blocks if block.examples]


def _block(rel: str, start: int, lines: list[tuple[int, str]]) -> Block:
    block = Block(name=f"{rel}:{start}")
    for number, text in _join_continuations(lines):
        command, comment = split_comment(text)
        if not command:
            continue
        command = command.removeprefix("$ ")
        block.examples.append(Example(f"{rel}:{number}", command, marks_of(comment, f"{rel}:{number}"),
                                      block.name))
    return block


def help_examples(text: str, source: str) -> list[Example]:
    """The example lines under `examples:` in one --help text."""
    lines = text.splitlines()
    examples: list[Example] = []
    index = 0
    while index < len(lines):
        if re.match(r"^\s*examples?:\s*$", lines[index], re.IGNORECASE):
            section, index = [], index + 1
            while index < len(lines) and (not lines[index].strip() or lines[index][:1].isspace()):
                section.append((index, lines[index]))
                index += 1
            examples += _help_section(section, source)
        else:
            index += 1
    return examples


def _help_section(section: list[tuple[int, str]], source: str) -> list[Example]:
    found, pending = [], []
    for number, line in section:
        stripped = line.strip()
        if pending or stripped.startswith(EXAMPLE_STARTS):
            pending.append((number, line))
            if not stripped.endswith("\\"):
                found += _join_continuations(pending)
                pending = []
    examples = []
    for _, text in found:
        command, comment = split_comment(text)
        examples.append(Example(source, command, marks_of(comment, f"{source}: {command}"), source))
    return examples


def readmes(root: Path = ROOT) -> list[Path]:
    """The project's READMEs, the root one first (its `make run` makes the data later ones read)."""
    found = [root / "README.md"]
    for pattern in ("src/*/README.md", "*/README.md", "*/*/README.md"):
        for path in sorted(root.glob(pattern)):
            if path not in found and not any(part in {"build", "devel", "install", "logs"} or part.startswith(".")
                                             for part in path.relative_to(root).parts):  # .venv, .pytest_cache
                found.append(path)
    return found


def magna_help_texts() -> list[tuple[str, str]]:
    """(`magna ... --help`, its text) for the magna command and every subcommand, recursively."""
    import argparse

    from magna_master.cli import build_parser

    texts = []

    def walk(parser: argparse.ArgumentParser, words: list[str]) -> None:
        texts.append((" ".join(words + ["--help"]), parser.format_help()))
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, words + [name])

    walk(build_parser(), ["magna"])
    return texts


def help_blocks() -> list[Block]:
    blocks = []
    for source, text in magna_help_texts():
        examples = help_examples(text, source)
        if examples:
            blocks.append(Block(name=source, examples=examples, sourced=True))
    return blocks


def node_help_blocks(env: dict[str, str], root: Path = ROOT, timeout: float = 60.0) -> tuple[list[Block], list[str]]:
    """The `examples:` of every node's `rosrun PACKAGE NODE --help`, one block per node, and the
    nodes whose --help failed."""
    blocks, failed = [], []
    setup = shlex.quote(str(root / "devel" / "setup.bash"))
    for package, node in ros_nodes(root):
        source = f"rosrun {package} {node} --help"
        shown = subprocess.run(["timeout", "-k", "5", f"{timeout:.0f}", "bash", "-c", f"source {setup} && {source}"],
                               env=env, cwd=root, capture_output=True, text=True, stdin=subprocess.DEVNULL)
        if shown.returncode != 0:
            failed.append(f"{source} exited {shown.returncode}: {shown.stderr.strip()[-500:]}")
        examples = help_examples(shown.stdout, source)
        if examples:
            blocks.append(Block(name=source, examples=examples, sourced=True))
    return blocks, failed


def user_environment(home: Path, master_port: int, root: Path = ROOT) -> dict[str, str]:
    """A user's shell that has sourced nothing of this workspace, with its own HOME and ROS master port."""
    drop_prefixes = ("ROS_", "MAGNA_", "CATKIN_", "PYTHONPATH", "CMAKE_PREFIX_PATH", "LD_LIBRARY_PATH",
                     "PKG_CONFIG_PATH", "VIRTUAL_ENV", "ROSLISP_", "PYTEST_")
    env = {key: value for key, value in os.environ.items() if not key.startswith(drop_prefixes)}
    if os.environ.get("MAGNA_TEST_RUN"):
        env["MAGNA_TEST_RUN"] = os.environ["MAGNA_TEST_RUN"]  # the leak check's token stays
    keep = [entry for entry in os.environ.get("PATH", "").split(os.pathsep)
            if entry and not Path(entry).resolve().is_relative_to(root.resolve())]
    env["PATH"] = os.pathsep.join(keep)
    pyenv = next((Path(entry).parent for entry in keep if entry.endswith("/.pyenv/shims")), None)
    if pyenv and "PYENV_ROOT" not in env:
        env["PYENV_ROOT"] = str(pyenv)  # pyenv finds itself through HOME otherwise
    env.update(HOME=str(home), ROS_HOME=str(home / ".ros"), ROS_MASTER_URI=f"http://localhost:{master_port}",
               MPLBACKEND="Agg")
    env.pop("DISPLAY", None)
    return env


def _shell_line(example: Example, index: int, work: Path, timeout: float) -> str:
    out, rc = work / f"out_{index}", work / f"rc_{index}"
    command = example.command
    if example.background:
        started = (f"bash -c {shlex.quote(command)} > {out} 2>&1 < /dev/null & "
                   f"background_{index}=$!; echo $! >> {work / 'background'}\n")
        if command.startswith(("roscore", "roslaunch")):
            # As a user waits to see the master up before typing on: it answers, or 60 s pass.
            started += ("timeout 60 bash -c 'until rosparam get /rosdistro > /dev/null 2>&1; "
                        "do sleep 0.2; done'\n")
        return started
    if command.startswith(SHELL_STATE_COMMANDS):
        return f"{{ {command} ; }} > {out} 2>&1 < /dev/null; echo $? > {rc}\n"
    return (f"timeout -k 10 {timeout:.0f} bash -c {shlex.quote(command)} > {out} 2>&1 < /dev/null; "
            f"echo $? > {rc}; date +%s.%N > {work / f'end_{index}'}\n")


def run_block(block: Block, env: dict[str, str], work: Path, root: Path = ROOT,
              timeout: float = COMMAND_TIMEOUT) -> list[Outcome]:
    """Run the block's examples in one shell, in order; stop background ones at the end."""
    work.mkdir(parents=True, exist_ok=True)
    # Job control: each background example is a process group of its own (stopped as a whole) and
    # keeps Ctrl-C (without it bash makes background jobs ignore SIGINT).
    # Every process of the block carries its token, so one an example leaves behind is found.
    token = uuid.uuid4().hex
    script = ["set +e -m\n", f"export {BLOCK_TOKEN}={token}\n", f"cd {shlex.quote(str(root))}\n"]
    if block.sourced:
        script.append(f"source {shlex.quote(str(root / 'devel' / 'setup.bash'))}\n")
    runnable = [(index, example) for index, example in enumerate(block.examples) if example.runs_here]
    for index, example in runnable:
        script.append(f"date +%s.%N > {work / f'start_{index}'}\n")
        script.append(_shell_line(example, index, work, timeout))
    for index, example in runnable:
        if example.background:  # still running when the block ends, or ended by itself: with what status
            script.append(f"if kill -0 $background_{index} 2> /dev/null; then echo running > {work / f'rc_{index}'}; "
                          f"else wait $background_{index}; echo $? > {work / f'rc_{index}'}; fi\n")
    (work / "script.sh").write_text("".join(script))
    try:
        subprocess.run(["bash", str(work / "script.sh")], env=env, cwd=root, stdin=subprocess.DEVNULL,
                       timeout=timeout * max(1, len(runnable)) + 60, check=False)
    finally:
        _stop_background(work / "background")
        left = _end_leftovers(token)
    outcomes = [_outcome(example, index, work) for index, example in enumerate(block.examples)]
    if left:
        last = next((o for o in reversed(outcomes) if o.returncode is not None), None)
        if last is not None:  # the block's processes outlived it: blame the block's last run example
            last.status = "failed"
            last.output += "\n(processes left running after the block, now ended: " + "; ".join(left) + ")"
    return outcomes


def _end_leftovers(token: str) -> list[str]:
    """End, and name, the processes of a block still alive after its background examples were stopped."""
    from scripts.leftover_processes import carrying

    left = carrying(token.encode(), BLOCK_TOKEN.encode())
    for pid, _ in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return [command[:120] for _, command in left]


def _stop_background(pid_file: Path) -> None:
    if not pid_file.exists():
        return
    pids = [int(line) for line in pid_file.read_text().split()]
    # Ctrl-C, as a user ends a launch; then the usual escalation for what ignores it.
    for sig, grace in ((signal.SIGINT, STOP_GRACE), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        for pid in pids:
            _signal_group(pid, sig)
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline and any(_group_alive(pid) for pid in pids):
            time.sleep(0.1)


def _signal_group(pid: int, sig: int) -> None:
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _group_alive(pid: int) -> bool:
    try:
        os.killpg(pid, 0)
    except (ProcessLookupError, PermissionError):
        return False
    return True


def _outcome(example: Example, index: int, work: Path) -> Outcome:
    if not example.runs_here:
        mark = next(mark for mark in example.marks if mark in NOT_RUN_MARKS)
        return Outcome(example, f"not run: {mark}")
    rc_file, out_file = work / f"rc_{index}", work / f"out_{index}"
    output = out_file.read_text(errors="replace") if out_file.exists() else ""
    if not rc_file.exists():
        return Outcome(example, "failed", None, 0.0, output + "\n(the block's shell ended before this example)")
    status_text = rc_file.read_text().strip()
    returncode = 0 if status_text == "running" else int(status_text or -1)
    seconds = _seconds(work, index)
    if returncode == 124:
        output += f"\n(stopped after {COMMAND_TIMEOUT:.0f} s)"
    if example.background and DIED in output:
        # A node of a background launch crashed, or a normal stop reported a death.
        return Outcome(example, "failed", returncode, seconds, output + f"\n(its output says '{DIED}')")
    return Outcome(example, "passed" if returncode == 0 else "failed", returncode, seconds, output)


def _seconds(work: Path, index: int) -> float:
    try:
        start = float((work / f"start_{index}").read_text())
        end = float((work / f"end_{index}").read_text())
    except (OSError, ValueError):
        return 0.0
    return end - start


def write_table(outcomes: list[Outcome], path: Path) -> None:
    """Every documented command with its result, as a Markdown table (for people, not for parsing)."""
    rows = ["| where | command | result | s |", "|---|---|---|---|"]
    for outcome in outcomes:
        command = outcome.example.command.replace("|", "\\|")
        code = "" if outcome.returncode in (None, 0) else f" (exit {outcome.returncode})"
        seconds = f"{outcome.seconds:.0f}" if outcome.seconds else ""
        rows.append(f"| {outcome.example.source} | `{command}` | {outcome.status}{code} | {seconds} |")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text("\n".join(rows) + "\n")
    tmp.replace(path)


def new_untracked_files(root: Path, since: float) -> list[str]:
    """Files an example wrote into the repository (untracked, not ignored, made after `since`)."""
    if not shutil.which("git") or not (root / ".git").exists():
        return []
    listing = subprocess.run(["git", "ls-files", "--others", "--exclude-standard", "-z"], cwd=root,
                             capture_output=True, text=True, check=False).stdout
    return [name for name in listing.split("\0") if name and (root / name).stat().st_mtime >= since]
