"""How the docs test finds examples: README blocks, help sections, comments and marks."""
import pytest

from magna_common.ports import free_port
from tests import doc_examples


def test_split_comment_ignores_hashes_in_quotes_and_words():
    assert doc_examples.split_comment('echo "a # b" # why [long]') == ('echo "a # b"', "why [long]")
    assert doc_examples.split_comment("curl x#y") == ("curl x#y", "")


def test_readme_blocks_join_continuations_and_read_marks(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("text\n```sh\n./magna run --world A \\\n    --mission B   # fly [long]\n\n"
                      "# only a comment\nroslaunch x y.launch   # [background]\n```\n```json\n{}\n```\n")
    (block,) = doc_examples.readme_blocks(readme, root=tmp_path)
    assert [e.command for e in block.examples] == ["./magna run --world A --mission B", "roslaunch x y.launch"]
    assert block.examples[0].marks == ("long",) and not block.examples[0].runs_here
    assert block.examples[1].background and block.examples[1].runs_here
    assert block.examples[0].source == "README.md:3"


def test_an_unknown_mark_is_an_error_naming_the_place(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("```sh\nmake run  # [someday]\n```\n")
    with pytest.raises(doc_examples.ExampleError, match=r"README.md:2: unknown mark \[someday\]"):
        doc_examples.readme_blocks(readme, root=tmp_path)


def test_help_examples_are_the_command_lines_under_examples():
    text = ("usage: magna x\n\nsome words\n\nexamples:\n  magna x --a 1 \\\n      --b 2\n"
            "  a line of prose\n\n  ./magna x --c   # [display]\nafter: not an example\n  magna y\n")
    examples = doc_examples.help_examples(text, "magna x --help")
    assert [e.command for e in examples] == ["magna x --a 1 --b 2", "./magna x --c"]
    assert examples[1].marks == ("display",)


def test_a_block_runs_in_one_shell_and_reports_each_line(tmp_path):
    block = doc_examples.Block("b", [
        doc_examples.Example("s:1", "cd /tmp"),
        doc_examples.Example("s:2", "test \"$PWD\" = /tmp"),
        doc_examples.Example("s:3", "false"),
        doc_examples.Example("s:4", "sleep 600", ("background",)),
        doc_examples.Example("s:5", "true", ("display",)),
        doc_examples.Example("s:6", "exit 3", ("background",)),
        # (runs in the block's shell, as `export` lines do, to wait for the one before to end)
        doc_examples.Example("s:7", "export X=1; while kill -0 $background_5 2> /dev/null; do sleep 0.05; done"),
    ])
    env = doc_examples.user_environment(tmp_path / "home", free_port())
    outcomes = doc_examples.run_block(block, env, tmp_path / "work", timeout=60)
    assert [o.status for o in outcomes] == ["passed", "passed", "failed", "passed", "not run: display",
                                                 "failed", "passed"]
    assert outcomes[2].returncode == 1 and outcomes[5].returncode == 3  # a background one that ended badly
    pids = (tmp_path / "work" / "background").read_text().split()
    assert pids and not any(doc_examples._group_alive(int(pid)) for pid in pids)


def test_the_newcomer_has_nothing_of_the_workspace_sourced(tmp_path):
    env = doc_examples.user_environment(tmp_path, 12345)
    root = str(doc_examples.ROOT)
    assert not any(entry.startswith(root) for entry in env["PATH"].split(":"))
    assert "ROS_PACKAGE_PATH" not in env and "PYTHONPATH" not in env
    assert env["HOME"] == str(tmp_path) and env["ROS_MASTER_URI"] == "http://localhost:12345"


def test_a_process_an_example_leaves_behind_is_ended_and_reported(tmp_path):
    # `&` inside an example orphans the sleep when its shell ends: the block must not leave it running.
    block = doc_examples.Block("b", [doc_examples.Example("s:1", "sleep 600 & echo started")])
    env = doc_examples.user_environment(tmp_path / "home", free_port())
    (outcome,) = doc_examples.run_block(block, env, tmp_path / "work", timeout=60)
    assert outcome.status == "failed" and "sleep 600" in outcome.output


def test_the_readmes_are_the_projects_own(tmp_path):
    for folder in ("src/pkg", "mlr", ".pytest_cache", "build/pkg", ".venv/lib"):
        (tmp_path / folder).mkdir(parents=True)
        (tmp_path / folder / "README.md").write_text("x\n")
    (tmp_path / "README.md").write_text("x\n")
    found = [path.relative_to(tmp_path).as_posix() for path in doc_examples.readmes(tmp_path)]
    assert found == ["README.md", "src/pkg/README.md", "mlr/README.md"]


def test_readmes_are_found_one_and_two_folders_down_but_not_in_hidden_or_build_folders(tmp_path):
    for folder in ("", "src/pkg", "mlr", "mlr/gym", ".venv/lib", "build/x"):
        (tmp_path / folder).mkdir(parents=True, exist_ok=True)
        (tmp_path / folder / "README.md").write_text("# r\n")
    found = [str(p.relative_to(tmp_path)) for p in doc_examples.readmes(tmp_path)]
    assert found == ["README.md", "src/pkg/README.md", "mlr/README.md", "mlr/gym/README.md"]
