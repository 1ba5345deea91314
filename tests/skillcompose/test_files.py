"""Reading files that may not be what they seem: a pipe never blocks a reader, a device or a
huge file is never read whole (``skillcompose.files.read_limited``), and every command that
reads an FSA file says so in one line."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from skillcompose.cli import main
from skillcompose.files import NotARegularFile, not_a_file, read_limited

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")


@pytest.fixture(autouse=True)
def _never_hang() -> Iterator[None]:
    signal.alarm(30)  # a regression would wait on a pipe for ever: fail instead
    try:
        yield
    finally:
        signal.alarm(0)


def test_read_limited_reads_regular_files_only_and_never_past_the_limit(
    tmp_path: Path,
) -> None:
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    for path, kind in ((pipe, "a pipe"), (Path("/dev/zero"), "a device"),
                       (tmp_path, "a folder")):
        with pytest.raises(NotARegularFile, match=f"it is {kind}, not a regular file"):
            read_limited(path, 10)
        assert not_a_file(path) == kind
    big = tmp_path / "big"
    with big.open("wb") as f:
        f.truncate(1 << 30)  # sparse
    assert len(read_limited(big, 100)) == 101  # more than the limit: the file is larger
    small = tmp_path / "small"
    small.write_bytes(b"abc")
    assert read_limited(small, 3) == b"abc" and not_a_file(small) is None
    assert not_a_file(tmp_path / "missing") is None
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    assert not_a_file(tmp_path / "dangling") == "a broken link"


@pytest.mark.parametrize("command", [["validate"], ["show"], ["run"]])
def test_an_fsa_file_that_is_a_pipe_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    pipe = tmp_path / "fsa.yaml"
    os.mkfifo(pipe)
    assert main([*command, str(pipe)]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [
        f"skillcompose {command[0]}: error: {pipe}: cannot read the file: it is a pipe, not a "
        "regular file; give the path of an FSA file"]


def test_an_argument_naming_a_pipe_says_what_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    os.mkfifo(tmp_path / "s.yaml")
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp_path)
        with pytest.raises(SystemExit) as stop:  # a path: checked as it is parsed
            main(["skills", "--skills", "./s.yaml"])
        assert stop.value.code == 2
        assert "argument --skills: './s.yaml' is a pipe, not a file" in \
            capsys.readouterr().err
        assert main(["skills", "--skills", "s.yaml"]) == 2  # read as an FSA file
        assert capsys.readouterr().err.splitlines() == [
            "skillcompose skills: error: s.yaml: cannot read the file: it is a pipe, not a "
            "regular file; give the path of an FSA file"]
