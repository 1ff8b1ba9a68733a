"""The docs test: every shell example of the READMEs and the `magna ... --help` texts runs as written.

Each README ```sh block, and each help text's `examples:`, is one test; its lines run in one shell,
in order, from the repository root, in a temporary HOME (so `~/magna_data` starts empty) and with
ROS_MASTER_URI on a free port. README blocks run with nothing of the workspace sourced, as for a
newcomer; help examples run with `magna` on PATH, as for someone who just read `magna ... --help`.
The blocks run in file order, root README first: its `make run` makes the data later examples read.

Examples marked [display], [microphone], [hardware], [long], [cluster], [fresh clone] or [synopsis] are not run;
they are listed at the end of the session and, with every result, in
build/magna_test_results/documented_commands.md.
"""
from __future__ import annotations

import time

import pytest

from magna_common.ports import free_port
from tests import doc_examples

RESULTS = doc_examples.ROOT / "build" / "magna_test_results" / "documented_commands.md"


def _collect():
    blocks, problems = [], []
    for path in doc_examples.readmes():
        try:
            blocks += doc_examples.readme_blocks(path)
        except doc_examples.ExampleError as error:
            problems.append(str(error))
    try:
        blocks += doc_examples.help_blocks()
    except doc_examples.ExampleError as error:
        problems.append(str(error))
    return blocks, problems


BLOCKS, PROBLEMS = _collect()


@pytest.fixture(scope="module")
def newcomer(tmp_path_factory, request):
    """A user's shell: fresh HOME, a free ROS master port, nothing sourced; collects every outcome."""
    home = tmp_path_factory.mktemp("home")
    state = {"env": doc_examples.user_environment(home, free_port()), "home": home,
             "work": tmp_path_factory.mktemp("doc_examples"), "outcomes": [], "run_blocks": {}}
    yield state
    outcomes = state["outcomes"]
    doc_examples.write_table(outcomes, RESULTS)
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    not_run = [o for o in outcomes if o.status.startswith("not run")]
    if reporter and not_run:
        reporter.write_line(f"\ndocumented examples not run here ({len(not_run)}; all results: {RESULTS}):")
        for outcome in not_run:
            reporter.write_line(f"  {outcome.example.source}: {outcome.example.command}   ({outcome.status})")


def _run(block, newcomer) -> list[str]:
    """Run one block (or reuse the result of a block with the very same lines: a node's help can show
    its magna command's examples); return what failed."""
    key = (block.sourced, tuple(example.command for example in block.examples))
    if key in newcomer["run_blocks"]:
        first = newcomer["run_blocks"][key]
        outcomes = [doc_examples.Outcome(example, f"{o.status} (same lines as {first})", o.returncode)
                    for example, o in zip(block.examples, newcomer["by_block"][first], strict=True)]
        newcomer["outcomes"] += outcomes
        return []
    started = time.time()
    work = newcomer["work"] / block.name.replace("/", "_").replace(" ", "_").replace(":", "_")
    outcomes = doc_examples.run_block(block, newcomer["env"], work)
    newcomer["run_blocks"][key] = block.name
    newcomer.setdefault("by_block", {})[block.name] = outcomes
    newcomer["outcomes"] += outcomes
    report = [f"{o.example.source}: `{o.example.command}` exited {o.returncode}:\n{o.output[-3000:]}"
              for o in outcomes if o.status == "failed"]
    report += [f"an example wrote {name} into the repository; write under ~ or /tmp instead"
               for name in doc_examples.new_untracked_files(doc_examples.ROOT, started)]
    return report


def test_every_example_has_known_marks():
    assert PROBLEMS == []


def test_the_docs_have_examples_to_run():
    # Guards the extraction itself: the READMEs and help texts hold well over a hundred examples.
    runnable = [example for block in BLOCKS for example in block.examples if example.runs_here]
    assert len(runnable) > 50


@pytest.mark.timeout(3600)
@pytest.mark.parametrize("block", BLOCKS, ids=[block.name for block in BLOCKS])
def test_documented_examples_run(block, newcomer):
    report = _run(block, newcomer)
    assert not report, "\n\n".join(report)


@pytest.mark.timeout(3600)
def test_node_help_examples_run(newcomer):
    """The `examples:` of every `rosrun PACKAGE NODE --help` (asked of the nodes here, not at collection)."""
    blocks, report = doc_examples.node_help_blocks(newcomer["env"])
    assert blocks, "no node's --help shows examples; the search for them is broken"
    for block in blocks:
        report += _run(block, newcomer)
    assert not report, "\n\n".join(report)
