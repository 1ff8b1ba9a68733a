"""magna_common.files: a reader never sees half a file, and nothing is replaced unless asked."""
import json
import os
import stat

import pytest

from magna_common import files


def test_write_atomically_refuses_a_file_that_appears_while_writing(tmp_path):
    target = tmp_path / "x.txt"

    def racing_writer(out):
        out.write("ours")
        target.write_text("theirs")  # someone else got there first

    with pytest.raises(FileExistsError):
        files.write_atomically(target, racing_writer)
    assert target.read_text() == "theirs"
    assert [p.name for p in tmp_path.iterdir()] == ["x.txt"]
    files.write_atomically(target, lambda out: out.write(b"bytes"), overwrite=True, binary=True)
    assert target.read_bytes() == b"bytes"


def test_write_atomically_gives_the_mode_a_plain_open_would(tmp_path):
    old = os.umask(0o027)
    try:
        made = files.write_atomically(tmp_path / "new.txt", lambda out: out.write("x"))
        replaced = files.write_atomically(made, lambda out: out.write("y"), overwrite=True)
    finally:
        os.umask(old)
    assert stat.S_IMODE(made.stat().st_mode) == 0o640  # 0o666 less the umask, not mkstemp's 0o600
    assert stat.S_IMODE(replaced.stat().st_mode) == 0o640


def test_write_text_atomically_replaces_only_when_asked_and_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "deep" / "world.json"
    files.write_text_atomically(target, json.dumps({"a": [1, 2.5, "x"]}))
    assert json.loads(target.read_text()) == {"a": [1, 2.5, "x"]}
    with pytest.raises(FileExistsError):
        files.write_text_atomically(target, json.dumps({"b": 2}))
    files.write_text_atomically(target, json.dumps({"b": 2}), overwrite=True)  # replaces
    assert json.loads(target.read_text()) == {"b": 2}
    assert [p.name for p in target.parent.iterdir()] == ["world.json"]  # no temporary file left


def test_write_atomically_keeps_the_old_file_when_writing_fails(tmp_path):
    target = tmp_path / "world.json"
    files.write_text_atomically(target, json.dumps({"good": True}))
    with pytest.raises(TypeError):
        files.write_atomically(target, lambda out: json.dump({"good": 1, "bad": object()}, out), overwrite=True)
    assert json.loads(target.read_text()) == {"good": True}
    assert [p.name for p in tmp_path.iterdir()] == ["world.json"]
