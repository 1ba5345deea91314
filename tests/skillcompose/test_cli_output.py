"""The scriptable command line: --json documents, --version, -q/-v everywhere, a light --help."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from skillcompose import __version__
from skillcompose.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = str(ROOT / "examples" / "pour_water_reference.fsa.yaml")


def _json(capsys: pytest.CaptureFixture[str], argv: list[str], status: int = 0) -> dict:
    assert main(argv) == status
    out = capsys.readouterr().out
    return json.loads(out)  # the whole of standard output is one document


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"skillcompose {__version__}"


def test_every_subcommand_takes_q_and_v_before_and_after_it() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert isinstance(sub, argparse._SubParsersAction)
    assert {"run", "validate", "show", "skills", "evolve", "robustness", "robot"} <= set(
        sub.choices)
    for name, command in sub.choices.items():
        options = set(command._option_string_actions)
        assert {"-q", "--quiet", "-v", "--verbose"} <= options, name
    for argv in (["-q", "validate", "f.yaml"], ["validate", "f.yaml", "-q"]):
        assert parser.parse_args(argv).quiet is True
    for argv in (["-vv", "validate", "f.yaml"], ["validate", "-vv", "f.yaml"]):
        assert parser.parse_args(argv).verbose == 2
    args = parser.parse_args(["-v", "evolve", "examples.toy_task"])
    assert (args.verbose, args.quiet) == (1, False)


def test_validate_json(capsys: pytest.CaptureFixture[str]) -> None:
    doc = _json(capsys, ["validate", REFERENCE, "--json", "--task", "examples.pour_water"])
    assert doc["command"] == "validate" and doc["valid"] is True
    assert doc["states"] == 6 and doc["start"] == "Recognise"
    assert doc["skills_checked"] > 0 and doc["problems"] == [] and doc["traps"] == []


def test_validate_json_of_a_broken_file_lists_its_problems_with_lines(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: 1\nstart: A\nstates:\n  A:\n    skill: Noop\n"
                   "    transitions: {success: B}\n")
    assert main(["validate", str(bad), "--json"]) == 2
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["valid"] is False and doc["problems"]
    assert any(p["line"] == 6 and "B" in p["message"] for p in doc["problems"]), doc
    assert "error" in captured.err  # the one-line error still goes to standard error


def test_skills_json(capsys: pytest.CaptureFixture[str]) -> None:
    doc = _json(capsys, ["skills", "--task", "examples.pour_water", "--json"])
    names = [s["name"] for s in doc["skills"]]
    assert names == sorted(names) and "GraspObject" in names
    pour = next(s for s in doc["skills"] if s["name"] == "GraspObject")
    assert set(pour) == {"name", "backends", "outcomes", "params", "reads", "writes", "doc"}
    assert "success" in pour["outcomes"]


def test_run_json_keeps_standard_output_for_the_document(
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = ["run", REFERENCE, "--task", "examples.pour_water", "--trials", "20", "--seed", "3",
            "--json", "--trace"]
    doc = _json(capsys, argv)
    assert doc["trials"] == 20 and sum(doc["outcomes"].values()) == 20
    assert doc["fitness"]["minimize"] in (True, False)
    assert doc["errors"] == {"count": 0, "first": None}
    assert _json(capsys, argv) == doc  # same seed, same document
    main(argv)
    assert "ended:" in capsys.readouterr().err  # the trace went to standard error


def test_quiet_and_verbose_notes(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    fsa = tmp_path / "f.yaml"
    fsa.write_text(Path(REFERENCE).read_text().replace("step_limit:", "# step_limit:")
                   + "step_limit: 99\n")
    argv = ["run", str(fsa), "--task", "examples.pour_water"]
    assert main(argv) == 0
    assert "step limit" in capsys.readouterr().err  # a note: the task's limit applies
    assert main(["-q", *argv]) == 0
    assert capsys.readouterr().err == ""
    assert main([*argv, "-v"]) == 0
    err = capsys.readouterr().err
    assert "loaded" in err and "exit status 0 after" in err


def test_evolve_json(capsys: pytest.CaptureFixture[str]) -> None:
    doc = _json(capsys, [  # no --out: no run directory, no pictures to draw
        "evolve", "examples.toy_task", "--population", "8", "--initial-nodes", "4",
        "--generations", "2", "--backend", "serial", "--check-trials", "5",
        "--simplify-trials", "5", "--json"])
    assert doc["command"] == "evolve" and doc["task"] == "toy_fetch"
    assert doc["generations"] <= 2 and doc["evaluations"] > 0
    assert doc["fresh"]["episodes"] == 5 and doc["files"] == [] and doc["out_dir"] is None
    assert set(doc) >= {"solved", "best_fitness", "states", "faults", "run_command"}


@pytest.mark.parametrize("argv", [["--help"], ["validate", REFERENCE]])
def test_help_and_validate_load_no_heavy_package(argv: list[str]) -> None:
    code = (
        "import sys\n"
        "from skillcompose.cli import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = ('pinocchio', 'casadi', 'matplotlib', 'ray', 'networkx', 'py_trees', 'numpy')\n"
        "print(sorted(m for m in heavy if m in sys.modules), file=sys.stderr)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert ("robot" in proc.stdout) if argv == ["--help"] else ("valid" in proc.stdout)
    assert proc.stderr.strip() == "[]"


@pytest.mark.parametrize("text", [
    "format: 1\nstart: A\nstates:\n  A: {skill: X, transitions: {ok: success}}\n  B: [\n",
    "format: 1\nstart: A\nstates:\n  A: {skill: X, transitions: {ok: nowhere}}\n",
])
def test_validate_json_of_an_invalid_file_goes_to_standard_output(
        text: str, tmp_path: Path) -> None:
    """`skillcompose validate bad.yaml --json > o.json` as a program: the document lands in
    o.json (it used to go to standard error exactly when the file was invalid), and the
    one-line error on standard error."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(text, encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "skillcompose", "validate", str(bad),
                           "--json"], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    document = json.loads(done.stdout)
    assert document["valid"] is False and document["problems"][0]["line"] >= 4
    assert len(done.stderr.strip().splitlines()) == 1
    assert done.stderr.startswith("skillcompose validate: error: ")
