"""Every error is one line on standard error, whatever the names and messages hold: line
breaks and control characters are printed as escapes, never acted on by the terminal."""

from __future__ import annotations

from pathlib import Path

import pytest

from skillcompose import FSA, FSAValidationError, State
from skillcompose.cli import main
from skillcompose.errors import Problem, SkillcomposeError, one_line, printable

ROOT = Path(__file__).resolve().parents[2]
TOY = str(ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml")


def _one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.endswith("\n") and err.count("\n") == 1, err
    line = err[:-1]
    assert line.isprintable(), repr(line)
    return line


def test_one_line_escapes_line_breaks_and_control_characters() -> None:
    assert one_line("plain é 🤖 \\ text") == "plain é 🤖 \\ text"
    assert one_line("a\nb\r\tc\x1b[2J\x00\x7f\x85\u2028\u202e\U000e0001") == (
        "a\\nb\\r\\tc\\x1b[2J\\x00\\x7f\\x85\\u2028\\u202e\\U000e0001")


def test_printable_keeps_a_list_of_problems_and_escapes_within_it() -> None:
    exc = FSAValidationError([Problem("bad\nvalue", "A\x1b", "k", "fix\x07it", 3, 4),
                              Problem("second", None, None, None, 5, 1)], "dir\n/f.yaml")
    assert printable(exc) == (
        "invalid FSA (2 problems):\n"
        "  dir\\n/f.yaml:3:4: state A\\x1b: bad\\nvalue; fix\\x07it\n"
        "  dir\\n/f.yaml:5:1: second")
    assert printable(SkillcomposeError("one\n  two\x1b")) == "one\\n  two\\x1b"
    assert printable(ValueError("x\ny")) == "x\\ny"


def test_a_file_name_and_state_name_with_line_breaks_stay_on_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    bad = tmp_path / "bad\nname.yaml"
    bad.write_text('format: 1\nstart: "A\\nB"\nstates: {"A\\nB": {skill: X, transitions: '
                   "{ok: success}}}\n")
    assert main(["validate", str(bad)]) == 2
    shown = str(bad).replace("\n", "\\n")
    assert _one_error_line(capsys) == (
        f"skillcompose validate: error: {shown}:3:10: state A\\nB: state name 'A\\nB' must be "
        "a non-empty string without spaces")
    assert main(["run", str(tmp_path / "gone\x1b[2J.yaml")]) == 2
    assert _one_error_line(capsys) == (
        f"skillcompose run: error: {tmp_path}/gone\\x1b[2J.yaml: file not found; check the path")


def test_a_state_name_with_escape_is_refused_not_printed_raw(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    esc = tmp_path / "esc.yaml"
    esc.write_text('format: 1\nstart: "A\\e[2J"\nstates: {"A\\e[2J": {skill: FindBlock, '
                   "transitions: {success: success}}}\n")
    assert main(["validate", str(esc), "--task", "examples.toy_task"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "\x1b" not in captured.err
    assert captured.err == (
        f"skillcompose validate: error: {esc}:3:10: state A\\x1b[2J: state name 'A\\x1b[2J' "
        "holds a control character (U+001B), which would act on a terminal or a drawing "
        "instead of showing; rename the state without it\n")


def test_an_exception_message_with_line_breaks_stays_on_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    task = tmp_path / "mt.py"
    task.write_text('def make_task(**kw):\n    raise ValueError("bad setting\\nsecond line'
                    '\\x1b[2J")\n')
    assert main(["run", TOY, "--task", str(task)]) == 2
    line = _one_error_line(capsys)
    assert line.startswith("skillcompose run: error: task ")
    assert line.endswith("ValueError: bad setting\\nsecond line\\x1b[2J")


def test_a_usage_error_with_a_line_break_stays_on_one_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["run", TOY, "--trials", "1\n2"])
    assert exit_.value.code == 2
    assert _one_error_line(capsys) == (
        "skillcompose run: error: argument --trials: must be a whole number from 1 to "
        "1000000, got '1\\n2' (see skillcompose run --help)")


def test_an_fsa_built_in_python_reports_on_one_line_too() -> None:
    with pytest.raises(FSAValidationError) as refused:
        FSA({"A": State("X", {}, {"ok": "B\nC"})}, "A")
    assert "\n" not in str(refused.value)


def test_results_naming_the_file_escape_it_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """Not only errors: the lines `validate` and `run` print name the file escaped."""
    odd = tmp_path / "a\x1b[31m\nb.yaml"
    odd.write_text(Path(TOY).read_text())
    shown = str(odd).replace("\x1b", "\\x1b").replace("\n", "\\n")
    assert main(["validate", str(odd), "--task", "examples.toy_task"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{shown}: valid, ") and out.count("\n") == 1, out
    assert main(["run", str(odd), "--task", "examples.toy_task", "--trials", "2"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{shown}: 2 run(s), seed ") and "\x1b" not in out, out


def test_the_first_error_of_runs_prints_its_message_escaped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """A skill's exception message with line breaks and escape sequences, in the report of
    runs that ended in error: escaped as every error line is."""
    (tmp_path / "loud.py").write_text(
        "from typing import Literal\nfrom skillcompose import skill\n@skill()\n"
        "def loud(bb, rng) -> Literal['success']:\n"
        "    raise RuntimeError('line1\\nline2\\x1b[2J\\x07')\n")
    fsa = tmp_path / "l.yaml"
    fsa.write_text("format: 1\nstart: A\nstates: {A: {skill: Loud, transitions: "
                   "{success: success}}}\n")
    assert main(["run", str(fsa), "--skills", str(tmp_path / "loud.py"), "--trials", "2"]) == 1
    captured = capsys.readouterr()
    text = captured.out + captured.err
    assert "RuntimeError: line1\\nline2\\x1b[2J\\x07" in text
    assert "\x1b" not in text and "\x07" not in text


def test_task_and_fsa_names_with_control_characters_are_refused(tmp_path: Path) -> None:
    """The task's name goes into every evolved FSA's name and every line naming the task:
    a task named with a line break or an escape is refused where it is made, and an FSA
    file whose name holds one is refused at its line."""
    from skillcompose import Blackboard, Registry, load_fsa
    from skillcompose.task import Task, TaskError

    def make(name: str) -> Task:
        return Task(name=name, registry=Registry(), setup=lambda rng: Blackboard(),
                    fitness=lambda outcome, bb, steps: 0.0)

    assert make("fetch é").name == "fetch é"
    for name in ("a\nb", "a\x1b[2Jb", "", "  "):
        with pytest.raises(TaskError, match="must be non-empty text without control"):
            make(name)
    bad = tmp_path / "named.yaml"
    bad.write_text('format: 1\nname: "mine\\e[2J"\nstart: A\nstates: {A: {skill: X, '
                   "transitions: {ok: success}}}\n")
    with pytest.raises(FSAValidationError) as err:
        load_fsa(bad)
    assert "name 'mine\\x1b[2J' holds a control character (U+001B)" in str(err.value)
    assert ":2:" in printable(err.value)
