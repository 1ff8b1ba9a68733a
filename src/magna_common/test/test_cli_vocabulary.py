"""The shared command-line vocabulary: new spellings, old ones with their deprecation line."""
import argparse
from pathlib import Path

import pytest

from magna_common import cli_vocabulary as vocabulary
from magna_common.errors import UsageError


def _parser():
    parser = argparse.ArgumentParser(prog="magna demo")
    vocabulary.add_output(parser, help="where to write", required=True, old=("--out",))
    vocabulary.add_force(parser, old=("--overwrite",))
    vocabulary.add_search_path(parser)
    vocabulary.add_rtf(parser)
    return parser


def test_new_spellings_parse_quietly(capsys):
    args = _parser().parse_args(["-o", "a.png", "--force", "--search-path", "x", "--search-path", "y",
                                 "--rtf", "2"])
    assert args.output == Path("a.png") and args.force is True
    assert args.search_path == [Path("x"), Path("y")] and args.rtf == "2"
    assert capsys.readouterr().err == ""


def test_old_spellings_still_work_and_say_what_replaces_them(capsys):
    args = _parser().parse_args(["--out", "b.png", "--overwrite"])
    assert args.output == Path("b.png") and args.force is True
    err = capsys.readouterr().err.splitlines()
    assert err == [vocabulary.deprecation_line("magna demo", "--out", "-o/--output"),
                   vocabulary.deprecation_line("magna demo", "--overwrite", "--force")]


def test_a_required_output_names_only_the_new_spelling_when_missing(capsys):
    with pytest.raises(SystemExit):
        _parser().parse_args([])
    err = capsys.readouterr().err
    assert "-o/--output" in err and "--out " not in err


def test_help_hides_old_spellings_and_shows_the_rtf_metavar():
    text = _parser().format_help()
    assert "--out " not in text and "--overwrite" not in text
    assert "max|FACTOR" in text and "--force" in text


def test_force_defaults_to_false_without_any_spelling():
    args = _parser().parse_args(["-o", "c"])
    assert args.force is False and args.rtf == "max"


def test_check_output_refuses_an_existing_file_without_force(tmp_path):
    target = tmp_path / "picture.png"
    vocabulary.check_output(target, force=False)  # absent: fine
    target.write_text("x")
    with pytest.raises(vocabulary.OutputExists, match="pass --force"):
        vocabulary.check_output(target, force=False, what="picture")
    vocabulary.check_output(target, force=True)


def test_rtf_values_are_max_or_a_positive_factor():
    assert vocabulary.parse_rtf(" MAX ") == "max"
    assert vocabulary.parse_rtf("10.0") == "10" and vocabulary.parse_rtf("0.5") == "0.5"
    for bad in ("0", "-1", "fast", "nan", "inf"):
        with pytest.raises(UsageError, match=f"--rtf '{bad}': give 'max'"):
            vocabulary.parse_rtf(bad)
